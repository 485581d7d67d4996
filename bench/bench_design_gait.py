"""Gait-design benchmark: designing a RABBIT gait from the default start (one SLSQP run) vs
one evaluation of the objective and constraints (ratio = evaluations' worth of work)."""

from __future__ import annotations

import time

from timing import median_time, report


def main() -> None:
    from thrustwalk_cli.design.problem import Problem
    from thrustwalk_cli.design.solver import solve_design
    from thrustwalk_cli.design.spec import DesignSpec
    from thrustwalk_cli.studies.compile import compile_robot

    model = compile_robot("rabbit")
    spec = DesignSpec(speed=0.53, starts=1, seed=0)
    prob = Problem(model, spec)
    x0 = prob.start(None)
    t_eval = median_time(lambda: prob.evaluate(x0), repeat=21)
    t0 = time.perf_counter()
    res = solve_design(model, spec)
    t_design = time.perf_counter() - t0
    report("rabbit: one objective + constraints evaluation (baseline)", t_eval, unit="ms")
    report("rabbit: design from the default start (ratio = evaluations)", t_design, t_eval)
    print(f"{'':<58s} {res.evaluations} evaluations, feasible {res.feasible}, "
          f"effort {res.objective:.5g} N^2 m s, target < 60 s", flush=True)
