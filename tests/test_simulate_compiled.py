"""The compiled full-order simulation against the SciPy reference (SPEC 7).

The SciPy path (``method="scipy"``: ``solve_ivp`` with Python event functions) is the
independent computation: every step's zeta^- must agree to 1e-9 relative on both bundled
robots and every thrust model, every failure must be detected at the same step with the same
kind, and the step statistics must agree. The kernel is compiled once per machine (the robot
is its tape) and cached: a second process loads it without compiling.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
from thrustwalk_cli.simulation.full_order import Start, initial_state, simulate
from thrustwalk_cli.thrust.schedule import WrittenSchedule

REL = 1e-9  # zeta^- agreement between the methods (the requirement)


def _piecewise(walker, mode: str):
    """A walker whose gait carries a piecewise schedule (force or generalised mode)."""
    zd, gait = walker.zd, walker.gait
    name = walker.robot.thruster_names[0]
    vals = ((name, (0.0, -3.0, 2.0)),) if mode == "force" else (("T", (-2.0, 0.0, 3.0)),)
    sched = WrittenSchedule((0.0, 0.3, 0.7, 1.0), vals, mode, True)
    zd_s = replace(zd, gait=replace(gait, thrust=sched))
    S = sched.resolve(zd_s, zd_s.model.robot, "thrust", pad=True)[0]
    return zd_s, ThrustModel("piecewise", np.zeros(walker.model.n_thrusters), schedule=S)


def _thrust(walker, kind: str):
    m = walker.model.n_thrusters
    F = np.zeros(m)
    F[0] = -4.0
    if kind == "constant":
        return walker.zd, ThrustModel("constant", F)
    if kind == "first-order":
        return walker.zd, ThrustModel("first-order", F, tau=0.3)
    if kind == "second-order":
        return walker.zd, ThrustModel("second-order", F, wn=3.0, xi=0.7)
    return _piecewise(walker, kind.split(":")[1])


def _compare(ref, got):
    assert got.success == ref.success, (ref.reason, got.reason)
    assert got.failure == ref.failure, (ref.reason, got.reason)
    assert len(got.steps) == len(ref.steps), (ref.reason, got.reason)
    if ref.failure:
        assert got.reason.split(":")[0] == ref.reason.split(":")[0], (ref.reason, got.reason)
    for a, b in zip(ref.steps, got.steps):
        assert b.zeta_minus == pytest.approx(a.zeta_minus, rel=REL), a.step
        assert b.step_time == pytest.approx(a.step_time, rel=1e-9, abs=1e-12), a.step
        assert b.sigma_plus == pytest.approx(a.sigma_plus, rel=1e-9), a.step
        assert b.min_vertical_force == pytest.approx(a.min_vertical_force, rel=1e-7), a.step
        assert b.max_abs_torque == pytest.approx(a.max_abs_torque, rel=1e-7, abs=1e-9), a.step
        assert b.impulse == pytest.approx(a.impulse, rel=1e-8), a.step
        assert b.thrust_at_impact == pytest.approx(a.thrust_at_impact, rel=1e-9, abs=1e-12)
        assert b.torque_saturated == a.torque_saturated, a.step


KINDS = ["constant", "first-order", "second-order", "piecewise:force", "piecewise:generalized"]


@pytest.mark.parametrize("kind", KINDS)
def test_three_link_both_methods_agree_for_every_thrust_model(walker3, kind):
    zd, th = _thrust(walker3, kind)
    cfg = SimConfig(steps=3, rtol=1e-9, atol=1e-9)
    start = Start(perturb=0.1)
    ref = simulate(zd, th, replace(cfg, method="scipy"), start)
    got = simulate(zd, th, cfg, start)
    assert ref.success, ref.reason
    _compare(ref, got)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_rabbit_both_methods_agree_for_every_thrust_model(walker_rabbit, kind):
    zd, th = _thrust(walker_rabbit, kind)
    cfg = SimConfig(steps=2, rtol=1e-9, atol=1e-9)
    start = Start(perturb=0.05)
    ref = simulate(zd, th, replace(cfg, method="scipy"), start)
    got = simulate(zd, th, cfg, start)
    assert ref.success, ref.reason
    _compare(ref, got)


def test_rabbit_constant_thrust_both_methods_agree(walker_rabbit):
    zd, th = _thrust(walker_rabbit, "constant")
    cfg = SimConfig(steps=2, rtol=1e-9, atol=1e-9)
    _compare(simulate(zd, th, replace(cfg, method="scipy")), simulate(zd, th, cfg))


def test_dense_output_and_trajectory_match_the_reference(walker3):
    zd, th = _thrust(walker3, "second-order")
    cfg = SimConfig(steps=2, samples_per_step=30)
    ref = simulate(zd, th, replace(cfg, method="scipy"))
    got = simulate(zd, th, cfg)
    for key in ("q", "dq", "F", "F1", "u"):
        np.testing.assert_allclose(got.trajectory[key], ref.trajectory[key], rtol=1e-7,
                                   atol=1e-7, err_msg=key)
    t = np.linspace(got.steps[1].t_start, got.steps[1].t_impact, 17)
    np.testing.assert_allclose(got.sample(2, t)["q"], ref.sample(2, t)["q"], atol=1e-9)


def _failing(walker, case):
    zd, model = walker.zd, walker.model
    m = model.n_thrusters
    F = np.zeros(m)
    if case == "reverse":
        F[0] = 100.0
        return zd, ThrustModel("constant", F), Start(orbit="nominal"), SimConfig(steps=4)
    if case == "slow":
        return zd, ThrustModel("constant", F), Start(perturb=-0.9), SimConfig(steps=4)
    if case == "force":
        F[0] = -120.0
        return zd, ThrustModel("constant", F), Start(orbit="nominal"), SimConfig(steps=4)
    x0 = initial_state(zd, ThrustModel("constant", F), Start())
    dq2 = {"below": 0.2, "early": -0.2}[case]
    st = Start(q=x0[:3] + np.array([0.0, dq2, 0.0]), dq=x0[3:6] + np.array([0.0, 3.0, 0.0]))
    # early: the foot touches the ground before the guard is armed (s = min_impact_s); with a
    # tight scuff tolerance that touch is a scuff (an early strike)
    cfg = SimConfig(steps=2, scuff_tol=1e-9) if case == "early" else SimConfig(steps=2)
    return zd, ThrustModel("constant", F), st, cfg


@pytest.mark.parametrize("case", ["reverse", "slow", "force", "below", "early"])
def test_failures_are_detected_at_the_same_step_with_the_same_kind(walker3, case):
    zd, th, start, cfg = _failing(walker3, case)
    ref = simulate(zd, th, replace(cfg, method="scipy"), start)
    got = simulate(zd, th, cfg, start)
    assert not ref.success
    _compare(ref, got)
    words = ref.reason.split(" at t =")[0].split(" (")[0]
    assert words[:40] in got.reason, (ref.reason, got.reason)


@pytest.mark.parametrize("limit, perturb", [(25.0, 0.0), (20.0, 0.2)])
def test_torque_saturation_matches_the_reference(walker3, limit, perturb):
    """Saturated torques (the walker completes its steps at 25 N m, scuffs at 20 N m)."""
    zd = walker3.zd
    th = ThrustModel("constant", np.zeros(walker3.model.n_thrusters))
    cfg = SimConfig(steps=2, torque_limit=limit)
    ref = simulate(zd, th, replace(cfg, method="scipy"), Start(perturb=perturb))
    got = simulate(zd, th, cfg, Start(perturb=perturb))
    assert ref.success == (limit == 25.0), ref.reason
    if ref.success:
        assert all(s.torque_saturated for s in ref.steps), "the case must saturate"
    _compare(ref, got)


def test_first_cone_exits_are_timed_alike_and_where_the_force_crosses(walker3):
    """A step's first F_1^v <= cone_eps and first |F_1^h| > cone_mu F_1^v (a cone narrower
    than the gait's, so both happen late in each step): both methods give the same time and
    phase, and there the reference's dense stance force is on the boundary (F^v = eps,
    |F^h| = mu F^v), inside it 1e-6 s before."""
    zd = walker3.zd
    th = ThrustModel("constant", np.zeros(walker3.model.n_thrusters))
    cfg = SimConfig(steps=2, cone_mu=0.25, cone_eps=280.0)
    ref = simulate(zd, th, replace(cfg, method="scipy"), Start(perturb=0.1))
    got = simulate(zd, th, cfg, Start(perturb=0.1))
    assert ref.success and got.success
    for a, b in zip(ref.steps, got.steps):
        for name in ("low_force_at", "cone_exit_at"):
            ta, sa = getattr(a, name)
            tb, sb = getattr(b, name)
            assert tb == pytest.approx(ta, abs=1e-9) and sb == pytest.approx(sa, abs=1e-9)
            assert a.t_start < ta < a.t_impact
            F = ref.sample(a.step, np.array([ta - 1e-6, ta]))["F1"]
            if name == "low_force_at":
                assert F[1, 1] == pytest.approx(280.0, abs=1e-6) and F[0, 1] > 280.0
            else:
                assert abs(F[1, 0]) == pytest.approx(0.25 * F[1, 1], rel=1e-9)
                assert abs(F[0, 0]) < 0.25 * F[0, 1]
    # no cone given: nothing timed on a feasible orbit
    plain = simulate(zd, th, SimConfig(steps=1), Start(perturb=0.1))
    assert plain.steps[0].cone_exit_at is None and plain.steps[0].low_force_at is None


def test_unknown_method_and_integrator_are_parameter_errors():
    from thrustwalk_cli.errors import InputError

    with pytest.raises(InputError, match="method"):
        SimConfig(method="fast").validate()
    with pytest.raises(InputError, match="integrator: the compiled method"):
        SimConfig(integrator="LSODA").validate()
    SimConfig(method="scipy", integrator="LSODA").validate()


@pytest.mark.slow
def test_second_process_loads_the_compiled_kernel_from_the_cache(_cache_dir, walker3):
    """The kernel compiled by this session (cached in the thrustwalk cache folder, the same
    for every robot) is loaded, not recompiled, by a new process that simulates a robot:
    numba reports only cache hits."""
    from thrustwalk_cli.simulation.stepper import kernel

    kernel()  # compiled (or loaded) here
    code = ("import numpy as np\n"
            "from thrustwalk_cli.walker import load_walker\n"
            "from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel\n"
            "from thrustwalk_cli.simulation.full_order import simulate\n"
            "from thrustwalk_cli.simulation.stepper import kernel\n"
            "w = load_walker('rabbit', 'rabbit_walk')\n"
            "th = ThrustModel('constant', np.zeros(w.model.n_thrusters))\n"
            "res = simulate(w.zd, th, SimConfig(steps=1))\n"
            "jm = kernel()\n"
            "st = jm.module.run.stats\n"
            "print(jm.cache_hit and res.success, sum(st.cache_hits.values()), "
            "sum(st.cache_misses.values()))\n")
    env = dict(os.environ, THRUSTWALK_CACHE_DIR=str(_cache_dir))
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    hit, hits, misses = res.stdout.split()
    assert hit == "True" and int(hits) >= 1 and int(misses) == 0, res.stdout
