"""Walking on a slope (SPEC 14): the slope frame, limit cycles and contact on a slope, the
``--slope`` option of limit-cycle and feasibility.

Each check compares with an independent computation: the same robot on level ground with its
gravity turned (``g cos(gamma)`` normal to the ground, and the tangential part ``m_i g
sin(gamma)`` as world-frame thrusters at the links' centres of mass, the world thrusters'
directions turned by ``-gamma``), compiled as a robot of its own; or the energy balance over
a step, whose potential part comes from the kinematics alone.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.contact.evaluate import evaluate
from thrustwalk_cli.contact.terms import stance_terms
from thrustwalk_cli.description.robot import Thruster
from thrustwalk_cli.errors import InputError
from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.model.compiler import load_model
from thrustwalk_cli.studies.feasibility import feasibility
from thrustwalk_cli.studies.limit_cycle import limit_cycle
from thrustwalk_cli.thrust.schedule import Schedule
from thrustwalk_cli.walker import load_walker, walker_from

DATA = Path(__file__).resolve().parent / "data"
ROBOT5, GAIT5 = str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml")


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return load_walker(ROBOT5, GAIT5)


def turned_robot(robot, gamma: float):
    """The robot on level ground with gravity turned by the slope, built without the slope
    code: gravity ``g cos(gamma)``; one world thruster per link at its centre of mass along
    -x (driven with ``m_i g sin(gamma)``); world thrusters' directions turned by -gamma."""
    c, s = math.cos(gamma), math.sin(gamma)
    thrusters = []
    for t in robot.thrusters:
        d = t.direction
        if t.frame == "world":
            d = (c * d[0] + s * d[1], -s * d[0] + c * d[1])
        thrusters.append(replace(t, direction=d))
    for lk in robot.links:
        thrusters.append(Thruster(f"gravity_{lk.name}", lk.name, lk.com, (-1.0, 0.0), "world"))
    grav = [lk.mass * robot.gravity * s for lk in robot.links]
    return replace(robot, gravity=robot.gravity * c, thrusters=tuple(thrusters)), grav


def _cases(name, walker3, walker5):
    return {"three_link": (walker3, -0.03, [[0.0, 0.0], [-20.0, 0.0], [0.0, -15.0]]),
            "walker5": (walker5, 0.05, [[-20.0], [-40.0]])}[name]


@pytest.mark.parametrize("name", ["three_link", "walker5"])
def test_slope_equals_level_ground_with_gravity_turned(name, walker3, walker5):
    """zeta*, V_Z(alpha_f), the step time, the stance forces and torques and the contact
    verdict's worst points on a slope equal those of the independently turned robot on level
    ground, to 1e-12 (relative)."""
    walker, gamma, F = _cases(name, walker3, walker5)
    ws = walker.on_slope(gamma)
    assert ws.slope == gamma and ws.zd.slope == gamma
    robot2, grav = turned_robot(walker.robot, gamma)
    w2 = walker_from(load_model(robot2), walker.gait)
    F = np.array(F)
    F2 = np.hstack([F, np.tile(grav, (len(F), 1))])
    s1, s2 = Schedule.constant(ws.zd, F), Schedule.constant(w2.zd, F2)
    a, b = limit_cycles(ws.zd, s1), limit_cycles(w2.zd, s2)
    checked = 0
    for x, y in zip(a, b):
        assert x.exists == y.exists and x.stable == y.stable
        assert x.V_f == pytest.approx(y.V_f, rel=1e-12, abs=1e-12)
        if x.exists:
            checked += 1
            for key in ("zeta_star", "step_time", "speed", "min_abs_alpha_dot",
                        "touchdown_velocity"):
                assert getattr(x, key) == pytest.approx(getattr(y, key), rel=1e-12), key
    assert checked >= 1
    alpha = np.linspace(ws.zd.alpha_i, ws.zd.alpha_f, 9)
    t1, t2 = stance_terms(ws.model, ws.zd.maps, alpha), stance_terms(w2.model, w2.zd.maps, alpha)
    zeta = 400.0
    f1, f2 = t1.L0 + t1.L1 * zeta + t1.L2 @ F[-1], t2.L0 + t2.L1 * zeta + t2.L2 @ F2[-1]
    u1, u2 = t1.U0 + t1.U1 * zeta + t1.U2 @ F[-1], t2.U0 + t2.U1 * zeta + t2.U2 @ F2[-1]
    assert np.max(np.abs(f1 - f2)) <= 1e-12 * np.max(np.abs(f2))
    assert np.max(np.abs(u1 - u2)) <= 1e-12 * np.max(np.abs(u2))
    r1 = evaluate(ws.model, ws.zd, s1, mu=0.7, eps=0.0, cycles=a, polynomial=False,
                  torque=False, profiles=False)
    r2 = evaluate(w2.model, w2.zd, s2, mu=0.7, eps=0.0, cycles=b, polynomial=False,
                  torque=False, profiles=False)
    for c1, c2 in zip(r1.cases, r2.cases):
        assert c1.feasible == c2.feasible
        if c1.min_vertical_force is not None:
            assert c1.min_vertical_force == pytest.approx(c2.min_vertical_force, rel=1e-9)
            assert c1.max_friction_ratio == pytest.approx(c2.max_friction_ratio, rel=1e-9)


def test_world_thruster_turns_with_the_slope_link_thruster_does_not(walker3):
    """B_F on a slope: J_k^T Rot(-gamma) d_k for the world thruster (J_k by central
    differences of the thruster point), unchanged for the link-frame one."""
    gamma = 0.2
    flat = walker3.model
    sm = walker3.on_slope(gamma).model
    q = np.array([0.3, -0.2, 0.4])
    h = 1e-6
    J = np.array([(flat.thruster_points(q + h * e) - flat.thruster_points(q - h * e)) / (2 * h)
                  for e in np.eye(3)])  # (N, 2, m)
    c, s = math.cos(gamma), math.sin(gamma)
    d = flat.thruster_dirs(q)[:, 0]
    want = J[:, :, 0] @ np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
    assert np.allclose(sm.B_F(q)[:, 0], want, atol=1e-8)
    assert np.array_equal(sm.B_F(q)[:, 1], flat.B_F(q)[:, 1])


@pytest.mark.parametrize("name", ["three_link", "walker5"])
def test_energy_over_a_step_on_a_slope(name, walker3, walker5):
    """Over the stance phase of the slope orbit, the work of the joints and thrusters minus
    the gain of kinetic energy is the potential energy gained, ``m g d sin(gamma)`` (d the
    step length along the ground; SPEC 14): the zero dynamics, the slope's torques and the
    kinematics against each other."""
    walker, gamma, F = _cases(name, walker3, walker5)
    ws = walker.on_slope(gamma)
    zd, model = ws.zd, ws.model
    flat = walker.model
    F = np.array(F[1])  # one world thruster driven
    sched = Schedule.constant(zd, F[None])
    lc = limit_cycles(zd, sched)[0]
    assert lc.exists
    N = model.n
    x, wts = np.polynomial.legendre.leggauss(200)
    a, b = zd.alpha_i, zd.alpha_f
    alpha = 0.5 * (a + b) + 0.5 * (b - a) * x
    zeta = lc.zeta_plus + zd.V_Z(alpha, sched)[0]
    t = stance_terms(model, zd.maps, alpha)
    u = t.U0 + t.U1 * zeta[:, None] + t.U2 @ F
    phi = zd.maps.Phi(alpha)
    W_u = 0.5 * (b - a) * np.sum(wts * np.einsum("gi,gi->g", u, phi[:, :N - 1]))
    # constant thrust along a world-fixed direction: the work is F d_s . (p(q^-) - p(q^+))
    c, s = math.cos(gamma), math.sin(gamma)
    W_F = 0.0
    p_minus, p_plus = flat.thruster_points(zd.maps.q_minus), flat.thruster_points(zd.maps.q_plus)
    for k, th in enumerate(walker.robot.thrusters):
        if th.frame == "world" and F[k] != 0.0:
            d = np.asarray(th.direction, float)
            W_F += F[k] * np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]) @ (
                p_minus[:, k] - p_plus[:, k])
        else:
            assert F[k] == 0.0
    k1 = zd.terms(np.array([a, b]))["kappa1"]
    dq_plus = zd.maps.Phi(np.array(a)) * k1[0] * lc.sigma_plus
    dq_minus = zd.maps.Phi(np.array(b)) * k1[1] * lc.sigma_minus
    K = lambda q, dq: 0.5 * dq @ flat.D(q) @ dq  # noqa: E731
    dK = K(zd.maps.q_minus, dq_minus) - K(zd.maps.q_plus, dq_plus)
    d = float(flat.p_swing(zd.maps.q_minus)[0])
    M, g = walker.robot.total_mass, walker.robot.gravity
    assert W_u + W_F - dK == pytest.approx(M * g * d * math.sin(gamma), rel=1e-9)


def test_level_ground_is_the_walker_itself(walker3):
    """Slope 0 is level ground bit for bit: the same walker, model and zero dynamics, and
    the same documents; a slope and back gives the level-ground objects again."""
    assert walker3.on_slope(0.0) is walker3
    assert walker3.on_slope(0.1).on_slope(0.0).zd is walker3.zd
    a = limit_cycle(walker3, [0.0, -20.0], slope=0.0).document()
    b = limit_cycle(walker3, [0.0, -20.0]).document()
    assert a == b and "slope" not in a and "climb_rate" not in a["cycles"][0]


def test_limit_cycle_on_a_slope_reports_the_slope_and_climb_rate(walker5):
    gamma = 0.05
    doc = limit_cycle(walker5, [-20.0], slope=gamma).document()
    assert doc["slope"]["angle"] == gamma
    c = doc["cycles"][0]
    assert c["exists"] and c["climb_rate"] == pytest.approx(c["speed"] * math.sin(gamma))
    assert c["speed"] == pytest.approx(c["step_length"] / c["step_time"])
    fe = feasibility(walker5, [-20.0], slope=gamma).document()
    assert fe["slope"]["angle"] == gamma
    assert fe["cases"][0]["speed"] == pytest.approx(c["speed"], rel=1e-12)


@pytest.mark.parametrize("bad", [math.pi / 2, -1.6, float("nan"), float("inf"), "steep"])
def test_bad_slope_is_refused(bad, walker3):
    with pytest.raises(InputError, match="slope"):
        limit_cycle(walker3, [0.0], slope=bad)


@pytest.mark.parametrize("command", ["limit-cycle", "feasibility"])
def test_cli_slope(command, cli, tmp_path, monkeypatch):
    """--slope from a folder other than the robot's: the document holds the slope and the
    climb rate; a bad slope is one line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    r = cli(command, ROBOT5, GAIT5, "--thrust", "-20", "--slope", "0.05", "--out", out,
            "--quiet", "--formats", "")
    assert r.exit_code == 0, r.output
    doc = json.loads(next(out.glob("*.json")).read_text())
    assert doc["slope"]["angle"] == 0.05
    cases = doc["cycles"] if command == "limit-cycle" else doc["cases"]
    assert cases[0]["climb_rate"] == pytest.approx(cases[0]["speed"] * math.sin(0.05))
    for bad in ("1.6", "nan", "-2"):
        bad_out = tmp_path / f"bad{bad}"
        r = cli(command, ROBOT5, GAIT5, "--slope", bad, "--out", bad_out)
        assert r.exit_code == 2
        assert "--slope" in r.output and len(r.output.strip().splitlines()) == 1
        assert not bad_out.exists()


# ------------------------------------------------------------------------- the slope map
@pytest.mark.slow
@pytest.mark.parametrize("name", ["three_link", "walker5"])
def test_map_cells_equal_single_limit_cycle_calls(name, walker3, walker5):
    """Every sampled cell of the map (explicit in cos/sin of the slope, affine in thrust)
    equals a limit_cycle(slope=...) call of its own: the verdict, zeta*, step time and speed
    to 1e-12, the least vertical force and largest friction ratio where the orbit completes
    the step (polished near the limits: 1e-9; else on the grid: 1e-3 relative)."""
    from thrustwalk_cli.studies.slope import FAILURES, slope_map

    walker = {"three_link": walker3, "walker5": walker5}[name]
    slopes = np.linspace(-0.2, 0.2, 9)
    thrust = np.linspace(0.0, -50.0, 6)
    r = slope_map(walker, slopes, thrust)
    first = r.cells["first"]
    kinds = set()
    for i in range(0, 9, 2):
        for k in range(0, 6, 1):
            lc = limit_cycle(walker, [float(thrust[k])], slope=float(slopes[i]))
            c, walkable = lc.cycles[0], lc.walkable[0]
            kinds.add(FAILURES[first[i, k]])
            assert walkable == (first[i, k] == 0), (slopes[i], thrust[k], lc.verdicts[0],
                                                    FAILURES[first[i, k]])
            assert c.exists == bool(r.cells["completes"][i, k])
            if not c.exists:
                continue
            for key in ("zeta_star", "step_time", "speed"):
                assert r.cells[key][i, k] == pytest.approx(getattr(c, key), rel=1e-12), key
            assert r.cells["climb_rate"][i, k] == pytest.approx(c.speed * math.sin(slopes[i]),
                                                                rel=1e-12)
            f = lc.contact[0]
            tol = 1e-9 if r.cells["polished"][i, k] else 1e-3  # polished: exact; else grid
            if f.min_vertical_force is not None:
                assert r.cells["min_vertical_force"][i, k] == pytest.approx(
                    f.min_vertical_force, rel=tol, abs=1e-9)
            if f.max_friction_ratio is not None and np.isfinite(f.max_friction_ratio):
                assert r.cells["max_friction_ratio"][i, k] == pytest.approx(
                    f.max_friction_ratio, rel=tol)
    assert "" in kinds and len(kinds) >= 2  # walkable cells and at least one failure


def test_map_headline_and_steepest(walker5):
    """The headline names the walkable range at 0 N and at the largest thrust, as the
    cells say."""
    from thrustwalk_cli.studies.slope import slope_map

    r = slope_map(walker5, np.linspace(-0.3, 0.35, 27), [0.0, -25.0, -50.0])
    w0 = r.slopes[r.walkable[:, 0]]
    w50 = r.slopes[r.walkable[:, 2]]
    assert r.headline.startswith(f"without thrust this gait walks slopes from {w0.min():.4g} "
                                 f"to {w0.max():.4g} rad; with -50 N from {w50.min():.4g} up "
                                 f"to {w50.max():.4g} rad")
    assert w50.max() > w0.max()  # the thrust buys uphill slope
    assert r.steepest()["uphill"] == pytest.approx(r.slopes[r.walkable.any(axis=1)].max())
    assert "edge" not in r.headline
    edge = slope_map(walker5, [-0.1, 0.0, 0.1], [0.0])  # walks -0.1 and 0: -0.1 is the edge
    assert edge.headline.startswith("without thrust this gait walks slopes from -0.1 (the "
                                    "map's edge) to 0 rad")


def test_cli_slope_map(cli, tmp_path, monkeypatch):
    """`thrustwalk slope` from another folder: JSON, one CSV row per pair, both figures."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "map"
    r = cli("slope", ROBOT5, GAIT5, "--slope", "-0.1:0.1:0.05", "--thrust", "0,-20,-40",
            "--mu", "0.7", "--out", out, "--formats", "csv,png", "--quiet")
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "slope.json").read_text())
    assert doc["pairs"] == 15 and doc["headline"].startswith("without thrust")
    assert doc["slopes"]["count"] == 5 and doc["thrusts"]["count"] == 3
    rows = [ln for ln in (out / "slope.csv").read_text().splitlines()
            if ln and not ln.startswith("#")]
    assert len(rows) == 1 + 15
    assert (out / "slope_map.png").is_file() and (out / "steepest_slope.png").is_file()
    assert sum(doc["first_failure_counts"].values()) == 15


@pytest.mark.parametrize("args", [["--slope", "-1.6:0:0.1"], ["--slope", "0,1.5708"],
                                  ["--slope", "nan"], ["--slope", "0:1:-0.1"],
                                  ["--thrust", "0:-50:5"], ["--mu", "0"]])
def test_cli_slope_map_bad_input(args, cli, tmp_path, monkeypatch):
    """Bad input: one line naming the option, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "map"
    r = cli("slope", ROBOT5, GAIT5, *args, "--out", out)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and f"option {args[0]}" in lines[0], lines
    assert not out.exists()


def test_map_steepest_on_one_side_of_level(walker5):
    """Where every walkable slope of a thrust is uphill (walker5_thrust at -50 N), no downhill
    slope walks: steepest_downhill is None, not the lowest uphill slope; the band is
    lowest/highest. A lower end is the map's edge only at the map's first slope (the user
    robot of a 6-link tail walker got "from 0.02 (the map's edge)" at the map's last slope)."""
    from thrustwalk_cli.studies.slope import slope_map

    r = slope_map(walker5, [-0.1, 0.0, 0.1], [0.0, -50.0])
    w50 = r.slopes[r.walkable[:, 1]]
    assert w50.size and w50.min() > 0.0  # the premise: only uphill slopes walk at -50 N
    per = r.document()["per_thrust"][1]
    assert per["steepest_downhill"] is None
    assert per["steepest_uphill"] == per["highest"] == w50.max()
    assert per["lowest"] == w50.min()
    assert "with -50 N from 0.1 up to 0.1 (the map's edge) rad" in r.headline
    up = slope_map(walker5, [0.05, 0.1], [-50.0])  # walkable only uphill in the whole map
    assert up.success and up.steepest()["downhill"] is None
    assert "downhill none" in up.headline
