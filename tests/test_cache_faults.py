"""Model cache faults (issue 18): a bad entry is rebuilt, an unusable cache falls back to an
in-memory model with one warning line, the cache follows the platform's conventions, and
concurrent compiles of a new robot leave one valid entry. Numbers are always compared with
the session's normally compiled model, bit for bit."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.model import cache
from thrustwalk_cli.model import compiler as compiler_mod
from thrustwalk_cli.model.compiler import load_model

Q = np.array([[0.1, -0.2, 0.3], [0.4, 0.1, -0.5]])
DQ = np.array([[1.0, 0.5, -0.3], [-0.2, 0.3, 0.7]])


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch) -> Path:
    """An empty cache for one test; the in-process memo is cleared before and after."""
    path = tmp_path / "cache"
    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(path))
    compiler_mod._LOADED.clear()
    yield path
    compiler_mod._LOADED.clear()


def _same_numbers(model, reference) -> None:
    """The model gives exactly the reference's numbers (D, G, swing foot, impact)."""
    np.testing.assert_array_equal(model.D(Q), reference.D(Q))
    np.testing.assert_array_equal(model.G(Q), reference.G(Q))
    np.testing.assert_array_equal(model.p_swing(Q), reference.p_swing(Q))
    np.testing.assert_array_equal(model.impact(Q[0], DQ[0]).dq_plus,
                                  reference.impact(Q[0], DQ[0]).dq_plus)


def _seed(reference) -> Path:
    path = cache.entry_path(reference.robot.name, reference.key)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(reference.cache_path.read_bytes())
    return path


def _rewrite_body(path: Path, edit) -> None:
    """Change the entry's body and give it a *valid* checksum (a well-formed lie)."""
    head, _, body = path.read_text().partition("\n")
    body = edit(body)
    key = next(f for f in head.split() if f.startswith("key="))
    digest = hashlib.sha256(body.encode()).hexdigest()
    path.write_text(f"{cache.MAGIC} {key} sha256={digest}\n{body}")


# -- bad entries are rebuilt ------------------------------------------------------------------
@pytest.mark.parametrize("edit, error", [
    (lambda body: body + "\ndef broken(:\n", "SyntaxError"),
    (lambda body: body.replace("def D(", "def D_gone(", 1), "ImportError"),
    (lambda body: "raise RuntimeError('boom')\n" + body, "RuntimeError"),
    (lambda body: body + "\nimport thrustwalk_no_such_module\n", "ModuleNotFoundError"),
], ids=["syntax-error", "function-missing", "raises-on-import", "bad-import"])
def test_entry_with_valid_checksum_that_fails_to_load_is_rebuilt(edit, error, fresh_cache,
                                                                 three_link):
    path = _seed(three_link)
    _rewrite_body(path, edit)
    assert cache.verify_entry(path, three_link.key) is None, "the checksum must look valid"
    model = load_model(three_link.robot)
    assert not model.cache_hit
    assert model.cache_path == path
    assert len(model.notes) == 1 and error in model.notes[0] and "rebuilt" in model.notes[0]
    assert cache.verify_entry(path, three_link.key) is None
    assert "broken(" not in path.read_text() and "boom" not in path.read_text()
    _same_numbers(model, three_link)
    compiler_mod._LOADED.clear()
    again = load_model(three_link.robot)
    assert again.cache_hit and again.notes == (), "the rebuilt entry must be used next time"


# -- an unusable cache falls back to memory -----------------------------------------------------
def _entry_is_a_folder(cache_dir: Path, reference) -> tuple[str, Path]:
    path = cache.entry_path(reference.robot.name, reference.key)
    (path / "inside").mkdir(parents=True)
    return f"entry {path} is a folder", path


def _cache_path_is_a_file(cache_dir: Path, reference) -> tuple[str, Path]:
    cache_dir.parent.mkdir(parents=True, exist_ok=True)
    cache_dir.write_text("not a folder\n")
    return f"{cache_dir} is a file, not a folder", cache_dir


def _cache_under_a_file(cache_dir: Path, reference) -> tuple[str, Path]:
    cache_dir.parent.mkdir(parents=True, exist_ok=True)
    cache_dir.write_text("not a folder\n")
    os.environ["THRUSTWALK_CACHE_DIR"] = str(cache_dir / "deeper" / "still")
    return f"{cache_dir} is a file, not a folder", cache_dir


@pytest.mark.parametrize("setup", [_entry_is_a_folder, _cache_path_is_a_file,
                                   _cache_under_a_file],
                         ids=["entry-is-folder", "cache-is-file", "cache-under-file"])
def test_unusable_cache_path_falls_back_to_memory(setup, fresh_cache, three_link, monkeypatch):
    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(fresh_cache))
    expected, untouched = setup(fresh_cache, three_link)
    before = sorted(p.name for p in untouched.rglob("*")) if untouched.is_dir() else \
        untouched.read_bytes()
    model = load_model(three_link.robot)
    assert model.cache_path is None and not model.cache_hit
    assert len(model.notes) == 1, model.notes
    assert expected in model.notes[0] and "in memory" in model.notes[0]
    _same_numbers(model, three_link)
    after = sorted(p.name for p in untouched.rglob("*")) if untouched.is_dir() else \
        untouched.read_bytes()
    assert after == before, "the user's file or folder must not be touched"
    assert model.summary()["cache_entry"] == "in memory"
    again = load_model(three_link.robot)  # same process: reused, same note
    assert again._m is model._m and again.notes == model.notes


@pytest.mark.parametrize("err, where", [
    (errno.ENOSPC, "fsync"), (errno.EROFS, "mkstemp"), (errno.EACCES, "mkstemp"),
    (errno.EDQUOT, "fsync"),
], ids=["disk-full", "read-only-fs", "permission", "quota"])
def test_write_failures_fall_back_to_memory_and_leave_no_temporary(err, where, fresh_cache,
                                                                   three_link, monkeypatch):
    """Injected at the system call the real failure happens in; the real cleanup runs."""
    def fail(*args, **kwargs):
        raise OSError(err, os.strerror(err))

    if where == "fsync":
        monkeypatch.setattr(cache.os, "fsync", fail)
    else:
        monkeypatch.setattr(cache.tempfile, "mkstemp", fail)
    model = load_model(three_link.robot)
    assert model.cache_path is None
    assert len(model.notes) == 1 and os.strerror(err) in model.notes[0], model.notes
    _same_numbers(model, three_link)
    left = [p.name for p in fresh_cache.iterdir() if not p.name.endswith(".py.lock")] \
        if fresh_cache.exists() else []  # the entry's (empty) build lock stays
    assert left == [], f"temporary files left behind: {left}"


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="root ignores directory permissions")
def test_read_only_cache_directory_for_real(fresh_cache, three_link):
    fresh_cache.mkdir()
    fresh_cache.chmod(0o500)
    try:
        model = load_model(three_link.robot)
    finally:
        fresh_cache.chmod(0o700)
    assert model.cache_path is None and len(model.notes) == 1
    _same_numbers(model, three_link)


# -- where the cache lives ---------------------------------------------------------------------
class _Pw:
    def __init__(self, home: str):
        self.pw_dir = home


@pytest.fixture
def no_overrides(monkeypatch):
    for var in ("THRUSTWALK_CACHE_DIR", "XDG_CACHE_HOME", "LOCALAPPDATA"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr(cache.sys, "platform", "linux")
    return monkeypatch


@pytest.mark.parametrize("home", [None, ""], ids=["HOME-unset", "HOME-empty"])
def test_home_unset_or_empty_uses_the_password_database(home, no_overrides, tmp_path):
    import pwd

    if home is None:
        no_overrides.delenv("HOME", raising=False)
    else:
        no_overrides.setenv("HOME", home)
    no_overrides.setattr(pwd, "getpwuid", lambda uid: _Pw(str(tmp_path / "me")))
    assert cache.cache_dir() == tmp_path / "me" / ".cache" / "thrustwalk"


@pytest.mark.parametrize("pw_home", ["/", "", "relative/home"])
def test_no_home_at_all_compiles_in_memory_never_in_root(pw_home, no_overrides, three_link):
    import pwd

    no_overrides.setenv("HOME", "")
    no_overrides.setattr(pwd, "getpwuid", lambda uid: _Pw(pw_home))
    with pytest.raises(cache.NoCacheDir, match="THRUSTWALK_CACHE_DIR"):
        cache.cache_dir()
    compiler_mod._LOADED.clear()
    model = load_model(three_link.robot)
    assert model.cache_path is None
    assert len(model.notes) == 1 and "HOME" in model.notes[0]
    _same_numbers(model, three_link)
    compiler_mod._LOADED.clear()


def test_platform_conventions(no_overrides, tmp_path):
    no_overrides.setenv("HOME", str(tmp_path))
    assert cache.cache_dir() == tmp_path / ".cache" / "thrustwalk"
    no_overrides.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "xdg" / "thrustwalk"
    no_overrides.setenv("XDG_CACHE_HOME", "relative/xdg")  # not absolute: ignored (XDG spec)
    assert cache.cache_dir() == tmp_path / ".cache" / "thrustwalk"
    no_overrides.setattr(cache.sys, "platform", "darwin")
    assert cache.cache_dir() == tmp_path / "Library" / "Caches" / "thrustwalk"
    no_overrides.setattr(cache.sys, "platform", "win32")
    no_overrides.setenv("LOCALAPPDATA", str(tmp_path / "AppData" / "Local"))
    assert cache.cache_dir() == tmp_path / "AppData" / "Local" / "thrustwalk" / "Cache"
    no_overrides.setenv("THRUSTWALK_CACHE_DIR", str(tmp_path / "mine"))
    assert cache.cache_dir() == tmp_path / "mine"


# -- through the command line -----------------------------------------------------------------
@pytest.mark.slow
def test_cli_with_unusable_cache_warns_once_and_still_writes_results(tmp_path, cli_subprocess):
    blocker = tmp_path / "cache-file"
    blocker.write_text("x\n")
    out = tmp_path / "run"
    res = cli_subprocess(["limit-cycle", "--out", str(out), "--quiet", "--formats", "csv"],
                         THRUSTWALK_CACHE_DIR=str(blocker))
    assert res.returncode == 0, res.stderr
    lines = res.stderr.splitlines()
    assert lines[0] == (f"warning: model cache unusable: {blocker} is a file, not a folder; "
                        "compiled model kept in memory for this run")
    assert "Traceback" not in res.stderr
    assert json.loads((out / "limit_cycles.json").read_text())["success"] is True
    assert blocker.read_text() == "x\n"


# -- concurrency -------------------------------------------------------------------------------
@pytest.mark.slow
def test_four_processes_compiling_a_new_robot_build_it_once(tmp_path, fresh_cache):
    """Four processes compile the same never-seen robot into one empty cache at once (issue
    30 item 4): one derives it (SymPy), the others wait for its build lock, say so through
    the cache's wait reporter, and load its entry; all have identical numbers and exactly one
    valid entry remains (beside its lock file; no temporaries)."""
    src = Path(__file__).parents[1] / "robots" / "three_link.yaml"
    robot_file = tmp_path / "three_link_heavy.yaml"
    robot_file.write_text(src.read_text().replace("name: three_link", "name: three_link_heavy")
                          .replace("gravity: 9.8", "gravity: 9.81"))
    go = tmp_path / "go"
    script = textwrap.dedent(f"""
        import json, os, time
        from thrustwalk_cli.model import cache, compiler
        from thrustwalk_cli.model.compiler import load_model
        from thrustwalk_cli.files.robot_file import load_robot
        robot = load_robot({str(robot_file)!r})
        said = []
        getattr(cache, "set_wait_reporter", id)(said.append)  # (id: before issue 30)
        while not os.path.exists({str(go)!r}):
            time.sleep(0.005)
        m = load_model(robot)
        q = [0.1, -0.2, 0.3]
        print(json.dumps({{"notes": list(m.notes), "key": m.key, "said": said,
                          "derived": compiler.COMPILES, "hit": m.cache_hit,
                          "D": m.D(q).tolist(), "G": m.G(q).tolist()}}))
    """)
    env = dict(os.environ, THRUSTWALK_CACHE_DIR=str(fresh_cache))
    procs = [subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(4)]
    time.sleep(0.3)
    go.touch()
    results = []
    for i, p in enumerate(procs):
        out, err = p.communicate(timeout=180)
        assert p.returncode == 0, f"process {i} failed:\n{err}"
        results.append(json.loads(out))
    assert all(r["notes"] == [] for r in results), [r["notes"] for r in results]
    assert all(r["D"] == results[0]["D"] and r["G"] == results[0]["G"] for r in results)
    assert sorted(r["derived"] for r in results) == [0, 0, 0, 1], results
    builder = next(r for r in results if r["derived"])
    assert not builder["hit"] and builder["said"] == []
    others = [r for r in results if not r["derived"]]
    assert all(r["hit"] for r in others)
    waited = [r["said"] for r in others if r["said"]]
    assert waited, "nobody waited: the processes did not overlap"
    assert all(s == ["another thrustwalk process is building the model of robot "
                     "'three_link_heavy': waiting for it, then loading it"] for s in waited)
    # (Python's own bytecode folder aside: it is there wherever bytecode is written)
    files = sorted(x.name for x in fresh_cache.iterdir() if x.name != "__pycache__")
    assert len(files) == 2 and files[0].startswith("three_link_heavy-"), files
    assert files[1] == files[0] + ".lock"
    assert cache.verify_entry(fresh_cache / files[0], results[0]["key"]) is None


TINY = "def f(x):\n    return x * x + 1.0\n"
# a small module whose numba compile takes about a second (the processes overlap)
SMALL_JIT = """import numpy as np
def g(a):
    s = 0.0
    for i in range(a.shape[0]):
        s += np.sin(a[i]) * np.cos(a[i]) + np.exp(-a[i] * a[i])
    return s
def h(a):
    b = np.empty_like(a)
    for i in range(a.shape[0]):
        b[i] = g(a[i:]) + np.tanh(a[i])
    return b
def f(x):
    a = np.linspace(0.0, x, 16)
    return h(a).sum() * 0.0 + x * x + 1.0
"""
SMALL_JIT_NAMES = {"g": "float64(float64[:])", "h": "float64[:](float64[:])",
                   "f": "float64(float64)"}


@pytest.mark.slow
def test_three_processes_compiling_one_jit_module_compile_it_once(tmp_path, fresh_cache):
    """The numba modules (the simulation kernel) are built under the same lock: three
    processes loading a new small jit module at once: numba compiles it in one, the others
    wait (told through ``on_wait``) and load its machine code from the cache."""
    go = tmp_path / "go"
    script = textwrap.dedent(f"""
        import json, os, time
        import numba
        from thrustwalk_cli.model import jit
        said = []
        while not os.path.exists({str(go)!r}):
            time.sleep(0.005)
        import inspect
        kw = (dict(what="the test module", on_wait=said.append)
              if "on_wait" in inspect.signature(jit.load).parameters else {{}})
        jm = jit.load("locktest", {SMALL_JIT!r}, {SMALL_JIT_NAMES!r}, **kw)
        print(json.dumps({{"hit": jm.cache_hit, "said": said, "f2": jm.module.f(2.0),
                          "note": jm.note}}))
    """)
    env = dict(os.environ, THRUSTWALK_CACHE_DIR=str(fresh_cache))
    procs = [subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(3)]
    time.sleep(1.5)  # numba imported in each
    go.touch()
    results = []
    for i, p in enumerate(procs):
        out, err = p.communicate(timeout=180)
        assert p.returncode == 0, f"process {i} failed:\n{err}"
        results.append(json.loads(out))
    assert all(r["f2"] == 5.0 and r["note"] == "" for r in results)
    assert sorted(r["hit"] for r in results) == [False, True, True], results
    waited = [r["said"] for r in results if r["said"]]
    assert waited and all(s == ["another thrustwalk process is building the test module: "
                                "waiting for it, then loading it"] for s in waited)


def test_a_folder_in_place_of_an_entry_or_its_lock_is_left_alone(fresh_cache, three_link):
    """A folder where a jit module's file should be is reported and left as it is (the
    module goes to a private folder for this process); a folder where a model's lock file
    should be costs the lock, never the build."""
    from thrustwalk_cli.model import jit

    names = {"f": "float64(float64)"}
    entry = jit.entry_path("probe", TINY, names)
    (entry / "mine").mkdir(parents=True)
    (entry / "mine" / "notes.txt").write_text("keep me\n")
    path, note = jit._place("probe", TINY, names, False)
    assert path.parent == jit._private_folder() and path.is_file()
    assert f"cache entry {entry} is a folder, left as it is" in note
    assert (entry / "mine" / "notes.txt").read_text() == "keep me\n"
    model_entry = cache.entry_path(three_link.robot.name, three_link.key)
    cache.lock_path(model_entry).mkdir(parents=True)
    model = load_model(three_link.robot)
    assert not model.cache_hit and model.notes == () and model.cache_path == model_entry
    _same_numbers(model, three_link)
    assert cache.lock_path(model_entry).is_dir()


def _sim_case():
    from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
    from thrustwalk_cli.simulation.full_order import Start

    th = ThrustModel("second-order", np.array([-3.0, 0.0]), wn=3.0, xi=0.7)
    return th, SimConfig(steps=2), Start(perturb=0.05)


def _session_kernel(session_cache: Path, monkeypatch):
    """The compiled kernel as every test of the session gets it: loaded from the session's
    cache (which starts with it compiled), whatever cache folder the test has set since."""
    from thrustwalk_cli.simulation.stepper import kernel

    with monkeypatch.context() as m:
        m.setenv("THRUSTWALK_CACHE_DIR", str(session_cache))
        return kernel()


def test_compiled_simulation_runs_with_an_unusable_cache(fresh_cache, walker3, monkeypatch,
                                                          _cache_dir):
    """A model kept in memory (``cache_path`` None) needs no file of its own for the compiled
    simulation: the robot is its tape, the kernel is shared; the run equals the one of the
    session's cached model bit for bit, and warns nothing. (The kernel is the one this process
    has loaded; how the kernel itself fares with an unusable cache: the two tests below.)"""
    from thrustwalk_cli.hzd.zero_dynamics import zero_dynamics
    from thrustwalk_cli.simulation.full_order import simulate

    _session_kernel(_cache_dir, monkeypatch)  # loaded before the cache folder breaks
    _cache_path_is_a_file(fresh_cache, walker3.model)
    model = load_model(walker3.robot)
    assert model.cache_path is None and model.notes
    th, cfg, start = _sim_case()
    got = simulate(zero_dynamics(model, walker3.gait), th, cfg, start)
    ref = simulate(walker3.zd, th, cfg, start)
    assert got.success, got.reason
    assert [s.zeta_minus for s in got.steps] == [s.zeta_minus for s in ref.steps]


def test_kernel_with_an_unusable_cache_is_imported_from_a_private_folder(
        fresh_cache, walker3, monkeypatch, tmp_path, _cache_dir):
    """When the cache folder cannot hold the compiled kernel, the kernel's module is placed in
    this process's private folder, imported from there with a one-line note, and simulates
    exactly as the cached kernel. numba's machine code of the session's kernel is put beside
    the private folder's module first, as numba leaves it after compiling there, so that this
    test imports it instead of paying a second kernel compile (that a jit module really is
    compiled in the private folder: the next test, with a small module)."""
    from thrustwalk_cli.model import jit
    from thrustwalk_cli.simulation import stepper
    from thrustwalk_cli.simulation.full_order import simulate

    th, cfg, start = _sim_case()
    ref_jm = _session_kernel(_cache_dir, monkeypatch)
    ref = simulate(walker3.zd, th, cfg, start)
    private = tmp_path / "private"
    (private / "__pycache__").mkdir(parents=True)
    entry = ref_jm.path
    for f in entry.parent.glob(f"{entry.stem}.*"):
        shutil.copy2(f, private / f.name)
    for f in entry.parent.glob(f"__pycache__/{entry.stem}.*"):
        shutil.copy2(f, private / "__pycache__" / f.name)
    monkeypatch.setattr(jit, "_PRIVATE", [private])
    monkeypatch.setattr(jit, "_LOADED", {})  # as in a new process
    monkeypatch.delitem(sys.modules, f"thrustwalk_jit_{entry.stem.replace('-', '_')}")
    _cache_path_is_a_file(fresh_cache, walker3.model)

    jm = stepper.kernel()
    assert jm.path == private / entry.name and fresh_cache not in jm.path.parents
    assert jm.module is not ref_jm.module and jm.module.__file__ == str(jm.path)
    assert "cache folder unusable" in jm.note and "this process only" in jm.note
    assert jm.cache_hit, "numba must load the machine code beside the private module"
    got = simulate(walker3.zd, th, cfg, start)
    assert stepper.kernel() is jm
    assert got.success, got.reason
    assert [s.zeta_minus for s in got.steps] == [s.zeta_minus for s in ref.steps]
    assert fresh_cache.read_text().startswith("not a folder"), "the user's file must not change"


def test_jit_module_with_an_unusable_cache_is_compiled_in_a_private_folder(
        fresh_cache, monkeypatch):
    """A jit module that is not compiled anywhere yet, with the cache folder unusable, is
    written to a new private temporary folder, compiled there by numba (its machine code
    beside it) and works, with the one-line note; loaded again in the process, it is the same
    module."""
    from thrustwalk_cli.model import jit

    monkeypatch.setattr(jit, "_PRIVATE", [])
    monkeypatch.setattr(jit, "_LOADED", {})
    fresh_cache.parent.mkdir(parents=True, exist_ok=True)
    fresh_cache.write_text("a file where the cache folder should be\n")
    source = f"def twice(x):\n    return 2.0 * x  # {time.time_ns()}: never compiled before\n"
    names = {"twice": "float64(float64)"}
    try:
        jm = jit.load("probe", source, names)
        private = jit._private_folder()
        assert jm.path.parent == private and fresh_cache not in jm.path.parents
        assert not jm.cache_hit and jm.compile_seconds is not None and jm.compile_seconds > 0
        assert any(private.glob(f"__pycache__/{jm.path.stem}.*.nbi")), "no machine code"
        assert "cache folder unusable" in jm.note and "this process only" in jm.note
        assert jm.module.twice(1.5) == 3.0
        assert jit.load("probe", source, names) is jm
        assert fresh_cache.read_text().startswith("a file"), "the user's file must not change"
    finally:
        folder = jit._private_folder()
        stem = jit.entry_path("probe", source, names, folder).stem
        sys.modules.pop(f"thrustwalk_jit_{stem.replace('-', '_')}", None)
        shutil.rmtree(folder, ignore_errors=True)


def test_jit_module_falls_back_to_a_private_folder(fresh_cache, monkeypatch):
    """When the cache folder cannot hold the compiled kernel, its module goes to a private
    temporary folder for this process, with a one-line note (no compile here: placing the
    file is what can fail)."""
    from thrustwalk_cli.model import jit

    fresh_cache.parent.mkdir(parents=True, exist_ok=True)
    fresh_cache.write_text("a file where the cache folder should be\n")
    path, note = jit._place("probe", "def f(x):\n    return x\n", {"f": "(float64,)"}, False)
    assert path.is_file() and fresh_cache not in path.parents
    assert path.parent == jit._private_folder()
    assert "cache folder unusable" in note and "this process only" in note
    assert fresh_cache.read_text().startswith("a file"), "the user's file must not change"
    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(fresh_cache.parent / "fine"))
    path2, note2 = jit._place("probe", "def f(x):\n    return x\n", {"f": "(float64,)"},
                              False)
    assert note2 == "" and path2.parent == fresh_cache.parent / "fine"
