"""Full-order hybrid simulation (SPEC 7) against the zero dynamics (SPEC 3, 4), the affine
ground force (SPEC 5), energy and impact identities (SPEC 10), and the CLI.

Every expected value comes from a computation the simulator does not use: the zero-dynamics
fixed point and Poincare eigenvalue, the closed-form output decay of y'' = -Kp y - Kd y', the
analytic thruster responses, SPEC 5's formula built from kappa_1, kappa_2, beta, Phi, Phi',
and the plain-NumPy model of ``tests/independent.py`` (energy, thruster power, Carnot loss).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import independent as ind
import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.linalg import expm

from thrustwalk_cli.hzd.zero_dynamics import limit_cycles, paper_one_step_shift
from thrustwalk_cli.simulation.closed_loop import ClosedLoop, SimConfig, ThrustModel, zeta_star_at
from thrustwalk_cli.simulation.full_order import Start, initial_state, simulate
from thrustwalk_cli.simulation.reduced import ReducedModel, simulate_reduced
from thrustwalk_cli.thrust.schedule import Schedule, WrittenSchedule

TIGHT = SimConfig(steps=3, rtol=1e-10, atol=1e-10)
DATA = Path(__file__).resolve().parent / "data"


def schedule_from_gait(zd, ts):
    """A gait-format thrust section as a schedule (padded), problems reported at "thrust"."""
    return ts.resolve(zd, zd.model.robot, "thrust", pad=True)[0]


def const(model, **thrust) -> ThrustModel:
    F = np.zeros(model.n_thrusters)
    for name, v in thrust.items():
        F[model.robot.thruster_names.index(name)] = v
    return ThrustModel("constant", F)


def cycle(zd, F) -> object:
    return limit_cycles(zd, Schedule.constant(zd, np.asarray(F, float)[None, :]))[0]


# ------------------------------------------------------------------ on and off the orbit
def test_started_on_fixed_point_stays_on_zero_dynamics_orbit(walk3):
    model, _, zd = walk3
    res = simulate(zd, const(model), TIGHT)
    lc = cycle(zd, np.zeros(model.n_thrusters))
    assert res.success, res.reason
    assert len(res.steps) == 3
    for st in res.steps:
        assert st.zeta_minus == pytest.approx(lc.zeta_star, rel=1e-6), st.step
        assert st.max_abs_output < 1e-8, st.step
        assert st.step_time == pytest.approx(lc.step_time, rel=1e-6), st.step
        assert st.s_minus == pytest.approx(1.0, abs=1e-6), st.step


def test_rabbit_started_on_fixed_point_stays_on_orbit(walker_rabbit):
    model, zd = walker_rabbit.model, walker_rabbit.zd
    res = simulate(zd, const(model), replace(TIGHT, steps=2))
    assert res.success, res.reason
    for st in res.steps:
        assert st.zeta_minus == pytest.approx(res.prediction.zeta_star, rel=1e-6), st.step
        assert st.max_abs_output < 1e-8, st.step


def test_perturbed_start_contracts_at_delta_zero_squared(walk3):
    model, _, zd = walk3
    res = simulate(zd, const(model), replace(TIGHT, steps=5), Start(perturb=0.3))
    assert res.success, res.reason
    err = np.array([st.zeta_minus for st in res.steps]) - res.prediction.zeta_star
    assert err[0] == pytest.approx(0.3 * zd.delta_zero_sq * res.prediction.zeta_star, rel=1e-6)
    ratios = err[1:] / err[:-1]
    np.testing.assert_allclose(ratios, zd.delta_zero_sq, rtol=1e-2, err_msg="contraction")


def test_constant_thrust_converges_to_shifted_fixed_point_not_papers(walk3):
    model, _, zd = walk3
    F = np.zeros(model.n_thrusters)
    F[0] = -4.0
    res = simulate(zd, ThrustModel("constant", F), replace(TIGHT, steps=5),
                   Start(orbit="nominal"))
    assert res.success, res.reason
    z = np.array([st.zeta_minus for st in res.steps])
    # geometric convergence at the Poincare eigenvalue: Aitken's limit is exact for it
    limit = z[-1] - (z[-1] - z[-2]) ** 2 / (z[-1] - 2 * z[-2] + z[-3])
    shifted = cycle(zd, F).zeta_star
    nominal = cycle(zd, np.zeros_like(F)).zeta_star
    sched = Schedule.constant(zd, F[None, :])
    paper = nominal + float(paper_one_step_shift(zd, sched)[0])
    assert limit == pytest.approx(shifted, rel=1e-6)
    assert abs(limit - paper) > 0.1 * abs(shifted - nominal)  # the erratum matters
    np.testing.assert_allclose(np.diff(z)[1:] / np.diff(z)[:-1], zd.delta_zero_sq, rtol=1e-3)


# ------------------------------------------------------------------------ controller
def test_outputs_decay_as_the_closed_loop_linear_system(walk3):
    """y'' = -Kp y - Kd y' exactly, thrust on the joints cancelled: y(t) = expm(A t) y0."""
    model, gait, zd = walk3
    th = const(model, hip_x=-2.0, torso_back=3.0)
    x0 = initial_state(zd, th, Start())
    q0 = x0[:3] + np.array([0.01, -0.015, 0.0])  # swing leg net -0.005 rad: foot above ground
    res = simulate(zd, th, replace(TIGHT, steps=1), Start(q=q0, dq=x0[3:6]))
    assert res.success, res.reason
    st = res.steps[0]
    t = np.linspace(st.t_start, st.t_impact, 41)
    d = res.sample(1, t)
    A = np.array([[0.0, 1.0], [-gait.kp, -gait.kd]])
    for i in range(2):
        y0 = np.array([d["y"][0, i], d["dy"][0, i]])
        pred = np.array([(expm(A * (tk - t[0])) @ y0)[0] for tk in t])
        np.testing.assert_allclose(d["y"][:, i], pred, atol=1e-8, err_msg=f"output {i}")
    assert abs(d["y"][0, 0]) > 1e-3  # the test starts visibly off Z


def test_scalar_rhs_equals_vectorised_details(walk3):
    model, gait, zd = walk3
    sched = WrittenSchedule((0.0, 0.4, 1.0), (("T", (1.5, -2.0)),), "generalized", True)
    zd_g = replace(zd, gait=replace(gait, thrust=sched))
    th = ThrustModel("piecewise", np.zeros(2), schedule=schedule_from_gait(zd_g, sched))
    rng = np.random.default_rng(7)
    for cfg in (SimConfig(), SimConfig(torque_limit=20.0)):
        cl = ClosedLoop(zd_g, th, cfg)
        X = np.column_stack([rng.uniform(-0.4, 0.4, (25, 3)), rng.uniform(-2, 2, (25, 3))])
        segs = rng.integers(0, len(cl.breaks) + 1, 25)
        batch = cl.details(X, segs)
        for k in range(25):
            dx = np.array(cl.rhs(0.0, X[k], int(segs[k])))
            np.testing.assert_allclose(dx[3:], batch["ddq"][k], rtol=1e-9, atol=1e-9,
                                       err_msg=f"state {k}")
            assert cl.vertical_force(X[k], int(segs[k])) == pytest.approx(
                batch["F1"][k, 1], rel=1e-9, abs=1e-8)
        if cfg.torque_limit:
            assert np.abs(batch["u"]).max() <= 20.0 + 1e-12 and batch["saturated"].any()


# ------------------------------------------------------------------------ SPEC 5 forces
def _spec5_force(model, zd, alpha, zeta, F, sgn):
    """F_1 from SPEC 5 on Z at one alpha: q'' = Phi alpha'' + Phi' alpha'^2 with
    alpha'^2 = 2 kappa_1^2 zeta, alpha'' = 2 kappa_1' kappa_1 zeta + kappa_1 (kappa_2 + beta F),
    u from the pinned rows, F_1 from the unpinned force rows."""
    N = model.n
    mp = zd.maps

    def k1(a):
        q = mp.q_Z(np.array(a))
        return 1.0 / (model.D(q)[N - 1] @ mp.Phi(np.array(a)))

    q, phi, dphi = mp.q_Z(np.array(alpha)), mp.Phi(np.array(alpha)), mp.dPhi(np.array(alpha))
    h = 1e-5
    kap1 = k1(alpha)
    dk1 = (k1(alpha + h) - k1(alpha - h)) / (2 * h)
    kap2 = -model.G(q)[N - 1]
    beta = model.B_F(q)[N - 1]
    ad = sgn * np.sqrt(2 * zeta) * kap1
    add = 2 * dk1 * kap1 * zeta + kap1 * (kap2 + beta @ F)
    ddq = phi * add + dphi * ad**2
    dq = phi * ad
    u = (model.D(q) @ ddq + model.h(q, dq) - model.B_F(q) @ F)[: N - 1]
    gen = (model.D_u(q) @ np.r_[ddq, 0, 0] + model.h_u(q, np.r_[dq, 0, 0])
           - model.B_Fu(q) @ F - np.r_[u, 0, 0, 0])
    return gen[N:]


def test_ground_force_equals_affine_formula_of_spec5(walk3):
    model, _, zd = walk3
    F = np.array([-3.0, 2.0])
    res = simulate(zd, ThrustModel("constant", F), replace(TIGHT, steps=1))
    assert res.success, res.reason
    st = res.steps[0]
    d = res.sample(1, np.linspace(st.t_start, st.t_impact, 30))
    sgn = float(np.sign(d["sigma"][0]))
    m = model.n_thrusters
    for k, (a, s) in enumerate(zip(d["alpha"], d["sigma"])):
        L0 = _spec5_force(model, zd, a, 0.0, np.zeros(m), sgn)
        L1 = _spec5_force(model, zd, a, 1.0, np.zeros(m), sgn) - L0
        L2 = np.column_stack([_spec5_force(model, zd, a, 0.0, e, sgn) - L0
                              for e in np.eye(m)])
        affine = L2 @ F + L1 * (0.5 * s**2) + L0
        np.testing.assert_allclose(d["F1"][k], affine, rtol=1e-7, atol=1e-4,
                                   err_msg=f"sample {k} [N]")


# ------------------------------------------------------------------------ energy
def test_energy_bookkeeping_over_a_step(walk3):
    """E(pre_2) - E(pre_1) = int u.q_b' + int sum F_k d_k.p_k' - Carnot loss of impact 1."""
    model, _, zd = walk3
    robot = model.robot
    th = ThrustModel("second-order", np.array([-3.0, -3.0]), wn=2.0, xi=0.7)
    res = simulate(zd, th, TIGHT)
    assert res.success, res.reason

    def energy(q, dq):
        return 0.5 * dq @ ind.mass_matrix(robot, q) @ dq + ind.potential(robot, q)

    s1, s2 = res.steps[0], res.steps[1]
    t = np.linspace(s2.t_start, s2.t_impact, 2001)
    d = res.sample(2, t)
    p_u = np.einsum("ki,ki->k", d["u"], d["dq"][:, :2])
    p_f = np.array([ind.thruster_power(robot, q, dq, F)
                    for q, dq, F in zip(d["q"], d["dq"], d["F"])])
    work = simpson(p_u, x=t) + simpson(p_f, x=t)
    qm, dqm = np.array(s1.q_minus), np.array(s1.dq_minus)
    imp = model.impact(qm, dqm)
    dv = np.r_[dqm, 0.0, 0.0] - imp.dq_u_plus
    carnot = 0.5 * dv @ ind.unpinned_mass_matrix(robot, qm) @ dv
    e1, e2 = energy(qm, dqm), energy(np.array(s2.q_minus), np.array(s2.dq_minus))
    scale = abs(e1)
    assert abs(simpson(p_f, x=t)) > 1.0  # the thrust does work
    assert e2 - e1 == pytest.approx(work - carnot, abs=1e-8 * scale)
    # the relabelled post-impact state carries E^- minus the Carnot loss
    assert energy(d["q"][0], d["dq"][0]) == pytest.approx(e1 - carnot, abs=1e-9 * scale)
    assert s1.energy_minus - s1.energy_plus == pytest.approx(carnot, rel=1e-8)


# ------------------------------------------------------------------------ thruster dynamics
@pytest.mark.parametrize("kind", ["second-order", "first-order"])
def test_thrust_history_follows_its_ode_across_impacts(walk3, kind):
    model, _, zd = walk3
    Fss, wn, tau = -4.0, 2.0, 0.5
    th = ThrustModel(kind, np.array([Fss, 0.0]), wn=wn, xi=1.0, tau=tau)
    res = simulate(zd, th, TIGHT)
    assert res.success, res.reason
    t = res.trajectory["t"]
    exact = (Fss * (1 - (1 + wn * t) * np.exp(-wn * t)) if kind == "second-order"
             else Fss * (1 - np.exp(-t / tau)))
    np.testing.assert_allclose(res.trajectory["F"][:, 0], exact, atol=1e-7)
    np.testing.assert_allclose(res.trajectory["F"][:, 1], 0.0, atol=0)


def test_reduced_cascade_matches_full_order_under_slow_thrust(walk3):
    model, _, zd = walk3
    th = ThrustModel("second-order", np.array([-4.0, 0.0]), wn=2.0, xi=1.0)
    full = simulate(zd, th, TIGHT)
    x0 = initial_state(zd, th, Start())
    sigma0 = float(model.D(x0[:3])[2] @ x0[3:6])
    red = simulate_reduced(zd, th, 3, float(zd.maps.c @ x0[:3]), sigma0, th.initial_states(),
                           rtol=1e-10, atol=1e-10)
    assert full.success and red.success
    for a, b in zip(full.steps, red.steps):
        assert a.zeta_minus == pytest.approx(b.zeta_minus, rel=1e-6), a.step
        assert a.step_time == pytest.approx(b.step_time, rel=1e-6), a.step
        assert a.thrust_at_impact[0] == pytest.approx(b.thrust_at_impact[0], rel=1e-6)


def test_reduced_terms_equal_zero_dynamics_terms(walk3):
    _, _, zd = walk3
    rm = ReducedModel(zd)
    alpha = np.random.default_rng(3).uniform(zd.alpha_i, zd.alpha_f, 9)
    t = zd.terms(alpha)
    for k, a in enumerate(alpha):
        got = rm.terms(float(a))
        np.testing.assert_allclose(got, np.r_[t["kappa1"][k], t["kappa2"][k], t["beta"][k]],
                                   rtol=1e-12, atol=1e-12, err_msg=f"alpha {a}")


@pytest.mark.parametrize("mode", ["force", "generalized"])
def test_piecewise_schedule_fixed_point(walk3, mode):
    model, gait, zd = walk3
    vals = (("torso_back", (0.0, -3.0, 2.0)),) if mode == "force" else (("T", (-2.0, 0.0, 3.0)),)
    sched = WrittenSchedule((0.0, 0.3, 0.7, 1.0), vals, mode, True)
    zd_s = replace(zd, gait=replace(gait, thrust=sched))
    S = schedule_from_gait(zd_s, sched)
    th = ThrustModel("piecewise", np.zeros(2), schedule=S)
    res = simulate(zd_s, th, replace(TIGHT, steps=2))
    lc = limit_cycles(zd_s, S)[0]
    assert res.success, res.reason
    assert lc.zeta_star != pytest.approx(cycle(zd, np.zeros(2)).zeta_star, rel=1e-3)
    for st in res.steps:
        assert st.zeta_minus == pytest.approx(lc.zeta_star, rel=1e-6), st.step
        assert st.max_abs_output < 1e-8


# ------------------------------------------------------------------------ failures
@pytest.mark.parametrize("thrust, start, failure, words", [
    ({"hip_x": 100.0}, Start(orbit="nominal"), "fall", "alpha reverses"),
    ({}, Start(perturb=-0.9), "fall", "alpha reverses"),
    ({"hip_x": -120.0}, Start(orbit="nominal"), "fall", "vertical ground force"),
])
def test_falling_walker_is_reported_with_reason(walk3, thrust, start, failure, words):
    model, _, zd = walk3
    res = simulate(zd, const(model, **thrust), SimConfig(steps=6), start)
    assert not res.success
    assert res.failure == failure and words in res.reason and "step" in res.reason
    assert len(res.steps) < 6


def test_swing_foot_scuff_is_reported(walk3):
    """Swing leg swung down hard at the start: the foot starts below the ground."""
    model, _, zd = walk3
    x0 = initial_state(zd, const(model), Start())
    res = simulate(zd, const(model), SimConfig(steps=2),
                   Start(q=x0[:3] + np.array([0.0, 0.2, 0.0]),
                         dq=x0[3:6] + np.array([0.0, 3.0, 0.0])))
    assert not res.success and res.failure == "scuff", res.reason
    assert "swing foot" in res.reason and "below the ground" in res.reason


def _dipping_gait(walker, depth_col=4, delta=-0.3):
    """The bundled 3-link gait with its swing-leg column 4 lowered by 0.3 rad: on Z the swing
    foot dips 4 mm below the ground at s = 0.74 (a gait that strikes early)."""
    from thrustwalk_cli.hzd.constraints import apply_invariance
    from thrustwalk_cli.walker import walker_from

    A = np.array(walker.gait.A)
    A[1, depth_col] += delta
    gait = apply_invariance(walker.model, replace(walker.gait, A=tuple(map(tuple, A.tolist()))))
    return walker_from(walker.model, gait).zd


def test_early_strike_is_a_scuff_and_its_threshold_an_option(walker3):
    """A gait whose swing foot goes 4 mm below the ground at s = 0.74 (checked on Z here):
    with the default threshold (guard armed from s = 0.75) that is a scuff; with
    min_impact_s = 0.5 the same crossing is the strike, before s = 0.75. A bad threshold is a
    parameter error."""
    from thrustwalk_cli.errors import InputError

    zd = _dipping_gait(walker3)
    model = zd.model
    s = np.linspace(0.0, 1.0, 4001)
    h = model.p_swing(zd.maps.q_Z(zd.alpha_i + s * zd.maps.span))[:, 1]
    assert h.min() < -3e-3 and 0.6 < s[h.argmin()] < 0.75
    res = simulate(zd, const(model), SimConfig(steps=1))
    assert not res.success and res.failure == "scuff", res.reason
    assert "min_impact_s" in res.reason and "scuff_tol" in res.reason
    early = simulate(zd, const(model), SimConfig(steps=1, min_impact_s=0.5))
    assert early.steps and 0.5 < early.steps[0].s_minus < 0.75, early.reason
    assert model.p_swing(np.array(early.steps[0].q_minus))[1] == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(InputError, match="min_impact_s"):
        simulate(zd, const(model), SimConfig(steps=1, min_impact_s=0.3))


def test_slow_touchdown_is_struck_at_the_end_of_the_step(walker_rabbit):
    """A RABBIT gait whose swing foot reaches the ground at only -0.26 mm/s (the grazing case
    of a designed knee walker): the dip below the ground lasts less than one integrator step,
    yet the strike is found at s = 1 and every step stays on the zero-dynamics prediction
    (before the fix the strike was missed and the run ended in an integrator failure)."""
    from thrustwalk_cli.walker import load_walker

    zd = load_walker(None, str(DATA / "rabbit_grazing.yaml")).zd
    lc = cycle(zd, np.zeros(zd.model.n_thrusters))
    assert -1e-3 < lc.touchdown_velocity < 0, lc.touchdown_velocity
    res = simulate(zd, const(zd.model), SimConfig(steps=3))
    assert res.success, res.reason
    for st in res.steps:
        assert st.s_minus == pytest.approx(1.0, abs=1e-4), st.step
        assert st.zeta_minus == pytest.approx(lc.zeta_star, rel=1e-3), st.step


def test_integrator_failure_is_reported(walk3, monkeypatch):
    model, _, zd = walk3
    real = ClosedLoop.rhs

    def broken(self, t, x, seg):
        out = real(self, t, x, seg)
        return [np.nan] * len(out) if t > 0.2 else out

    monkeypatch.setattr(ClosedLoop, "rhs", broken)
    res = simulate(zd, const(model), SimConfig(steps=2, method="scipy"))
    assert not res.success and res.failure == "integrator" and "DOP853" in res.reason


def test_compiled_integrator_failure_is_reported(walk3):
    """A state the right-hand side cannot evaluate (NaN rates) stops the compiled DOP853."""
    model, _, zd = walk3
    x0 = initial_state(zd, const(model), Start())
    res = simulate(zd, const(model), SimConfig(steps=2),
                   Start(q=x0[:3], dq=np.array([np.nan, 0.0, 0.0])))
    assert not res.success and res.failure == "integrator", res.reason
    assert "DOP853 (compiled)" in res.reason and res.reason.startswith("step 1:")


def test_start_without_orbit_is_an_input_error(walk3):
    from thrustwalk_cli.errors import InputError

    model, _, zd = walk3
    with pytest.raises(InputError, match="no fixed point"):
        simulate(zd, const(model, hip_x=100.0), SimConfig(steps=1))
    assert zeta_star_at(zd, np.array([100.0, 0.0])) < 0


# ------------------------------------------------------------------------ CLI
STEP_KEYS = {"step", "step_time", "zeta_minus", "sigma_minus", "sigma_plus", "impulse",
             "thrust_at_impact", "min_vertical_force", "max_abs_output", "prediction"}


@pytest.mark.slow
def test_cli_writes_every_output(tmp_path, cli):
    out = tmp_path / "sim"
    res = cli("simulate", "--steps", "2", "--thrust", "0,-2", "--samples", "20",
                              "--animate", "--quiet", "--out", str(out))
    assert res.exit_code == 0, res.output
    for name in ("simulation.json", "steps.csv", "trajectory.csv", "thrust_time.png",
                 "thrust_time.pdf", "phase_portrait.png", "phase_portrait.pdf", "walker.gif"):
        assert (out / name).stat().st_size > 0, name
    doc = json.loads((out / "simulation.json").read_text())
    assert doc["success"] and doc["provenance"]["tool"] == "thrustwalk"
    assert [r["f_ss"] for r in doc["runs"]] == [0.0, -2.0]
    assert len(doc["steps"]) == 4
    for e in doc["steps"]:
        assert STEP_KEYS <= set(e), sorted(STEP_KEYS - set(e))
        assert abs(e["prediction"]["relative_error"]) < 1e-6, e["step"]
    lines = (out / "steps.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert {"zeta_minus_kg2m4_s2", "predicted_zeta_minus_kg2m4_s2", "thrust_hip_x_N"} <= set(
        header)
    assert doc["tables"]["steps.csv"]["columns"] == header
    assert (out / "walker.gif").read_bytes()[:6] == b"GIF89a"


# the CLI runs below draw every figure (PNG) but write no PDF: the PDFs are checked once, by
# test_cli_writes_every_output (the same figures encoded again by another matplotlib backend)
PNG_ONLY = "csv,png"


@pytest.mark.slow
def test_cli_falling_walker_exit_0_with_reason(tmp_path, cli):
    res = cli("simulate", "--thrust-model", "constant", "--thrust", "100",
                              "--start", "nominal", "--steps", "3", "--quiet", "--out",
                              str(tmp_path), "--formats", PNG_ONLY)
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "simulation.json").read_text())
    assert not doc["success"] and not doc["runs"][0]["success"]
    assert doc["runs"][0]["failure"] == "fall" and "alpha reverses" in doc["reason"]
    assert "warning: run 0" in res.output


@pytest.mark.slow
def test_cli_reduced_preview_and_npz(tmp_path, cli):
    res = cli("simulate", "--reduced", "--steps", "3", "--thrust", "0",
              "--samples", "7001", "--quiet", "--out", str(tmp_path), "--formats", PNG_ONLY)
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "simulation.json").read_text())
    assert doc["trajectory_file"] == "trajectory.npz" and doc["steps"][0]["model"] == "reduced"
    data = np.load(tmp_path / "trajectory.npz")
    assert data["t_s"].size == 21003
    assert {"alpha_rad", "sigma_kgm2_s", "thrust_hip_x_N"} <= set(data.files)


@pytest.mark.slow
def test_cli_integrator_failure_exit_1(tmp_path, monkeypatch, cli):
    real = ClosedLoop.rhs
    monkeypatch.setattr(ClosedLoop, "rhs", lambda self, t, x, seg: (
        [np.nan] * len(x) if t > 0.2 else real(self, t, x, seg)))
    res = cli("simulate", "--steps", "1", "--thrust", "0", "--method", "scipy", "--quiet",
              "--out", str(tmp_path), "--formats", PNG_ONLY)
    assert res.exit_code == 1
    assert json.loads((tmp_path / "simulation.json").read_text())["runs"][0]["failure"] == \
        "integrator"


@pytest.mark.parametrize("args, words", [
    (["--thrust-model", "bogus"], "--thrust-model"),
    (["--thrust", "500"], "outside the limits"),
    (["--wn", "0"], "--wn"),
    (["--q0", "0,0,0"], "--q0/--dq0"),
    (["--thruster", "nope"], "--thruster"),
    (["--thrust-model", "piecewise"], "thrust schedule"),
    (["--steps", "0"], "--steps"),
    (["--start", "sideways"], "--start"),
    (["--q0", "0,0", "--dq0", "0,0"], "expected 3 values"),
])
def test_cli_bad_input_one_line_exit_2(tmp_path, args, words, cli):
    res = cli("simulate", *args, "--quiet", "--out", str(tmp_path))
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and words in lines[0], res.output


@pytest.mark.slow
def test_cli_tangential_touchdown_is_a_physical_failure(tmp_path, walker_rabbit, cli):
    """The swing foot of tests/data/rabbit_tangent.yaml reaches the ground at vertical velocity
    0: there is no strike to find. The run ends as a physical ``no-impact`` failure naming
    the grazing touchdown (exit 0), not as an integrator failure of the tool (exit 1)."""
    res = cli("simulate", "rabbit", DATA / "rabbit_tangent.yaml", "--steps", "2",
              "--thrust-model", "constant", "--thrust", "0", "--quiet", "--out", tmp_path,
              "--formats", PNG_ONLY)
    assert res.exit_code == 0, res.output
    run = json.loads((tmp_path / "simulation.json").read_text())["runs"][0]
    assert not run["success"] and run["status"] == "failed", run
    assert run["failure"] == "no-impact" and "grazing" in run["reason"], run["reason"]
    assert run["predicted"]["touchdown_velocity"] == pytest.approx(0.0, abs=1e-12)
    assert "warning: run 0" in res.output


@pytest.mark.slow
def test_cli_one_value_without_orbit_does_not_spoil_the_list(tmp_path, cli):
    """F_ss = 20 N pushes the 3-link walker backwards: no periodic orbit (zeta* < 0). The other
    value still runs; the bad one is a failed run ``no-orbit`` with its reason; exit 0."""
    res = cli("simulate", "--thrust-model", "constant", "--thrust", "0,20", "--steps", "2",
              "--samples", "10", "--quiet", "--out", tmp_path, "--formats", PNG_ONLY)
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "simulation.json").read_text())
    ok, bad = doc["runs"]
    assert ok["success"] and ok["status"] == "ok" and ok["steps_completed"] == 2, ok
    assert not bad["success"] and bad["failure"] == "no-orbit" and bad["steps_completed"] == 0
    assert "no fixed point" in bad["reason"] and not bad["predicted"]["exists"]
    assert not doc["success"] and doc["status"] == "failed" and "run 1 (F_ss = 20.0)" in \
        doc["reason"]
    assert {e["run"] for e in doc["steps"]} == {0}
    assert "warning: run 1 (F_ss = 20.0)" in res.output
    for name in ("thrust_time.png", "phase_portrait.png", "steps.csv", "trajectory.csv"):
        assert (tmp_path / name).stat().st_size > 0, name


@pytest.mark.slow
def test_deviation_from_the_prediction_is_a_warning_with_reason(walker3, tmp_path, cli):
    """Started off the zero-dynamics manifold (outputs not zero), the first step's zeta^-
    misses the prediction by 0.7 %: the run completes but its status is ``warning`` and the
    reason says which step and by how much, never plain success; steps on Z agree to 1e-6.
    A tolerance on the impact's s flags the first impact (at s = 1 - 3e-7) the same way."""
    import thrustwalk_cli as tw

    th = ThrustModel("constant", np.zeros(walker3.model.n_thrusters))
    x0 = initial_state(walker3.zd, th, Start())
    q0 = (x0[:3] + np.array([0.01, -0.015, 0.0])).tolist()
    dq0 = (x0[3:6] + np.array([0.05, -0.05, 0.0])).tolist()
    res = tw.simulate(walker3, steps=3, thrust_model="constant", thrust=[0.0], q0=q0, dq0=dq0)
    doc = res.document()
    run = doc["runs"][0]
    assert run["success"] and run["status"] == "warning" and res.status == "warning"
    assert doc["status"] == "warning" and "off the zero-dynamics prediction" in doc["reason"]
    assert "step 1" in run["deviations"][0] and "-0.729" in run["deviations"][0], run
    errs = [e["prediction"]["relative_error"] for e in doc["steps"]]
    assert abs(errs[0]) > 1e-3 and max(abs(e) for e in errs[1:]) < 1e-6
    strict = tw.simulate(walker3, steps=1, thrust_model="constant", thrust=[0.0], q0=q0, dq0=dq0,
                         impact_s_tol=1e-8, zeta_tol=0.5).document()["runs"][0]
    assert strict["status"] == "warning" and "impact away from s = 1" in strict["reason"]
    on_z = tw.simulate(walker3, steps=2, thrust_model="constant", thrust=[0.0]).document()
    assert on_z["status"] == "ok" and on_z["runs"][0]["deviations"] == []
    out = cli("simulate", "--thrust-model", "constant", "--thrust", "0", "--steps", "2",
              "--q0", ",".join(map(str, q0)), "--dq0", ",".join(map(str, dq0)), "--out",
              tmp_path, "--formats", PNG_ONLY)
    assert out.exit_code == 0, out.output
    assert "ok" not in out.output.split("rel. error")[-1].split("wrote")[0]  # status column
    line = next(ln for ln in out.stderr.splitlines() if ln.startswith("warning: run 0"))
    assert line.startswith("warning: run 0 (F_ss = 0.0): ") and ": warning: " not in line
    assert "zeta^- off the zero-dynamics prediction (worst" in line


@pytest.mark.slow  # (this session's additions; CI runs every test)
def test_a_run_with_no_orbit_to_start_on_says_so(cli, tmp_path, monkeypatch, _cache_dir):
    """walker5 (a user's robot) 0.02 rad uphill: without thrust the zero dynamics has no orbit
    (the walker stops within the step; SPEC 3, checked independently by limit_cycle), yet the
    formula's zeta* is positive, so a run starts there. The run's warnings say there is no
    orbit to predict and that its start is not an orbit; a second-order thruster aiming at
    -40 N (whose orbit exists) starting from 0 N says the latter only; ideal -40 N says
    neither. The console table shows "no orbit" instead of the formula's number."""
    from thrustwalk_cli.studies.limit_cycle import limit_cycle
    from thrustwalk_cli.studies.simulate import simulate
    from thrustwalk_cli.walker import load_walker

    robot, gait = str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml")
    w = load_walker(robot, gait)
    none, pushed = limit_cycle(w, [0.0, -40.0], slope=0.02).cycles
    assert not none.exists and none.zeta_star > 0 and pushed.exists  # the formula: > 0

    def warnings(**kw):
        return simulate(w, steps=2, slope=0.02, **kw).document()["runs"][0]["warnings"]
    w0 = " ".join(warnings(thrust=[0.0], thrust_model="ideal"))
    assert "no prediction to compare with" in w0 and "not an orbit" in w0
    w2 = " ".join(warnings(thrust=[-40.0], thrust_model="second-order"))
    assert "no prediction" not in w2 and "not an orbit (0 N: no periodic orbit" in w2
    assert not any("orbit" in x for x in warnings(thrust=[-40.0], thrust_model="ideal"))
    monkeypatch.chdir(tmp_path)
    res = cli("simulate", robot, gait, "--slope", "0.02", "--thrust", "0", "--thrust-model",
              "ideal", "--steps", "2", "--formats", "none", "--out", "o")
    assert "no orbit" in res.stdout and "not an orbit" in res.output


def test_phase_curves_follow_the_orbit_where_uniform_samples_cut_corners(walk3):
    """The phase portrait's curves of a run started on the fixed point lie on the
    zero-dynamics orbit (alpha' as a function of alpha, from ``limit_cycles``, not the
    simulation) between their points too: every chord's middle within 2e-3 of the orbit's
    alpha' range. With 8 uniform samples a step (the trajectory's) the chords miss it by far
    more: the refinement is what draws the curve."""
    model, _, zd = walk3
    res = simulate(zd, const(model), replace(TIGHT, steps=2, samples_per_step=8))
    assert res.success, res.reason
    orbit = cycle(zd, np.zeros(model.n_thrusters)).orbit
    oa, od = np.asarray(orbit["alpha"]), np.asarray(orbit["alpha_dot"])
    order = np.argsort(oa)
    extent = np.ptp(od)

    def worst(a, d):  # the largest miss of a chord's middle from the orbit
        am, dm = 0.5 * (a[1:] + a[:-1]), 0.5 * (d[1:] + d[:-1])
        return np.max(np.abs(dm - np.interp(am, oa[order], od[order]))) / extent

    curves = res.phase_curves(8)
    assert len(curves) == 2
    for pieces in curves:  # a step's integration pieces, one after the other
        a = np.concatenate([p["alpha"] for p in pieces])
        d = np.concatenate([p["alpha_dot"] for p in pieces])
        assert a.size > 8 and np.all(np.diff(a) * np.sign(a[-1] - a[0]) >= 0)  # in time order
        assert worst(a, d) < 2e-3
    tr = res.trajectory
    sel = tr["step"] == 1
    assert worst(tr["alpha"][sel], tr["alpha_dot"][sel]) > 1e-2
