"""Result folders are written as a whole (issue 18): runs killed (SIGKILL) at many points of
their writing, and two runs writing the same folder at once, never leave a folder that mixes
two runs or holds a partial file; the next run cleans the temporaries up.

A folder is *complete* when its manifest lists exactly the files present, each with its
SHA-256 (checked here independently of the tool's own check)."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from thrustwalk_cli.files import output

MANIFEST = ".thrustwalk-run.json"
ARGS = ["limit-cycle", "three_link", "three_link_walk", "--quiet"]


def _complete(folder: Path) -> dict:
    """The manifest of a complete run (asserted), as a dict."""
    manifest = json.loads((folder / MANIFEST).read_text())
    present = {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
               for p in folder.rglob("*") if p.is_file() and p.name != MANIFEST}
    assert present == manifest["files"], f"{folder}: files and manifest differ"
    return manifest


def _thrust_of(folder: Path) -> list:
    return [c["thrust"] for c in json.loads((folder / "limit_cycles.json").read_text())["cycles"]]


def _leftovers(parent: Path, name: str) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if p.name.startswith(f".{name}."))


# A hook run in the child before the command (tests/preforked.py: a process of its own, forked
# with the package imported) that kills it (SIGKILL: no cleanup at all) at the K-th call of one
# function of the writer: each file write, the manifest, either rename of the swap.
KILLER = textwrap.dedent("""
    import os, signal
    from thrustwalk_cli.files import output
    what, k = {what!r}, {k!r}
    calls = [0]
    def hit():
        calls[0] += 1
        if calls[0] == k:
            os.kill(os.getpid(), signal.SIGKILL)
    if what == "rename":
        orig_rename = os.rename
        def rename(a, b):
            hit()
            return orig_rename(a, b)
        output.os.rename = rename
    else:
        orig = getattr(output, what)
        def wrapped(*a, **kw):
            hit()
            return orig(*a, **kw)
        setattr(output, what, wrapped)
""")


@pytest.fixture(scope="module")
def forked(_cache_dir):
    """Runs of the command in processes of their own, forked from one that imported the
    package, matplotlib, scipy and numba once (tests/preforked.py): the runs killed at a
    writer's call and the runs after them skip 2 s of imports each."""
    from preforked import Zygote

    zygote = Zygote(["thrustwalk_cli.cli", "thrustwalk_cli.commands.limit_cycle",
                     "thrustwalk_cli.studies.limit_cycle", "thrustwalk_cli.plots.limit_cycle",
                     "thrustwalk_cli.files.output", "matplotlib.backends.backend_agg",
                     "matplotlib.backends.backend_pdf", "scipy.integrate", "scipy.optimize",
                     "numba"])
    yield zygote
    zygote.close()


@pytest.fixture(scope="module")
def previous(tmp_path_factory, forked):
    """A complete previous run (thrust 0 and -10 N) to be replaced."""
    base = tmp_path_factory.mktemp("previous")
    res = forked.run([*ARGS, "--thrust", "0,-10", "--out", base / "run"], folder=base / "io")
    assert res.returncode == 0, res.stderr
    return base / "run"


# every point at which the writer can be killed: (function, K-th call)
KILL_POINTS = [("write_bytes_atomic", k) for k in (1, 2, 3, 4, 6)] + \
    [("write_json", 1), ("write_json", 2), ("write_csv", 1), ("rename", 1), ("rename", 2),
     ("rename", 3)]


@pytest.mark.parametrize("what, k", KILL_POINTS, ids=[f"{w}-{k}" for w, k in KILL_POINTS])
@pytest.mark.slow
def test_killed_while_writing_leaves_one_whole_run(what, k, tmp_path, previous, forked):
    out = tmp_path / "run"
    os.system(f"cp -a '{previous}' '{out}'")
    old = _complete(out)
    child = forked.run([*ARGS, "--thrust", "-20,-30,-40", "--out", out],
                       prelude=KILLER.format(what=what, k=k), folder=tmp_path / "io")
    killed = child.returncode == -signal.SIGKILL
    if out.exists():  # the previous run or the new one, whole: never a mix
        _complete(out)
        assert _thrust_of(out) in ([0.0, -10.0], [-20.0, -30.0, -40.0])
    else:  # killed between the two renames of the swap: nothing at the target yet
        assert killed and what == "rename"
    if not killed:  # the K-th call never came: the run finished normally
        assert child.returncode == 0, child.stderr
        assert _thrust_of(out) == [-20.0, -30.0, -40.0]
    # the next run tidies up: the target is whole and no temporary of the dead run is left
    # (a real next run at the swap and at the first write; the tidying step alone elsewhere)
    if what == "rename" or (what, k) == ("write_bytes_atomic", 1):
        res = forked.run([*ARGS, "--thrust", "0", "--out", out], folder=tmp_path / "io2")
        assert res.returncode == 0, res.stderr
        assert _thrust_of(out) == [0.0]
    else:
        output.clean_stale(out)
    _complete(out)
    assert _leftovers(tmp_path, "run") == [], "temporaries of the killed run left behind"
    assert old  # the previous run was complete to begin with


@pytest.mark.slow
def test_a_killed_swap_is_restored_before_anything_else(tmp_path, previous, forked):
    """Killed between moving the previous folder aside and moving the new one in: the next
    run's first step (``clean_stale``) puts the newest whole run back (here the new one, whose
    manifest exists) before anything else."""
    out = tmp_path / "run"
    os.system(f"cp -a '{previous}' '{out}'")
    child = forked.run([*ARGS, "--thrust", "-20,-30", "--out", out],
                       prelude=KILLER.format(what="rename", k=2), folder=tmp_path / "io")
    assert child.returncode == -signal.SIGKILL and not out.exists()
    output.clean_stale(out)
    _complete(out)
    assert _thrust_of(out) == [-20.0, -30.0]
    assert _leftovers(tmp_path, "run") == []


@pytest.mark.parametrize("delay", [0.3, 0.8, 1.5, 2.5])
@pytest.mark.slow
def test_killed_at_a_random_moment(delay, tmp_path, previous):
    """SIGKILL after a delay (wherever the run is: loading, computing, drawing, writing)."""
    out = tmp_path / "run"
    os.system(f"cp -a '{previous}' '{out}'")
    proc = subprocess.Popen([sys.executable, "-m", "thrustwalk_cli", *ARGS, "--thrust",
                             "0:-50:-1", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    time.sleep(delay)
    proc.kill()
    proc.wait(timeout=60)
    if out.exists():
        _complete(out)
    output.clean_stale(out)
    _complete(out)
    assert _leftovers(tmp_path, "run") == []


@pytest.mark.slow
def test_two_runs_writing_one_folder_at_once(tmp_path, previous):
    """Both succeed; the folder holds one of the two runs, whole; no temporaries left."""
    out = tmp_path / "run"
    os.system(f"cp -a '{previous}' '{out}'")
    procs = [subprocess.Popen([sys.executable, "-m", "thrustwalk_cli", *ARGS, "--thrust", t,
                               "--out", str(out)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
             for t in ("-1,-2", "-3,-4,-5")]
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
    _complete(out)
    assert _thrust_of(out) in ([-1.0, -2.0], [-3.0, -4.0, -5.0])
    assert _leftovers(tmp_path, "run") == []


@pytest.mark.slow
def test_disk_full_midway_keeps_the_previous_run(tmp_path, previous, monkeypatch, cli):
    """ENOSPC while writing a figure: one line with the reason, exit 1, the previous run
    untouched and no temporary left."""
    import errno

    out = tmp_path / "run"
    os.system(f"cp -a '{previous}' '{out}'")
    before = _complete(out)
    real = output.write_bytes_atomic

    def full(path, data):
        if str(path).endswith(".pdf"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        return real(path, data)

    monkeypatch.setattr(output, "write_bytes_atomic", full)
    res = cli(*ARGS, "--thrust", "-20", "--out", out)
    assert res.exit_code == 1
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "No space left" in lines[0]
    assert _complete(out) == before
    assert _leftovers(tmp_path, "run") == []


@pytest.mark.parametrize("err", ["EROFS", "EACCES"])
def test_report_on_a_folder_it_cannot_write(err, tmp_path, monkeypatch, cli):
    """``report`` on a read-only folder (injected: the tests may run as root, which ignores
    permissions): one line naming the path and the reason, exit 1, the folder untouched. The
    run it reports on is made in this process (no forked command server for a quick test)."""
    import errno

    folder = tmp_path / "figs"
    folder.mkdir()
    res = cli(*ARGS, "--thrust", "0,-10", "--formats", "csv", "--out", folder / "lc")
    assert res.exit_code == 0, res.output
    before = sorted(p.name for p in folder.rglob("*"))
    code = getattr(errno, err)

    def refuse(path, data):
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(output, "write_bytes_atomic", refuse)
    res = cli("report", folder, "-q")
    assert res.exit_code == 1
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0] == f"error: {folder / 'index.md'}: {os.strerror(code)}"
    assert sorted(p.name for p in folder.rglob("*")) == before


def test_csv_cells_of_numpy_scalars_are_plain_numbers(tmp_path):
    """A numpy scalar in a table row is written as the number it holds: np.float64 is a
    float subclass whose repr is 'np.float64(0.25)' (mujoco's steps.csv held such cells)."""
    import csv

    import numpy as np

    path = output.write_csv(tmp_path / "t.csv", ["a", "b", "c", "d"],
                            [[np.float64(0.25), np.float32(1.5), np.int64(3), np.bool_(True)]])
    rows = list(csv.reader(path.read_text().splitlines()))
    assert rows[1] == ["0.25", "1.5", "3", "true"]
    with pytest.raises(output.ComputationError, match="non-finite"):
        output.write_csv(tmp_path / "n.csv", ["a"], [[np.float32("nan")]])


def test_csv_columns_read_back_as_written(tmp_path):
    """Every kind of column (floats, numpy floats, floats with blanks, flags, text with
    commas and line breaks, integers, ragged rows) reads back with the csv module as the
    values it was given: each float to the same number (its shortest repr), a NaN in a float
    column refused."""
    import csv

    import numpy as np

    rng = np.random.default_rng(2)
    n = 50
    f = rng.standard_normal(n) * 10.0 ** rng.integers(-300, 300, n)
    cols = [list(map(float, f)), list(f), [None if i % 3 else float(i) for i in range(n)],
            [bool(i % 2) for i in range(n)], [f"a,b\n{i % 4}" for i in range(n)],
            [i * 7 for i in range(n)], [np.bool_(i % 5 == 0) for i in range(n)]]
    rows = list(zip(*cols))
    path = output.write_csv(tmp_path / "t.csv", ["f", "g", "h", "b", "s", "i", "c"], rows)
    got = list(csv.reader(path.read_text().splitlines()))
    assert got[0] == ["f", "g", "h", "b", "s", "i", "c"] and len(got) == n + 1
    for r, row in zip(rows, got[1:]):
        assert float(row[0]) == r[0] and float(row[1]) == r[1] and row[0] == repr(r[0])
        assert row[2] == ("" if r[2] is None else repr(r[2]))
        assert row[3] == ("true" if r[3] else "false") and row[6] == ("true" if r[6] else "false")
        assert row[4] == r[4].replace(",", ";").replace("\n", " ") and row[5] == str(r[5])
    ragged = output.write_csv(tmp_path / "r.csv", ["a", "b"], [[0.5, 1], [0.25]])
    assert ragged.read_text().splitlines()[1:] == ["0.5,1", "0.25"]
    with pytest.raises(output.ComputationError, match="non-finite"):
        output.write_csv(tmp_path / "n.csv", ["a"], [[0.5], [np.float64("nan")]])
