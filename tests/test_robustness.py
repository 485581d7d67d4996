"""Robustness (SPEC 12): impulsive pushes, the exact basin of the reduced walker, push and basin
trials of the full-order closed loop, parameter uncertainty, the maps' summaries and the
command (outputs, resuming, bad options), on the bundled 3-link walker only (one compiled
kernel).

Independent computations: the reduced basin's bounds from an adaptive quadrature of
``V_Z`` (SciPy ``quad``, not the Chebyshev series) and the ground force of the full-order
closed loop's own dynamics (``ClosedLoop.details``, not the Lambda terms), each extremum over
alpha found by SciPy's bounded Brent search; the push's ground reaction against the robot's
linear momentum (``J_com``) and its rate jump against the angular momentum about the stance
foot; the controlled basin's ends against the QP's own feasibility; the Monte-Carlo draws
against numpy's generator called directly; survivable pushes against grids worked out by
hand; the first event of a trial against the swing foot's height on the orbit (its zero by
Brent) and against the SciPy reference simulation's stance force (its cone exit by Brent).
Also on the user's 5-link knee walker (tests/data/walker5*.yaml).
"""

from __future__ import annotations

import json
import os
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq, minimize_scalar

from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.resilience.basin import reduced_basin
from thrustwalk_cli.resilience.maps import single_outcome, summary_impulse, survivable
from thrustwalk_cli.resilience.push import push_point, rate_jump, stance_impulse
from thrustwalk_cli.resilience.strategy import Strategy, realize
from thrustwalk_cli.resilience.trials import Trial, TrialRunner
from thrustwalk_cli.resilience.uncertainty import controlled_sample, fixed_sample
from thrustwalk_cli.simulation.closed_loop import ClosedLoop, SimConfig, ThrustModel
from thrustwalk_cli.simulation.full_order import Start, initial_state, simulate
from thrustwalk_cli.studies.robustness import plan_robustness, robustness, run_robustness
from thrustwalk_cli.thrust.schedule import Schedule

MU = 0.7
STRATEGIES = (Strategy("none"), Strategy("constant", thrust=-20.0), Strategy("control"))
REPO = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
# column 2 of q2 raised: on the orbit the swing leg passes under the hip early and its foot
# dips below the ground at s ~ 0.36, well before mid-step
DIP = ("0.11874783356434716, 0.2445021030062819", "0.28, 0.2445021030062819")


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    """The user's 5-link knee walker and its 0.6 m/s gait (tests/data)."""
    from thrustwalk_cli.walker import load_walker

    return load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"))


@pytest.fixture(scope="module")
def dipping(walker3, tmp_path_factory):
    """The bundled 3-link gait edited (as test_verdicts builds SCUFFING) so that its swing
    foot dips below the ground at s ~ 0.36."""
    from thrustwalk_cli.walker import load_walker

    text = (REPO / "gaits" / "three_link_walk.yaml").read_text()
    assert DIP[0] in text
    path = tmp_path_factory.mktemp("dip") / "dipping.yaml"
    path.write_text(text.replace(*DIP).replace("name: three_link_walk", "name: dipping"))
    return load_walker("three_link", str(path))


@pytest.fixture(scope="module")
def realized(walker3):
    """The three strategies made concrete for the 3-link walker (mu = 0.7)."""
    return {s.label: realize(walker3.zd, s, mu=MU) for s in STRATEGIES}


def _runner(walker3, real, steps=10, **kw):
    return TrialRunner(walker3.zd, real, push_point(walker3.model), steps=steps, mu=MU, **kw)


# ------------------------------------------------------------------- the reduced basin
def _independent_bounds(walker, F: float, mu: float) -> tuple[float, float]:
    """SPEC 12's closed form computed another way: V_Z by adaptive quadrature of
    ``(kappa_2 + beta F)/kappa_1``; F_1 from the full-order closed loop on Z at zeta = 0 and 1
    (affine in zeta); each row's bound ``-g/c`` extremised over alpha on a grid, then by
    bounded Brent between the neighbouring grid points."""
    zd, model = walker.zd, walker.model
    d2 = zd.delta_zero_sq
    Fv = np.zeros(model.n_thrusters)
    Fv[0] = F

    def integrand(a):
        t = zd.terms(np.array([a]))
        return float((t["kappa2"][0] + t["beta"][0] @ Fv) / t["kappa1"][0])

    def VZ(a):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return quad(integrand, zd.alpha_i, a, epsabs=0, epsrel=1e-12, limit=200)[0]

    cl = ClosedLoop(zd, ThrustModel("constant", Fv), SimConfig())

    def F1(a, zeta):
        t = zd.terms(np.atleast_1d(a))
        dq = t["Phi"] * (t["kappa1"] * zd.sigma_sign * np.sqrt(2.0 * zeta))[:, None]
        return cl.details(np.hstack([t["q"], dq]), np.zeros(1, int))["F1"][0]

    def rows(a):
        A = F1(a, 0.0)
        B = F1(a, 1.0) - A
        v = VZ(a)
        F0, dF = A + B * v, B * d2
        return [(v, d2), (F0[1], dF[1]), (mu * F0[1] - F0[0], mu * dF[1] - dF[0]),
                (mu * F0[1] + F0[0], mu * dF[1] + dF[0])]

    grid = np.linspace(zd.alpha_i, zd.alpha_f, 201)
    table = [rows(a) for a in grid]
    lo, hi = -np.inf, np.inf
    for r in range(4):
        g = np.array([t[r][0] for t in table])
        c = np.array([t[r][1] for t in table])
        for sign in (1.0, -1.0):
            with np.errstate(divide="ignore"):
                b = np.where(sign * c > 0, -g / c, -sign * np.inf)
            if not np.any(np.isfinite(b)):
                continue
            j = int(np.argmax(b) if sign > 0 else np.argmin(b))
            br = (grid[max(j - 1, 0)], grid[min(j + 1, grid.size - 1)])
            def ratio(a, r=r, sign=sign):
                g_a, c_a = rows(a)[r]  # one evaluation of the rows per point
                return sign * g_a / c_a

            res = minimize_scalar(ratio, bounds=br, method="bounded", options={"xatol": 1e-13})
            best = -sign * res.fun
            if sign > 0:
                lo = max(lo, best, b[j])
            else:
                hi = min(hi, best, b[j])
    return lo, hi


@pytest.mark.parametrize("F", [0.0, -20.0])
@pytest.mark.slow
def test_reduced_basin_bounds_equal_the_closed_form(walker3, F):
    zd = walker3.zd
    sched = Schedule.constant(zd, np.array([[F, 0.0]]))
    b = reduced_basin(zd, sched, mu=MU)
    lo, hi = _independent_bounds(walker3, F, MU)
    assert b.exists, b.reason
    assert b.lower.value == pytest.approx(lo, rel=1e-9), (b.lower, lo)
    assert b.upper.value == pytest.approx(hi, rel=1e-9), (b.upper, hi)
    # the stop bound is -min V_Z / delta_zero^2 (SPEC 12): the walker nearly stops there
    assert b.lower.family == "stop"
    lc = limit_cycles(zd, sched)[0]
    assert lo < lc.zeta_star < hi and b.zeta_star == pytest.approx(lc.zeta_star, rel=1e-12)
    # inside converges without leaving (map contracts into the interval); just outside not
    d2, V = zd.delta_zero_sq, float(zd.V_Z(np.array(zd.alpha_f), sched)[0])
    for x in (lo * (1 + 1e-6), hi * (1 - 1e-6)):
        for _ in range(50):
            x = d2 * x + V
            assert lo < x <= hi
        assert x == pytest.approx(lc.zeta_star, rel=1e-5)
    assert not b.contains(lo * (1 - 1e-9)) and not b.contains(hi * (1 + 1e-9))


@pytest.mark.slow
def test_controlled_basin_ends_are_where_the_qp_stops_being_feasible(realized):
    """The controlled basin's ends (two LPs over (x, u)) against the planner's own QP: just
    inside a thrust exists, just outside the step is infeasible. It is wider than the
    uncontrolled one, and iterating the controlled map from across it converges."""
    r = realized["control"]
    b = r.basin
    assert b.exists, b.reason
    for x, inside in ((b.lower.value * (1 + 1e-6), True), (b.upper.value * (1 - 1e-6), True),
                      (b.lower.value * (1 - 1e-3), False), (b.upper.value * (1 + 1e-3), False)):
        plan = r.planner.plan(x, r.zeta_ref, np.zeros(r.planner.nu))
        assert (plan.status != "infeasible") == inside, (x, plan.status)
    none = realized["none"].basin
    assert b.lower.value < none.lower.value and b.upper.value > none.upper.value
    assert b.verified["converged"] == b.verified["starts"] == 41


def test_the_controlled_map_stops_at_its_fixed_point_with_the_full_iterations_verdict(
        realized):
    """The basin's check iterates the controlled map from 41 starts; it stops a start once
    ``(x, u)`` maps to itself bit for bit. The same 60 steps written out here (the map
    ``x' = delta_0^2 x + z0 + Gamma u``, the planner's QP each step) end every start at the
    same ``x`` and give the same verdict, with far fewer QPs."""
    from thrustwalk_cli.resilience import basin as B

    r = realized["control"]
    pl, b = r.planner, r.basin
    d2, rw = pl.zd.delta_zero_sq, pl.grid_rows()
    lo, hi = b.lower.value, b.upper.value
    w = hi - lo
    worst, ok = 0.0, 0
    for x0 in np.linspace(lo + 1e-6 * w, hi - 1e-6 * w, B.VERIFY_STARTS):
        x, u = float(x0), np.zeros(pl.nu)
        for _ in range(B.VERIFY_STEPS):
            plan = pl.plan(x, r.zeta_ref, u)
            assert plan.status != "infeasible"
            u = plan.u
            x = float(d2 * x + rw.z0[-1] + rw.Zu[-1] @ u)
        err = abs(x - r.zeta_ref) / r.zeta_ref
        worst, ok = max(worst, err), ok + (err <= 1e-9)
    calls = []
    plan_of = pl.plan

    def counted(*a, **k):
        calls.append(1)
        return plan_of(*a, **k)

    pl.plan = counted
    try:
        got = B._iterate(pl, r.zeta_ref, b.lower, b.upper)
    finally:
        del pl.plan
    assert got["converged"] == ok == B.VERIFY_STARTS
    assert got["worst_relative_error"] == worst
    assert len(calls) < B.VERIFY_STARTS * B.VERIFY_STEPS / 4


# ------------------------------------------------------------------------------ pushes
def test_push_reaction_conserves_linear_and_angular_momentum(walker3):
    """For a push P at the hip with the stance foot pinned: the robot's linear momentum
    changes by P + F (F the foot's impulsive reaction), and sigma_N, the angular momentum about
    the stance foot, by (p x P)_z (the reaction has no moment about the foot)."""
    model, zd = walker3.model, walker3.zd
    pt = push_point(model)
    M = model.robot.total_mass
    for s in (0.1, 0.5, 0.9):
        q = zd.maps.q_Z(np.array(zd.alpha_i + s * (zd.alpha_f - zd.alpha_i)))
        P = np.array([7.0, -3.0])
        dq = rate_jump(model, q, pt, P)
        F = stance_impulse(model, q, pt, P)
        dv_com = model.J_com(q) @ dq
        np.testing.assert_allclose(M * dv_com, P + F, rtol=0, atol=1e-10)
        hip = model.link_points(q)[4 * pt.index + 2:4 * pt.index + 4]
        d_sigma = model.D(q)[-1] @ dq
        assert d_sigma == pytest.approx(hip[0] * P[1] - hip[1] * P[0], abs=1e-10)


def test_zero_push_always_recovers(walker3, realized):
    """Every strategy, pushes of 0 N s at the start, mid-step and just before the impact: the
    walker stays on its orbit (zeta^- to the integration tolerance)."""
    for label, r in realized.items():
        run = _runner(walker3, r, steps=3)
        for s in (0.0, 0.5, 1.0):
            res = run.run(Trial(0.0, s))
            assert res.outcome == "recovered", (label, s, res.reason)
            assert res.relative_error < 1e-8, (label, s, res.relative_error)
            assert res.push is None


def test_a_push_at_a_breakpoints_phase_is_applied(walker3, realized):
    """A push at exactly s = min_impact_s (where the guard is armed, 0.75) meets the
    breakpoint at the same alpha: both must take effect (once, the bug: one located first
    hid the other, the push was lost or the guard never armed and the step ended in a false
    early strike). The outcome is continuous in the phase: at 0.75 it equals the outcomes at
    0.75 -+ 1e-4, and the post-push error lies between theirs."""
    for label in ("none", "constant:-20"):
        run = _runner(walker3, realized[label], steps=3)
        res = {s: run.run(Trial(-2.0, s)) for s in (0.7499, 0.75, 0.7501)}
        assert all(r.pushed for r in res.values()), (label, {s: r.reason for s, r in
                                                             res.items()})
        assert {r.outcome for r in res.values()} == {"recovered"}, label
        lo, mid, hi = (res[s].relative_error for s in (0.7499, 0.75, 0.7501))
        assert min(lo, hi) - 1e-6 <= mid <= max(lo, hi) + 1e-6, (label, lo, mid, hi)


def test_push_outcomes_and_the_controllers_advantage(walker3, realized):
    """A backward push early in the step pulls the stance foot up (its impulsive reaction is
    not pressing: lifted, SPEC 12); a small forward push recovers; a larger one leaves the
    uncontrolled walker 7 % off its orbit after 4 steps (unsettled, converging), and 6 steps
    later the error has contracted by exactly delta_zero^2 per step (the reduced map, once the
    outputs have settled); the controller is back after one step (deadbeat)."""
    none, ctl = _runner(walker3, realized["none"], 4), _runner(walker3, realized["control"], 4)
    res = none.run(Trial(-4.0, 0.1))
    assert res.outcome == "lifted" and res.step == 1 and res.push["reaction"][1] <= 0
    res = none.run(Trial(2.0, 0.1))
    assert res.outcome == "recovered" and res.pushed and res.push["ratio"] < MU
    a, b = none.run(Trial(4.0, 0.1)), ctl.run(Trial(4.0, 0.1))
    assert a.outcome == "unsettled" and a.converging and a.relative_error > 0.05, a.reason
    assert b.outcome == "recovered" and b.relative_error < 1e-8, b.reason
    c = _runner(walker3, realized["none"], 10).run(Trial(4.0, 0.1))
    assert c.outcome == "recovered"
    assert c.relative_error / a.relative_error == pytest.approx(
        walker3.zd.delta_zero_sq ** 6, rel=1e-4)


def test_a_push_after_an_earlier_scuff_is_never_judged(walker3, realized, dipping):
    """Issue 6: on a gait whose swing foot dips below the ground at s ~ 0.36, a push at
    s = 0.5 whose impulsive reaction would lift the stance foot never happens: the trial
    scuffs first (it was reported lifted). The scuff's phase is where the orbit's swing foot
    (q on Z) first goes scuff_tol below the ground, by Brent; the same push on the bundled
    gait, which lives to feel it, is lifted at the push, judged on the simulated state (its
    reaction equals the orbit's prediction)."""
    zd, model = dipping.zd, dipping.model
    tol = SimConfig().scuff_tol

    def height(s):
        q = zd.maps.q_Z(np.array(zd.alpha_i + s * (zd.alpha_f - zd.alpha_i)))
        return float(model.p_swing(q)[1]) + tol

    grid = np.linspace(0.05, 0.5, 91)
    i = int(np.argmax([height(s) < 0 for s in grid]))
    s_dip = brentq(height, grid[i - 1], grid[i], xtol=1e-14)
    assert 0.3 < s_dip < 0.45
    run = TrialRunner(zd, realize(zd, Strategy("none"), mu=MU), push_point(model), steps=3,
                      mu=MU)
    pred, out, _ = run.push_check(Trial(-4.0, 0.5))
    assert out == "lifted" and pred["reaction"][1] <= 0 and not pred["applied"]
    res = run.run(Trial(-4.0, 0.5))
    assert res.outcome == "scuffed" and res.step == 1, res.reason
    assert res.phase == pytest.approx(s_dip, abs=1e-6), res.reason
    assert f"s = {res.phase:.4g}" in res.reason and f"t = {res.time:.6g} s" in res.reason
    assert not res.pushed and res.push["applied"] is False and res.push["reaction"] is None
    assert res.fields()["push_vertical_impulse"] is None and res.fields()["outcome"] == "scuffed"
    bundled = _runner(walker3, realized["none"], 3)
    ok = bundled.run(Trial(-4.0, 0.5))
    assert ok.outcome == "lifted" and ok.pushed and ok.push["applied"], ok.reason
    assert ok.phase == pytest.approx(0.5, abs=1e-9) and "the push lifts" in ok.reason
    orbit, _, _ = bundled.push_check(Trial(-4.0, 0.5))
    np.testing.assert_allclose(ok.push["reaction"], orbit["reaction"], rtol=1e-6)


@pytest.mark.slow
def test_a_trial_that_leaves_the_cone_and_then_lifts_is_reported_at_the_exit(walker5):
    """Issue 6: the user's knee walker under constant -20 N, started with sigma_N^+ 50 %
    high: its stance force leaves the friction cone and later its vertical force becomes
    negative (the run stops there: that later event was the outcome, lifted). Now slipped,
    at the cone exit, which the SciPy reference run from the same start locates too: the
    first |F^h| = mu F^v on its dense stance force, by Brent, before its own stop."""
    zd, model = walker5.zd, walker5.model
    real = realize(zd, Strategy("constant", thrust=-20.0), mu=MU)
    res = TrialRunner(zd, real, push_point(model), steps=3, mu=MU).run(Trial(sigma=0.5))
    assert res.outcome == "slipped" and res.step == 1, res.reason
    N = model.n
    x0 = initial_state(zd, real.thrust, Start(zeta_minus=real.zeta_ref * 1.5 ** 2))
    ref = simulate(zd, real.thrust, SimConfig(steps=1, method="scipy"),
                   Start(q=x0[:N], dq=x0[N:2 * N]))
    assert ref.failure == "fall" and "vertical ground force becomes negative" in ref.reason
    t_stop = float(re.search(r"at t = ([-+.e\d]+) s", ref.reason).group(1))

    def margin(t):
        F = ref.sample(1, np.atleast_1d(t))["F1"]
        return MU * F[:, 1] - np.abs(F[:, 0])

    grid = np.linspace(0.0, t_stop, 801)
    m = margin(grid)
    i = int(np.argmax(m < 0))
    assert i > 0 and grid[i] < t_stop
    t_exit = brentq(lambda t: float(margin(t)[0]), grid[i - 1], grid[i], xtol=1e-13)
    assert res.time == pytest.approx(t_exit, abs=1e-7), res.reason
    assert res.time < t_stop - 1e-3
    assert f"t = {res.time:.6g} s" in res.reason


def test_basin_slice_agrees_with_the_reduced_basin_along_sigma(walker3, realized):
    """Started on Z (zero output rate) with sigma_N^+ scaled by 1 + e, the full-order walker
    converges exactly where the reduced walker's basin says (zeta^- = (1 + e)^2 zeta*), except
    within the recovery test's tolerance of an end (15 steps: every start inside is back or
    converging)."""
    for label in ("none", "constant:-20"):
        r = realized[label]
        run = _runner(walker3, r, steps=15, recovery_tol=0.05)
        zs, b = r.zeta_ref, r.basin
        lo, hi = b.lower.value, b.upper.value
        es = np.sort(np.concatenate([np.sqrt(np.array([lo, hi]) / zs) - 1.0 + d
                                     for d in (-0.05, -0.01, 0.01, 0.05)]))
        for e in np.concatenate([es, [-0.5, 0.0, 0.3]]):
            x = zs * (1 + e) ** 2
            if min(abs(x - lo), abs(x - hi)) <= 0.05 * zs:
                continue  # within the recovery tolerance of an end
            res = run.run(Trial(sigma=float(e)))
            assert res.converging == b.contains(x), (label, e, x, lo, hi, res.reason)


# ------------------------------------------------------------------------- uncertainty
def test_reduced_samples_of_the_nominal_robot_walk_its_orbit(walker3, realized):
    """A sample that is the nominal robot: every fixed strategy walks its own orbit (the limit
    cycle's speed), the controller settles at once on its reference."""
    zd = walker3.zd
    res = fixed_sample(zd, Strategy("constant", thrust=-20.0), mu=MU)
    lc = limit_cycles(zd, Schedule.constant(zd, np.array([[-20.0, 0.0]])))[0]
    assert res.success and res.speed == pytest.approx(lc.speed, rel=1e-12)
    r = realized["control"]
    res = controlled_sample(zd, r.planner, r.zeta_ref, (0.0, 0.5, 1.0), r.driven, mu=MU)
    assert res.success and res.steps == 1, res.reason
    assert res.zeta_star == pytest.approx(r.zeta_ref, rel=1e-9)


def _uncertainty_file(tmp_path, seed=7):
    p = tmp_path / f"unc{seed}.yaml"
    p.write_text(f"seed: {seed}\nparameters:\n"
                 "  MT: {distribution: normal, mean: 10.0, std: 1.0, unit: kg}\n"
                 "  MH: {distribution: uniform, low: 14.0, high: 16.0}\n")
    return p


def test_monte_carlo_draws_are_reproducible_from_the_seed(walker3, tmp_path):
    kw = dict(push_impulse=[0.0], push_phase=[0.5], strategy=["none"], basin_grid=0,
              samples=5)
    a = plan_robustness(walker3, uncertainty=_uncertainty_file(tmp_path), **kw)
    b = plan_robustness(walker3, uncertainty=_uncertainty_file(tmp_path), **kw)
    c = plan_robustness(walker3, uncertainty=_uncertainty_file(tmp_path, seed=8), **kw)
    rng = np.random.default_rng(7)  # numpy's generator directly: parameters in file order
    mt, mh = rng.normal(10.0, 1.0, 5), rng.uniform(14.0, 16.0, 5)
    np.testing.assert_array_equal(a.draws["robot.MT"], mt)
    np.testing.assert_array_equal(a.draws["robot.MH"], mh)
    assert a.draws == b.draws and a.identity == b.identity
    assert a.draws["robot.MT"] != c.draws["robot.MT"] and a.identity != c.identity
    samples = [dict(t.values) for t, k in zip(a.tasks, a.kinds) if k == "sample"]
    assert [s["robot.MT"] for s in samples] == list(mt)


# --------------------------------------------------------------------------- the maps
def test_the_documented_uncertainty_example_plans_on_the_bundled_robot(walker3):
    """docs/examples/torso_mass.yaml (the example of docs/commands.md) names parameters of
    the bundled 3-link robot; its draws follow its seed."""
    path = Path(__file__).resolve().parents[1] / "docs" / "examples" / "torso_mass.yaml"
    plan = plan_robustness(walker3, push_impulse=[0.0], push_phase=[0.5], strategy=["none"],
                           steps=2, basin_grid=0, uncertainty=path, samples=3)
    rng = np.random.default_rng(7)
    np.testing.assert_array_equal(plan.draws["robot.MT"], rng.normal(10.0, 1.0, 3))
    np.testing.assert_array_equal(plan.draws["robot.MH"], rng.uniform(13.5, 16.5, 3))


def test_survivable_push_from_a_grid():
    imp = [-6.0, -4.0, -2.0, 0.0, 2.0, 4.0, 6.0]
    row = ["fell", "recovered", "recovered", "recovered", "recovered", "slipped", "recovered"]
    assert survivable(imp, row, 1.0) == (2.0, "failed")  # 6 recovers, 4 does not: 2
    assert survivable(imp, row, -1.0) == (4.0, "failed")
    assert survivable(imp, ["recovered"] * 7, 1.0) == (6.0, "grid edge")
    assert survivable(imp, row[:4] + ["error", "recovered", "recovered"], 1.0) == (0.0, "error")
    assert survivable(imp, row[:5] + [None, "recovered"], 1.0) == (2.0, "not run")
    assert survivable([0.0, 2.0], ["recovered"] * 2, -1.0) == (None, "none")
    assert summary_impulse([2.0, 4.0], [4.0, None]) == pytest.approx((3.0 + 4.0) / 2)


def test_single_outcome_of_a_direction():
    imp = [-4.0, -2.0, 0.0, 2.0, 4.0] * 2  # two phases
    row = ["lifted", "slipped", "recovered", "lifted", "lifted"] * 2
    assert single_outcome(imp, row, 1.0) == ("lifted", 4)
    assert single_outcome(imp, row, -1.0) == (None, 4)
    assert single_outcome(imp, row[:4] + [None] + row[5:], 1.0) == ("lifted", 3)
    # one size says nothing about the others
    assert single_outcome([0.0, 2.0, 0.0, 2.0], ["recovered", "lifted"] * 2, 1.0) == (None, 2)


# ---------------------------------------------------------------- the study and command
@pytest.mark.slow
def test_a_map_where_every_forward_push_lifts_says_so(cli, walker5, tmp_path, monkeypatch):
    """Issue 8: on the user's knee walker every forward push at the default point (the end of
    the stance shin: the stance knee, not the hip)
    lifts the stance foot, whatever its size and the strategy (its impulsive reaction's
    vertical part, linear in the impulse, is negative at every phase: checked here from the
    reaction of a unit push); the command, run from another folder, says so in the warnings
    (console and robustness.json, naming the outcome and the push duration's option) and in
    the summary."""
    model, zd = walker5.model, walker5.zd
    phases = [0.2, 0.5, 0.8]
    for s in phases:
        q = zd.maps.q_Z(np.array(zd.alpha_i + s * (zd.alpha_f - zd.alpha_i)))
        assert stance_impulse(model, q, push_point(model), np.array([1.0, 0.0]))[1] < 0
    monkeypatch.chdir(tmp_path)
    gait = os.path.relpath(DATA / "walker5_walk.yaml", tmp_path)
    res = cli("robustness", DATA / "walker5.yaml", gait, "--push-impulse", "-2,0,2,4,6",
              "--push-phase", "0.2,0.5,0.8", "--strategy", "none,control", "--steps", "2",
              "--basin-grid", "0", "--workers", "1", "--formats", "csv", "--out", "rob")
    assert res.exit_code == 0, res.output
    assert ("warning: every forward push (3 sizes x 3 phases) of every strategy is `lifted`"
            in res.stderr), res.stderr
    assert "--push-duration" in res.stderr and "--push-link" in res.stderr
    doc = json.loads((tmp_path / "rob" / "robustness.json").read_text())
    for s in doc["strategies"]:
        assert s["push"]["single_outcome"] == {"forward": "lifted", "backward": None}
        assert s["push"]["mean_forward"] == 0.0
    notes = [w for w in doc["warnings"] if "every forward push" in w]
    assert len(notes) == 1 and "`lifted`" in notes[0] and "`push_duration`" in notes[0]
    assert "every forward push of every strategy is lifted" in doc["reason"]
    assert "`push_duration`" in doc["reason"]


@pytest.mark.slow
def test_no_single_outcome_warning_on_the_readme_map_or_with_a_push_duration(walker3,
                                                                            walker5):
    """The bundled 3-link map (README options, a small grid) mixes outcomes in each direction:
    no warning. On the knee walker a push spread over 0.05 s is checked with the stance
    force over that time, so the forward map is no longer one outcome."""
    kw = dict(push_impulse=[-6.0, -4.0, -2.0, 0.0, 2.0, 4.0, 6.0], push_phase=[0.2, 0.5, 0.8],
              strategy=["none", "control"], steps=3, basin_grid=0, workers=1)
    res = robustness(walker3, **kw)
    assert not any("every forward" in w or "every backward" in w for w in res.warnings())
    assert "every " not in res.reason.split("survivable")[1]
    for k in range(2):
        assert res.strategy_summary(k)["push"]["single_outcome"] == {"forward": None,
                                                                    "backward": None}
    res = robustness(walker5, push_impulse=[2.0, 4.0, 6.0], push_phase=[0.2, 0.5, 0.8],
                     strategy=["none"], steps=2, basin_grid=0, workers=1, push_duration=0.05)
    assert res.strategy_summary(0)["push"]["single_outcome"]["forward"] is None
    assert not any("every forward" in w for w in res.warnings())
@pytest.mark.slow
def test_command_writes_every_output_and_resumes(tmp_path, cli, walker3):
    out = tmp_path / "rob"
    unc = _uncertainty_file(tmp_path)
    args = ("robustness", "three_link", "three_link_walk", "--push-impulse", "-4,0,4,12",
            "--push-phase", "0.1,0.6,1", "--strategy", "none,constant:-20,control", "--steps",
            "4", "--basin-grid", "3", "--uncertainty", str(unc), "--samples", "2",
            "--workers", "1", "--out", str(out))
    res = cli(*args, "-q")
    assert res.exit_code == 0, res.output
    names = {p.name for p in out.iterdir()}
    for f in ("robustness.json", "trials.csv", "uncertainty.csv", "push_map.png",
              "push_map.pdf", "survivable_push.png", "survivable_push.pdf", "basin.png",
              "basin.pdf", "uncertainty.png", "uncertainty.pdf", "trials"):
        assert f in names, f
    text = (out / "robustness.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text)
    for key in ("schema_version", "units", "success", "reason", "warnings", "provenance",
                "settings", "strategies", "definitions"):
        assert key in doc, key
    assert doc["units"]["impulse"] == "N s" and doc["units"]["zeta"] == "kg^2 m^4/s^2"
    assert doc["success"] and doc["counts"]["trials"] == 3 * (12 + 9)
    assert doc["counts"]["samples"] == 6
    assert len(list((out / "trials").glob("*.json"))) == 3 * 21 + 6
    import pandas as pd

    df = pd.read_csv(out / "trials.csv")
    assert len(df) == 63 and "push_impulse_Ns" in df.columns and "speed_m_s" in df.columns
    zero = df[(df.kind == "push") & (df.push_impulse_Ns == 0)]
    assert set(zero.outcome) == {"recovered"}
    # the document's map is the trials' outcomes; the study in Python gives the same numbers
    ctl = next(s for s in doc["strategies"] if s["label"] == "control")
    assert ctl["orbit"]["zeta_star"] == pytest.approx(limit_cycles(
        walker3.zd, Schedule.constant(walker3.zd, np.zeros((1, 2))))[0].zeta_star)
    # the same command again: every trial kept, none computed, the same document (its
    # figures, drawn above and checked there, are not drawn again)
    res = cli(*args, "--formats", "csv", "-q")
    assert res.exit_code == 0, res.output
    again = json.loads((out / "robustness.json").read_text())
    assert again["counts"]["skipped"] == 69 and again["counts"]["computed"] == 0
    assert again["strategies"] == doc["strategies"]
    # another set of trials is refused in this folder, nothing replaced
    res = cli("robustness", "--push-impulse", "0", "--push-phase", "0.5", "--out", str(out),
              "-q")
    assert res.exit_code == 2 and "holds another sweep" in res.output


@pytest.mark.slow
def test_a_trial_is_the_same_in_process_and_on_2_local_workers(walker3):
    kw = dict(push_impulse=[-4.0, 4.0, 12.0], push_phase=[0.1, 0.6], strategy=["none",
                                                                               "control"],
              steps=3, basin_grid=0)
    a = robustness(walker3, workers=1, **kw)
    b = robustness(walker3, workers=2, **kw)
    strip = [{k: v for k, v in r.items() if k != "seconds"} for r in a.records]
    assert strip == [{k: v for k, v in r.items() if k != "seconds"} for r in b.records]
    assert b.executor["kind"] == "local" and a.executor["kind"] == "in-process"


def _strip(res) -> list[dict | None]:
    """The records of a result without their wall time (the one field that differs by run)."""
    return [None if r is None else {k: v for k, v in r.items() if k != "seconds"}
            for r in res.records]


def _outputs(res, folder: Path) -> tuple[str, dict[str, bytes]]:
    """robustness.json's document (without what differs by run: wall time, executor, what this
    run computed) as canonical JSON, and the bytes of the CSV files as the command writes
    them."""
    from thrustwalk_cli.files import output

    doc = res.document()
    for key in ("wall_time", "executor", "counts"):
        doc.pop(key)
    folder.mkdir(parents=True, exist_ok=True)
    csv = {}
    for name, t in res.tables().items():
        csv[name] = output.write_csv(folder / f"{name}.csv", t.header, t.rows).read_bytes()
    return json.dumps(output.jsonable(doc), sort_keys=True), csv


@pytest.fixture(scope="module")
def mixed_plan(walker3, tmp_path_factory):
    """Push trials, basin trials and samples of three strategies (36 trials, 6 samples;
    every outcome of a trial: recovered, lifted, slipped, scuffed, stopped, unsettled)."""
    unc = _uncertainty_file(tmp_path_factory.mktemp("unc"))
    return plan_robustness(walker3, push_impulse=[-4.0, 0.0, 4.0, 12.0],
                           push_phase=[0.6, 1.0], strategy=["none", "constant:-20",
                                                            "control"],
                           steps=3, basin_grid=2, uncertainty=unc, samples=2)


@pytest.fixture(scope="module")
def one_per_task(mixed_plan):
    """The plan run the way it ran before chunks: one trial per engine task."""
    return run_robustness(mixed_plan, workers=1, chunk=1)


@pytest.mark.slow
def test_trials_in_chunks_equal_one_trial_per_task(mixed_plan, one_per_task, tmp_path, counting):
    """The trials run in chunks (the automatic size in this process and on 2 local workers,
    and 5 per task: chunks that straddle phases and strategies) give every trial the record
    of the run with one trial per task, and bit-for-bit the same robustness.json and CSV
    files; the samples run one per task."""
    plan = mixed_plan
    n_trials = sum(kd != "sample" for kd in plan.kinds)
    ref = _outputs(one_per_task, tmp_path / "ref")
    from thrustwalk_cli.sweep.executors import InProcess

    ex = counting(InProcess())
    runs = {"auto-1": run_robustness(plan, executor=ex), "auto-2":
            run_robustness(plan, workers=2), "5-1": run_robustness(plan, workers=1, chunk=5)}
    # 36 trials on 1 worker: ceil(36 / 8) = 5 per task -> 8 tasks; 6 samples one each
    assert ex.submitted == 8 + 6
    assert runs["auto-2"].executor["kind"] == "local"
    for name, res in runs.items():
        assert res.counts.ok + res.counts.failed == n_trials + 6, name
        assert _strip(res) == _strip(one_per_task), name
        assert _outputs(res, tmp_path / name) == ref, name


@pytest.mark.slow
def test_a_trial_that_raises_keeps_the_other_trials_of_its_chunk(mixed_plan, one_per_task,
                                                                  monkeypatch):
    """A push trial whose computation raises inside a chunk is recorded as an error with its
    reason, as it is with one trial per task; every other trial of the chunk keeps its own
    record (equal to the run without the failure)."""
    from dataclasses import replace

    from thrustwalk_cli.studies import sweep_studies

    study = sweep_studies.STUDIES["push-trial"]

    def point(walker, p, start):
        if p["push_impulse"] == 4.0 and p["push_phase"] == 0.6:
            raise FloatingPointError("injected")
        return study.point(walker, p, start)

    monkeypatch.setitem(sweep_studies.STUDIES, "push-trial", replace(study, point=point))
    plan = mixed_plan
    single = run_robustness(plan, workers=1, chunk=1)
    chunked = run_robustness(plan, workers=1, chunk=8)
    assert _strip(chunked) == _strip(single)
    bad = [i for i, t in enumerate(plan.tasks) if dict(t.values).get("push_impulse") == 4.0
           and dict(t.values).get("push_phase") == 0.6]
    assert len(bad) == 3
    for i, (a, b) in enumerate(zip(_strip(chunked), _strip(one_per_task))):
        if i in bad:
            assert a["status"] == "failed" and "FloatingPointError: injected" in a["reason"]
            assert chunked._outcome(a) == "error"
        else:
            assert a == b, i
    assert chunked.errors == 3 and "3 trial(s) could not be computed" in chunked.reason


@pytest.mark.slow
def test_a_stopped_chunked_run_resumes_to_the_same_result(mixed_plan, one_per_task,
                                                          tmp_path):
    """A run stopped after some records (the caller stops mid-chunk) resumes with the records
    it has: none is computed again, the others are, and the result equals the run with one
    trial per task."""
    class Stop(Exception):
        pass

    plan = mixed_plan
    kept: dict[str, dict] = {}

    def on_record(rec):
        kept[rec["key"]] = rec
        if len(kept) == 20:
            raise Stop

    with pytest.raises(Stop):
        run_robustness(plan, workers=2, on_record=on_record)
    assert len(kept) == 20
    computed: list[str] = []
    res = run_robustness(plan, workers=2, finished=dict(kept),
                         on_record=lambda r: computed.append(r["key"]))
    assert res.counts.skipped == 20 and not set(computed) & set(kept)
    assert sorted(computed + list(kept)) == sorted(t.key for t in plan.tasks)
    assert _strip(res) == _strip(one_per_task)
    assert _outputs(res, tmp_path / "resumed") == _outputs(one_per_task, tmp_path / "ref")


@pytest.mark.slow
def test_a_robustness_run_killed_mid_run_resumes_exactly(tmp_path, cli):
    """SIGKILL of the command (2 local worker processes, trials in chunks) once some trials
    are recorded; the same command again runs only the trials without a record and writes
    the same robustness.json (but for what differs by run: provenance's command line and
    time, counts, executor, wall time), trials.csv and trial records as an uninterrupted run
    in this process. The killed run is a process of its own; the same command again runs in
    this process (what it reads is the folder). 3 steps a trial: a trial's length is not what
    is checked, and 126 trials in 16 chunks leave most of them to do at the kill."""
    import signal
    import subprocess
    import sys
    import time

    args = ["robustness", "three_link", "three_link_walk", "--push-impulse", "0,2",
            "--push-phase", "0:1:0.05", "--strategy", "none,constant:-20,control", "--steps",
            "3", "--basin-grid", "0", "--formats", "csv", "-q"]
    ref = tmp_path / "ref"
    assert cli(*args, "--workers", "1", "--out", ref).exit_code == 0
    out = tmp_path / "o"
    cmd = [sys.executable, "-m", "thrustwalk_cli", *args, "--workers", "2", "--out", str(out)]
    proc = subprocess.Popen(cmd, stderr=subprocess.DEVNULL)
    try:
        t0 = time.monotonic()
        while not any((out / "trials").glob("*.json")) if (out / "trials").is_dir() \
                else True:
            assert proc.poll() is None and time.monotonic() - t0 < 120, "no trial recorded"
            time.sleep(0.01)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    done = len(list((out / "trials").glob("*.json")))
    total = 2 * 21 * 3
    if done == total:  # pragma: no cover - the run outran the kill
        pytest.skip("every trial had finished before the kill")
    assert not (out / "robustness.json").exists()
    res = cli(*args, "--workers", "2", "--out", out)
    assert res.exit_code == 0, res.output
    a, b = (json.loads((d / "robustness.json").read_text()) for d in (out, ref))
    assert a["counts"]["skipped"] == done and a["counts"]["computed"] == total - done
    for doc in (a, b):
        for key in ("wall_time", "executor", "counts", "provenance"):
            doc.pop(key)
    assert a == b
    assert (out / "trials.csv").read_bytes() == (ref / "trials.csv").read_bytes()

    def records(folder):
        recs = [json.loads(p.read_text()) for p in sorted((folder / "trials").glob("*.json"))]
        return [{k: v for k, v in r.items() if k != "seconds"} for r in recs]

    assert records(out) == records(ref) and len(records(out)) == total


@pytest.mark.slow
def test_a_trial_is_the_same_on_a_dask_cluster(walker3, tmp_path):
    """A scheduler and a worker as separate processes on 127.0.0.1 (bounded in time, stopped
    here), the trials in chunks (20 trials on 1 worker: 3 per task): every trial's record
    equals the local one, run one trial per task."""
    pytest.importorskip("distributed")
    from test_sweep_cluster import Cluster

    plan = plan_robustness(walker3, push_impulse=[-4.0, 0.0, 4.0, 12.0], push_phase=[0.1, 0.8],
                           strategy=["none", "control"], steps=3, basin_grid=2,
                           basin_rate=0.0)
    local = run_robustness(plan, workers=1, chunk=1)  # one trial per task
    cluster = Cluster(tmp_path, workers=1)
    try:
        remote = run_robustness(plan, scheduler=cluster.address)
    finally:
        cluster.stop()
    assert remote.executor["kind"] == "dask" and remote.executor["workers"] == 1

    def strip(res):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in res.records]

    assert strip(remote) == strip(local), cluster.logs()


@pytest.mark.parametrize("args, message", [
    (["--strategy", "foo"], "option --strategy: unknown strategy 'foo'"),
    (["--strategy", "constant:fast"], "option --strategy: constant:F needs a thrust"),
    (["--strategy", "none,none"], "option --strategy: strategy none is given twice"),
    (["--strategy", "constant:-500"], "option --strategy: constant:-500: -500 N is outside"),
    (["--strategy", "schedule:gaits/three_link_walk.yaml"], "option --strategy:"),
    (["--push-phase", "0.5,1.5"], "option --push-phase: phases are fractions"),
    (["--push-impulse", "a:b"], "option --push-impulse:"),
    (["--push-direction", "0,0"], "option --push-direction: a direction is two numbers"),
    (["--push-direction", "1"], "option --push-direction:"),
    (["--push-link", "tail"], "option --push-link: unknown link 'tail'"),
    (["--push-at", "2"], "option --push-at: must lie in [0, 1]"),
    (["--steps", "0"], "option --steps:"),
    (["--recovery-tol", "1.5"], "option --recovery-tol:"),
    (["--basin-sigma", "1:-1"], "option --basin-sigma:"),
    (["--basin-grid", "1"], "option --basin-grid:"),
    (["--basin-joint", "q9"], "option --basin-joint: unknown actuated coordinate 'q9'"),
    (["--strategy", "control", "--thruster", "nozzle"],
     "option --thruster: control: unknown thruster 'nozzle'"),
    (["--strategy", "control", "--knots", "0,0.6,0.4,1"], "option --knots:"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "options --workers/--scheduler"),
    (["--uncertainty", "missing.yaml"], "missing.yaml: file not found"),
    (["--samples", "0", "--uncertainty", "UNC"], "option --samples:"),
])
def test_bad_options_are_one_line_exit_two(tmp_path, cli, args, message):
    unc = tmp_path / "unc.yaml"
    unc.write_text("parameters:\n  MT: {distribution: normal, mean: 10, std: 1}\n")
    args = [str(unc) if a == "UNC" else a for a in args]
    out = tmp_path / "bad"
    res = cli("robustness", "--push-impulse", "0", "--push-phase", "0.5", "--basin-grid", "0",
              "--strategy", "none", *args, "--out", str(out), "-q")
    assert res.exit_code == 2, res.output
    assert message in res.output, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in res.output
    assert not out.exists()


def test_uncertainty_file_problems_name_file_line_and_key(tmp_path, cli):
    unc = tmp_path / "unc.yaml"
    unc.write_text("seed: 1\nparameters:\n  MT: {distribution: normal, mean: 10, std: 1}\n"
                   "  MX: {distribution: uniform, low: 1, high: 2}\n")
    out = tmp_path / "bad"
    res = cli("robustness", "--push-impulse", "0", "--push-phase", "0.5", "--basin-grid", "0",
              "--strategy", "none", "--uncertainty", str(unc), "--out", str(out), "-q")
    assert res.exit_code == 2, res.output
    assert f"{unc}:4: parameters.MX: no parameter 'MX' in robot three_link" in res.output
    assert not out.exists()
