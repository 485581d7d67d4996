"""design-gait --objective cot (issue 28, SPEC 15): the gait of least mechanical cost of
transport for a target speed. The solver's smoothed objective is checked against the exact CoT
of a gait's orbit, and a design on a user's robot (walker5, from another folder) against an
independent dense-grid integral of the joints' positive power; it walks at a fraction of the
CoT of the effort-designed gait for the same speed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "data"


def dense_cot(walker, thrust: float = 0.0, points: int = 40001) -> tuple[float, float]:
    """The mechanical CoT of the walker's periodic orbit at constant ``thrust`` on its first
    thruster, computed here: ``sum_j int max(0, u_j q_j') dt = sum_j int max(0, s u_j Phi_j)
    |dalpha|`` (q' = Phi alpha', dt = dalpha / alpha') by the trapezoid rule on ``points``
    uniform alpha values, plus the thrust's positive work ``int max(0, s F (B_F^T Phi)) |dalpha|``,
    over ``m g L`` (L the step length); and the orbit's speed."""
    from thrustwalk_cli.contact.terms import stance_terms
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule

    zd = walker.zd
    model, maps = zd.model, zd.maps
    F = np.zeros(model.n_thrusters)
    if model.n_thrusters:
        F[0] = thrust
    sched = Schedule.constant(zd, F[None, :])
    lc = limit_cycles(zd, sched)[0]
    assert lc.exists
    a = np.linspace(zd.alpha_i, zd.alpha_f, points)
    st = stance_terms(model, maps, a)
    zeta = lc.zeta_plus + zd.V_Z(a, sched)[0]
    u = np.einsum("gim,m->gi", st.U2, F) + st.U1 * zeta[:, None] + st.U0
    phi = maps.Phi(a)
    s = np.sign(zd.alpha_f - zd.alpha_i)
    power = u * phi[:, :model.n - 1] * s
    if model.n_thrusters:
        bt = np.einsum("gnm,gn->gm", model.B_F(maps.q_Z(a)), phi) * s * F
        power = np.concatenate([power, bt], axis=1)
    h = abs(zd.alpha_f - zd.alpha_i) / (points - 1)
    pos = np.maximum(power, 0.0)
    work = float(np.sum(h * (pos[1:] + pos[:-1]) / 2.0))
    L = lc.step_length
    return work / (model.robot.weight * L), lc.speed


def test_the_solvers_cot_is_the_exact_cot_within_its_smoothing(walker3):
    """For a finished gait (the bundled 3-link gait put into the design variables), the
    solver's objective is the exact CoT of its orbit (energetics.orbit, SPEC 15) plus the bias
    of the smoothed positive part, which is >= 0 and below ``e |alpha_f - alpha_i| / 2`` per
    term over ``m g L``; the exact CoT equals the dense-grid integral of this test."""
    from thrustwalk_cli.design.problem import COT_SMOOTH, Problem
    from thrustwalk_cli.design.spec import DesignSpec
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.studies.limit_cycle import limit_cycle
    from thrustwalk_cli.thrust.schedule import Schedule

    zd = walker3.zd
    model = zd.model
    lc = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, model.n_thrusters))))[0]
    exact = limit_cycle(walker3, [0.0]).energy[0].cot()["mechanical"]
    mine, _ = dense_cot(walker3)
    assert exact == pytest.approx(mine, rel=1e-6)
    prob = Problem(model, DesignSpec(speed=lc.speed, clearance=0.0, objective="cot"))
    x = prob.warm_start(zd.maps.q_minus, walker3.gait.coefficients, lc.zeta_star)
    ev = prob.evaluate(x)
    terms = model.n - 1 + model.n_thrusters
    bias = 0.5 * COT_SMOOTH * prob.u_scale * abs(zd.alpha_f - zd.alpha_i) * terms \
        / (model.robot.weight * lc.step_length)
    assert ev.ok
    assert exact - 1e-3 * exact <= ev.objective <= exact + bias + 1e-3 * exact, \
        (ev.objective, exact, bias)


@pytest.mark.slow
def test_cot_design_on_a_users_robot_walks_cheaper_than_the_effort_design(tmp_path,
                                                                          monkeypatch, cli):
    """walker5 (user robot, 4 actuated joints and a torso thruster), designed from another
    folder for 0.6 m/s with --objective cot: a feasible gait whose report names the objective
    (unit 1) and gives as its value the exact CoT of the designed orbit, equal to this test's
    dense-grid integral; at the target speed; and its CoT is below half that of
    walker5_walk.yaml, the gait designed for the same speed with the effort objective."""
    import thrustwalk_cli as tw

    monkeypatch.chdir(tmp_path)
    res = cli("design-gait", str(DATA / "walker5.yaml"), "--target-speed", "0.6",
              "--objective", "cot", "--starts", "1", "--out", "d", "-q")
    assert res.exit_code == 0, res.stderr
    rep = json.loads((tmp_path / "d" / "walker5_designed.report.json").read_text())
    assert rep["feasible"] and rep["objective"]["name"] == "cot"
    assert rep["objective"]["unit"] == "1"
    designed = tw.load_walker(str(DATA / "walker5.yaml"),
                              str(tmp_path / "d" / "walker5_designed.yaml"))
    cot, speed = dense_cot(designed)
    assert speed == pytest.approx(0.6, rel=1e-4)
    assert rep["objective"]["value"] == pytest.approx(cot, rel=1e-6)
    assert rep["energy"]["cot"]["mechanical"] == rep["objective"]["value"]
    effort = tw.load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"))
    cot_effort, speed_effort = dense_cot(effort)
    assert speed_effort == pytest.approx(0.6, rel=1e-4)
    assert cot < 0.5 * cot_effort, (cot, cot_effort)
