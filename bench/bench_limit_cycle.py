"""Limit-cycle benchmark: 1,000 thrust values vs one (zeta* is affine in thrust), and the cost
of the energy on the orbit (limit-cycle with and without it, SPEC 15).

Two quantities: the fixed point zeta* = V_Z(alpha_f)/(1 - delta_zero^2) (SPEC 4), the
quantity of the issue's "a 1,000-value thrust sweep" line, and whole limit cycles (fixed
point, step time by spectral quadrature, extrema polished by Newton), which cost per orbit.
"""

from __future__ import annotations

import numpy as np
from timing import median_time, report


def main() -> None:
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles, zero_dynamics
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    for gait in ("three_link_walk", "rabbit_walk"):
        walker = load_walker(None, gait)
        model, g = walker.model, walker.gait
        t_zd = median_time(lambda: zero_dynamics(model, g), repeat=5)
        zd = zero_dynamics(model, g)
        one = np.zeros((1, model.n_thrusters))
        many = np.zeros((1000, model.n_thrusters))
        many[:, 0] = np.linspace(0, -50, 1000)
        af = np.array(zd.alpha_f)
        s_one, s_many = Schedule.constant(zd, one), Schedule.constant(zd, many)
        fp_one = median_time(lambda: zd.V_Z(af, s_one) / (1.0 - zd.delta_zero_sq), repeat=7,
                             number=200)
        fp_many = median_time(lambda: zd.V_Z(af, s_many) / (1.0 - zd.delta_zero_sq),
                              repeat=7, number=200)
        report(f"{gait}: fixed point zeta*, one thrust (baseline)", fp_one, unit="us")
        report(f"{gait}: fixed points zeta*, 1,000 thrusts (ratio; target < 2)", fp_many,
               fp_one, unit="us")
        t_one = median_time(lambda: limit_cycles(zd, Schedule.constant(zd, one)), repeat=7)
        t_many = median_time(lambda: limit_cycles(zd, Schedule.constant(zd, many)), repeat=3)
        report(f"{gait}: zero-dynamics precomputation", t_zd)
        report(f"{gait}: one whole limit cycle (baseline)", t_one)
        report(f"{gait}: 1,000 whole limit cycles (ratio)", t_many, t_one)
        report(f"{gait}: precomputation + 1,000 whole cycles vs precomputation + one",
               t_zd + t_many, t_zd + t_one)

    # the energy on the orbit (SPEC 15): limit-cycle with and without it, document included
    from thrustwalk_cli.studies.limit_cycle import limit_cycle

    walker = load_walker(None, "rabbit_walk")
    thrust = np.arange(0, -40, -0.04)

    def run(energy: bool) -> None:
        limit_cycle(walker, thrust=thrust, energy=energy).document()
    run(True)
    t_off = median_time(lambda: run(False), repeat=5)
    t_on = median_time(lambda: run(True), repeat=5)
    report("rabbit_walk: limit-cycle, 1,000 thrusts, no energy (baseline)", t_off)
    report("rabbit_walk: limit-cycle, 1,000 thrusts, with energy (ratio; target < 1.1)", t_on,
           t_off)
