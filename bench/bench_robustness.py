"""Robustness benchmark (SPEC 12): push trials of the 3-link walker, 10 steps each, on the local
executor (2 worker processes), against the same trials in this process (1 worker, the baseline
measured in the same run). The trials run in chunks of the size the command picks
(``trial_chunk``: several trials per engine task, printed); the 2 workers are also timed with
one trial per task (``chunk=1``, how the command ran before chunks), for the engine's cost per
task. Every trial's record is written to a fresh trials folder, as the command does.

Two trial mixes:

* "map": the issue's map, impulses -30 to 30 N s by 2 at phases 0 to 1 by 0.05 of three
  strategies (none, constant:-20, control): 1,953 trials (``--trials N``: about N, the
  impulses spaced more finely or coarsely). Many trials end early (a push that lifts the
  stance foot is decided before any simulation; a fall ends the run), so the mean number of
  steps simulated is printed beside the rate;
* "walk": zero pushes, which recover, every trial walking all 10 steps (the slowest trials; a
  third as many as the map): the worst case of any mix.

Reported per mix: trials per second with 1 and 2 workers, the speed-up, 2 workers with one
trial per task, and the projected time of 10,000 trials on 2 workers (target: under 5 minutes
on 2 cores with the local executor).
Before and after, the speed-up this machine allows two processes at that moment (two
pure-Python loops, as in bench_sweep) is printed, since the machine may be shared.

The simulation kernel is compiled before the clock starts. Each process keeps the walker and
each strategy's trial runner (the strategy made concrete: orbit, reduced basin, controller)
once made; that one-time set-up (a few tenths of a second per strategy, paid once per worker
process by the command) is timed on its own, with one trial per strategy, and then kept for
both timed runs (the local workers, forked, inherit it): the rates are those of the trials.

    python bench/bench_robustness.py [--trials 10000]    (or: make bench, python bench/run.py
                                                       robustness)
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

TARGET = 300.0  # [s] for 10,000 trials
STRATEGIES = ["none", "constant:-20", "control"]


def _run(plan, workers: int, folder: Path, chunk: int | None = None):
    from thrustwalk_cli.files.output import SweepFolder
    from thrustwalk_cli.studies.robustness import run_robustness

    out = SweepFolder(folder, {"identity": plan.identity, "sweep": "bench", "file": "-",
                               "points": len(plan.tasks)}, records="trials")
    try:
        t0 = time.perf_counter()
        res = run_robustness(plan, workers=workers, on_record=out.write_point, chunk=chunk)
        return res, time.perf_counter() - t0
    finally:
        out.close()


def _mixes(trials: int) -> dict[str, dict]:
    """About ``trials`` map trials (21 phases x n impulses x 3 strategies; 1,953: the issue's
    grid, impulses by 2 N s) and a third as many walk trials."""
    phases = np.round(np.arange(0.0, 1.0 + 1e-9, 0.05), 12)
    n_im = max(2, round(trials / (len(phases) * len(STRATEGIES))))
    impulses = np.round(np.linspace(-30.0, 30.0, n_im), 9)
    n_walk = max(2, round(trials / 3 / len(STRATEGIES)))
    return {
        "map": dict(push_impulse=impulses, push_phase=phases, strategy=STRATEGIES),
        "walk": dict(push_impulse=[0.0], push_phase=np.round(np.linspace(0.0, 1.0, n_walk), 12),
                     strategy=STRATEGIES),
    }


def _first_of_each(plan):
    """The plan cut to its first task of each strategy."""
    keep = sorted({wh[0]: i for i, wh in reversed(list(enumerate(plan.where)))}.values())
    return replace(plan, tasks=tuple(plan.tasks[i] for i in keep),
                   kinds=tuple(plan.kinds[i] for i in keep),
                   where=tuple(plan.where[i] for i in keep))


def main(trials: int = 1953) -> None:
    from bench_sweep import ceiling

    from thrustwalk_cli.studies import sweep_points
    from thrustwalk_cli.studies.compile import compile_kernel
    from thrustwalk_cli.studies.robustness import plan_robustness, trial_chunk
    from thrustwalk_cli.walker import load_walker

    w = load_walker("three_link", "three_link_walk")
    compile_kernel()
    tmp = Path(tempfile.mkdtemp(prefix="tw-bench-robustness-"))
    print(f"{'machine ceiling, 2 processes vs 1, before':<58s} {ceiling():12.3f}", flush=True)
    for name, kw in _mixes(trials).items():
        plan = plan_robustness(w, steps=10, basin_grid=0, **kw)
        n = len(plan.tasks)
        sweep_points.CACHE.clear()  # this process's walkers and runners: made anew, timed
        _, setup = _run(_first_of_each(plan), 1, tmp / f"{name}-setup")
        print(f"{f'{name}: set-up of {len(plan.strategies)} strategies (+1 trial each)':<58s} "
              f"{setup:12.2f} s", flush=True)
        runs = {workers: _run(plan, workers, tmp / f"{name}-{workers}") for workers in (1, 2)}
        (res1, dt1), (res, dt2) = runs[1], runs[2]
        res_single, dt_single = _run(plan, 2, tmp / f"{name}-2-single", chunk=1)
        out1 = [r["fields"]["outcome"] for r in res1.records]
        out2 = [r["fields"]["outcome"] for r in res.records]
        counts: dict[str, int] = {}
        for o in out2:
            counts[o] = counts.get(o, 0) + 1
        steps = np.mean([r["fields"]["steps_completed"] for r in res.records])
        rate1, rate2 = n / dt1, n / dt2
        proj = 10_000 / rate2
        same = out1 == out2 == [r["fields"]["outcome"] for r in res_single.records]
        print(f"{name}: {n} trials, outcomes {counts}, mean steps simulated {steps:.1f}"
              f"{'' if same else ' (OUTCOMES DIFFER between the runs)'}", flush=True)
        print(f"{name}: trials per task, 1 / 2 workers: {trial_chunk(n, 1, 10)} / "
              f"{trial_chunk(n, 2, 10)}", flush=True)
        print(f"{f'{name}: 1 worker (in process, baseline)':<58s} {rate1:12.1f} trials/s",
              flush=True)
        print(f"{f'{name}: 2 local worker processes':<58s} {rate2:12.1f} trials/s  "
              f"speed-up {dt1 / dt2:.2f}", flush=True)
        print(f"{f'{name}: 2 local worker processes, one trial per task':<58s} "
              f"{n / dt_single:12.1f} trials/s  speed-up {dt1 / dt_single:.2f}", flush=True)
        print(f"{f'{name}: projected 10,000 trials, 2 workers':<58s} {proj:12.1f} s  "
              f"(target < {TARGET:.0f} s: {'met' if proj < TARGET else 'NOT met'})", flush=True)
    print(f"{'machine ceiling, 2 processes vs 1, after':<58s} {ceiling():12.3f}", flush=True)


if __name__ == "__main__":
    import argparse
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    ap = argparse.ArgumentParser(description="Push trials per second of the 3-link walker "
                                             "(10 steps each), 2 local workers against 1.")
    ap.add_argument("--trials", type=int, default=1953,
                    help="map trials (about; default 1953, the issue's map; the walk mix has a "
                         "third as many)")
    main(ap.parse_args().trials)
