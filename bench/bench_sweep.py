"""Sweep benchmark: a 200-point simulate sweep (3-link, constant thrust 0 to -49.75 N, 15
compiled full-order steps per point, so that each point takes >= 50 ms) on 2 local worker
processes against 1 (in this process), and the per-task overhead of the sweep machinery
(planning, dispatch, the point's record and its atomic JSON file, progress) against the time of
the points themselves.

Both runs write every point file into a fresh sweep folder, as the command does; the
simulation kernel and the model are compiled and loaded before either run. Ratios are
measured in the same run (targets: speed-up >= 1.7, overhead < 5 %). The speed-up a shared
machine allows at that moment (two pure-Python processes against one) is printed beside it."""

from __future__ import annotations

import tempfile
import textwrap
from pathlib import Path

SWEEP = """\
name: bench
study: simulate
robot: three_link
gait: three_link_walk
settings: {thrust_model: constant, steps: 15}
grid:
  thrust: {start: 0, stop: -49.75, step: -0.25}
collect: [final_relative_error, max_abs_torque]
"""


def _spin(n: int) -> int:
    s = 0
    for i in range(n):
        s += i * i
    return s


def ceiling(n: int = 10_000_000) -> float:
    """What this machine gives 2 processes right now: a pure-Python loop twice in one process
    against once in each of 2 processes (1.0: no second core free, e.g. other jobs running)."""
    import multiprocessing
    import time

    t0 = time.perf_counter()
    _spin(n)
    _spin(n)
    one = time.perf_counter() - t0
    ctx = multiprocessing.get_context("fork")  # forked: the target is not pickled
    procs = [ctx.Process(target=_spin, args=(n,)) for _ in range(2)]
    t0 = time.perf_counter()
    for p in procs:
        p.start()
    for p in procs:
        p.join()
    two = time.perf_counter() - t0
    return one / two


def _run(sweep, workers: int, folder: Path):
    from thrustwalk_cli.files.output import SweepFolder
    from thrustwalk_cli.studies.sweep import run_sweep

    out = SweepFolder(folder, {"identity": sweep.identity, "sweep": sweep.name, "file": "-",
                               "points": len(sweep.tasks)})
    try:
        return run_sweep(sweep, workers=workers, on_point=out.write_point)
    finally:
        out.close()


def main() -> None:
    from timing import report

    from thrustwalk_cli.studies.compile import compile_kernel
    from thrustwalk_cli.studies.sweep import load_sweep

    compile_kernel()
    tmp = Path(tempfile.mkdtemp(prefix="tw-bench-sweep-"))
    path = tmp / "bench.yaml"
    path.write_text(textwrap.dedent(SWEEP))
    sweep = load_sweep(path)
    n = len(sweep.tasks)
    before = ceiling()
    one = _run(sweep, 1, tmp / "one")
    two = _run(sweep, 2, tmp / "two")
    after = ceiling()
    w1, w2 = one.counts.seconds, two.counts.seconds
    task1 = sum(r["seconds"] for r in one.records)
    task2 = sum(r["seconds"] for r in two.records)
    report(f"{n}-point simulate sweep, 1 worker (in process)", w1)
    report(f"{n}-point simulate sweep, 2 local worker processes", w2, w1)
    print(f"{'  speed-up 2 workers vs 1 (target >= 1.7)':<58s} {w1 / w2:12.3f}")
    print(f"{'  machine ceiling, 2 processes vs 1, before / after':<58s} {before:12.3f} / "
          f"{after:.3f}")
    report("mean point (simulate, 15 steps), 1 worker", task1 / n, unit="ms")
    over1 = (w1 - task1) / n
    over2 = (2 * w2 - task2) / n
    report("per-task overhead, 1 worker", over1, task1 / n, unit="ms")
    report("per-task overhead, 2 workers (idle time included)", over2, task2 / n, unit="ms")
    print(f"{'  overhead / mean point, 1 worker (target < 0.05)':<58s} "
          f"{over1 / (task1 / n):12.4f}")
    print(f"{'  overhead / mean point, 2 workers (target < 0.05)':<58s} "
          f"{over2 / (task2 / n):12.4f}")


if __name__ == "__main__":
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    main()
