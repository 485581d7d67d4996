"""Limit-cycle benchmark: 1,000 thrust values vs one orbit (zeta* is affine in thrust)."""

from __future__ import annotations

import numpy as np
from timing import median_time, report


def main() -> None:
    from thrustwalk_cli.hzd.zero_dynamics import Schedule, limit_cycles, zero_dynamics
    from thrustwalk_cli.walker import load_walker

    for gait in ("three_link_walk", "rabbit_walk"):
        walker = load_walker(None, gait)
        model, g = walker.model, walker.gait
        t_zd = median_time(lambda: zero_dynamics(model, g), repeat=5)
        zd = zero_dynamics(model, g)
        one = np.zeros((1, model.n_thrusters))
        many = np.zeros((1000, model.n_thrusters))
        many[:, 0] = np.linspace(0, -50, 1000)
        t_one = median_time(lambda: limit_cycles(zd, Schedule.constant(zd, one)), repeat=7)
        t_many = median_time(lambda: limit_cycles(zd, Schedule.constant(zd, many)), repeat=3)
        report(f"{gait}: zero-dynamics precomputation", t_zd)
        report(f"{gait}: one orbit (baseline)", t_one)
        report(f"{gait}: 1,000 orbits (ratio to one orbit)", t_many, t_one)
        report(f"{gait}: precomputation + 1,000 orbits vs precomputation + one",
               t_zd + t_many, t_zd + t_one)
