"""The thruster family (thrust/dynamics.py, SPEC 7, 11, 13) and thrust schedules
(thrust/schedule.py, SPEC 4).

The models are checked against the textbook equations they stand for (the servo form's
arithmetic is the classic formulas' to the last bit; its standard form and closed-form
responses are the matrix exponential's), and a thruster model defined through
thrust/dynamics.py alone (a first-order lag with a different time constant per thruster,
registered in the option table ``MODELS``) runs through the compiled simulation and the
Floquet analysis: its thrust is the lag's analytic response and its Floquet multipliers are
``eig(exp(A T*))`` (SPEC 13; T* the step time of the orbit), because the thruster's dynamics
do not depend on the walker.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

import thrustwalk_cli as tw
from thrustwalk_cli.errors import InputError
from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.thrust import dynamics as D
from thrustwalk_cli.thrust.schedule import Schedule, WrittenSchedule, thrust_on

SERVOS = [D.second_order_servo(20.0, 1.0), D.second_order_servo(3.0, 0.3),
          D.second_order_servo(5.0, 2.5), D.first_order_servo(0.3),
          D.state_space_servo([[0.0, 1.0], [-9.0, -1.2]], [0.0, 9.0], [1.0, 0.0])]


@pytest.mark.parametrize("servo", SERVOS)
def test_thruster_response_equals_the_matrix_exponential(servo):
    """Phi = C e^{A t}, Psi = C int_0^t e^{A s} ds B + D (SPEC 11), closed form or not."""
    A, B, C = servo.A, servo.B, servo.c
    t = np.linspace(0.0, 1.5, 9)
    Phi, Psi = servo.response(t)
    k = A.shape[0]
    aug = np.zeros((k + 1, k + 1))
    aug[:k, :k], aug[:k, k] = A, B
    E = np.array([expm(tt * aug) for tt in t])
    np.testing.assert_allclose(Phi, E[:, :k, :k].transpose(0, 2, 1) @ C, atol=1e-12)
    np.testing.assert_allclose(Psi, E[:, :k, k] @ C + servo.d, atol=1e-12)


def test_servo_form_is_the_classic_equations_bit_for_bit():
    """The rates the kernel and the Python paths compute are the classic models' formulas,
    operation for operation: tau F' = u - F and F'' = wn^2 (u - F) - 2 xi wn F'."""
    rng = np.random.default_rng(3)
    wn, xi, tau = 2.7, 0.63, 0.37
    second, first = D.second_order(3, wn, xi), D.first_order(3, tau)
    w2, d = wn * wn, 2.0 * xi * wn
    for _ in range(20):
        z = rng.normal(0, 30, 6).tolist()
        u = rng.normal(0, 30, 3).tolist()
        assert second.rates(z, u) == z[3:] + [w2 * (u[k] - z[k]) - d * z[3 + k]
                                              for k in range(3)]
        assert first.rates(z[:3], u) == [(u[k] - z[k]) / tau for k in range(3)]
        assert second.thrust(z, u) == z[:3] and first.thrust(z[:3], u) == z[:3]
        assert D.ideal(3).thrust([], u) == u


def test_rows_are_the_single_state_arithmetic_bit_for_bit():
    """``rates_rows`` / ``thrust_rows`` (the vectorised paths of the Floquet analysis and the
    sampling) equal ``rates`` / ``thrust`` row by row to the last bit, for a mixed stack of
    servos (ideal, first-, second-order, a general state-space one), and ``rates`` equals the
    standard form ``A z + B u`` to rounding."""
    rng = np.random.default_rng(5)
    dyn = D.ThrusterDynamics("mixed", (D.ideal_servo(), *SERVOS))
    A, B, _, _ = dyn.matrices()
    Z = rng.normal(0, 30, (25, dyn.n_states))
    u = rng.normal(0, 30, dyn.m).tolist()
    rows = dyn.rates_rows(Z, u)
    assert rows.tolist() == [dyn.rates(z, u) for z in Z.tolist()]
    assert dyn.thrust_rows(Z, u).tolist() == [dyn.thrust(z, u) for z in Z.tolist()]
    np.testing.assert_allclose(rows, Z @ A.T + np.asarray(u) @ B.T, rtol=1e-12, atol=1e-9)


def test_stacked_standard_form_of_the_second_order_thruster():
    """z = (F_1, F_2, F_1', F_2'): A = [[0, I], [-wn^2 I, -2 xi wn I]], B = [0; wn^2 I]."""
    wn, xi = 2.0, 0.7
    A, B, C, Dm = D.second_order(2, wn, xi).matrices()
    I2 = np.eye(2)
    np.testing.assert_array_equal(A, np.block([[0 * I2, I2], [-wn**2 * I2, -2 * xi * wn * I2]]))
    np.testing.assert_array_equal(B, np.vstack([0 * I2, wn**2 * I2]))
    np.testing.assert_array_equal(C, np.hstack([I2, 0 * I2]))
    np.testing.assert_array_equal(Dm, 0 * I2)
    assert D.second_order(2, wn, xi).state_names(["a", "b"]) == ["F_a", "F_b", "F_a'", "F_b'"]


def test_constant_is_the_deprecated_name_of_ideal():
    assert D.canonical("constant") == "ideal"
    assert D.make("constant", 2).kind == "ideal"
    with pytest.raises(tw.InputError, match="thrust_model: unknown model"):
        D.make("third-order", 2)


def test_written_schedule_resolves_to_the_schedule_on_alpha(walker3):
    """A written section (fractions, by name, partial) becomes knots in alpha, zero-padded."""
    zd = walker3.zd
    ws = WrittenSchedule((0.25, 0.75), (("torso_back", (-5.0,)),))
    s, fr = ws.resolve(zd, walker3.robot, "thrust", pad=True)
    assert fr == [0.0, 0.25, 0.75, 1.0]
    span = zd.alpha_f - zd.alpha_i
    np.testing.assert_allclose(s.knots, zd.alpha_i + np.array(fr) * span, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(s.force[0], [[0.0, 0.0], [0.0, -5.0], [0.0, 0.0]])
    np.testing.assert_array_equal(Schedule.on_thruster(zd, [1.0, 2.0], 1, 2).force[:, 0],
                                  thrust_on([1.0, 2.0], 1, 2))


# ---------------------------------------------------------- a model added in dynamics.py only
TAU_FACTOR = (1.0, 3.0)  # hip_x lags by tau, torso_back by 3 tau


def lag_per_thruster(m: int, tau: float) -> D.ThrusterDynamics:
    """A first-order lag with its own time constant per thruster."""
    return D.ThrusterDynamics("lag-each", tuple(D.first_order_servo(tau * TAU_FACTOR[t])
                                                for t in range(m)))


@pytest.fixture
def lag_each(monkeypatch):
    """The new model in the option table (for this test only)."""
    monkeypatch.setitem(D.MODELS, "lag-each", D.Model(("tau",), lag_per_thruster,
                                                      "tau_t F_t' = u_t - F_t"))
    return "lag-each"


def test_a_new_thruster_model_simulates_as_its_analytic_lag(walker3, lag_each):
    """Each thruster's thrust at every impact is F_ss (1 - exp(-t/tau_t)) from F(0) = 0: the
    compiled kernel integrates the new model from its data alone."""
    tau, F = 0.2, -10.0
    res = tw.simulate(walker3, steps=3, thrust_model=lag_each, thrust=[F], tau=tau,
                      thruster=["hip_x", "torso_back"], samples=5)
    run = res.outcomes[0].full
    assert run.success, run.reason
    for st in run.steps:
        want = [F * (1.0 - np.exp(-st.t_impact / (tau * f))) for f in TAU_FACTOR]
        np.testing.assert_allclose(st.thrust_at_impact, want, rtol=0, atol=1e-7)
    doc = res.document()
    assert doc["settings"]["thrust_model"] == "lag-each"


@pytest.mark.slow
def test_a_new_thruster_model_has_the_floquet_multipliers_of_exp_AT(walker3, lag_each):
    """SPEC 13: at the equilibrium thrust the Jacobian is block-triangular, so the thruster's
    multipliers are eig(exp(A T*)) = exp(-T*/tau_t), to the stability verdict's tolerance."""
    tau, F = 0.15, -10.0
    res = tw.stability(walker3, thrust_model=lag_each, thrust=F, tau=tau)
    f = res.cases[0].floquet
    assert f.verdict == "stable", f.reason
    zd = walker3.zd
    T = limit_cycles(zd, Schedule.constant(zd, np.array([[F, 0.0]])))[0].step_time
    A = lag_per_thruster(2, tau).matrices()[0]
    expected = np.sort(np.linalg.eigvals(expm(A * T)).real)
    got = np.sort([m.value.real for m in f.multipliers if m.kind == "thruster"])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)
    assert [m.value.imag for m in f.multipliers if m.kind == "thruster"] == [0.0, 0.0]
    names = res.document()["cases"][0]["state_names"]
    assert names[-2:] == ["F_hip_x", "F_torso_back"]


def test_the_stiffness_bound_reads_any_model_of_the_family(walker3, monkeypatch):
    """The 1 ms bound on a thruster model's fastest pole (MAX_THRUSTER_RATE): the classic
    models' closed forms are max |eig(A)| of their matrices, and a model added in dynamics.py
    alone is bounded by max |eig(A)| over the robot's thrusters, refused up front naming its
    parameter (here a lag whose second thruster is 3 times faster: 1/tau = 500 1/s and
    3/tau = 1500 1/s)."""
    from thrustwalk_cli.simulation.closed_loop import (
        MAX_THRUSTER_RATE,
        check_thruster_rate,
        thruster_rate,
    )

    for kind, wn, xi, tau in (("first-order", 2.0, 1.0, 0.01), ("second-order", 30.0, 0.4, 0.5),
                              ("second-order", 30.0, 2.5, 0.5)):
        A = D.make(kind, 1, wn=wn, xi=xi, tau=tau).matrices()[0]
        assert thruster_rate(kind, wn, xi, tau) == pytest.approx(
            np.max(np.abs(np.linalg.eigvals(A))), rel=1e-12)

    def fast_second(m: int, tau: float) -> D.ThrusterDynamics:
        return D.ThrusterDynamics("lag-fast", tuple(D.first_order_servo(tau / (1.0 + 2.0 * t))
                                                    for t in range(m)))

    monkeypatch.setitem(D.MODELS, "lag-fast", D.Model(("tau",), fast_second, "lags"))
    assert thruster_rate("lag-fast", 2.0, 1.0, 0.002, m=2) == pytest.approx(1500.0)
    check_thruster_rate("lag-fast", 2.0, 1.0, 3.0 / MAX_THRUSTER_RATE * 1.01, m=2)
    with pytest.raises(tw.InputError, match="tau: a thruster with a 0.667 ms"):
        tw.simulate(walker3, steps=1, thrust_model="lag-fast", thrust=[-10.0], tau=0.002,
                    thruster=["hip_x", "torso_back"])


# ---------------------------------------------------------- a model given as an object
def test_a_model_built_once_is_passed_as_an_object(walker3):
    """tw.thruster_dynamics(...) (or a ThrusterDynamics made by hand, without touching the
    option table) passed as thrust_model: the same run as the model by name, the document
    naming the object's kind and poles instead of the unused wn/xi/tau."""
    F = -10.0
    dyn = tw.thruster_dynamics("first-order", 2, tau=0.3)
    by_object = tw.simulate(walker3, steps=3, thrust_model=dyn, thrust=[F], samples=5)
    by_name = tw.simulate(walker3, steps=3, thrust_model="first-order", tau=0.3, thrust=[F],
                          samples=5)
    a, b = by_object.outcomes[0].full.steps, by_name.outcomes[0].full.steps
    assert [s.zeta_minus for s in a] == [s.zeta_minus for s in b]  # bit for bit
    st = by_object.document()["settings"]
    assert st["tau"] is None and st["thruster_dynamics"]["kind"] == "first-order"
    np.testing.assert_allclose(st["thruster_dynamics"]["poles"], [[-1 / 0.3, 0.0]] * 2)
    # a model that is in no option table: the analytic lag of each thruster
    lag = lag_per_thruster(2, 0.2)
    res = tw.simulate(walker3, steps=2, thrust_model=lag, thrust=[F],
                      thruster=["hip_x", "torso_back"], samples=5)
    for s in res.outcomes[0].full.steps:
        want = [F * (1.0 - np.exp(-s.t_impact / (0.2 * f))) for f in TAU_FACTOR]
        np.testing.assert_allclose(s.thrust_at_impact, want, rtol=0, atol=1e-7)
    assert res.document()["settings"]["thrust_model"] == "lag-each"


def test_a_model_object_for_another_robot_or_too_fast_is_refused(walker3):
    with pytest.raises(InputError, match="thrust_model: thruster dynamics for 3 thruster"):
        tw.simulate(walker3, steps=1, thrust_model=tw.thruster_dynamics("ideal", 3))
    fast = lag_per_thruster(2, 1e-4)
    with pytest.raises(InputError, match="thrust_model: poles up to"):
        tw.stability(walker3, thrust_model=fast, thrust=-10.0)


@pytest.mark.slow
def test_stability_of_a_model_object_equals_the_model_by_name(walker3):
    dyn = tw.thruster_dynamics("first-order", 2, tau=0.2)
    a = tw.stability(walker3, thrust_model=dyn, thrust=-10.0)
    b = tw.stability(walker3, thrust_model="first-order", tau=0.2, thrust=-10.0)
    va = sorted(abs(m.value) for m in a.cases[0].floquet.multipliers)
    vb = sorted(abs(m.value) for m in b.cases[0].floquet.multipliers)
    assert va == vb
    assert a.document()["settings"]["thruster_dynamics"]["kind"] == "first-order"


def test_control_takes_a_model_object(walker3):
    """control with tw.thruster_dynamics(...) runs the same plant and controller as the model
    by name (bit for bit); the document records the object's kind and poles."""
    kw = dict(reference="nominal", steps=3, knots=[0.0, 1.0], compare=False)
    dyn = tw.thruster_dynamics("first-order", 2, tau=0.1)
    a = tw.control(walker3, thrust_model=dyn, **kw)
    b = tw.control(walker3, thrust_model="first-order", tau=0.1, **kw)
    da, db = a.document(), b.document()
    za = [s["zeta_minus_end"] for s in da["steps"]]
    zb = [s["zeta_minus_end"] for s in db["steps"]]
    assert za == zb and len(za) == 3
    td = da["settings"]["thruster_dynamics"]
    assert td["kind"] == "first-order" and td["poles"] == [[-10.0, 0.0]] * 2
    with pytest.raises(InputError, match="thrust_model: thruster dynamics for 3"):
        tw.control(walker3, thrust_model=tw.thruster_dynamics("ideal", 3), **kw)
