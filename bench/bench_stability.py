"""Floquet analysis benchmark (SPEC 13): the Jacobian of the Poincare map by each method, and
their ratio measured in the same run.

* finite differences: central differences of the compiled one-step simulation at the five
  steps of the convergence sweep (``2 (n-1)`` runs per step, threads over the batch);
* variational equations: the orbit and ``Phi' = f_x Phi`` integrated together (``solve_ivp``,
  DOP853), ``f_x`` from the closed loop's vectorised right-hand side;
* baseline: one compiled full-order step at the same tolerance.
"""

from __future__ import annotations

import numpy as np
from timing import median_time, report


def main() -> None:
    from thrustwalk_cli.floquet.poincare import (
        PoincareMap,
        Setting,
        fd_jacobian,
        newton,
        predicted_state,
        section_basis,
    )
    from thrustwalk_cli.floquet.variational import variational_jacobian
    from thrustwalk_cli.simulation.closed_loop import ThrustModel
    from thrustwalk_cli.walker import load_walker

    for robot, gait in (("three_link", "three_link_walk"), ("rabbit", "rabbit_walk")):
        walker = load_walker(robot, gait)
        zd, m = walker.zd, walker.model.n_thrusters
        target = np.zeros(m)
        if m:
            target[0] = -10.0
        th = ThrustModel("second-order", target, wn=2.0, xi=0.7)
        setting = Setting(th, float(walker.gait.kp), float(walker.gait.kd))
        P = PoincareMap(zd, setting)
        x0, _ = predicted_state(zd, th)
        fp = newton(P, x0)
        B = section_basis(zd, fp.x, th.n_states)
        n = B.shape[1]
        t_step = median_time(lambda: P.one(fp.x), repeat=5)
        report(f"{gait}: baseline: one compiled step (rtol 1e-12)", t_step, unit="ms")
        t_fd = median_time(lambda: fd_jacobian(P, fp.x, B), repeat=3)
        report(f"{gait}: Jacobian ({n}x{n}) by finite differences", t_fd, t_step, unit="ms")
        t_var = median_time(lambda: variational_jacobian(zd, setting, fp.x), repeat=3)
        report(f"{gait}: Jacobian by variational equations", t_var, t_step, unit="ms")
        report(f"{gait}: variational / finite differences", t_var, t_fd, unit="ms")


if __name__ == "__main__":
    main()
