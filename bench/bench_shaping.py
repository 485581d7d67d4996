"""Shaping benchmark: a k-sweep of 51 shaped orbits (T_j = k(j - 2), k = 0..50) vs one orbit.

The paper's example on the bundled 3-link gait: knots solved once for shape-only thrust, then
the limit cycles of the whole sweep in one batch (the fixed point is affine in T_j).
"""

from __future__ import annotations

import numpy as np
from timing import median_time, report


def main() -> None:
    from thrustwalk_cli import shaping as S
    from thrustwalk_cli import shaping_study as SS
    from thrustwalk_cli.model import load_model
    from thrustwalk_cli.robot_io import load_gait_for
    from thrustwalk_cli.zero_dynamics import limit_cycles, zero_dynamics

    robot, g = load_gait_for(None, "three_link_walk")
    zd = zero_dynamics(load_model(robot), g)
    ks = np.arange(51.0)
    P = S.pattern_values(S.DEFAULT_PATTERN, 3, ks)
    t_knots = median_time(lambda: S.solve_knots(zd, [0.0, None, None, 1.0], P, "generalized"))
    sol = S.solve_knots(zd, [0.0, None, None, 1.0], P, "generalized")
    one = S.make_schedule(zd, sol.alpha, P[-1:], "generalized")
    many = S.make_schedule(zd, sol.alpha, P, "generalized")
    t_one = median_time(lambda: limit_cycles(zd, one), repeat=9)
    t_many = median_time(lambda: limit_cycles(zd, many), repeat=9)
    t_study = median_time(lambda: SS.shape_study(zd, SS.ShapeRequest(ks=tuple(ks))), repeat=5)
    report("shape: solve the 2 interior knots (paper's example)", t_knots, unit="ms")
    report("shape: one shaped orbit (baseline)", t_one, unit="ms")
    report("shape: 51 shaped orbits, k = 0..50 (ratio to one orbit)", t_many, t_one, unit="ms")
    report("shape: whole study, 51 k + nominal + k = 60 (ratio)", t_study, t_one,
           unit="ms")


if __name__ == "__main__":
    main()
