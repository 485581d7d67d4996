"""Ground-contact feasibility (SPEC 5): the affine ground force against independent dynamics,
Newton's law for the whole robot, the impact impulse against the momentum change, and the
``feasibility`` command."""

from __future__ import annotations

import json

import numpy as np
import pytest

from thrustwalk_cli.contact import evaluate as CE
from thrustwalk_cli.contact import region as CR
from thrustwalk_cli.contact import terms as CT
from thrustwalk_cli.hzd.constraints import bezier
from thrustwalk_cli.thrust.schedule import Schedule

RTOL = 1e-8


def full_dynamics(model, gait, maps, alpha, alpha_dot, F, T=0.0):
    """Independent ground force: the unpinned equations of motion with the stance foot held by
    F_1, the torques u unknown and the virtual constraint held (y'' = 0), solved as one linear
    system per state. Uses neither kappa_1, the unactuated-row trick, Phi nor dPhi.

        D_u q_u'' + h_u(q, q_u') = [B_tau; 0] u + B_Fu F + [0; I_2] F_1 + [e_N; 0] T
        [0, I_2] q_u'' = 0                                    (stance foot fixed)
        q_b'' - dh_d/dalpha alpha'' - d2h_d/dalpha2 alpha'^2 = 0,  alpha = c q    (y'' = 0)
    Returns (F_1, u, q'') per state.
    """
    N = model.n
    c = np.asarray(gait.c, float)
    A = gait.coefficients
    span = maps.alpha_f - maps.alpha_i
    out_F, out_u, out_dd = [], [], []
    for a, ad, f in zip(alpha, alpha_dot, F):
        s = (a - maps.alpha_i) / span
        hd = bezier(A, np.array(s))
        dh = bezier(A, np.array(s), 1) / span
        d2h = bezier(A, np.array(s), 2) / span**2
        # configuration from the constraint q_b = h_d(alpha), c q = alpha
        M = np.vstack([np.hstack([np.eye(N - 1), np.zeros((N - 1, 1))]), c])
        q = np.linalg.solve(M, np.append(hd, a))
        dq = np.linalg.solve(M, np.append(dh * ad, ad))
        Du = model.D_u(q)
        hu = model.h_u(q, np.append(dq, [0.0, 0.0]))
        BFu = model.B_Fu(q)
        n_unk = (N + 2) + (N - 1) + 2
        K = np.zeros((n_unk, n_unk))
        r = np.zeros(n_unk)
        iu, iF = N + 2, N + 2 + N - 1
        K[:N + 2, :N + 2] = Du
        K[:N - 1, iu:iF] = -np.eye(N - 1)
        K[N:N + 2, iF:] = -np.eye(2)
        r[:N + 2] = BFu @ f - hu
        r[N - 1] += T
        K[N + 2:N + 4, N:N + 2] = np.eye(2)
        # y'' = q_b'' - dh (c q'') - d2h (c q')^2 = 0
        K[N + 4:, :N] = np.hstack([np.eye(N - 1), np.zeros((N - 1, 1))]) - np.outer(dh, c)
        r[N + 4:] = d2h * (c @ dq) ** 2
        sol = np.linalg.solve(K, r)
        out_F.append(sol[iF:])
        out_u.append(sol[iu:iF])
        out_dd.append(sol[:N])
    return np.array(out_F), np.array(out_u), np.array(out_dd)


def _states(zd, n=9, seed=3):
    rng = np.random.default_rng(seed)
    alpha = np.sort(rng.uniform(min(zd.alpha_i, zd.alpha_f), max(zd.alpha_i, zd.alpha_f), n))
    alpha_dot = rng.uniform(0.3, 2.5, n) * zd.direction
    F = rng.uniform(-60.0, 40.0, (n, zd.model.n_thrusters))
    return alpha, alpha_dot, F


def _zeta(zd, alpha, alpha_dot):
    """zeta = sigma_N^2 / 2 with sigma_N = e_N^T D q' (from the definition, not kappa_1)."""
    t = zd.terms(alpha)
    D = zd.model.D(t["q"])
    dq = t["Phi"] * alpha_dot[:, None]
    sigma = np.einsum("gj,gj->g", D[:, -1, :], dq)
    return 0.5 * sigma**2


def test_affine_force_equals_full_unpinned_dynamics(walk3):
    model, gait, zd = walk3
    alpha, ad, F = _states(zd)
    T = np.random.default_rng(5).uniform(-20, 20, len(alpha))
    t = CT.stance_terms(model, zd.maps, alpha)
    zeta = _zeta(zd, alpha, ad)
    F1 = (np.einsum("gim,gm->gi", t.L2, F) + t.L1 * zeta[:, None] + t.L0
          + t.LT * T[:, None])
    u = (np.einsum("gim,gm->gi", t.U2, F) + t.U1 * zeta[:, None] + t.U0 + t.UT * T[:, None])
    for i in range(len(alpha)):
        Fr, ur, _ = full_dynamics(model, gait, zd.maps, alpha[i:i + 1], ad[i:i + 1],
                                  F[i:i + 1], T[i])
        scale = np.abs(Fr[0]).max()
        assert np.allclose(F1[i], Fr[0], rtol=0, atol=RTOL * scale), f"state {i}: F_1"
        assert np.allclose(u[i], ur[0], rtol=0, atol=RTOL * np.abs(ur[0]).max()), f"state {i}: u"


def test_lambdas_are_the_partial_derivatives(walk3):
    """Lambda_1 = dF_1/dzeta and Lambda_2 = dF_1/dF_T by central differences of the
    independent full-dynamics force (exact up to rounding: F_1 is affine)."""
    model, gait, zd = walk3
    alpha, ad, F = _states(zd, n=4, seed=11)
    t = CT.stance_terms(model, zd.maps, alpha)
    zeta = _zeta(zd, alpha, ad)
    for i in range(len(alpha)):
        # zeta +/- h through alpha' (alpha'^2 is proportional to zeta)
        h = 1e-3 * zeta[i]
        adp = ad[i] * np.sqrt((zeta[i] + h) / zeta[i])
        adm = ad[i] * np.sqrt((zeta[i] - h) / zeta[i])
        Fp = full_dynamics(model, gait, zd.maps, alpha[i:i + 1], [adp], F[i:i + 1])[0][0]
        Fm = full_dynamics(model, gait, zd.maps, alpha[i:i + 1], [adm], F[i:i + 1])[0][0]
        d1 = (Fp - Fm) / (2 * h)
        assert np.allclose(d1, t.L1[i], rtol=1e-6, atol=1e-9), f"Lambda_1 at state {i}"
        for k in range(model.n_thrusters):
            e = np.zeros(model.n_thrusters)
            e[k] = 1.0
            Fp = full_dynamics(model, gait, zd.maps, alpha[i:i + 1], ad[i:i + 1],
                               (F[i] + e)[None])[0][0]
            Fm = full_dynamics(model, gait, zd.maps, alpha[i:i + 1], ad[i:i + 1],
                               (F[i] - e)[None])[0][0]
            assert np.allclose((Fp - Fm) / 2, t.L2[i, :, k], rtol=1e-6, atol=1e-9), \
                f"Lambda_2 column {k} at state {i}"


def test_newton_law_for_the_whole_robot(walk3):
    """F_1 + sum_k F_k d_k - m g e_y = m a_com, with a_com = J_com q'' + (dJ_com/dt) q' and
    dJ_com/dt from central differences of J_com along q' (independent of D, h, Lambda)."""
    model, gait, zd = walk3
    alpha, ad, F = _states(zd, n=7, seed=17)
    zeta = _zeta(zd, alpha, ad)
    t = CT.stance_terms(model, zd.maps, alpha)
    F1 = np.einsum("gim,gm->gi", t.L2, F) + t.L1 * zeta[:, None] + t.L0
    add = np.einsum("gm,gm->g", t.A2, F) + t.A1 * zeta + t.A0  # alpha''
    q = zd.maps.q_Z(alpha)
    dq = zd.maps.Phi(alpha) * ad[:, None]
    ddq = zd.maps.Phi(alpha) * add[:, None] + zd.maps.dPhi(alpha) * (ad**2)[:, None]
    m = model.robot.total_mass
    g = model.robot.gravity
    h = 1e-5
    dJ = (model.J_com(q + h * dq) - model.J_com(q - h * dq)) / (2 * h)
    acc = (np.einsum("gij,gj->gi", model.J_com(q), ddq) + np.einsum("gij,gj->gi", dJ, dq))
    thrust = np.einsum("gik,gk->gi", model.thruster_dirs(q), F)
    lhs = F1 + thrust - np.array([0.0, m * g])
    assert np.allclose(lhs, m * acc, rtol=0, atol=1e-6 * m * g)


def test_impact_impulse_equals_momentum_change(walk3):
    """F_2 = m (v_com^+ - v_com^-), with v_com^+ = J_com q'^+ + (old stance foot velocity)."""
    model, gait, zd = walk3
    imp = CT.impact_data(model, zd)
    sigma = 37.0  # any |sigma_N^-| [kg m^2/s]: the impulse is proportional to it
    t = zd.terms(np.array([zd.alpha_f]))
    dq_minus = t["Phi"][0] * t["kappa1"][0] * zd.sigma_sign * sigma
    Mu, _, _ = model.impact_maps(zd.maps.q_minus)
    dqu = Mu @ dq_minus
    J = model.J_com(zd.maps.q_minus)
    m = model.robot.total_mass
    dp = m * (J @ dqu[:model.n] + dqu[model.n:]) - m * (J @ dq_minus)
    assert np.allclose(imp.impulse_per_sigma * sigma, dp, rtol=1e-10, atol=1e-10)
    # swing foot (new stance foot) at rest after the impact (no rebound, no slip)
    Eu = model.E_swing_u(zd.maps.q_minus)
    assert np.allclose(Eu @ dqu, 0.0, atol=1e-10)


def test_piecewise_with_equal_values_equals_constant(walk3):
    model, gait, zd = walk3
    knots = zd.alpha_i + np.array([0.0, 0.3, 0.7, 1.0]) * (zd.alpha_f - zd.alpha_i)
    force = np.zeros((1, 3, model.n_thrusters))
    force[0, :, 0] = -7.0
    pw = CE.evaluate(model, zd, Schedule(knots, force, np.zeros((1, 3))), mu=0.7)
    cst = CE.evaluate(model, zd, Schedule.constant(zd, np.array([[-7.0, 0.0]])), mu=0.7)
    a, b = pw.cases[0], cst.cases[0]
    assert a.feasible == b.feasible
    assert a.min_vertical_force == pytest.approx(b.min_vertical_force, rel=1e-9)
    assert a.max_friction_ratio == pytest.approx(b.max_friction_ratio, rel=1e-9)


def test_worst_points_are_polished_minima(walk3):
    """The reported minimum vertical force is no larger than on a fine independent grid and is
    attained at the reported alpha."""
    model, gait, zd = walk3
    F = np.array([[-3.0, 0.0]])
    rep = CE.evaluate(model, zd, Schedule.constant(zd, F), mu=0.7)
    c = rep.cases[0]
    a = np.linspace(zd.alpha_i, zd.alpha_f, 20001)
    t = CT.stance_terms(model, zd.maps, a)
    zeta = c.cycle.zeta_plus + zd.V_Z(a, Schedule.constant(zd, F))[0]
    Fv = (np.einsum("gim,m->gi", t.L2, F[0]) + t.L1 * zeta[:, None] + t.L0)[:, 1]
    assert c.min_vertical_force <= Fv.min() + 1e-9
    assert c.min_vertical_force == pytest.approx(Fv.min(), abs=1e-3)
    t1 = CT.stance_terms(model, zd.maps, np.array([c.alpha_at_min_vertical_force]))
    z1 = c.cycle.zeta_plus + zd.V_Z(np.array([c.alpha_at_min_vertical_force]),
                                    Schedule.constant(zd, F))[0]
    v1 = (t1.L2[0] @ F[0] + t1.L1[0] * z1[0] + t1.L0[0])[1]
    assert v1 == pytest.approx(c.min_vertical_force, rel=1e-12)


def test_polynomial_fits_meet_their_target_and_agree(walk3):
    model, gait, zd = walk3
    fits = CT.fit_terms(model, zd, tol=1e-4)
    a = np.linspace(zd.alpha_i, zd.alpha_f, 777)  # neither the fit nor the check grid
    t = CT.stance_terms(model, zd.maps, a)
    for name, exact in (("L0", t.L0), ("L1", t.L1), ("L2", t.L2), ("LT", t.LT)):
        f = fits.fits[name]
        approx = f(fits.x(a))
        assert f.reached, name
        assert np.abs(approx - exact).max() <= 2 * f.max_error + 1e-12, name
        assert f.relative_error <= 1e-4, name
    rep = CE.evaluate(model, zd, Schedule.constant(zd, np.array([[0.0, 0.0], [-4.0, 0.0]])),
                           mu=0.7, fits=fits)
    for c in rep.cases:
        assert c.poly["agrees"], c.label
    fixed = CT.fit_terms(model, zd, degree=3)
    assert all(f.degree == 3 for f in fixed.fits.values())
    assert fixed.fits["L1"].max_error > fits.fits["L1"].max_error


def test_bundled_gait_contact_at_zero_thrust(walk3):
    """The shipped gait at mu = 0.7 without thrust: vertical force positive, inside the cone,
    admissible impact, trailing foot lifts off, swing foot above ground inside the step."""
    model, gait, zd = walk3
    rep = CE.evaluate(model, zd, Schedule.constant(zd, np.zeros((1, 2))), mu=0.7)
    c = rep.cases[0]
    assert c.feasible, c.reason
    assert c.min_vertical_force > 0
    assert c.max_friction_ratio < 0.7
    assert rep.impact.admissible(0.7)
    assert c.liftoff_velocity > 0
    assert not rep.swing["scuffs"]


def test_bundled_gait_thrust_sweep_verdicts_are_consistent(walk3):
    """Over thrust 0 ... -50 N on hip_x: the verdict of each case follows from its own margins,
    and the impact (direction independent of speed) stays admissible with lift-off."""
    model, gait, zd = walk3
    vals = np.arange(0.0, -50.5, -5.0)
    F = np.zeros((len(vals), 2))
    F[:, 0] = vals
    rep = CE.evaluate(model, zd, Schedule.constant(zd, F), mu=0.7)
    for v, c in zip(vals, rep.cases):
        assert c.cycle.exists, v
        ok = c.min_vertical_force >= 0 and c.max_friction_ratio is not None \
            and c.max_friction_ratio <= 0.7
        assert c.feasible == ok, f"thrust {v}: {c.reason}"
        assert c.liftoff_velocity > 0, v
        assert c.impact_friction_ratio < 0.7, v


def test_bundled_gait_feasible_for_thrust_0_to_minus_50(walk3):
    """SPEC 5 target for the shipped gait: feasible at mu = 0.7 for 0 ... -50 N on hip_x."""
    model, gait, zd = walk3
    vals = np.arange(0.0, -50.5, -10.0)
    F = np.zeros((len(vals), 2))
    F[:, 0] = vals
    rep = CE.evaluate(model, zd, Schedule.constant(zd, F), mu=0.7)
    bad = [(v, c.reason) for v, c in zip(vals, rep.cases) if not c.feasible]
    assert not bad, bad


def test_feasible_region_matches_case_evaluation(walk3):
    """On the fixed-point curve the region's verdict equals the per-case evaluation."""
    model, gait, zd = walk3
    e = np.array([[1.0, 0.0]])
    scales = np.array([0.0, -4.0, -30.0])
    reg = CR.feasible_region(model, zd, Schedule.constant(zd, e), scales,
                                  np.linspace(50, 5000, 11), mu=0.7, points=401)
    F = np.zeros((3, 2))
    F[:, 0] = scales
    rep = CE.evaluate(model, zd, Schedule.constant(zd, F), mu=0.7)
    for i, c in enumerate(rep.cases):
        assert reg.fixed_point[i] == pytest.approx(c.cycle.zeta_star, rel=1e-9)
        assert bool(reg.fixed_point_feasible[i]) == c.feasible, scales[i]


def test_schedule_file_section_pads_and_validates(walk3):
    from thrustwalk_cli.errors import InputError
    from thrustwalk_cli.thrust.schedule import WrittenSchedule

    model, gait, zd = walk3
    spec = WrittenSchedule((0.25, 0.75), (("hip_x", (-5.0,)),), "force", True)
    s = spec.resolve(zd, zd.model.robot, "schedule", pad=True)[0]
    assert len(s.knots) == 4 and s.knots[0] == zd.alpha_i and s.knots[-1] == zd.alpha_f
    assert s.force[0, :, 0].tolist() == [0.0, -5.0, 0.0]
    bad = WrittenSchedule((0.0, 1.0), (("nozzle", (1.0,)),), "force", True)
    with pytest.raises(InputError, match="unknown thruster"):
        bad.resolve(zd, zd.model.robot, "schedule", pad=True)
    with pytest.raises(InputError, match=r"expected 1 value \(one per interval"):
        WrittenSchedule((0.0, 1.0), (("hip_x", (1.0, 2.0)),)).resolve(zd, zd.model.robot,
                                                                      "schedule", pad=True)
    with pytest.raises(InputError, match="increase strictly"):
        WrittenSchedule((0.5, 0.2), (("hip_x", (1.0,)),)).resolve(zd, zd.model.robot,
                                                                  "schedule", pad=True)


# ------------------------------------------------------------------------------------ CLI
CASE_KEYS = {"thrust", "feasible", "min_vertical_force", "alpha_at_min_vertical_force",
             "max_friction_ratio", "alpha_at_max_friction_ratio", "impact_impulse",
             "impact_friction_ratio", "liftoff_velocity", "min_swing_foot_height",
             "fit_errors", "reason"}


@pytest.mark.slow
def test_cli_feasibility_writes_every_output(walk3, tmp_path, cli):
    out = tmp_path / "f"
    res = cli("feasibility", "--thrust", "0,-5,-30", "--out", str(out), "-q")
    assert res.exit_code == 0, res.output
    for name in ("feasibility.json", "feasibility.md", "grf.png", "grf.pdf",
                 "feasible_region.png", "feasible_region.pdf"):
        assert (out / name).stat().st_size > 0, name
    doc = json.loads((out / "feasibility.json").read_text())
    assert len(doc["cases"]) == 3
    for c in doc["cases"]:
        assert CASE_KEYS <= set(c), CASE_KEYS - set(c)
    assert doc["mu"] == 0.7 and "29 %" in doc["friction_cone"]
    md = (out / "feasibility.md").read_text()
    assert "![ground reaction force](grf.png)" in md and "feasible_region.png" in md


@pytest.mark.slow
def test_cli_infeasible_verdict_exits_zero(walk3, tmp_path, cli):
    out = tmp_path / "inf"
    res = cli("feasibility", "--thrust", "0", "--mu", "0.05", "--out", str(out), "-q",
              "--formats", "png,md")  # PDFs: test_cli_feasibility_writes_every_output
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "feasibility.json").read_text())
    assert doc["verdict"] == "infeasible"
    c = doc["cases"][0]
    assert c["feasible"] is False and "friction" in c["reason"]


@pytest.mark.slow
def test_cli_schedule_file(walk3, tmp_path, cli):
    src = tmp_path / "sched.yaml"
    gait_file = walk3[1].source_file
    text = open(gait_file).read()
    text += ("thrust:\n  mode: force\n  knots: [0, 0.5, 1]\n  fractions: true\n"
             "  values:\n    hip_x: [-3, 2]\n")
    src.write_text(text)
    out = tmp_path / "s"
    res = cli("feasibility", "--schedule", str(src), "--out", str(out), "-q",
              "--formats", "png,md")  # PDFs: test_cli_feasibility_writes_every_output
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "feasibility.json").read_text())
    assert doc["mode"] == "schedule"
    assert doc["cases"][0]["thrust"]["values"] == {"hip_x": [-3.0, 2.0]}


@pytest.mark.parametrize("args, message", [
    (["--thrust", "abc"], "--thrust"),
    (["--mu", "-1"], "--mu"),
    (["--eps", "-2"], "--eps"),
    (["--degree", "0"], "--degree"),
    (["--fit-tol", "2"], "--fit-tol"),
    (["--thruster", "nozzle"], "--thruster"),
    (["--thrust", "0", "--schedule", "x.yaml"], "not both"),
])
def test_cli_bad_input_exits_two(walk3, tmp_path, args, message, cli):
    res = cli("feasibility", *args, "--out", str(tmp_path / "bad"), "-q")
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert "Traceback" not in res.output


def test_cli_schedule_without_thrust_section_exits_two(walk3, tmp_path, cli):
    gait_file = walk3[1].source_file
    res = cli("feasibility", "--schedule", gait_file, "--out",
                              str(tmp_path / "x"), "-q")
    assert res.exit_code == 2
    assert "no `thrust:` section" in res.output


@pytest.mark.slow
def test_max_abs_torque_and_swing_extremes_are_polished(walk3):
    """max |u_i| per joint equals the maximum of the affine torque over 40001 points per knot
    interval (to 1e-8 relative, never below it), also for a piecewise schedule whose torque jumps at
    the knots; the swing-foot minimum over the window, maximum and deepest point equal a
    fine grid of the kinematics. The 401-point grid was up to 3e-5 low."""
    model, _, zd = walk3
    span = zd.alpha_f - zd.alpha_i
    knots = zd.alpha_i + span * np.array([0.0, 0.4, 1.0])
    force = np.zeros((1, 2, model.n_thrusters))
    force[0, :, 0] = [-30.0, 10.0]
    scheds = [Schedule.constant(zd, np.array([[0.0, 0.0], [-25.0, 0.0]])),
              Schedule(knots, force, np.zeros((1, 2)))]
    for sched in scheds:
        rep = CE.evaluate(model, zd, sched, mu=0.7, profiles=False)
        kn = sched.knots
        for i, c in enumerate(rep.cases):
            umax = np.zeros(model.n - 1)
            for j in range(len(kn) - 1):  # each knot interval with its own thrust, both ends
                a = np.linspace(kn[j], kn[j + 1], 40001)
                t = CT.stance_terms(model, zd.maps, a)
                zeta = c.cycle.zeta_plus + zd.V_Z(a, sched)[i]
                u = (np.einsum("gim,m->gi", t.U2, sched.force[i, j]) + t.U1 * zeta[:, None]
                     + t.U0 + t.UT * sched.generalized[i, j])
                umax = np.maximum(umax, np.abs(u).max(axis=0))
            assert np.all(np.array(c.max_abs_torque) >= umax - 1e-12), (i, c.max_abs_torque)
            assert c.max_abs_torque == pytest.approx(umax, rel=1e-8), i
    sw = CT.swing_clearance(model, zd)
    a = np.linspace(zd.alpha_i, zd.alpha_f, 100001)
    h = model.p_swing(zd.maps.q_Z(a))[:, 1]
    s = (a - zd.alpha_i) / span
    win = (s >= CT.SWING_WINDOW[0]) & (s <= CT.SWING_WINDOW[1])
    assert sw["min_height"] <= h[win].min() + 1e-15
    assert sw["min_height"] == pytest.approx(h[win].min(), abs=1e-10)
    assert sw["max_height"] >= h.max() - 1e-15
    assert sw["max_height"] == pytest.approx(h.max(), abs=1e-10)
    assert sw["deepest"] == pytest.approx(min(h[1:-1].min(), 0.0), abs=1e-10)


@pytest.mark.slow
def test_tangential_touchdown_is_not_a_strike(tmp_path, walker_rabbit, cli):
    """A swing foot that reaches the ground at vertical velocity 0 does not strike it (the
    impact of the hybrid model needs a transversal crossing): feasibility says so, reports the
    touchdown velocity per case and warns; the bundled gaits strike (touchdown < 0)."""
    from pathlib import Path

    from thrustwalk_cli.walker import load_walker

    data = Path(__file__).resolve().parent / "data"
    w = load_walker(None, str(data / "rabbit_tangent.yaml"))
    imp = CT.impact_data(w.model, w.zd)
    assert not imp.strikes and not imp.admissible(10.0)
    assert any("not a strike" in r for r in imp.reasons(10.0))
    res = cli("feasibility", "rabbit", data / "rabbit_tangent.yaml", "--thrust", "0", "--mu",
              "2", "-q", "--out", tmp_path, "--formats", "png,md")  # no PDF: drawn all the same
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "feasibility.json").read_text())
    case = doc["cases"][0]
    assert not case["feasible"] and "not a strike" in case["reason"]
    assert case["touchdown_velocity"] == pytest.approx(0.0, abs=1e-12)
    assert doc["warnings"] and "grazing" in (tmp_path / "feasibility.md").read_text()
    for walker in (load_walker(None, "three_link_walk"), load_walker(None, "rabbit_walk")):
        imp = CT.impact_data(walker.model, walker.zd)
        assert imp.strikes and imp.touchdown_per_sigma < 0
