"""The batch entry point (SPEC 7, 12): many compiled runs in one call agree with single runs
of the SciPy reference, threads do not change results, pushes are ``q' += D^-1 J_p^T P``."""

from __future__ import annotations

import numpy as np
import pytest

from thrustwalk_cli.simulation.batch import push_row, simulate_batch, start_states
from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
from thrustwalk_cli.simulation.full_order import Start, simulate


@pytest.fixture(scope="module")
def setup(walker3):
    zd = walker3.zd
    th = ThrustModel("constant", np.zeros(walker3.model.n_thrusters))
    starts = [Start(perturb=p) for p in (-0.9, -0.1, 0.0, 0.15, 0.3)]
    return walker3, zd, th, starts, start_states(zd, th, starts)


def test_batch_runs_equal_single_reference_runs(setup):
    walker, zd, th, starts, X0 = setup
    cfg = SimConfig(steps=3)
    targets = np.zeros((len(starts), 2))
    targets[:, 0] = [0.0, -2.0, 0.0, 3.0, -1.0]
    res = simulate_batch(zd, th, X0, cfg, targets=targets, workers=2, chunk=1)
    for r in range(len(starts)):
        ref = simulate(zd, ThrustModel("constant", targets[r]), SimConfig(steps=3,
                       method="scipy"), Start(q=X0[r, :3], dq=X0[r, 3:6]))
        assert bool(res.success[r]) == ref.success, (r, ref.reason, res.reason[r])
        assert res.failure[r] == ref.failure, r
        assert res.steps_completed[r] == len(ref.steps), r
        z = res.field("zeta_minus")[r]
        for j, s in enumerate(ref.steps):
            assert z[j] == pytest.approx(s.zeta_minus, rel=1e-9), (r, j)
        if not ref.success:
            assert res.failed_step[r] == len(ref.steps) + 1
            assert np.isnan(z[len(ref.steps):]).all()
        recs = res.step_records(r)
        assert [s.step for s in recs] == [s.step for s in ref.steps]


def test_threads_do_not_change_results(setup):
    _, zd, th, _, X0 = setup
    cfg = SimConfig(steps=2)
    a = simulate_batch(zd, th, X0, cfg, workers=1)
    b = simulate_batch(zd, th, X0, cfg, workers=2, chunk=1)
    np.testing.assert_array_equal(a.records, b.records)
    np.testing.assert_array_equal(a.final_state, b.final_state)
    assert a.reason == b.reason


def test_gains_and_pre_impact_states(setup):
    walker, zd, th, _, X0 = setup
    cfg = SimConfig(steps=1)
    gains = np.array([[400.0, 40.0], [900.0, 60.0]])
    res = simulate_batch(zd, th, X0[2:4], cfg, gains=gains)
    assert res.success.all()
    xm = res.state_minus()[:, 0]
    model = walker.model
    for r in range(2):
        imp = model.impact(xm[r, :3], xm[r, 3:6])  # the next start is the impact of x^-
        np.testing.assert_allclose(res.final_state[r, :3], imp.q_plus, atol=1e-12)
        np.testing.assert_allclose(res.final_state[r, 3:6], imp.dq_plus, rtol=1e-10,
                                   atol=1e-10)
    # other gains, other transient: the outputs start at zero on Z, so only rounding differs
    assert res.field("max_abs_output")[:, 0].max() < 1e-8


def test_push_at_step_start_is_the_impulse_map(setup):
    """A push at s <= s_start of step 1 equals starting from q'^+ + D^-1 J_p^T P, J_p from
    the model's link-point Jacobian (hip = end of the stance link)."""
    walker, zd, th, _, X0 = setup
    model = walker.model
    cfg = SimConfig(steps=2)
    P = np.array([6.0, -2.0])
    x = X0[2].copy()
    q = x[:3]
    J = model.link_points_J(q).reshape(-1, 2, 3)[1]  # rows 2, 3: the stance link's end
    x_pushed = x.copy()
    x_pushed[3:6] += np.linalg.solve(model.D(q), J.T @ P)
    pushes = np.array([push_row(model, 1, -1.0, P), np.full(6, -1.0)])
    res = simulate_batch(zd, th, np.array([x, x_pushed]), cfg, pushes=pushes)
    assert res.success.all(), res.reason
    np.testing.assert_allclose(res.field("zeta_minus")[0], res.field("zeta_minus")[1],
                               rtol=1e-10)
    assert res.field("pushed")[0, 0] == 1.0 and res.field("pushed")[1, 0] == 0.0
    ref = simulate(zd, th, SimConfig(steps=2, method="scipy"),
                   Start(q=x_pushed[:3], dq=x_pushed[3:6]))
    np.testing.assert_allclose(res.field("zeta_minus")[0], [s.zeta_minus for s in ref.steps],
                               rtol=1e-9)


def test_push_mid_step_changes_the_run_and_zero_push_does_not(setup):
    """A forward push at the hip mid-step adds angular momentum about the stance foot, a
    backward one removes it; either way the walker returns toward zeta* at delta_zero^2."""
    walker, zd, th, _, X0 = setup
    model = walker.model
    cfg = SimConfig(steps=3)
    X = np.repeat(X0[2:3], 4, axis=0)
    pushes = np.array([np.full(6, -1.0), push_row(model, 2, 0.4, (0.0, 0.0)),
                       push_row(model, 2, 0.4, (3.0, 0.0)),
                       push_row(model, 2, 0.4, (-3.0, 0.0))])
    res = simulate_batch(zd, th, X, cfg, pushes=pushes)
    assert res.success.all(), res.reason
    z = res.field("zeta_minus")
    np.testing.assert_allclose(z[1], z[0], rtol=1e-12)
    assert z[2, 0] == z[0, 0] == z[3, 0]
    assert z[2, 1] > z[0, 1] * 1.02 and z[3, 1] < z[0, 1] * 0.98
    zs = z[0, 0]
    for r in (2, 3):
        assert abs(z[r, 2] - zs) < abs(z[r, 1] - zs)
    with pytest.raises(Exception, match="unknown link"):
        push_row(model, 1, 0.5, (1.0, 0.0), link="tail")
