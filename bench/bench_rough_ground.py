"""Rough-ground benchmark (SPEC 14): the mesh chain of one strategy (none) for one sigma on the
3-link walker (the command's default mesh: 21 zeta^- values x the impact heights, 25 terrain
samples; target: under 10 s on 2 cores), and the Monte-Carlo trials per second on the local
executor with 2 worker processes against 1 (this process), each trial walking until failure
or the cap. The simulation kernel is compiled, and the walker and the strategy made concrete,
before the clock starts.

    python bench/bench_rough_ground.py [--trials 240]    (or: python bench/run.py rough_ground)
"""

from __future__ import annotations

import sys
import time

TARGET = 10.0  # [s] the mesh chain for one sigma
SIGMA = 0.0045  # [m] MFPT about 35 steps on the 3-link walker


def main(trials: int = 240) -> None:
    from thrustwalk_cli.studies.compile import compile_kernel
    from thrustwalk_cli.studies.rough_ground import mesh_chain, plan_rough_ground, run_rough_ground
    from thrustwalk_cli.walker import load_walker

    compile_kernel()
    walker = load_walker("three_link", None)
    plan = plan_rough_ground(walker, sigma=[SIGMA], strategy=["none"], trials=trials, cap=1000)
    t0 = time.perf_counter()
    mesh = mesh_chain(plan, 0)
    t_mesh = time.perf_counter() - t0
    row = mesh["sigmas"][0]
    print(f"mesh chain, 1 sigma ({mesh['states']} states, {mesh['simulations']} one-step "
          f"simulations): {t_mesh:.2f} s (target < {TARGET:g} s: "
          f"{'met' if t_mesh < TARGET else 'NOT met'}); MFPT {row['mfpt']:.4g} +- "
          f"{row['uncertainty']:.2g} steps")
    rates = {}
    for workers in (1, 2):
        t0 = time.perf_counter()
        res = run_rough_ground(plan, workers=workers, meshes=[mesh])
        dt = time.perf_counter() - t0  # the mesh is given: trials only
        steps = sum(r["fields"]["attempted"] for r in res.records)
        rates[workers] = trials / dt
        print(f"Monte-Carlo, {workers} worker(s): {trials} trials ({steps} steps) in {dt:.2f} s "
              f"= {rates[workers]:.1f} trials/s")
    print(f"Monte-Carlo speed-up 2 workers / 1: {rates[2] / rates[1]:.2f}")


if __name__ == "__main__":
    main(int(sys.argv[sys.argv.index("--trials") + 1]) if "--trials" in sys.argv else 240)
