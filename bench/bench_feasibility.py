"""Contact feasibility and optimal schedules (SPEC 5, 6): cost of a thrust sweep and of the QP.

Affinity makes a sweep cheap: the Lambdas are evaluated once on the grid and every case only
combines them; the golden-section polish of the worst points is vectorised over the cases.
"""

from __future__ import annotations

import numpy as np
from timing import median_time, report

from thrustwalk_cli.contact.evaluate import evaluate
from thrustwalk_cli.contact.region import feasible_region
from thrustwalk_cli.contact.terms import fit_terms, stance_terms
from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.optimize import min_effort as opt
from thrustwalk_cli.optimize import qp
from thrustwalk_cli.thrust.schedule import Schedule
from thrustwalk_cli.walker import load_walker


def main() -> None:
    walker = load_walker(None, "three_link_walk")
    model, zd = walker.model, walker.zd
    fits = fit_terms(model, zd)
    m = model.n_thrusters

    def sweep(k: int) -> Schedule:
        F = np.zeros((k, m))
        F[:, 0] = np.linspace(0.0, -50.0, k)
        return Schedule.constant(zd, F)

    one, many = sweep(1), sweep(1000)
    for polish in (True, False):
        tag = "polished" if polish else "grid only"
        t1 = median_time(lambda p=polish: evaluate(
            model, zd, one, mu=0.7, fits=fits, polish=p, profiles=False), repeat=5)
        tk = median_time(lambda p=polish: evaluate(
            model, zd, many, mu=0.7, fits=fits, polish=p, profiles=False), repeat=3)
        report(f"feasibility, 1 case ({tag})", t1, unit="ms")
        report(f"feasibility, 1000 cases ({tag}), vs 1 case", tk, t1, unit="ms")
        report(f"  per case in the 1000 sweep ({tag}), vs 1 case", tk / 1000, t1, unit="ms")
    t_lc = median_time(lambda: limit_cycles(zd, many), repeat=3)
    report("  of which limit_cycles for 1000 cases", t_lc, unit="ms")
    t_terms = median_time(lambda: stance_terms(
        model, zd.maps, np.linspace(zd.alpha_i, zd.alpha_f, 401)), repeat=7)
    report("stance_terms on 401 points (exact Lambdas, torques)", t_terms, unit="ms")
    t_fit = median_time(lambda: fit_terms(model, zd), repeat=5)
    report("polynomial fits L_0..L_2 (degree from tolerance 1e-3)", t_fit, unit="ms")
    e = np.zeros((1, m))
    e[0, 0] = 1.0
    t_reg = median_time(lambda: feasible_region(
        model, zd, Schedule.constant(zd, e), np.linspace(-60, 10, 61),
        np.linspace(20, 5000, 81), mu=0.7), repeat=3)
    report("feasible region 61 x 81 (thrust, zeta^-)", t_reg, unit="ms")

    fr = np.linspace(0.0, 1.0, 5)
    n = len(fr) - 1
    prob = opt.build_problem(model, zd, fr, mu=0.7, zeta_min_rel=0.01,
                             bounds=(np.full(n, -100.0), np.full(n, 100.0)))
    zlo, zhi, _ = opt.zeta_range(prob)
    z0 = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, m))))[0].zeta_star
    target = z0 + 0.5 * (zhi - z0)
    A, b, ae, be = prob.at(target)
    print(f"QP: {prob.n} variables, {len(b)} inequality rows, 1 equality", flush=True)
    t_lp = median_time(lambda: qp.lp_feasible(A, b, ae, be), repeat=7)
    report("LP feasibility (HiGHS)", t_lp, unit="ms")
    t_ldp = median_time(lambda: qp.ldp_qp(A, b, ae, be, prob.weights), repeat=7)
    report("least-distance QP (NNLS), vs LP", t_ldp, t_lp, unit="ms")
    x0 = qp.lp_feasible(A, b, ae, be)[1]
    t_as = median_time(lambda: qp.active_set_qp(A, b, ae, be, prob.weights, x0), repeat=7)
    report("primal active-set QP, vs LP", t_as, t_lp, unit="ms")
    t_fix = median_time(lambda: opt._solve_fixed(prob, target), repeat=7)
    report("QP at fixed zeta* (LP + NNLS + KKT check), vs LP", t_fix, t_lp, unit="ms")
    t_opt = median_time(lambda: opt.optimize(model, zd, fr, target_zeta=target, mu=0.7),
                        repeat=3)
    report("optimize, target zeta* (with exchange re-checks), vs QP", t_opt, t_fix, unit="ms")
    v0 = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, m))))[0].speed
    t_spd = median_time(lambda: opt.optimize(model, zd, fr, target_speed=1.05 * v0, mu=0.7),
                        repeat=3)
    report("optimize, target speed (root search over zeta*), vs QP", t_spd, t_fix, unit="ms")


if __name__ == "__main__":
    main()
