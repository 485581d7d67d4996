"""Where sweep points run, and sweeps that are killed: the same rows (bitwise) in this
process, on 2 local worker processes, on a Dask ``LocalCluster`` and on a real Dask cluster (a
scheduler and two workers started here as separate processes on 127.0.0.1, random free ports,
bounded in time, stopped by the test); a sweep killed by SIGKILL at several points resumes
with every point present exactly once and identical to an uninterrupted run; a worker lost
mid-run loses no point."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

# 21 feasibility points of ~0.02-0.1 s each (three robot models): enough that a kill after
# 5 points lands mid-run even on an idle machine, few enough for CI
N_POINTS = 21
SWEEP = """\
name: cluster
study: feasibility
robot: three_link
gait: three_link_walk
grid:
  robot.MT: {values: [9, 10, 11], unit: kg}
  thrust: {values: [0, -5, -10, -15, -20, -25, -30]}
collect: [feasible, min_vertical_force, max_friction_ratio, zeta_star]
"""
LC = """\
name: lc
study: limit-cycle
robot: three_link
gait: three_link_walk
grid:
  robot.MT: {values: [9, 11], unit: kg}
  thrust: {values: [0, -15, -30]}
collect: [speed, zeta_star, delta_zero_sq, walkable]
"""


def _file(tmp_path: Path, text: str, name: str) -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def _records(out: Path) -> dict[str, dict]:
    """Point records by key, without the wall time (the one field that differs by run)."""
    out_ = {}
    for p in sorted((out / "points").glob("*.json")):
        rec = json.loads(p.read_text())
        rec.pop("seconds")
        out_[rec["key"]] = rec
    return out_


@pytest.fixture(scope="module")
def reference(tmp_path_factory, _cache_dir):
    """The uninterrupted run of each sweep in this process (1 worker)."""
    from thrustwalk_cli.commands.sweep import run_sweep_command

    base = tmp_path_factory.mktemp("reference")
    out = {}
    for name, text in (("cluster", SWEEP), ("lc", LC)):
        path = _file(base, text, f"{name}.yaml")
        run_sweep_command(path, base / name, workers=1, quiet=True, formats={"csv"})
        out[name] = (path, base / name)
    return out


def test_two_local_worker_processes_give_the_same_rows(reference, tmp_path, cli_subprocess):
    path, ref = reference["lc"]
    res = cli_subprocess(["sweep", path, "--out", tmp_path / "o", "--workers", "2", "-q",
                          "--formats", "csv"], timeout=240)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "o" / "results.csv").read_bytes() == (ref / "results.csv").read_bytes()
    assert _records(tmp_path / "o") == _records(ref)
    doc = json.loads((tmp_path / "o" / "sweep.json").read_text())
    assert doc["executor"] == {"kind": "local", "workers": 2, "restarts": 0}


def test_a_dask_local_cluster_gives_the_same_rows(reference, tmp_path):
    from distributed import LocalCluster

    from thrustwalk_cli.commands.sweep import run_sweep_command

    path, ref = reference["lc"]
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None, silence_logs=40) as cluster:
        doc = run_sweep_command(path, tmp_path / "o", scheduler=cluster.scheduler_address,
                                quiet=True, formats={"csv"})
    assert doc["executor"]["kind"] == "dask" and doc["executor"]["workers"] == 2
    assert (tmp_path / "o" / "results.csv").read_bytes() == (ref / "results.csv").read_bytes()
    assert _records(tmp_path / "o") == _records(ref)


class Cluster:
    """A Dask scheduler and workers as separate processes on 127.0.0.1 (ports chosen by the
    scheduler, read from its scheduler file)."""

    def __init__(self, folder: Path, workers: int = 2, timeout: float = 60.0):
        self.procs: list[subprocess.Popen] = []
        self.folder = folder
        env = dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
        file = folder / "scheduler.json"
        self.log = open(folder / "cluster.log", "w")  # noqa: SIM115 - closed in stop()
        self.procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", "--no-dashboard", "--scheduler-file", str(file)],
            env=env, stdout=self.log, stderr=subprocess.STDOUT))
        t0 = time.monotonic()
        while not file.is_file() or not file.read_text().strip():
            if time.monotonic() - t0 > timeout or self.procs[0].poll() is not None:
                self.stop()
                raise RuntimeError("the scheduler did not start: " + self.logs())
            time.sleep(0.1)
        time.sleep(0.2)
        self.address = json.loads(file.read_text())["address"]
        assert self.address.startswith("tcp://127.0.0.1:"), self.address
        for i in range(workers):
            self.procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", self.address,
                 "--host", "127.0.0.1", "--nthreads", "1", "--no-nanny", "--no-dashboard",
                 "--name", f"w{i}", "--memory-limit", "0"],
                env=env, stdout=self.log, stderr=subprocess.STDOUT))
        from distributed import Client

        with Client(self.address, timeout="30s") as c:
            c.wait_for_workers(workers, timeout=timeout)

    def logs(self) -> str:
        self.log.flush()
        return (self.folder / "cluster.log").read_text()[-3000:]

    def stop(self) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=5)
        self.log.close()


@pytest.fixture
def dask_cluster(tmp_path):
    c = Cluster(tmp_path)
    try:
        yield c
    finally:
        c.stop()


def test_a_dask_cluster_of_separate_processes_gives_the_same_rows(reference, tmp_path,
                                                                  dask_cluster):
    from thrustwalk_cli.commands.sweep import run_sweep_command

    for name in ("lc", "cluster"):
        path, ref = reference[name]
        doc = run_sweep_command(path, tmp_path / name, scheduler=dask_cluster.address,
                                quiet=True, formats={"csv"})
        assert doc["executor"] == {"kind": "dask", "scheduler": dask_cluster.address,
                                   "workers": 2}, dask_cluster.logs()
        assert (tmp_path / name / "results.csv").read_bytes() == \
            (ref / "results.csv").read_bytes(), name
        assert _records(tmp_path / name) == _records(ref), name


def test_a_worker_lost_mid_run_loses_no_point(reference, tmp_path, dask_cluster,
                                              cli_subprocess):
    """One of the two workers is killed while the sweep runs: Dask runs its tasks on the
    other; every point is present once and identical to the uninterrupted run."""
    path, ref = reference["cluster"]
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "thrustwalk_cli", "sweep", str(path),
                             "--out", str(out), "--scheduler", dask_cluster.address, "-q",
                             "--formats", "csv"], stderr=subprocess.PIPE, text=True)
    try:
        _wait_points(out, 1, proc, timeout=120)
        dask_cluster.procs[1].kill()  # a worker, no nanny: gone
        proc.wait(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, proc.stderr.read()
    assert (out / "results.csv").read_bytes() == (ref / "results.csv").read_bytes()
    assert _records(out) == _records(ref)


def test_a_local_worker_process_lost_mid_run_loses_no_point(reference, tmp_path):
    """One of the 2 local worker processes is killed: the pool is restarted, the tasks in
    flight run again, every point is present once and identical to the uninterrupted run."""
    path, ref = reference["cluster"]
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "thrustwalk_cli", "sweep", str(path),
                             "--out", str(out), "--workers", "2", "-q", "--formats", "csv"],
                            stderr=subprocess.PIPE, text=True)
    try:
        _wait_points(out, 1, proc, timeout=120)
        kids = _children(proc.pid)
        assert kids, "no worker process"
        os.kill(kids[-1], signal.SIGKILL)
        _, err = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    doc = json.loads((out / "sweep.json").read_text())
    if doc["executor"]["restarts"] == 0:  # pragma: no cover - the sweep outran the kill
        pytest.skip("every point had finished before the worker was killed")
    assert doc["counts"]["resubmitted"] >= 1, doc
    assert (out / "results.csv").read_bytes() == (ref / "results.csv").read_bytes()
    assert _records(out) == _records(ref)


def _wait_points(out: Path, n: int, proc: subprocess.Popen, timeout: float) -> None:
    t0 = time.monotonic()
    while len(list((out / "points").glob("*.json"))) < n:
        if proc.poll() is not None:
            return
        if time.monotonic() - t0 > timeout:
            raise TimeoutError(f"fewer than {n} points after {timeout} s")
        time.sleep(0.01)


def _children(pid: int) -> list[int]:
    import psutil

    try:
        return [c.pid for c in psutil.Process(pid).children(recursive=True)]
    except psutil.NoSuchProcess:
        return []


def _alive(pids: list[int]) -> list[int]:
    import psutil

    out = []
    for pid in pids:
        try:
            if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                out.append(pid)
        except psutil.NoSuchProcess:
            pass
    return out


def test_a_sweep_killed_at_several_points_resumes_exactly(reference, tmp_path, _cache_dir):
    """SIGKILL of the command (2 local worker processes) after 1, then 3, then 5 points;
    the workers exit with it; the last run completes. Every point is present exactly once,
    identical to the uninterrupted run, and no temporary is left."""
    path, ref = reference["cluster"]
    out = tmp_path / "o"
    cmd = [sys.executable, "-m", "thrustwalk_cli", "sweep", str(path), "--out", str(out),
           "--workers", "2", "-q", "--formats", "csv"]
    killed = []
    for n in (1, 3, 5):
        before = len(list((out / "points").glob("*.json"))) if out.exists() else 0
        proc = subprocess.Popen(cmd, stderr=subprocess.DEVNULL)
        try:
            _wait_points(out, before + 1 if n == 1 else n, proc, timeout=120)
            kids = _children(proc.pid)
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=10)
        finally:
            if proc.poll() is None:
                proc.kill()
        killed.append(proc.returncode)
        t0 = time.monotonic()
        while _alive(kids) and time.monotonic() - t0 < 10:
            time.sleep(0.1)
        assert not _alive(kids), "worker processes outlived the killed sweep"
        assert not (out / "results.csv").exists()
    assert all(rc == -signal.SIGKILL for rc in killed), killed
    done = len(list((out / "points").glob("*.json")))
    assert 1 <= done < N_POINTS, done
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["counts"]["skipped"] == done and doc["counts"]["computed"] == N_POINTS - done
    assert (out / "results.csv").read_bytes() == (ref / "results.csv").read_bytes()
    assert _records(out) == _records(ref)
    keys = [p.stem for p in (out / "points").iterdir()]
    assert len(keys) == len(set(keys)) == N_POINTS
    assert not [p for p in out.rglob(".*") if p.name != ".thrustwalk-sweep.json"]
