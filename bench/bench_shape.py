"""Shaping benchmark: a k-sweep of 51 shaped orbits (T_j = k(j - 2), k = 0..50) vs one orbit.

The paper's example on the bundled 3-link gait: knots solved once for shape-only thrust, then
the limit cycles of the whole sweep in one batch (the fixed point is affine in T_j).
"""

from __future__ import annotations

import numpy as np
from timing import median_time, report


def main() -> None:
    from thrustwalk_cli.hzd.shaping import DEFAULT_PATTERN, solve_knots
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.studies.shape import ShapeRequest, pattern_values, shape
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    walker = load_walker(None, "three_link_walk")
    zd = walker.zd
    ks = np.arange(51.0)
    P = pattern_values(DEFAULT_PATTERN, 3, ks)
    t_knots = median_time(lambda: solve_knots(zd, [0.0, None, None, 1.0], P, "generalized"))
    sol = solve_knots(zd, [0.0, None, None, 1.0], P, "generalized")
    m = zd.model.n_thrusters
    one = Schedule.piecewise(sol.alpha, P[-1:], "generalized", m)
    many = Schedule.piecewise(sol.alpha, P, "generalized", m)
    t_one = median_time(lambda: limit_cycles(zd, one), repeat=9)
    t_many = median_time(lambda: limit_cycles(zd, many), repeat=9)
    t_study = median_time(lambda: shape(walker, ShapeRequest(ks=tuple(ks))), repeat=5)
    report("shape: solve the 2 interior knots (paper's example)", t_knots, unit="ms")
    report("shape: one shaped orbit (baseline)", t_one, unit="ms")
    report("shape: 51 shaped orbits, k = 0..50 (ratio to one orbit)", t_many, t_one, unit="ms")
    report("shape: whole study, 51 k + nominal + k = 60 (ratio)", t_study, t_one,
           unit="ms")


if __name__ == "__main__":
    main()
