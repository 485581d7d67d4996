"""Step-to-step control benchmark (SPEC 11): the per-step QP against the full-order simulated
step it plans, both measured in this run.

* "QP per step": ``Planner.plan`` (constraint update for the measured zeta^-, the exact QP with
  generated rows, warm-started from the previous step's active set) on the bundled gaits,
  knots 0, 0.5, 1, 401-point alpha grid with the exact Lambda terms;
* baseline "simulated step": one full-order step of the compiled kernel (``Stepper.step``)
  under the same thrust; the ratio says how much of a control cycle the QP takes;
* the slow-thruster planner (second-order, linear response with the fixed-point time map).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from timing import median_time, report

REPO = Path(__file__).resolve().parents[1]


def _gaits() -> list[str]:
    return [g for g in ("three_link_walk", "rabbit_walk")
            if (REPO / "gaits" / f"{g}.yaml").is_file()]


def main() -> None:
    from thrustwalk_cli.controller.planner import Planner, Settings
    from thrustwalk_cli.controller.step_model import IdealThrust, ResponseThrust, Terms
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.simulation.closed_loop import ClosedLoop, SimConfig, ThrustModel
    from thrustwalk_cli.simulation.full_order import Start, initial_state
    from thrustwalk_cli.simulation.stepper import Stepper
    from thrustwalk_cli.thrust.dynamics import second_order
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    for gait in _gaits():
        w = load_walker(None, gait)
        zd, model = w.zd, w.model
        m = model.n_thrusters
        lc = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, m))))[0]
        zs = lc.zeta_star
        lim = model.robot.thrusters[0].limits
        st = Settings(mu=zd.gait.mu, eps=0.0, zeta_min=0.01 * zs, lo=np.array([lim[0]]),
                      hi=np.array([lim[1]]), rate=None, tracking=None, effort=1.0, smooth=0.0,
                      noise=0.0, points=401, zeta_scale=zs,
                      force_scale=max(abs(lim[0]), abs(lim[1])))
        kn = zd.alpha_i + np.array([0.0, 0.5, 1.0]) * (zd.alpha_f - zd.alpha_i)
        pl = Planner(zd, Terms(model, zd), IdealThrust(zd, kn, [0]), st)
        pl.plan(zs, 1.2 * zs, np.zeros(2))  # factorisations and rows, once per gait
        refs = iter(np.tile([1.2, 1.1, 1.25], 1000) * zs)
        t_qp = median_time(lambda: pl.plan(zs, next(refs), np.zeros(2)), repeat=50)

        sched = Schedule(kn, np.zeros((1, 2, m)), np.zeros((1, 2)))
        cl = ClosedLoop(zd, ThrustModel("piecewise", np.zeros(m), schedule=sched),
                        SimConfig(steps=1))
        stepper = Stepper(cl, 10 * lc.step_time)
        x0 = initial_state(zd, cl.thrust, Start(zeta_minus=zs))
        stepper.step(1, 0.0, x0)  # load the kernel
        t_step = median_time(lambda: stepper.step(1, 0.0, x0), repeat=7)
        report(f"{gait}: baseline: one simulated step (compiled kernel, "
               f"{lc.step_time:.3f} s of walking)", t_step, unit="ms")
        report(f"{gait}: one QP per step (ratio to the simulated step)", t_qp, t_step,
               unit="ms")
        dyn = second_order(model.n_thrusters, wn=20.0, xi=1.0)
        ps = Planner(zd, Terms(model, zd), ResponseThrust(zd, dyn, [0]), st)
        z = np.zeros(2 * m)
        t_slow = median_time(lambda: ps.plan(zs, 1.2 * zs, np.zeros(1), z), repeat=5)
        report(f"{gait}: slow-thruster plan, linear response (ratio to the simulated step)",
               t_slow, t_step, unit="ms")
