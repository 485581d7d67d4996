"""Center-manifold shaping with piecewise thrust (SPEC 4, 10; issue 4).

Every closed-form result of ``thrustwalk_cli.hzd.shaping`` (spectral b_F / Gamma_j, the true shift
``sum b_F T_j / (1 - delta_zero^2)``, solved knots and thrust values) is checked against an
independent computation: time integration of the 2-D hybrid zero dynamics
``alpha' = kappa_1 sigma, sigma' = kappa_2 + u_j`` interval by interval (solve_ivp with
terminal events at the knots, then the impact ``sigma^+ = delta_zero sigma^-``), adaptive
``scipy.integrate.quad`` of the integrands evaluated directly on the model (``zd.terms``),
and ``numpy.linalg.lstsq``. Tolerances are stated in every assertion.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from thrustwalk_cli.errors import InputError
from thrustwalk_cli.hzd import shaping as S
from thrustwalk_cli.hzd.zero_dynamics import (
    fixed_point_shift,
    limit_cycles,
    paper_one_step_shift,
)
from thrustwalk_cli.studies.shape import pattern_values
from thrustwalk_cli.thrust import schedule as SC
from thrustwalk_cli.thrust.schedule import Schedule, WrittenSchedule

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ independent helpers
def term(zd, alpha: float, key: str):
    return zd.terms(np.array([alpha]))[key][0]


def quad_integral(zd, f, a: float, b: float) -> float:
    """int_a^b f(terms(alpha)) dalpha by adaptive Gauss-Kronrod (not the spectral series)."""
    val, _ = quad(lambda x: float(f(zd.terms(np.array([x])))[0]), a, b, epsabs=1e-13,
                  epsrel=1e-13, limit=200)
    return val


def bF_quad(zd, a, b):
    return quad_integral(zd, lambda t: 1.0 / t["kappa1"], a, b)


def gamma_quad(zd, a, b, thruster):
    return quad_integral(zd, lambda t: t["beta"][:, thruster] / t["kappa1"], a, b)


def sigma_sign(zd) -> float:
    """sigma_N has the sign that makes alpha' = kappa_1 sigma_N move alpha along the step."""
    return float(np.sign(zd.alpha_f - zd.alpha_i) * np.sign(term(zd, zd.alpha_i, "kappa1")))


def integrate_piecewise(zd, sigma_plus: float, knots, T=None, F=None):
    """One step of the piecewise zero dynamics by time integration, interval by interval.

    ``T[j]`` generalised force [N m] or ``F[j]`` thrust vector [N] on interval j; returns
    (sigma^- at alpha_f, step time [s]).
    """
    sigma, t_total = sigma_plus, 0.0
    for j in range(len(knots) - 1):
        a0, a1 = float(knots[j]), float(knots[j + 1])

        def rhs(t, x, j=j):
            tm = zd.terms(np.array([x[0]]))
            u = T[j] if T is not None else tm["beta"][0] @ F[j]
            return [tm["kappa1"][0] * x[1], tm["kappa2"][0] + u]

        def reach(t, x, a1=a1):
            return x[0] - a1

        reach.terminal = True
        reach.direction = np.sign(a1 - a0)
        sol = solve_ivp(rhs, (0.0, 20.0), [a0, sigma], method="DOP853", rtol=1e-12,
                        atol=1e-12, events=reach)
        assert sol.status == 1, f"interval {j} not completed: {sol.message}"
        sigma = sol.y_events[0][0][1]
        t_total += sol.t_events[0][0]
    return sigma, t_total


def poincare_int(zd, zeta_minus: float, knots, T=None, F=None) -> float:
    """rho(zeta^-): impact sigma^+ = delta_zero sigma^-, then integrate one step."""
    s_minus = sigma_sign(zd) * np.sqrt(2.0 * zeta_minus)
    s_next, _ = integrate_piecewise(zd, zd.delta_zero * s_minus, knots, T, F)
    return 0.5 * s_next**2


def aitken(z0: float, z1: float, z2: float) -> float:
    """Fixed point of an affine iteration from three iterates (exact for affine maps)."""
    return z2 - (z2 - z1) ** 2 / ((z2 - z1) - (z1 - z0))


def fractions_knots(zd, fr):
    return SC.knots_alpha(zd, np.asarray(fr, float))


# ------------------------------------------------------------------------- b_F, Gamma_j
def test_interval_integrals_match_quadrature(walk3):
    """b_F and Gamma_j per interval equal adaptive quadrature of 1/kappa_1, beta/kappa_1."""
    model, _, zd = walk3
    kn = fractions_knots(zd, [0, 0.17, 0.5, 0.81, 1])
    iv = S.intervals(zd, kn)
    for j in range(len(kn) - 1):
        ref = bF_quad(zd, kn[j], kn[j + 1])
        assert iv.b_F[j] == pytest.approx(ref, rel=1e-10), f"b_F interval {j + 1}"
        for m in range(model.n_thrusters):
            refG = gamma_quad(zd, kn[j], kn[j + 1], m)
            assert iv.Gamma[j, m] == pytest.approx(refG, rel=1e-10), f"Gamma {j + 1}, {m}"
    np.testing.assert_allclose(iv.fractions, [0, 0.17, 0.5, 0.81, 1], atol=1e-15)


def test_shift_formulas_two_ways(walk3):
    """Interval-integral shifts equal the V_Z-based ones of zero_dynamics (two computations);
    the true shift is the one-step value divided by 1 - delta_zero^2."""
    model, _, zd = walk3
    kn = fractions_knots(zd, [0, 0.25, 0.6, 1])
    rng = np.random.default_rng(4)
    sched = Schedule.piecewise(kn, rng.normal(0, 20, (3, 3)), "generalized", zd.model.n_thrusters)
    F = np.zeros((3, 3, model.n_thrusters))
    F[:] = rng.normal(0, 10, F.shape)
    sched = Schedule(kn, F, sched.generalized)
    np.testing.assert_allclose(S.one_step_change(zd, sched), paper_one_step_shift(zd, sched),
                               rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(S.true_shift(zd, sched), fixed_point_shift(zd, sched),
                               rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(S.true_shift(zd, sched) * (1 - zd.delta_zero_sq),
                               S.one_step_change(zd, sched), rtol=1e-14)


# ----------------------------------------------------------------- fixed point vs iteration
@pytest.mark.slow
def test_shaped_fixed_point_equals_iterated_poincare_map(walk3):
    """zeta*_0 + sum b_F T_j / (1 - delta_zero^2) is the fixed point of the time-integrated
    piecewise Poincare map, and the paper's one-step value is not (SPEC 4 erratum)."""
    _, _, zd = walk3
    kn = fractions_knots(zd, [0, 0.3, 0.7, 1])
    T = np.array([-30.0, 10.0, 25.0])
    sched = Schedule.piecewise(kn, T[None, :], "generalized", zd.model.n_thrusters)
    z0_pred = S.nominal_zeta_star(zd)
    shift = float(S.true_shift(zd, sched)[0])
    one_step = float(S.one_step_change(zd, sched)[0])
    predicted = z0_pred + shift
    lc = limit_cycles(zd, sched)[0]
    assert lc.exists, lc.reason
    assert lc.zeta_star == pytest.approx(predicted, rel=1e-12)
    # iterate the integrated map from the NOMINAL fixed point
    zs = [z0_pred]
    for _ in range(12):
        zs.append(poincare_int(zd, zs[-1], kn, T=T))
    errs = np.abs(np.array(zs) - predicted)
    assert np.all(np.diff(errs) < 0), f"iterates do not approach zeta*: {errs}"
    rate = zd.delta_zero_sq + 0.02
    assert errs[-1] < rate**12 * errs[0], errs  # contraction at the rate delta_zero^2
    fixed = aitken(*zs[-3:])
    assert fixed == pytest.approx(predicted, rel=1e-8)
    # the paper's value zeta_0* + sum b_F T_j misses the fixed point by a lot
    assert abs(fixed - (z0_pred + one_step)) > 1e4 * 1e-8 * fixed
    assert abs(shift) > 10.0, "choose T so that the shift is significant"
    # the integrated map is exactly rho with zeta^+ = delta_zero^2 zeta^-
    z = 1.3 * predicted
    assert poincare_int(zd, z, kn, T=T) == pytest.approx(
        zd.delta_zero_sq * z + float(zd.V_Z(np.array(zd.alpha_f), sched)[0]), rel=1e-9)


def test_force_mode_fixed_point_equals_iterated_map(walk3):
    """Force mode with two thrusters: Gamma_j shift equals the integrated map's fixed point."""
    model, _, zd = walk3
    kn = fractions_knots(zd, [0, 0.45, 1])
    F = np.array([[-15.0, 4.0], [-5.0, -8.0]])
    sched = Schedule(kn, F[None], np.zeros((1, 2)))
    predicted = S.nominal_zeta_star(zd) + float(S.true_shift(zd, sched)[0])
    zs = [S.nominal_zeta_star(zd)]
    for _ in range(4):
        zs.append(poincare_int(zd, zs[-1], kn, F=F))
    assert aitken(*zs[-3:]) == pytest.approx(predicted, rel=1e-8)


# --------------------------------------------------------------------- shape-only knots
def test_paper_example_knots_shape_only(walk3):
    """n = 4, T_j = k (j - 2): solved knots give b_F(a2, a1) = b_F(a4, a3) (quadrature), the
    pre/post-impact states are unchanged to 1e-9 while the orbit between knots differs."""
    _, _, zd = walk3
    ks = [0.0, 10.0, 50.0]
    P = pattern_values(S.DEFAULT_PATTERN, 3, ks)
    np.testing.assert_array_equal(P, [[0, 0, 0], [-10, 0, 10], [-50, 0, 50]])
    sol = S.solve_knots(zd, [0.0, None, None, 1.0], P, "generalized")
    assert sol.success, sol.reason
    a = sol.alpha
    b1, b2, b3 = (bF_quad(zd, a[j], a[j + 1]) for j in range(3))
    assert b1 == pytest.approx(b3, rel=1e-10)
    assert b2 == pytest.approx(b1, rel=1e-10)  # equal spacing in b_F: the closest solution
    assert sol.residual < 1e-12
    sched = Schedule.piecewise(a, P, "generalized", zd.model.n_thrusters)
    nominal = limit_cycles(zd, Schedule.zero(a, zd.model.n_thrusters))[0]
    cycles = limit_cycles(zd, sched)
    for k, lc in zip(ks, cycles):
        assert lc.exists, (k, lc.reason)
        assert abs(lc.zeta_star - nominal.zeta_star) < 1e-9, k
        assert abs(lc.zeta_plus - nominal.zeta_plus) < 1e-9, k
    # independent: one integrated step from the nominal zeta^- returns to it (k = 50)
    z = poincare_int(zd, nominal.zeta_star, a, T=P[2])
    assert z == pytest.approx(nominal.zeta_star, rel=1e-9)
    # ... while the orbit between the knots differs: in interval 1 the change of zeta is
    # -k int_{alpha_1}^{alpha} 1/kappa_1 (quadrature)
    lc50 = cycles[2]
    o, on = lc50.orbit, nominal.orbit
    inside = (o["alpha"] > a[0]) & (o["alpha"] < a[1])
    idx = np.flatnonzero(inside)[::10]
    for i in idx:
        ref = -50.0 * bF_quad(zd, a[0], o["alpha"][i])
        assert o["zeta"][i] - on["zeta"][i] == pytest.approx(ref, rel=1e-9, abs=1e-9), i
    assert np.max(np.abs(o["alpha_dot"] - on["alpha_dot"])) > 0.2


def test_knot_solver_force_mode_and_partial_knots(walk3):
    """Force mode: Gamma(a2, a1) = Gamma(a4, a3) for hip_x; one given interior knot: the other
    is solved; five knots: three solved; all checked by quadrature."""
    _, _, zd = walk3
    P = pattern_values("k*(j-2)", 3, [20.0])
    sol = S.solve_knots(zd, [0.0, None, None, 1.0], P, "force", 0)
    assert sol.success, sol.reason
    g = [gamma_quad(zd, sol.alpha[j], sol.alpha[j + 1], 0) for j in range(3)]
    assert g[0] == pytest.approx(g[2], rel=1e-10)
    sol = S.solve_knots(zd, [0.0, 0.2, None, 1.0], P, "generalized")
    assert sol.success, sol.reason
    assert sol.fractions[1] == 0.2
    b = [bF_quad(zd, sol.alpha[j], sol.alpha[j + 1]) for j in range(3)]
    assert b[0] == pytest.approx(b[2], rel=1e-10)
    P5 = pattern_values("k*(j-2)", 4, [10.0])  # T = (-k, 0, k, 2k)
    sol = S.solve_knots(zd, [0.0, None, None, None, 1.0], P5, "generalized")
    assert sol.success, sol.reason
    assert np.all(np.diff(sol.fractions) > 0)
    b = np.array([bF_quad(zd, sol.alpha[j], sol.alpha[j + 1]) for j in range(4)])
    assert abs(P5[0] @ b) < 1e-9 * np.abs(P5[0] * b).sum()


@pytest.mark.parametrize("pattern, free, needle", [
    ("k", [0.0, None, None, 1.0], "1 independent condition"),       # T constant: k B != 0
    ("k*(j-2)+1", [0.0, None, None, 1.0], "2 independent condition"),  # rank 2 over k
    ("k*(j-1)", [0.0, None, None, 1.0], "two knots together"),   # T = (0, k, 2k) >= 0
])
def test_knot_solver_reports_when_no_knots_exist(walk3, pattern, free, needle):
    _, _, zd = walk3
    P = pattern_values(pattern, 3, [0.0, 10.0, 20.0])
    sol = S.solve_knots(zd, free, P, "generalized")
    assert not sol.success
    assert "no shape-only knots exist" in sol.reason and needle in sol.reason, sol.reason
    assert sol.alpha is None and sol.fractions is None


# ------------------------------------------------------------------ solver (a): targets
@pytest.mark.parametrize("mode", ["generalized", "force"])
def test_min_norm_hits_target_and_equals_lstsq(walk3, mode):
    """The minimum-norm values reach zeta* exactly and equal lstsq of the linear fixed-point
    relation built independently by quadrature."""
    model, _, zd = walk3
    kn = fractions_knots(zd, [0, 0.2, 0.55, 0.8, 1])
    target = 1800.0
    sol = S.solve_target_zeta(zd, kn, target, mode, 0 if mode == "force" else None)
    assert sol.success, sol.reason
    assert sol.zeta_star == pytest.approx(target, rel=1e-12)
    m = zd.model.n_thrusters
    lc = limit_cycles(zd, Schedule.piecewise(kn, sol.values[None], mode, m, 0))[0]
    assert lc.zeta_star == pytest.approx(target, rel=1e-12)
    # (1 - delta^2) zeta* = V_0(alpha_f) + a . x with a and V_0 by quadrature
    if mode == "generalized":
        a = np.array([bF_quad(zd, kn[j], kn[j + 1]) for j in range(4)])
    else:
        a = np.array([gamma_quad(zd, kn[j], kn[j + 1], 0) for j in range(4)])
    V0f = quad_integral(zd, lambda t: t["kappa2"] / t["kappa1"], zd.alpha_i, zd.alpha_f)
    rhs = (1 - zd.delta_zero_sq) * target - V0f
    x_ls, *_ = np.linalg.lstsq(a[None, :], np.array([rhs]), rcond=None)
    np.testing.assert_allclose(sol.values, x_ls, rtol=1e-9)
    # any other solution (add a null-space direction) is longer
    null = np.linalg.svd(a[None, :])[2][1]
    assert np.linalg.norm(sol.values + 3.0 * null) > np.linalg.norm(sol.values)


@pytest.mark.slow
def test_target_speed_reached_and_checked_by_integration(walk3):
    """Brent on zeta*: the speed of the solved orbit equals the target; the step time from
    time integration agrees; unreachable speeds fail with a reason."""
    _, _, zd = walk3
    kn = fractions_knots(zd, [0, 1 / 3, 2 / 3, 1])
    sol = S.solve_target_speed(zd, kn, 1.1, "generalized")
    assert sol.success, sol.reason
    assert sol.speed == pytest.approx(1.1, rel=1e-9)
    s_minus = sigma_sign(zd) * np.sqrt(2 * sol.zeta_star)
    _, T_step = integrate_piecewise(zd, zd.delta_zero * s_minus, kn, T=sol.values)
    step_length = float(zd.model.p_swing(zd.maps.q_minus)[0])
    assert step_length / T_step == pytest.approx(1.1, rel=1e-8)
    slow = S.solve_target_speed(zd, kn, 0.01, "generalized")
    assert not slow.success and "below the slowest periodic orbit" in slow.reason
    assert slow.values is None


# ---------------------------------------------------- generalized vs force on a fine grid
def test_force_mode_converges_to_generalized_mode(walk3):
    """F = T_j / beta(alpha_mid) on sub-intervals of a refining grid reproduces the
    generalized-mode fixed point, with second-order (midpoint) convergence."""
    model, _, zd = walk3
    fr = np.array([0.0, 1 / 3, 2 / 3, 1.0])
    kn = fractions_knots(zd, fr)
    T = np.array([20.0, -10.0, 15.0])
    nt = zd.model.n_thrusters
    z_gen = limit_cycles(zd, Schedule.piecewise(kn, T[None], "generalized", nt))[0].zeta_star
    errs = []
    for m in (2, 4, 8, 16, 32):
        fine = np.concatenate([np.linspace(fr[j], fr[j + 1], m + 1)[:-1] for j in range(3)]
                              + [[1.0]])
        kf = fractions_knots(zd, fine)
        mid = 0.5 * (kf[:-1] + kf[1:])
        beta = zd.terms(mid)["beta"][:, 0]
        Tj = np.repeat(T, m)
        z_f = limit_cycles(zd, Schedule.piecewise(kf, (Tj / beta)[None], "force", nt, 0))[0]
        errs.append(abs(z_f.zeta_star - z_gen))
    errs = np.array(errs)
    ratios = errs[:-1] / errs[1:]
    assert np.all(ratios > 3.0), f"errors {errs}, ratios {ratios}"
    assert ratios[-1] == pytest.approx(4.0, abs=0.2), f"not second order: ratios {ratios}"
    assert errs[-1] < 1e-5 * z_gen, errs


# -------------------------------------------------------------------------- vector field
def test_vector_field_matches_flow(walk3):
    """alpha'' of the (alpha, alpha') field equals the time derivative of alpha' along the
    integrated flow (Richardson-extrapolated central difference), away from the knots; in the
    sigma plane the field is (kappa_1 sigma, kappa_2 + u)."""
    _, _, zd = walk3
    kn = fractions_knots(zd, [0, 0.5, 1])
    T = np.array([-40.0, 30.0])
    sched = Schedule.piecewise(kn, T[None], "generalized", zd.model.n_thrusters)
    vf = S.vector_field(zd, sched, "alpha_dot", (0.5, 1.5), n_alpha=6, n_y=3)
    vs = S.vector_field(zd, sched, "sigma", (-40.0, -20.0), n_alpha=6, n_y=3)
    h = 1e-3
    checked = 0
    for ia, a0 in enumerate(vf.alpha):
        if min(abs(a0 - kn[1]), abs(a0 - kn[0]), abs(a0 - kn[-1])) < 1e-2:
            continue
        j = 0 if a0 < kn[1] else 1
        k1 = term(zd, a0, "kappa1")
        for iy, y0 in enumerate(vf.y):
            def rhs(t, x, u=T[j]):
                tm = zd.terms(np.array([x[0]]))
                return [tm["kappa1"][0] * x[1], tm["kappa2"][0] + u]

            def adot(t, x0=(a0, y0 / k1)):
                sol = solve_ivp(rhs, (0, t), list(x0), method="DOP853", rtol=1e-13,
                                atol=1e-13)
                return term(zd, sol.y[0, -1], "kappa1") * sol.y[1, -1]

            fd1 = (adot(h) - adot(-h)) / (2 * h)
            fd2 = (adot(h / 2) - adot(-h / 2)) / h
            fd = (4 * fd2 - fd1) / 3  # Richardson: error O(h^4)
            assert vf.d_y[iy, ia] == pytest.approx(fd, rel=1e-7), (ia, iy)
            assert vf.d_alpha[iy, ia] == y0
            checked += 1
        k2 = term(zd, a0, "kappa2")
        np.testing.assert_allclose(vs.d_y[:, ia], k2 + T[j], rtol=1e-14)
        np.testing.assert_allclose(vs.d_alpha[:, ia], k1 * vs.y, rtol=1e-14)
    assert checked >= 9


# ------------------------------------------------------------------------- gait thrust
def test_gait_thrust_section_to_schedule(walk3):
    """A gait's thrust: section (alpha knots, per-thruster values) equals the same schedule
    built directly; problems are collected with their key paths."""
    model, _, zd = walk3
    kn = [zd.alpha_i, 0.0, zd.alpha_f]
    ts = WrittenSchedule(tuple(kn), (("hip_x", (-10.0, -20.0)), ("torso_back", (0.0, 5.0))),
                        "force", fractions=False)
    sched, fr = ts.resolve(zd, zd.model.robot, "gait thrust")
    assert fr[1] == pytest.approx(-zd.alpha_i / (zd.alpha_f - zd.alpha_i), abs=1e-12)
    np.testing.assert_array_equal(sched.force[0], [[-10.0, 0.0], [-20.0, 5.0]])
    G = [[gamma_quad(zd, kn[j], kn[j + 1], m) for m in range(2)] for j in range(2)]
    assert S.one_step_change(zd, sched)[0] == pytest.approx(
        np.sum(np.array(G) * sched.force[0]), rel=1e-9)
    bad = WrittenSchedule((0.0, 0.7, 0.4, 1.0), (("hip_x", (1.0,)), ("nozzle", (1, 2, 3))),
                         "force")
    with pytest.raises(InputError) as ei:
        bad.resolve(zd, zd.model.robot, "gait thrust")
    text = str(ei.value)
    assert "increase strictly" in text and "expected 3 values" in text and "nozzle" in text
    gen = WrittenSchedule((0.0, 1.0), (("hip_x", (1.0,)),), "generalized")
    with pytest.raises(InputError, match="only key is T"):
        gen.resolve(zd, zd.model.robot, "gait thrust")


def test_pattern_language_is_safe_and_checked(walk3):
    vals = pattern_values("sin(pi*j/4)*k**2 - 3/j", 3, [1.0, 2.0])
    for a, k in enumerate([1.0, 2.0]):
        for j in (1, 2, 3):
            assert vals[a, j - 1] == pytest.approx(np.sin(np.pi * j / 4) * k**2 - 3 / j,
                                                   rel=1e-15)
    for bad, needle in [("__import__('os')", "column"), ("k*x", "unknown name 'x'"),
                        ("k/(j-1)", "pattern"), ("k*(j-2", "pattern")]:
        with pytest.raises(InputError, match=needle):
            pattern_values(bad, 3, [0.0, 1.0])


# ---------------------------------------------------------------------------------- CLI
def _one_error_line(res) -> str:
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert "Traceback" not in res.output
    return lines[0]


@pytest.mark.parametrize("args, needle", [
    (["--pattern", "__import__('os')"], "option --pattern"),
    (["--knots", "0,0.6,0.3,1"], "knots must increase strictly"),
    (["--knots", "0.5"], "need at least 2 knots"),
    (["--knots", "0,?,0.9"], "the first must be 0 and the last 1"),
    (["--knots", "0,x,1"], "is not a number or ?"),
    (["--mode", "thrust"], "option --mode"),
    (["--target-zeta", "2000", "--pattern", "k"], "cannot be combined with --target-zeta"),
    (["--target-zeta", "-1"], "must be > 0"),
    (["--thruster", "hip_x"], "only used with --mode force"),
])
def test_cli_bad_input_one_line_exit_2(tmp_path, args, needle, cli):
    res = cli("shape", *args, "--out", str(tmp_path), "-q")
    assert res.exit_code == 2, res.output
    line = _one_error_line(res)
    assert re.match(r"error: option --[a-z-]+: ", line) and needle in line, line
    assert not (tmp_path / "shape.json").exists()


def test_cli_gait_thrust_errors_name_file_line(tmp_path, cli):
    text = (REPO / "gaits" / "three_link_walk.yaml").read_text().replace(
        "robot: three_link", f"robot: {REPO}/robots/three_link.yaml")
    gait = tmp_path / "g.yaml"
    gait.write_text(text + "thrust:\n  mode: generalized\n  knots: [0, 0.5, 1]\n"
                    "  values:\n    T: [1, 2, 3]\n")
    res = cli("shape", "three_link", str(gait), "--out", str(tmp_path / "out"), "-q")
    assert res.exit_code == 2, res.output
    line = _one_error_line(res)
    assert re.match(rf"error: {re.escape(str(gait))}:\d+: thrust\.values\.T: expected 2 values",
                    line), line


def test_cli_no_knots_exit_1_with_reason(tmp_path, cli):
    res = cli("shape", "--pattern", "k", "--k", "0,10", "--out", str(tmp_path),
                              "-q")
    assert res.exit_code == 1
    assert "no shape-only knots exist" in res.output
    doc = json.loads((tmp_path / "shape.json").read_text())
    assert doc["success"] is False and "no shape-only knots" in doc["reason"]
    assert doc["knot_solver"]["success"] is False


@pytest.mark.slow
def test_cli_writes_every_output(tmp_path, cli):
    res = cli("shape", "three_link", "three_link_walk", "--knots", "0,?,?,1",
                              "--pattern", "k*(j-2)", "--k", "0:50:10", "--out", str(tmp_path))
    assert res.exit_code == 0, res.output
    assert "an erratum of the paper" in res.output
    for name in ("shape.json", "shape.csv", "shape.png", "shape.pdf", "vector_field.png",
                 "vector_field.pdf"):
        assert (tmp_path / name).stat().st_size > 0, name
    doc = json.loads((tmp_path / "shape.json").read_text())
    for key in ("provenance", "units", "robot", "gait", "mode", "pattern", "knots", "b_F",
                "Gamma_j", "nominal", "schedules", "erratum", "knot_solver", "vector_field"):
        assert key in doc, key
    assert doc["success"] is True and doc["mode"] == "generalized"
    assert len(doc["knots"]["alpha"]) == 4 and len(doc["b_F"]) == 3
    assert [s["k"] for s in doc["schedules"]] == [0, 10, 20, 30, 40, 50]
    s = doc["schedules"][-1]
    assert s["T_j"] == [-50.0, 0.0, 50.0]
    for key in ("zeta_star", "shift", "pre_impact", "post_impact"):
        assert key in s, key
    assert set(s["zeta_star"]) == {"nominal", "shaped"}
    assert set(s["shift"]) >= {"true_fixed_point_shift", "paper_one_step_shift"}
    assert set(s["pre_impact"]) == {"nominal", "shaped"}
    assert abs(s["pre_impact"]["shaped"]["zeta"] - s["pre_impact"]["nominal"]["zeta"]) < 1e-9
    assert doc["b_F"][0] == pytest.approx(doc["b_F"][2], rel=1e-12)
    assert doc["vector_field"]["label"] == "k = 60"
    csv = (tmp_path / "shape.csv").read_text().splitlines()
    header = csv[0]
    assert header.startswith("schedule,k,exists,segment,alpha_rad")
    assert sum(1 for ln in csv if ln.startswith("k = 50,")) > 100


@pytest.mark.slow
def test_cli_target_speed_force_mode(tmp_path, cli):
    res = cli("shape", "--target-speed", "1.2", "--mode", "force",
                              "--knots", "0,0.5,1", "--out", str(tmp_path), "-q",
                              "--formats", "csv,png")  # PDFs: test_cli_writes_every_output
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "shape.json").read_text())
    assert doc["target"]["success"] and doc["thruster"] == "hip_x"
    assert doc["schedules"][0]["speed"] == pytest.approx(1.2, rel=1e-9)
    assert set(doc["schedules"][0]["F_j"]) == {"hip_x"}
