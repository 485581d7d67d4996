"""Energy's share of whole commands (SPEC 15, issue 28: "energy on the orbit adds < 10 % to
limit-cycle; energy along a run adds < 10 % to simulate"): the CPU time a command spends in
its energies (on the orbit: ``energetics.orbit.orbit_energy`` as limit-cycle calls it; along a
run: ``energetics.run.run_energy``) against the command's CPU time, both measured in the same
run, the energy function wrapped by a timer and nothing else changed. Two measurements:

- **the command as a user runs it**: ``thrustwalk ...`` as a process of its own (``cli.main``,
  its BLAS setting and all), its CPU from the operating system's account at its exit
  (start-up, imports, the work, the files); medians of 4 processes after one not counted;
- **the command's work alone**: the command run again and again in one process (Typer's test
  runner, after a warm-up call): no start-up or import counted and every cache warm, so the
  energies' share is larger. In a process of its own with BLAS single-threaded as the command
  line sets it (with OpenBLAS's thread pool spinning the same command spent 0.39 s of CPU
  instead of 0.22 s).

The figures are drawn (``--formats png``: one format) as a user's command draws them, and
left out (``--formats none``). ``bench_energy.py`` and ``simulate_energy.py`` measure the
library calls alone (``tw.limit_cycle``, ``tw.simulate``), where the share is larger still.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from timing import run_cli_here

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"
# the command line's BLAS setting (``cli.BLAS_THREADS``: one thread unless the environment
# says otherwise); the in-process measurement runs in a process that starts with it
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
MODULES = {"orbit_energy": "thrustwalk_cli.studies.limit_cycle",
           "run_energy": "thrustwalk_cli.energetics.run"}


def _wrap(name: str) -> list[float]:
    """Wrap the energy function ``name`` where the commands call it: returns the CPU seconds
    spent inside it so far (a one-element list, updated by every call)."""
    import importlib

    module = importlib.import_module(MODULES[name])
    inner = getattr(module, name)
    spent = [0.0]

    def timed(*a, **k):
        t0 = time.process_time()
        try:
            return inner(*a, **k)
        finally:
            spent[0] += time.process_time() - t0

    setattr(module, name, timed)
    return spent


def _child(name: str, args: list[str]) -> None:
    """One command as a process of its own (``cli.main``), the energy function timed; prints
    ``{"energy": s, "cpu": s}`` (the process's user + system CPU at its end) on stderr."""
    spent = _wrap(name)
    cpu = run_cli_here(args)
    print(json.dumps({"energy": spent[0], "cpu": cpu}), file=sys.stderr)


def _process_share(name: str, args: list[str], runs: int = 4) -> tuple[float, float]:
    """(median CPU seconds of the command as a process, median share inside ``name``)."""
    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREADS}  # as a user's shell
    totals, shares = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(runs + 1):
            res = subprocess.run(
                [sys.executable, __file__, "--child", name, *args, "--out",
                 str(Path(tmp) / f"p{i}"), "-q"], env=env, capture_output=True, text=True)
            if res.returncode != 0:
                raise RuntimeError(f"{args}: exit {res.returncode}: {res.stderr[-500:]}")
            got = json.loads(res.stderr.strip().splitlines()[-1])
            if i:  # the first run warms the disk caches (the compiled model)
                totals.append(got["cpu"])
                shares.append(got["energy"] / got["cpu"])
    return statistics.median(totals), statistics.median(shares)


def _warm_share(name: str, args: list[str], repeat: int = 5) -> tuple[float, float]:
    """(median CPU seconds of the command run in this process, median share inside
    ``name``), after one warm-up call."""
    from typer.testing import CliRunner

    from thrustwalk_cli.cli import app

    spent = _wrap(name)
    runner = CliRunner()
    totals, shares = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat + 1):
            spent[0] = 0.0
            t0 = time.process_time()
            res = runner.invoke(app, [*args, "--out", str(Path(tmp) / f"r{i}"), "-q"])
            total = time.process_time() - t0
            if res.exit_code != 0:
                raise RuntimeError(f"{args}: exit {res.exit_code}: {res.output[-500:]}")
            if i:  # the first call loads the walker and warms the caches
                totals.append(total)
                shares.append(spent[0] / total)
    return statistics.median(totals), statistics.median(shares)


CASES = (
    ("limit-cycle rabbit, 200 thrust values",
     ["limit-cycle", "rabbit", "rabbit_walk", "--thrust", "0:-50:-0.25"], "orbit_energy"),
    ("limit-cycle walker5, 200 thrust values",
     ["limit-cycle", str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"),
      "--thrust", "0:-40:-0.2"], "orbit_energy"),
    ("simulate rabbit, 2 runs x 20 steps",
     ["simulate", "rabbit", "rabbit_walk", "--steps", "20", "--thrust", "0,-10"],
     "run_energy"),
    ("simulate three_link, 2 runs x 20 steps",
     ["simulate", "three_link", "three_link_walk", "--steps", "20", "--thrust", "0,-10"],
     "run_energy"),
)


def _line(label: str, how: str, total: float, share: float) -> None:
    """One case: the energies' share of the command and what they add to it (the command
    with them over the command without them, ``1 / (1 - share)``; target < 1.10)."""
    print(f"{label + ', ' + how:<64s} energies {100 * share:4.1f} % of {total:.2f} s CPU: "
          f"ratio {1.0 / (1.0 - share):.3f} (target < 1.10)", flush=True)


def main() -> None:
    if any(os.environ.get(v) != "1" for v in BLAS_THREADS):  # the warm runs: as cli.main
        env = {**os.environ, **{v: "1" for v in BLAS_THREADS}}
        for label, args, name in CASES:
            for formats in ("png", "none"):
                total, share = _process_share(name, [*args, "--formats", formats])
                _line(label, f"--formats {formats}, as a process", total, share)
        subprocess.run([sys.executable, __file__], env=env, check=True)
        return
    for label, args, name in CASES:
        for formats in ("png", "none"):
            total, share = _warm_share(name, [*args, "--formats", formats])
            _line(label, f"--formats {formats}, its work alone", total, share)


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        _child(sys.argv[2], sys.argv[3:])
    else:
        main()
