"""Robot-file generality and the shipped gaits' walkability claims (SPEC 1, 2, 5, 9)."""

from __future__ import annotations

from pathlib import Path

import independent as ind
import numpy as np
import pytest

from thrustwalk_cli.errors import InputError
from thrustwalk_cli.files.robot_file import load_robot
from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.model import compiler as model_mod
from thrustwalk_cli.model import derive
from thrustwalk_cli.model.compiler import load_model
from thrustwalk_cli.thrust.schedule import Schedule

REPO = Path(__file__).resolve().parents[1]

# A genuinely branched tree: torso and swing leg are both children of the stance leg, a
# four-link walker with a tail hanging from the torso, offset joints, inertias, a rotor, and
# q_N on a leaf link.
BRANCHED = """
name: branched
parameters: {r: 0.9}
gravity: 9.81
links:
  - {name: stance_leg, parent: null, mass: 4, com: [0.01, 0.45], inertia: 0.2, end: [0, r]}
  - {name: swing_leg, parent: stance_leg, joint: [0, r], mass: 4, com: [0.01, -0.45],
     inertia: 0.2, end: [0, -r], rotor: {inertia: 1e-4, gear_ratio: 40}}
  - {name: torso, parent: stance_leg, joint: [0, r], mass: 12, com: [0.03, 0.3],
     inertia: 0.9, end: [0, 0.6]}
  - {name: tail, parent: torso, joint: [0, 0.1], mass: 1.5, com: [-0.2, -0.1], inertia: 0.05}
coordinates:
  actuated:
    - {name: qs, joint: swing_leg}
    - {name: qt, joint: torso}
    - {name: qa, joint: tail}
  unactuated: {name: qN, link: tail}
feet:
  stance: {link: stance_leg, point: [0, 0]}
  swing: {link: swing_leg, point: [0, -r]}
relabel:
  swap: [[stance_leg, swing_leg]]
thrusters:
  - {name: tail_push, link: tail, point: [-0.3, 0], direction: [0.6, 0.8], frame: link}
"""


def test_branched_tree_matches_independent_model(tmp_path):
    """Any planar tree works: D, G, swing foot and thruster map vs independent.py."""
    path = tmp_path / "branched.yaml"
    path.write_text(BRANCHED)
    robot = load_robot(str(path))
    m = load_model(robot)
    rng = np.random.default_rng(3)
    for q in rng.uniform(-1, 1, (10, robot.n)):
        np.testing.assert_allclose(m.D(q), ind.mass_matrix(robot, q), atol=1e-10)
        np.testing.assert_allclose(m.p_swing(q), ind.swing_foot(robot, q), atol=1e-12)
        G_ind = ind.complex_step(lambda x: np.atleast_1d(ind.potential(robot, x)), q)[0]
        np.testing.assert_allclose(m.G(q), G_ind, atol=1e-9)
        dq = rng.uniform(-1, 1, robot.n)
        F = np.array([7.0])
        power = ind.thruster_power(robot, q, np.concatenate([dq, [0.0, 0.0]]), F)
        assert dq @ m.B_F(q) @ F == pytest.approx(power, rel=1e-10, abs=1e-12)
    # legs that are not mirror images cannot swap roles: the compile check says so
    path.write_text(BRANCHED.replace("com: [0.01, -0.45]", "com: [-0.01, -0.45]"))
    with pytest.raises(InputError, match="relabel: relabelling does not swap the feet"):
        load_model(load_robot(str(path)))


def test_inertia_depending_on_qN_is_rejected(monkeypatch):
    """The dD/dq_N = 0 compile check names the file and key (exercised by forcing D(q_N))."""
    robot = load_robot("three_link")
    real = derive.derive

    def fake(r, **kw):
        der = real(r, **kw)
        der.exprs["D"] = der.exprs["D"] + der.exprs["D"].applyfunc(lambda e: 0) + \
            der.q[-1] * np.eye(r.n).tolist()[0][0] * der.exprs["D"].applyfunc(lambda e: 1)
        return der

    monkeypatch.setattr(derive, "derive", fake)
    with pytest.raises(InputError) as exc:
        model_mod.generate_source(robot, "k")
    msg = str(exc.value)
    assert "three_link.yaml:" in msg and "coordinates.unactuated" in msg
    assert "dD/dq_N" in msg


def test_shipped_three_link_gait_claims(walk3):
    """Stable, invariant, swing foot never below the ground (touching at mid-step), torso
    leaning forward steadily; made by design-gait, so it is reproducible by one command."""
    model, gait, zd = walk3
    lc = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, model.n_thrusters))))[0]
    assert lc.stable and 0 < zd.delta_zero_sq < 1
    assert zd.maps.position_residual < 1e-12 and zd.maps.velocity_residual < 1e-12
    alpha = np.linspace(zd.alpha_i, zd.alpha_f, 4001)
    h = model.p_swing(zd.maps.q_Z(alpha))[:, 1]
    # >= 0 up to 0.1 um: the touch point of straight legs is a numerical zero
    assert h.min() > -1e-7, f"swing foot {h.min():.3g} m below ground at alpha={alpha[h.argmin()]}"
    # straight legs: the foot touches where the stance leg is vertical (alpha = 0), only there
    away = np.abs(alpha) > 0.02
    inner = (alpha > zd.alpha_i + 0.02) & (alpha < zd.alpha_f - 0.02) & away
    assert h[inner].min() > 0
    # the foot rises after lift-off and descends onto the ground at impact (guard crossing)
    assert (h[1] - h[0]) > 0 and (h[-1] - h[-2]) < 0
    assert lc.speed == pytest.approx(0.8, rel=1e-3)
    theta = zd.maps.q_Z(alpha) @ model.robot.T.T
    torso = theta[:, model.robot.link_index("torso")]
    assert -0.35 < torso.min() and torso.max() < -0.1  # leaning forward 6 to 20 degrees
    assert "# command: thrustwalk design-gait three_link" in Path(gait.source_file).read_text()


def test_shipped_rabbit_gait_claims(walker_rabbit):
    """Stable, invariant, knees never hyperextend, clearance >= 3 cm at mid-step."""
    robot, model, zd = walker_rabbit.robot, walker_rabbit.model, walker_rabbit.zd
    lc = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, model.n_thrusters))))[0]
    assert lc.stable, lc.reason
    assert zd.maps.position_residual < 1e-12 and zd.maps.velocity_residual < 1e-12
    s = np.linspace(0, 1, 2001)
    q = zd.maps.q_Z(zd.alpha_i + s * (zd.alpha_f - zd.alpha_i))
    for j, c in enumerate(robot.coordinates[:-1]):
        lo, hi = c.range
        assert q[:, j].min() >= lo - 1e-9 and q[:, j].max() <= hi + 1e-9, c.name
    h = model.p_swing(q)[:, 1]
    assert h[(s > 0.02) & (s < 0.98)].min() > 0
    assert h[1000] >= 0.03


# --------------------------------------------------------------- a robot without thrusters
DATA = Path(__file__).resolve().parent / "data"
BARE = str(DATA / "three_link_bare.yaml")  # robots/three_link.yaml with `thrusters: []`
BARE_WALK = str(DATA / "three_link_bare_walk.yaml")  # gaits/three_link_walk.yaml's coefficients


def _json(path: Path) -> dict:
    import json

    return json.loads(path.read_text())


@pytest.mark.slow
def test_robot_without_thrusters_through_every_analysis(tmp_path, walk3, cli):
    """compile, inspect, limit-cycle, feasibility, shape (generalised mode), optimize
    (generalised mode) and simulate run on a robot with `thrusters: []`; thrust options refer
    to no thruster and default to 0. Thrusters do not enter D, C, G or the impact, so every
    zero-thrust number equals the bundled 3-link robot's (an independent reference). Each
    command draws its figures once (as PNG: the PDF of a figure is the same figure)."""
    model3, _, zd3 = walk3
    ref = limit_cycles(zd3, Schedule.constant(zd3, np.zeros((1, model3.n_thrusters))))[0]
    res = cli("compile", BARE)
    assert res.exit_code == 0 and "none" in res.output, res.output
    res = cli("inspect", BARE, "--q", "0.1,0.2,0.1", "--json", tmp_path / "state.json")
    assert res.exit_code == 0, res.output
    assert _json(tmp_path / "state.json")["B_F"] == [[], [], []]
    for args in (["--formats", "csv,png"], ["--thrust", "0", "--formats", "csv"]):
        res = cli("limit-cycle", BARE, BARE_WALK, *args, "-q", "--out", tmp_path / "lc")
        assert res.exit_code == 0, res.output
        doc = _json(tmp_path / "lc" / "limit_cycles.json")
        assert doc["thruster"] is None and doc["robot"]["thrusters"] == []
        (c,) = doc["cycles"]
        assert c["thrust"] == 0.0 and c["stable"]
        assert c["zeta_star"] == pytest.approx(ref.zeta_star, rel=1e-12)
        assert c["touchdown_velocity"] == pytest.approx(ref.touchdown_velocity, rel=1e-12)
    res = cli("feasibility", BARE, BARE_WALK, "-q", "--formats", "png", "--out", tmp_path / "fe")
    assert res.exit_code == 0, res.output
    doc = _json(tmp_path / "fe" / "feasibility.json")
    assert doc["verdict"] == "feasible" and [c["thrust"] for c in doc["cases"]] == [0.0]
    assert (tmp_path / "fe" / "feasible_region.png").stat().st_size > 0
    res = cli("shape", BARE, BARE_WALK, "--k", "0:10:5", "-q", "--formats", "csv,png", "--out",
              tmp_path / "sh")
    assert res.exit_code == 0, res.output
    assert _json(tmp_path / "sh" / "shape.json")["mode"] == "generalized"
    res = cli("optimize", BARE, BARE_WALK, "--mode", "generalized", "--max-thrust", "20",
              "--target-speed", "0.9", "-q", "--formats", "png", "--out", tmp_path / "op")
    assert res.exit_code == 0, res.output
    assert _json(tmp_path / "op" / "optimal_schedule.json")["feasible"]
    res = cli("simulate", BARE, BARE_WALK, "--steps", "2", "--samples", "10", "-q",
              "--formats", "csv,png", "--out", tmp_path / "sim")
    assert res.exit_code == 0, res.output
    doc = _json(tmp_path / "sim" / "simulation.json")
    (run,) = doc["runs"]
    assert run["f_ss"] == 0.0 and run["success"] and doc["settings"]["thrusters"] == []
    assert run["final_zeta_minus"] == pytest.approx(ref.zeta_star, rel=1e-6)


@pytest.mark.slow
def test_robot_without_thrusters_in_stability_and_robustness(tmp_path, walk3, cli):
    """The later commands on `thrusters: []`: stability's zero-dynamics multiplier is the
    3-link's delta_zero^2 (thrusters do not enter the dynamics); robustness compares the one
    strategy a thruster-free robot has (none), whose reduced basin equals the 3-link's
    zero-thrust basin."""
    _, _, zd3 = walk3
    res = cli("stability", BARE, BARE_WALK, "-q", "--formats", "none", "--out",
              tmp_path / "st")
    assert res.exit_code == 0, res.output
    doc = _json(tmp_path / "st" / "stability.json")
    (case,) = doc["cases"]
    assert case["verdict"] == "stable" and case["thruster"] is None
    assert case["zero_dynamics"]["delta_zero_sq"] == pytest.approx(zd3.delta_zero_sq,
                                                                   rel=1e-12)
    assert case["zero_dynamics"]["multiplier"]["re"] == pytest.approx(zd3.delta_zero_sq,
                                                                      rel=1e-6)
    res = cli("robustness", BARE, BARE_WALK, "--push-impulse", "-2:2:2", "--push-phase", "0.5",
              "--steps", "3", "--basin-grid", "0", "--workers", "1", "-q", "--formats", "none",
              "--out", tmp_path / "rb")
    assert res.exit_code == 0, res.output
    doc = _json(tmp_path / "rb" / "robustness.json")
    assert [s["strategy"] for s in doc["settings"]["strategies"]] == ["none"]
    (none,) = doc["strategies"]
    assert none["reduced_basin"]["exists"]
    assert none["reduced_basin"]["zeta_star"] == pytest.approx(
        limit_cycles(zd3, Schedule.constant(
            zd3, np.zeros((1, zd3.model.n_thrusters))))[0].zeta_star, rel=1e-12)
    res = cli("robustness", BARE, BARE_WALK, "--strategy", "control", "--out", tmp_path / "x")
    assert res.exit_code == 2 and "no thruster" in res.output
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("args, flag", [
    (["limit-cycle", BARE, BARE_WALK, "--thrust", "0,-10"], "--thrust"),
    (["limit-cycle", BARE, BARE_WALK, "--thruster", "hip_x"], "--thruster"),
    (["feasibility", BARE, BARE_WALK, "--thrust", "-5"], "--thrust"),
    (["inspect", BARE, "--q", "0,0,0", "--thrust", "3"], "--thrust"),
    (["shape", BARE, BARE_WALK, "--mode", "force"], "--mode"),
    (["optimize", BARE, BARE_WALK, "--target-speed", "0.9"], "--mode"),
    (["simulate", BARE, BARE_WALK, "--thrust", "-10"], "--thrust"),
    (["simulate", BARE, BARE_WALK, "--f0", "2"], "--f0"),
    (["design-gait", BARE, "--target-speed", "0.8", "--design-thrust"], "--design-thrust"),
    (["design-gait", BARE, "--target-speed", "0.8", "--thrust-range", "hip_x:-1:0"],
     "--thrust-range"),
])
def test_thrust_for_a_robot_without_thrusters_is_one_line_exit_2(tmp_path, args, flag, cli):
    extra = ["--out", str(tmp_path / "o")]
    res = cli(*args, *([] if args[0] == "inspect" else extra))
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: option {flag}"), res.output
    assert "no thruster" in lines[0] and "Traceback" not in res.output


@pytest.mark.slow
def test_design_gait_for_a_robot_without_thrusters(tmp_path, cli):
    """design-gait on the thruster-free 3-link robot: a feasible gait, written and reloaded."""
    out = tmp_path / "bare.yaml"
    res = cli("design-gait", BARE, "--target-speed", "0.8", "--clearance", "0", "--starts", "1",
              "--out", tmp_path, "--name", "bare", "-q")
    assert res.exit_code == 0, res.output
    report = _json(tmp_path / "bare.report.json")
    assert report["feasible"] and report["thrust"] == []
    assert report["fixed_point"]["speed"] == pytest.approx(0.8, rel=1e-3)
    # the stick figure in both default kinds (the other design-gait runs of the tests draw it
    # as PNG only: tests/test_design_gait.py, STICK_PDF)
    assert (tmp_path / "bare.stick.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "bare.stick.pdf").read_bytes()[:5] == b"%PDF-"
    # the reloaded gait's orbit (its figures: test_robot_without_thrusters_through_every_analysis)
    res = cli("limit-cycle", BARE, out, "-q", "--formats", "csv", "--out", tmp_path / "lc")
    assert res.exit_code == 0, res.output


TAILBOT = """
name: tailbot
links:
  - {name: st_shank, parent: null, mass: 2, com: [0, 0.21], inertia: 0.03, end: [0, 0.42]}
  - {name: st_thigh, parent: st_shank, joint: [0, 0.42], mass: 4, com: [0, 0.2], inertia: 0.05,
     end: [0, 0.4]}
  - {name: torso, parent: st_thigh, joint: [0, 0.4], mass: 10, com: [0.02, 0.25], inertia: 0.2,
     end: [0, 0.5]}
  - {name: sw_thigh, parent: torso, mass: 4, com: [0, -0.2], inertia: 0.05, end: [0, -0.4]}
  - {name: sw_shank, parent: sw_thigh, joint: [0, -0.4], mass: 2, com: [0, -0.21],
     inertia: 0.03, end: [0, -0.42]}
  - {name: tail, parent: torso, joint: [0, 0.1], mass: 1.5, com: [-0.25, 0], inertia: 0.03,
     end: [-0.5, 0], point_masses: [{mass: 1.0, at: [-0.5, 0]}]}
coordinates:
  actuated:
    - {name: k_st, joint: st_thigh}
    - {name: h_st, joint: torso}
    - {name: h_sw, joint: sw_thigh}
    - {name: k_sw, joint: sw_shank}
    - {name: tail_a, joint: tail}
  unactuated: {name: th_T, link: torso}
feet:
  stance: {link: st_shank, point: [0, 0]}
  swing: {link: sw_shank, point: [0, -0.42]}
relabel:
  swap: [[st_shank, sw_shank], [st_thigh, sw_thigh]]
"""


def test_default_push_point_is_named_truthfully(tmp_path):
    """The default push point is the end of the stance link: the hip only when the stance leg
    is one link. On a kneed walker (rabbit, walker5, a 6-link walker with a tail) it is the
    stance knee, and control.json / the help said "at the hip" (a user's 6-link robot)."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.commands.options import PushOpt

    (tmp_path / "tailbot.yaml").write_text(TAILBOT)
    cases = {"three_link": ("stance_leg",), "rabbit": ("stance_tibia", "stance_femur"),
             str(DATA / "walker5.yaml"): ("stance_shin", "stance_thigh"),
             str(DATA / "kneed4.yaml"): ("st_shin", "st_thigh"),
             str(tmp_path / "tailbot.yaml"): ("st_shank", "st_thigh")}
    for name, leg in cases.items():
        robot = tw.load_robot(name)
        assert robot.stance_leg == leg, name
        text = robot.stance_end_text()
        if len(leg) == 1:
            assert text.startswith("the hip"), text
        else:
            assert text.endswith("not the hip") and f"stance link {leg[0]}" in text, text
    assert "at the hip at phase" not in PushOpt.__metadata__[0].help
