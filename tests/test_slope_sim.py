"""The full-order simulation on a slope (SPEC 14, 7): ``simulate --slope``.

Checks, each against an independent computation or a physical identity:

* an independent full-order simulation written here, in WORLD coordinates (``solve_ivp`` on
  the level-ground model's ``D``, ``h``, ``B_F`` at the world posture, the ground an inclined
  line through the stance foot: the guard is the swing foot's height above that line, the
  relabelling is done in the slope's frame; the controller written out as ``u = (J D^-1
  B)^-1 (...)``, not the kernel's 2 x 2 reduction), gives the same ``zeta^-`` per step as the
  compiled kernel on the slope to 1e-8; no part of ``model/slope.py`` is used;
* the work-energy balance on a slope: over the stance phase ``E^- - E_start = int (u q_b' +
  F B_F^T q') dt`` with the slope's potential ``V = M g (sin(gamma) x_com + cos(gamma)
  y_com)`` from the kinematics alone; over a step of the periodic orbit the potential energy
  dropped, ``-M g d sin(gamma)``, plus the joints' and thrusters' work is the impact's loss;
* slope 0 is level ground bit for bit; compiled against ``method="scipy"`` (which runs the
  slope model's ``G_x`` decomposition, not the kernel's turned posture) per step;
* bad slopes: one line, exit 2, nothing written.

Robots: the user robot walker5 with its gait designed over -40..0 N of its world-frame torso
thruster, RABBIT (a world-frame thruster) and the 3-link walker (one world-frame, one
link-frame thruster).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import simpson, solve_ivp

from thrustwalk_cli.hzd.constraints import bezier
from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel, zeta_star_at
from thrustwalk_cli.simulation.full_order import Start, initial_state, simulate
from thrustwalk_cli.studies.simulate import simulate as simulate_study
from thrustwalk_cli.walker import load_walker

DATA = Path(__file__).resolve().parent / "data"
ROBOT5, GAIT5 = DATA / "walker5.yaml", DATA / "walker5_thrust.yaml"


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return load_walker(str(ROBOT5), str(GAIT5))


def _case(name, walker3, walker5, walker_rabbit):
    """(walker, slope [rad], constant thrust per thruster [N])."""
    return {"walker5": (walker5, 0.04, [-20.0]),
            "rabbit": (walker_rabbit, -0.05, [-10.0]),
            "three_link": (walker3, 0.03, [-5.0, -8.0])}[name]


# ------------------------------------------------------------------ the world-frame simulation
def world_frame_run(walker, gamma: float, F, x0, steps: int, min_impact_s: float = 0.75,
                    tol: float = 1e-12) -> list[float]:
    """zeta^- per step of the walker on the ground line inclined by ``gamma``, simulated in
    world coordinates: the posture is ``q_w = q + gamma e_N`` (the world angle of the one
    absolute coordinate), gravity the level-ground model's (0, -g), a world thruster keeps its
    world direction. The gait's outputs are measured in the slope's frame (``q = q_w - gamma
    e_N``). ``x0``: the post-impact state in the slope's frame."""
    model, mp, gait = walker.model, walker.zd.maps, walker.gait
    N = model.n
    nb = N - 1
    e = np.zeros(N)
    e[-1] = 1.0
    c, A, ai, span = mp.c, mp.A, mp.alpha_i, mp.span
    kp, kd = float(gait.kp), float(gait.kd)
    F = np.asarray(F, float)
    B = np.vstack([np.eye(nb), np.zeros((1, nb))])
    H0 = np.hstack([np.eye(nb), np.zeros((nb, 1))])
    cg, sg = math.cos(gamma), math.sin(gamma)

    def rhs(t, x):
        qw, dq = x[:N], x[N:]
        q = qw - gamma * e
        s = (c @ q - ai) / span
        hd, hd1, hd2 = (bezier(A, s, k) / span ** k for k in range(3))
        J = H0 - np.outer(hd1, c)
        y, dy = q[:nb] - hd, J @ dq
        D = model.D(qw)
        f = -model.h(qw, dq) + model.B_F(qw) @ F
        Dinv = np.linalg.inv(D)
        # y'' = J q'' - h_d'' alpha'^2 = -kp y - kd y',  q'' = D^-1 (B u + f)
        u = np.linalg.solve(J @ Dinv @ B, -kp * y - kd * dy - J @ Dinv @ f
                            + hd2 * (c @ dq) ** 2)
        return np.concatenate([dq, Dinv @ (B @ u + f)])

    def phase(t, x):
        return (c @ (x[:N] - gamma * e) - ai) / span - min_impact_s
    phase.terminal, phase.direction = True, 1

    def height(t, x):  # the swing foot above the ground line through the stance foot
        p = model.p_swing(x[:N])
        return -sg * p[0] + cg * p[1]
    height.terminal, height.direction = True, -1

    x = np.array(x0, float)
    x[:N] += gamma * e
    out = []
    t = 0.0
    for _ in range(steps):
        for event in (phase, height):
            sol = solve_ivp(rhs, (t, t + 10.0), x, method="DOP853", rtol=tol, atol=tol,
                            events=[event])
            assert sol.status == 1, sol.message
            t, x = float(sol.t_events[0][0]), sol.y_events[0][0]
        qw, dq = x[:N], x[N:]
        out.append(0.5 * float(model.D(qw)[N - 1] @ dq) ** 2)
        imp = model.impact(qw, dq)  # the velocity map: angular rates, the same in any frame
        q_plus = model.R @ (qw - gamma * e) + model.b + gamma * e
        x = np.concatenate([q_plus, imp.dq_plus])
    return out


@pytest.mark.slow
@pytest.mark.parametrize("name", ["walker5", "rabbit", "three_link"])
def test_independent_world_frame_simulation(name, walker3, walker5, walker_rabbit):
    """zeta^- per step of the compiled kernel on the slope equals that of the world-frame
    simulation above to 1e-8 (relative), starting from the same state a little off the
    orbit (so the outputs are not zero)."""
    walker, gamma, F = _case(name, walker3, walker5, walker_rabbit)
    zd = walker.zd.on_slope(gamma)
    th = ThrustModel("constant", np.array(F))
    x0 = initial_state(zd, th, Start(perturb=0.05))
    N = walker.model.n
    x0[N] += 0.1  # off Z (a joint rate): the controller works
    cfg = SimConfig(steps=3, rtol=1e-12, atol=1e-12)
    res = simulate(zd, th, cfg, Start(q=x0[:N], dq=x0[N:2 * N]))
    assert res.success, res.reason
    ref = world_frame_run(walker, gamma, F, x0[:2 * N], 3)
    got = [st.zeta_minus for st in res.steps]
    assert got == pytest.approx(ref, rel=1e-8)


def _potential(model, q, gamma):
    """The slope's potential ``M g (sin(gamma) x_com + cos(gamma) y_com)`` [J] from the
    kinematics alone (the level-ground V is ``M g y_com``: checked)."""
    r = model.robot
    mg = r.total_mass * r.gravity
    com = model.p_com(q)
    assert np.allclose(model.V(q)[..., 0], mg * com[..., 1], rtol=1e-12, atol=1e-9)
    return mg * (math.sin(gamma) * com[..., 0] + math.cos(gamma) * com[..., 1])


@pytest.mark.parametrize("name", ["walker5", "rabbit"])
def test_energy_balance_on_a_slope(name, walker3, walker5, walker_rabbit):
    """Stance: ``E^- - E_start = int (u q_b' + F B_F^T q') dt`` (to 1e-6 of the energy
    moved); the step's record energies are ``K + V`` of the slope; over a step of the
    periodic orbit the potential dropped, ``-M g d sin(gamma)``, plus the work of joints and
    thrusters equals the impact's loss of kinetic energy (the impact map of level ground)."""
    walker, gamma, F = _case(name, walker3, walker5, walker_rabbit)
    model = walker.model
    N, nb = model.n, model.n - 1
    zd = walker.zd.on_slope(gamma)
    th = ThrustModel("constant", np.array(F))
    res = simulate(zd, th, SimConfig(steps=2, rtol=1e-11, atol=1e-11, samples_per_step=2001))
    assert res.success, res.reason
    tr = res.trajectory
    e = np.zeros(N)
    e[-1] = 1.0
    mg = model.robot.total_mass * model.robot.gravity
    for st in res.steps:
        sel = tr["step"] == st.step
        t, q, dq, u = tr["t"][sel], tr["q"][sel], tr["dq"][sel], tr["u"][sel]
        BF = model.B_F(q + gamma * e)  # world thrusters keep their world direction
        power = np.einsum("ki,ki->k", u, dq[:, :nb]) + np.einsum("kij,kj,ki->k", BF,
                                                                  tr["F"][sel], dq)
        work = simpson(power, x=t)
        K = 0.5 * np.einsum("ki,kij,kj->k", dq, model.D(q), dq)
        E = K + _potential(model, q, gamma)
        scale = abs(work) + abs(E[-1] - E[0]) + 1.0
        assert E[-1] - E[0] == pytest.approx(work, abs=1e-6 * scale)
        assert st.energy_minus == pytest.approx(E[-1], rel=1e-9)
        # the impact (level ground's map: it does not depend on the slope)
        qm, dqm = np.array(st.q_minus), np.array(st.dq_minus)
        imp = model.impact(qm, dqm)
        loss = (0.5 * dqm @ model.D(qm) @ dqm
                - 0.5 * imp.dq_plus @ model.D(imp.q_plus) @ imp.dq_plus)
        d = float(model.p_swing(qm)[0])  # the step along the ground
        assert loss > 0 and d > 0
        if st.step >= 2:  # on the periodic orbit (started at the predicted fixed point)
            drop = -mg * d * math.sin(gamma)
            assert drop + work == pytest.approx(loss, rel=1e-6)


def test_slope_zero_is_level_ground_bit_for_bit(walker5):
    """``slope=0`` (and -0.0) gives exactly the document of a run without it."""
    kw = dict(steps=2, thrust=[-20.0], thrust_model="constant", perturb=0.02)
    base = simulate_study(walker5, **kw).document()
    for zero in (0.0, -0.0):
        assert simulate_study(walker5, slope=zero, **kw).document() == base
    assert "slope" not in base


@pytest.mark.slow
@pytest.mark.parametrize("name", ["walker5", "rabbit"])
def test_compiled_matches_scipy_on_a_slope(name, walker3, walker5, walker_rabbit):
    """Per step, the compiled kernel (level-ground tape at the turned posture) and the SciPy
    path (the slope model's G_x decomposition) agree as on level ground."""
    walker, gamma, F = _case(name, walker3, walker5, walker_rabbit)
    zd = walker.zd.on_slope(gamma)
    th = ThrustModel("second-order", np.array(F), wn=3.0, xi=0.7)
    start = Start(zeta_minus=1.05 * zeta_star_at(zd, np.array(F)))
    a = simulate(zd, th, SimConfig(steps=3, method="scipy"), start)
    b = simulate(zd, th, SimConfig(steps=3), start)
    assert a.success and b.success, (a.reason, b.reason)
    assert len(a.steps) == len(b.steps) == 3
    for x, y in zip(a.steps, b.steps):
        assert y.zeta_minus == pytest.approx(x.zeta_minus, rel=1e-9)
        assert y.step_time == pytest.approx(x.step_time, rel=1e-9)
        assert y.min_vertical_force == pytest.approx(x.min_vertical_force, rel=1e-7)
        assert y.max_friction_ratio == pytest.approx(x.max_friction_ratio, rel=1e-7)
        assert y.impulse == pytest.approx(x.impulse, rel=1e-8)
        assert y.energy_minus == pytest.approx(x.energy_minus, rel=1e-9)
        assert y.energy_plus == pytest.approx(x.energy_plus, rel=1e-9)


def test_cli_simulate_on_a_slope(cli, tmp_path, monkeypatch):
    """``simulate --slope``: the slope block, speed along the ground and climb rate, the
    prediction of the zero dynamics on that slope (which the run follows)."""
    monkeypatch.chdir(tmp_path)
    gamma = -0.04
    r = cli("simulate", str(ROBOT5), str(GAIT5), "--slope", str(gamma), "--steps", "3",
            "--thrust-model", "ideal", "--thrust", "-20", "--formats", "csv", "--out", "o",
            "--quiet")
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "o" / "simulation.json").read_text())
    assert doc["slope"]["angle"] == gamma
    assert doc["slope"]["degrees"] == pytest.approx(math.degrees(gamma), rel=1e-15)
    assert doc["status"] == "ok", doc["reason"]
    run = doc["runs"][0]
    w = load_walker(str(ROBOT5), str(GAIT5)).on_slope(gamma)
    assert run["predicted"]["zeta_star"] == pytest.approx(zeta_star_at(w.zd, np.array([-20.0])),
                                                           rel=1e-12)
    assert run["final_zeta_minus"] == pytest.approx(run["predicted"]["zeta_star"], rel=1e-6)
    assert run["speed"] == pytest.approx(run["predicted"]["speed"], rel=1e-6)
    assert run["climb_rate"] == pytest.approx(run["speed"] * math.sin(gamma), rel=1e-12)
    assert run["predicted"]["climb_rate"] == pytest.approx(
        run["predicted"]["speed"] * math.sin(gamma), rel=1e-12)


@pytest.mark.slow
def test_stability_on_a_slope(walker5):
    """Floquet analysis on a slope: the zero dynamics' fixed point on the slope is a fixed
    point of the compiled full-order map (Newton's residual at the prediction, two independent
    routes: the slope series of the zero dynamics and the kernel at the turned posture); the
    finite differences of the kernel agree with the variational equations of the slope
    model's G_x decomposition; the zero-dynamics multiplier is level ground's delta_zero^2
    (the impact does not depend on the slope)."""
    from thrustwalk_cli.studies.stability import stability

    gamma = 0.03
    doc = stability(walker5, thrust_model="ideal", thrust=-20.0, slope=gamma).document()
    assert doc["slope"]["angle"] == gamma and doc["verdict"] == "stable"
    case = doc["cases"][0]
    F5 = np.array([-20.0])
    zs = zeta_star_at(walker5.zd.on_slope(gamma), F5)
    assert case["predicted"]["zeta_star"] == pytest.approx(zs, rel=1e-12)
    assert zs != pytest.approx(zeta_star_at(walker5.zd, F5), rel=1e-3)  # not level ground
    assert case["fixed_point"]["newton"]["start_residual"] < 1e-9
    assert case["jacobian"]["agreement"]["agree"]
    assert case["zero_dynamics"]["multiplier"]["re"] == pytest.approx(
        walker5.zd.delta_zero_sq, abs=1e-8)


@pytest.mark.slow
def test_control_on_a_slope(walker5):
    """Step-to-step control on a downhill slope: the full-order walker on the slope (the
    compiled kernel at the turned posture) walks at the reference speed along the ground, the
    controller braking (positive thrust of the backward-pointing thruster); the document
    holds the slope and the nominal climb rate."""
    from thrustwalk_cli.studies.control import control

    gamma = -0.03
    doc = control(walker5, reference="speed", profile=[(0, 0.6)], steps=10, slope=gamma,
                  compare=False).document()
    assert doc["slope"]["angle"] == gamma and doc["status"] == "ok", doc["reason"]
    last = doc["steps"][-1]
    assert last["speed"] == pytest.approx(0.6, rel=1e-8)
    assert min(last["thrust_commanded"]["back"]) > 0
    s = doc["settings"]
    assert s["nominal_climb_rate"] == pytest.approx(s["nominal_speed"] * math.sin(gamma),
                                                    rel=1e-12)


@pytest.mark.parametrize("command", ["simulate", "stability", "control"])
@pytest.mark.parametrize("bad", ["2", "nan", "-1.6", "inf"])
def test_cli_bad_slope(command, bad, cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = cli(command, str(ROBOT5), str(GAIT5), f"--slope={bad}", "--out", "o")
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: option --slope: "), r.output
    assert not (tmp_path / "o").exists()
