"""Full-order simulation benchmark (SPEC 7): one step, right-hand side, fixed point by simulation.

Baselines measured in the same run:
* "compiled dynamics": the passive pinned model ``q'' = D^-1 (-h)`` from the same generated
  scalar functions plus ``numpy.linalg.solve``, integrated by the same ``solve_ivp`` over the
  same time without events (the least any closed-loop right-hand side can cost);
* "zero-dynamics formula": ``zeta* = V_Z(alpha_f)/(1 - delta_zero^2)`` (one limit cycle, and
  with the precomputation of V_Z) against simulating until ``zeta^-`` settles to 1e-6.
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
    from scipy.integrate import solve_ivp

    from thrustwalk_cli.hzd.zero_dynamics import Schedule, limit_cycles, zero_dynamics
    from thrustwalk_cli.simulation.closed_loop import ClosedLoop, SimConfig, ThrustModel
    from thrustwalk_cli.simulation.full_order import Start, simulate
    from thrustwalk_cli.walker import load_walker

    for gait in _gaits():
        walker = load_walker(None, gait)
        model, g, zd = walker.model, walker.gait, walker.zd
        N, m = model.n, model.n_thrusters
        th = ThrustModel("constant", np.zeros(m))
        cfg = SimConfig(steps=1, rtol=1e-9, atol=1e-9)
        res = simulate(zd, th, cfg)
        T = res.steps[0].step_time
        t_step = median_time(lambda: simulate(zd, th, cfg), repeat=5)
        report(f"{gait}: one simulated step at rtol 1e-9 ({res.nfev} RHS calls)", t_step,
               unit="ms")

        x0 = np.concatenate([zd.maps.q_plus, res.steps[0].dq_minus])

        def passive(t, x):
            q, dq = x[:N].tolist(), x[N:].tolist()
            ddq = np.linalg.solve(np.array(model.D_s(q)).reshape(N, N),
                                  -np.array(model.h_s(q, dq)))
            return np.concatenate([x[N:], ddq])

        t_base = median_time(lambda: solve_ivp(passive, (0, T), x0, method="DOP853",
                                               rtol=1e-9, atol=1e-9, dense_output=True),
                             repeat=5)
        report(f"{gait}: baseline: passive compiled dynamics over the same time", t_base,
               unit="ms")
        report(f"{gait}: one step (ratio to the compiled-dynamics baseline)", t_step, t_base,
               unit="ms")

        cl = ClosedLoop(zd, th, cfg)
        x = np.concatenate([zd.maps.q_plus, np.ones(N)])
        n = 2000
        t_rhs = median_time(lambda: cl.rhs(0.0, x, 0), repeat=7, number=n)
        t_prhs = median_time(lambda: passive(0.0, x), repeat=7, number=n)
        report(f"{gait}: baseline RHS: passive D_s + h_s + numpy solve", t_prhs, unit="us")
        report(f"{gait}: closed-loop RHS (ratio to the passive RHS)", t_rhs, t_prhs, unit="us")
        print(f"{gait + ': closed-loop RHS evaluations per second':<58s} {1 / t_rhs:12.4g}",
              flush=True)

        # the fixed point: simulate from 30 % off until zeta^- is within 1e-6 of zeta*, vs the
        # formula zeta* = V_Z(alpha_f)/(1 - delta_zero^2) (alone, as a whole limit cycle, and
        # with the precomputation of V_Z)
        sched = Schedule.constant(zd, np.zeros((1, m)))
        zs = limit_cycles(zd, sched)[0].zeta_star
        start = Start(perturb=0.3)
        probe = simulate(zd, th, SimConfig(steps=80, rtol=1e-9, atol=1e-9), start)
        z = np.array([st.zeta_minus for st in probe.steps])
        done = np.nonzero(np.abs(z / zs - 1) < 1e-6)[0]
        if not probe.success or done.size == 0:
            print(f"{gait}: simulation did not settle: {probe.reason}")
            continue
        n_steps = int(done[0]) + 1
        conv = SimConfig(steps=n_steps, rtol=1e-9, atol=1e-9)
        t_sim = median_time(lambda: simulate(zd, th, conv, start), repeat=3)
        af = np.array(zd.alpha_f)
        t_formula = median_time(
            lambda: zd.V_Z(af, sched) / (1.0 - zd.delta_zero_sq), repeat=7, number=200)
        t_cycle = median_time(lambda: limit_cycles(zd, sched), repeat=7)
        t_full = median_time(lambda: limit_cycles(zero_dynamics(model, g), sched), repeat=5)
        print(f"{gait + ': steps to zeta* within 1e-6 by simulation':<58s} {n_steps:12d}",
              flush=True)
        report(f"{gait}: baseline: zeta* by the formula V_Z(af)/(1-d0^2)", t_formula,
               unit="us")
        report(f"{gait}: zeta* by simulation (ratio to the formula)", t_sim, t_formula,
               unit="ms")
        report(f"{gait}: ... ratio to one whole limit cycle (orbit, T)", t_sim, t_cycle,
               unit="ms")
        report(f"{gait}: ... ratio to limit cycle incl. V_Z precomputation", t_sim, t_full,
               unit="ms")


if __name__ == "__main__":
    main()
