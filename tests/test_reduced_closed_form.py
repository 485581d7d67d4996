"""The reduced cascade's closed form for thrust without states (SPEC 3, 4; issue 26), and
its spectral solution in alpha for thrusters with linear dynamics.

For ideal thrusters and piecewise schedules the steps of the zero-dynamics cascade are
``zeta^- = zeta_start + V_Z(alpha_f) - V_Z(alpha_start)``, ``sigma^+ = delta_zero sigma^-``
and the step time ``int dalpha / (kappa_1 sigma_N)``. Checked against the time integration
of the cascade at rtol 1e-12 (the old path) and against an independent integration in alpha
(``dzeta/dalpha = (kappa_2 + beta F_T + T) / kappa_1``, ``dt/dalpha = 1 / (kappa_1 sigma_N)``,
SciPy's DOP853 on the model's terms, no V_Z series, no time events).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from thrustwalk_cli.simulation.closed_loop import ThrustModel, alpha_pieces
from thrustwalk_cli.simulation.full_order import SimConfig, Start, initial_state
from thrustwalk_cli.simulation.reduced import (
    ReducedModel,
    closed_form_steps,
    simulate_reduced,
    spectral_steps,
)
from thrustwalk_cli.simulation.scenario import Scenario, run_scenario
from thrustwalk_cli.thrust.schedule import WrittenSchedule
from thrustwalk_cli.walker import load_walker

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))


def _start(zd, th, start=Start()):
    N = zd.model.n
    x0 = initial_state(zd, th, start)
    D0 = np.array(zd.model.D_s(x0[:N].tolist())).reshape(N, N)
    return float(zd.maps.c @ x0[:N]), float(D0[N - 1] @ x0[N:2 * N])


def _piecewise(zd, mode):
    vals = ((zd.model.robot.thruster_names[0], (0.0, -3.0, 2.0)),) if mode == "force" else \
        (("T", (-2.0, 0.0, 3.0)),)
    sched = WrittenSchedule((0.0, 0.3, 0.7, 1.0), vals, mode, True)
    zd_s = replace(zd, gait=replace(zd.gait, thrust=sched))
    S = sched.resolve(zd_s, zd_s.model.robot, "thrust", pad=True)[0]
    return zd_s, ThrustModel("piecewise", np.zeros(zd.model.n_thrusters), schedule=S)


def _independent_step(zd, th, alpha0, sigma0):
    """One step integrated in alpha: (zeta^-, step time), from the model's terms only."""
    rm = ReducedModel(zd)
    breaks, forces, gens = alpha_pieces(zd, th)
    edges = [alpha0] + [zd.alpha_i + b * zd.maps.span for b in breaks
                        if zd.direction * (zd.alpha_i + b * zd.maps.span - alpha0) > 0]
    edges.append(zd.alpha_f)
    sgn = np.sign(sigma0)
    y = np.array([0.5 * sigma0**2, 0.0])
    seg0 = int(np.searchsorted(breaks, (alpha0 - zd.alpha_i) / zd.maps.span, side="right"))
    for j, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        F = forces[seg0 + j] if th.piecewise else th.force([])
        T = gens[seg0 + j]

        def f(alpha, y, F=F, T=T):
            k = rm.terms(float(alpha))
            num = k[1] + sum(bb * ff for bb, ff in zip(k[2:], F)) + T
            return [num / k[0], 1.0 / (k[0] * sgn * np.sqrt(2.0 * y[0]))]

        y = solve_ivp(f, (a, b), y, method="DOP853", rtol=1e-13, atol=1e-13).y[:, -1]
    return float(y[0]), float(y[1])


CASES = [("walker3", "ideal:0"), ("walker3", "ideal:-10"), ("walker3", "piecewise:force"),
         ("walker3", "piecewise:generalized"), ("walker5", "ideal:-20"),
         ("walker_rabbit", "ideal:-10")]


@pytest.mark.parametrize("name, kind", CASES)
def test_closed_form_equals_tight_integration_and_independent_step(request, name, kind):
    w = request.getfixturevalue(name)
    zd, m = w.zd, w.model.n_thrusters
    if kind.startswith("piecewise"):
        zd, th = _piecewise(zd, kind.split(":")[1])
    else:
        F = np.zeros(m)
        F[-1] = float(kind.split(":")[1])
        th = ThrustModel("ideal", F)
    a0, s0 = _start(zd, th, Start(perturb=0.05))
    steps = 4
    cf = closed_form_steps(zd, th, steps, a0, s0)
    ref = simulate_reduced(zd, th, steps, a0, s0, [], rtol=1e-12, atol=1e-14)
    assert cf is not None and ref.success and len(cf) == steps
    for a, b in zip(cf, ref.steps):
        for key in ("zeta_start", "zeta_minus", "zeta_plus", "sigma_minus", "sigma_plus",
                    "step_time", "t_impact"):
            assert getattr(a, key) == pytest.approx(getattr(b, key), rel=1e-10), (a.step, key)
        assert a.thrust_at_impact == pytest.approx(b.thrust_at_impact, rel=1e-12, abs=1e-12)
    z_ind, t_ind = _independent_step(zd, th, a0, s0)
    assert cf[0].zeta_minus == pytest.approx(z_ind, rel=1e-10)
    assert cf[0].step_time == pytest.approx(t_ind, rel=1e-10)


def test_closed_form_from_mid_step(walker3):
    """A start inside the step (alpha0 > alpha_i): the first step integrates from alpha0."""
    zd = walker3.zd
    th = ThrustModel("ideal", np.array([-5.0, 0.0]))
    a0 = zd.alpha_i + 0.4 * zd.maps.span
    s0 = zd.sigma_sign * 1.1 * np.sqrt(2.0 * limit_zeta(zd))
    cf = closed_form_steps(zd, th, 3, a0, s0)
    ref = simulate_reduced(zd, th, 3, a0, s0, [], rtol=1e-12, atol=1e-14)
    assert cf is not None and ref.success
    for a, b in zip(cf, ref.steps):
        assert a.zeta_minus == pytest.approx(b.zeta_minus, rel=1e-10)
        assert a.step_time == pytest.approx(b.step_time, rel=1e-10)
    z_ind, t_ind = _independent_step(zd, th, a0, s0)
    assert cf[0].zeta_minus == pytest.approx(z_ind, rel=1e-10)
    assert cf[0].step_time == pytest.approx(t_ind, rel=1e-10)


def limit_zeta(zd):
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule

    return limit_cycles(zd, Schedule.constant(zd, np.zeros((1, zd.model.n_thrusters))))[0] \
        .zeta_star


def test_falling_cascade_falls_back_to_the_integration(walker3):
    """A thrust the walker cannot pass the barrier with: no closed form; the integration
    reports the fall, with or without a time history."""
    zd = walker3.zd
    th = ThrustModel("ideal", np.array([100.0, 0.0]))
    a0, s0 = _start(zd, ThrustModel("ideal", np.zeros(2)))
    assert closed_form_steps(zd, th, 3, a0, s0) is None
    a = simulate_reduced(zd, th, 3, a0, s0, [], trajectory=False)
    b = simulate_reduced(zd, th, 3, a0, s0, [])
    assert not a.success and a.failure == b.failure == "fall"
    assert a.reason == b.reason and a.nfev > 0


def test_scenario_takes_the_closed_form_only_without_a_time_history(walker3):
    """Beside a full-order run the cascade is the closed form (no right-hand side
    evaluations, no trajectory); the reduced-only preview still integrates (its time
    history is the output), and both give the same steps to the integration's tolerance."""
    zd = walker3.zd
    cfg = SimConfig(steps=3)
    sc = Scenario("ideal", (-10.0,), (0,), config=cfg)
    full = run_scenario(zd, sc)[0]
    prev = run_scenario(zd, replace(sc, reduced_only=True))[0]
    assert full.reduced.success and full.reduced.nfev == 0 and full.reduced.trajectory == {}
    assert prev.reduced.nfev > 0 and prev.reduced.trajectory["t"].size > 0
    for a, b in zip(full.reduced.steps, prev.reduced.steps):
        assert a.zeta_minus == pytest.approx(b.zeta_minus, rel=1e-7)
        assert a.step_time == pytest.approx(b.step_time, rel=1e-7)
    for c, st in zip(full.comparison, full.reduced.steps):
        assert c["reduced_zeta_minus"] == st.zeta_minus
        assert c["reduced_step_time"] == st.step_time


@pytest.mark.parametrize("kind", ["ideal", "first-order", "second-order"])
def test_thrust_rows_equal_thrust_bit_for_bit(kind):
    from thrustwalk_cli.thrust.dynamics import make

    dyn = make(kind, 2, tau=0.3, wn=3.0, xi=0.7)
    Z = np.random.default_rng(1).normal(size=(7, dyn.n_states)) * 10
    u = [-3.3, 7.1]
    rows = dyn.thrust_rows(Z, u)
    for z, r in zip(Z, rows):
        assert r.tolist() == dyn.thrust(z.tolist(), u)


def test_dense_rows_equal_each_solution_bit_for_bit(walker_rabbit):
    """The trajectory's batched evaluation of the kernel's dense output is the per-piece
    evaluation, number for number (pieces of several steps, nodes and ends included)."""
    from thrustwalk_cli.simulation.full_order import dense_rows, simulate
    from thrustwalk_cli.simulation.stepper import DenseSolution

    zd = walker_rabbit.zd
    res = simulate(zd, ThrustModel("ideal", np.zeros(zd.model.n_thrusters)), SimConfig(steps=2))
    parts = []
    for s in res.segments:
        assert isinstance(s.sol, DenseSolution)
        parts.append((s.sol, np.r_[s.t0, np.linspace(s.t0, s.t1, 9), s.sol.t_new, s.t1]))
    got = dense_rows(parts)
    want = np.vstack([sol(tt).T for sol, tt in parts])
    assert got.shape == want.shape and np.array_equal(got, want)


def test_predicted_cycle_is_kept_per_schedule(walker3):
    from thrustwalk_cli.simulation.closed_loop import predicted_cycle

    zd = walker3.zd
    a = predicted_cycle(zd, ThrustModel("ideal", np.array([-5.0, 0.0])))
    b = predicted_cycle(zd, ThrustModel("first-order", np.array([-5.0, 0.0])))
    c = predicted_cycle(zd, ThrustModel("ideal", np.array([-6.0, 0.0])))
    assert a is b and c is not a and c.zeta_star != a.zeta_star


def _independent_dynamic_step(zd, th, alpha0, sigma0, z0):
    """One step of the cascade with thruster states, integrated in alpha (zeta, t, z):
    ``dz/dalpha = z' / alpha'``, from the model's terms and the thrusters' rates only."""
    rm = ReducedModel(zd)
    sgn = np.sign(sigma0)

    def f(alpha, y):
        k = rm.terms(float(alpha))
        z = y[2:].tolist()
        F = th.force(z)
        sigma = sgn * np.sqrt(2.0 * y[0])
        adot = k[0] * sigma
        dzeta = sigma * (k[1] + sum(b * ff for b, ff in zip(k[2:], F))) / adot
        return [dzeta, 1.0 / adot] + [r / adot for r in th.derivatives(z)]

    y0 = [0.5 * sigma0**2, 0.0] + list(z0)
    y = solve_ivp(f, (alpha0, zd.alpha_f), y0, method="DOP853", rtol=1e-13,
                  atol=1e-13).y[:, -1]
    return float(y[0]), float(y[1]), th.force(y[2:].tolist())


DYNAMIC = [("walker3", "first-order", {"tau": 0.4}), ("walker3", "second-order", {}),
           ("walker5", "second-order", {"wn": 3.0, "xi": 0.6}),
           ("walker_rabbit", "first-order", {"tau": 0.2})]


@pytest.mark.parametrize("name, kind, params", DYNAMIC)
def test_spectral_steps_equal_tight_integration_and_independent_step(request, name, kind,
                                                                      params):
    w = request.getfixturevalue(name)
    zd, m = w.zd, w.model.n_thrusters
    F = np.zeros(m)
    F[-1] = -15.0
    th = ThrustModel(kind, F, **params)
    a0, s0 = _start(zd, th, Start(perturb=0.05))
    z0 = th.initial_states()
    steps = 3
    sp = spectral_steps(zd, th, steps, a0, s0, z0)
    ref = simulate_reduced(zd, th, steps, a0, s0, z0, rtol=1e-12, atol=1e-14)
    assert sp is not None and ref.success
    for a, b in zip(sp, ref.steps):
        for key in ("zeta_minus", "sigma_plus", "step_time", "t_impact"):
            assert getattr(a, key) == pytest.approx(getattr(b, key), rel=1e-10), (a.step, key)
        np.testing.assert_allclose(a.thrust_at_impact, b.thrust_at_impact, rtol=1e-9,
                                   atol=1e-9)
    z_ind, t_ind, F_ind = _independent_dynamic_step(zd, th, a0, s0, z0)
    assert sp[0].zeta_minus == pytest.approx(z_ind, rel=1e-10)
    assert sp[0].step_time == pytest.approx(t_ind, rel=1e-10)
    np.testing.assert_allclose(sp[0].thrust_at_impact, F_ind, rtol=1e-9, atol=1e-9)


def test_step_prediction_of_dynamic_thrust_starts_off_alpha_i(walker3):
    """The per-step prediction starts from the simulated post-impact state, a little off
    alpha_i: the spectral steps take it (and agree with the time integration)."""
    zd = walker3.zd
    th = ThrustModel("second-order", np.array([-8.0, 0.0]))
    a0, s0 = _start(zd, th)
    z0 = th.initial_states()
    for da in (-1e-3, 2e-3):
        a = a0 + da * zd.maps.span
        sp = spectral_steps(zd, th, 1, a, s0, z0)
        ref = simulate_reduced(zd, th, 1, a, s0, z0, rtol=1e-12, atol=1e-14)
        assert sp is not None
        assert sp[0].zeta_minus == pytest.approx(ref.steps[0].zeta_minus, rel=1e-10)
        assert sp[0].step_time == pytest.approx(ref.steps[0].step_time, rel=1e-10)
