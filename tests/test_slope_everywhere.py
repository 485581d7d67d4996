"""Slope (and terrain) on every remaining command (issue 27, SPEC 14): robustness, control
--terrain, shape, optimize, design-gait and sweep files.

Each slope result is compared with an independent route: the robot on level ground with its
gravity turned (``test_slope.turned_robot``: built without the slope code), a world-frame
computation rotated by hand, or the single-command run the result must equal.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from test_slope import turned_robot

from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.model.compiler import load_model
from thrustwalk_cli.studies.rough_ground import plan_rough_ground, run_rough_ground
from thrustwalk_cli.thrust.schedule import Schedule
from thrustwalk_cli.walker import load_walker, walker_from

DATA = Path(__file__).resolve().parent / "data"
ROBOT5, GAIT5 = str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml")


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return load_walker(ROBOT5, GAIT5)


def _turn(v, gamma: float) -> np.ndarray:
    """A world-frame vector in the slope frame, by hand: Rot(-gamma) v."""
    c, s = math.cos(gamma), math.sin(gamma)
    return np.array([c * v[0] + s * v[1], -s * v[0] + c * v[1]])


def _turned_cycle(walker, gamma: float, thrust: float):
    """The limit cycle of ``walker`` under ``thrust`` [N] on its first thruster, from the
    robot on level ground with gravity turned (independent of the slope code)."""
    robot2, grav = turned_robot(walker.robot, gamma)
    w2 = walker_from(load_model(robot2), walker.gait)
    F = np.zeros((1, len(walker.robot.thrusters)))
    if F.shape[1]:
        F[0, 0] = thrust
    return limit_cycles(w2.zd, Schedule.constant(w2.zd, np.hstack([F, [grav]])))[0]


# ------------------------------------------------------------------------------ robustness
def test_robustness_push_trial_on_a_slope_equals_a_simulation_of_the_same_push(walker5):
    """A push trial on a slope (world-frame thruster, a push with a vertical part): the
    strategy's orbit is the turned robot's (zeta* to 1e-10); the push's impulsive ground
    reaction is the level-ground robot's at the turned posture rotated into the slope frame by
    hand; and zeta^- of every step equals a compiled simulation of the slope walker with the
    push turned into the slope frame by hand (1e-10 relative)."""
    from thrustwalk_cli.resilience.push import push_point, stance_impulse
    from thrustwalk_cli.resilience.trials import Trial, TrialRunner
    from thrustwalk_cli.simulation.batch import simulate_batch
    from thrustwalk_cli.simulation.closed_loop import SimConfig
    from thrustwalk_cli.simulation.full_order import Start, initial_state
    from thrustwalk_cli.studies.robustness import plan_robustness, run_robustness

    gamma, P, phase, steps = 0.04, 3.0, 0.4, 3
    d = np.array([1.0, -0.5]) / math.hypot(1.0, 0.5)
    plan = plan_robustness(walker5, push_impulse=[P], push_phase=[phase],
                           strategy=["constant:-20"], steps=steps, basin_grid=0,
                           push_direction=tuple(d), push_duration=0.2, mu=2.0, slope=gamma)
    res = run_robustness(plan, workers=1)
    doc = res.document()
    assert doc["slope"]["angle"] == gamma and doc["settings"]["slope"] == gamma
    orbit = doc["strategies"][0]["orbit"]
    ref = _turned_cycle(walker5, gamma, -20.0)
    assert orbit["zeta_star"] == pytest.approx(ref.zeta_star, rel=1e-10)
    assert orbit["speed"] == pytest.approx(ref.speed, rel=1e-10)
    assert orbit["climb_rate"] == pytest.approx(ref.speed * math.sin(gamma), rel=1e-10)
    trial = res.records[0]["document"]
    assert trial["outcome"] == "recovered", trial["reason"]
    # the simulation of the same push, turned into the slope frame by hand
    ws, real = walker5.on_slope(gamma), plan.realized[0]
    x0 = initial_state(ws.zd, real.thrust, Start(zeta_minus=real.zeta_ref))
    row = np.array([1.0, phase, 0.0, 1.0, *_turn(P * d, gamma)])
    b = simulate_batch(ws.zd, real.thrust, x0[None], SimConfig(steps=steps), pushes=row[None],
                       workers=1)
    assert bool(b.success[0])
    np.testing.assert_allclose(trial["zeta_minus"], b.field("zeta_minus")[0], rtol=1e-10)
    # the push's ground reaction: the level-ground robot at the turned posture, rotated
    point = push_point(walker5.model, None, 1.0, tuple(d))
    N = walker5.model.n
    alpha = ws.zd.alpha_i + phase * (ws.zd.alpha_f - ws.zd.alpha_i)
    q = ws.zd.maps.q_Z(np.array(alpha)).copy()
    q[N - 1] += gamma
    F_world = stance_impulse(walker5.model, q, point, P * d)
    got = TrialRunner(ws.zd, real, point, steps=1).push_check(Trial(P, phase))[0]["reaction"]
    np.testing.assert_allclose(got, _turn(F_world, gamma), rtol=1e-8, atol=1e-9)


def test_robustness_slope_zero_is_level_ground(walker5):
    """--slope 0: the same trials, keys and identity as without the option (no trial run)."""
    from thrustwalk_cli.studies.robustness import plan_robustness

    kw = dict(push_impulse=[1.0, 2.0], push_phase=[0.5], strategy=["none", "constant:-20"],
              basin_grid=3)
    a, b = plan_robustness(walker5, **kw), plan_robustness(walker5, slope=0.0, **kw)
    assert a.identity == b.identity and a.settings == b.settings and "slope" not in a.settings
    c = plan_robustness(walker5, slope=-0.02, **kw)
    assert c.identity != a.identity and c.settings["slope"] == -0.02
    assert all(dict(t.settings)["slope"] == -0.02 for t in c.tasks)


def test_robustness_cli_on_a_slope(cli, tmp_path, monkeypatch):
    """robustness --slope from another folder: the slope block, the orbit's climb rate; bad
    slopes one line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    r = cli("robustness", ROBOT5, GAIT5, "--push-impulse", "1", "--push-phase", "0.5",
            "--strategy", "constant:-20", "--basin-grid", "0", "--steps", "2", "--slope",
            "-0.03", "--workers", "1", "--out", out, "--quiet", "--formats", "")
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "robustness.json").read_text())
    assert doc["slope"]["angle"] == -0.03 and doc["units"]["climb_rate"] == "m/s"
    o = doc["strategies"][0]["orbit"]
    assert o["climb_rate"] == pytest.approx(o["speed"] * math.sin(-0.03), rel=1e-15)
    (tmp_path / "up.yaml").write_text("steps: [0.004]\n")
    r = cli("robustness", ROBOT5, GAIT5, "--push-impulse", "1", "--push-phase", "0.5",
            "--strategy", "none", "--basin-grid", "0", "--steps", "2", "--terrain", "up.yaml",
            "--workers", "1", "--out", tmp_path / "t", "--quiet", "--formats", "")
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "t" / "robustness.json").read_text())
    assert doc["settings"]["terrain"]["heights"] == [0.004, 0.0]
    (tmp_path / "bad.yaml").write_text("rough: {distribution: cauchy, sigma: 0.01}\n")
    for args in (["--slope", "nan"], ["--slope", "1.6"], ["--slope", "-inf"],
                 ["--terrain", "bad.yaml"]):
        bad = args[1]
        bad_out = tmp_path / f"bad{bad}"
        r = cli("robustness", ROBOT5, GAIT5, *args, "--out", bad_out)
        assert r.exit_code == 2 and (args[0] in r.output or "bad.yaml" in r.output), r.output
        assert len(r.output.strip().splitlines()) == 1 and not bad_out.exists()


def test_robustness_on_a_terrain_equals_simulate_on_it(walker5):
    """robustness --terrain: an unpushed trial walks zeta^- per step as simulate --terrain of
    the same strategy from the same orbit (1e-10); a terrain of zero heights gives the level
    trials bit for bit (but for the failed step's height: 0, not None); a drop past s_max is
    a fall by missed footing."""
    from thrustwalk_cli.description.terrain import Terrain
    from thrustwalk_cli.studies.robustness import plan_robustness, run_robustness
    from thrustwalk_cli.studies.simulate import simulate

    kw = dict(push_impulse=[0.0, 2.0], push_phase=[0.5], strategy=["none"], steps=4,
              basin_grid=0, push_duration=0.2, mu=2.0)
    terrain = Terrain(steps=(0.005, -0.003))
    plan = plan_robustness(walker5, terrain=terrain, **kw)
    res = run_robustness(plan, workers=1)
    assert res.document()["settings"]["terrain"]["heights"] == [0.005, -0.003, 0.0, 0.0]
    sim = simulate(walker5, steps=4, thrust=[0.0], thrust_model="ideal", terrain=terrain,
                   zeta0=plan.realized[0].zeta_ref).document()
    np.testing.assert_allclose(res.records[0]["document"]["zeta_minus"],
                               [st["zeta_minus"] for st in sim["steps"]], rtol=1e-10)
    level = run_robustness(plan_robustness(walker5, **kw), workers=1)
    zero = run_robustness(plan_robustness(walker5, terrain=Terrain(steps=(0.0,)), **kw),
                          workers=1)
    for a, b in zip(level.records, zero.records):  # but the failed step's height: level
        da, db = dict(a["document"]), dict(b["document"])  # ground has no terrain to say it
        assert da.pop("failed_height_reason") == "no terrain: level ground"
        assert da.pop("failed_height") is None
        assert db.pop("failed_height") == (None if db["step"] is None else 0.0)
        db.pop("failed_height_reason")
        assert da == db
    drop = run_robustness(plan_robustness(walker5, terrain=Terrain(steps=(-0.2,), s_max=1.02),
                                          **{**kw, "push_impulse": [0.0]}), workers=1)
    d = drop.records[0]["document"]
    assert d["outcome"] == "fell" and "missed its footing" in d["reason"]


def test_robustness_terrain_trials_carry_the_failed_steps_height(cli, tmp_path, monkeypatch):
    """robustness --terrain FILE: each trial's record and trials.csv carry the height of the
    step it failed on (the file's height at its failed step: a drop past s_max missed at step
    2, a push that lifts the foot on the 4 mm step up of step 1), and None with the reason when
    every step was walked; level ground has no such column (as before)."""
    import csv

    monkeypatch.chdir(tmp_path)
    (tmp_path / "drop.yaml").write_text("steps: [0.004, -0.2]\ns_max: 1.02\n")
    (tmp_path / "up.yaml").write_text("steps: [0.004]\n")
    base = ["robustness", ROBOT5, GAIT5, "--push-impulse", "0,1", "--push-phase", "0.5",
            "--strategy", "none", "--basin-grid", "0", "--steps", "3", "--mu", "2",
            "--workers", "1", "-q", "--formats", "csv"]
    heights = {"drop.yaml": [0.004, -0.2], "up.yaml": [0.004]}
    for name in heights:
        r = cli(*base, "--terrain", name, "--out", name[:-5])
        assert r.exit_code == 0, r.output
        out = tmp_path / name[:-5]
        recs = [json.loads(p.read_text()) for p in (out / "trials").glob("*.json")]
        rows = list(csv.DictReader(ln for ln in (out / "trials.csv").read_text().splitlines()
                                   if not ln.startswith("#")))
        assert len(recs) == len(rows) == 2
        seen = set()
        for rec, row in zip(sorted(recs, key=lambda d: d["key"]),
                            sorted(rows, key=lambda d: d["key"])):
            d = rec["document"]
            if d["outcome"] in ("recovered", "unsettled"):
                assert d["failed_height"] is None and "no failure" in d["failed_height_reason"]
                assert row["failed_height_m"] == ""
                seen.add("walked")
            else:
                want = (heights[name] + [0.0] * 3)[d["step"] - 1]
                assert d["failed_height"] == want and d["failed_height_reason"] is None
                assert float(row["failed_height_m"]) == want
                seen.add((d["outcome"], d["step"]))
        # the unpushed trial: misses the drop of step 2, or walks past the step up
        assert (("fell", 2) if name == "drop.yaml" else "walked") in seen, seen
        assert ("lifted", 1) in seen, seen  # the push of 1 N s, on the step up
    r = cli(*base, "--out", "level")
    assert r.exit_code == 0, r.output
    assert "failed_height" not in (tmp_path / "level" / "trials.csv").read_text()


# ------------------------------------------------------------------------- control --terrain
def test_control_on_steps_equals_simulate_on_the_same_terrain(walker5):
    """control --terrain: the uncontrolled plant (zero thrust) on a step up then a step down
    walks zeta^- per step as ``simulate --terrain`` of the same file (the simulate study's
    own loop: 1e-8 relative); every step records the file's height; the controller, whose
    step model is level ground, brings the walker back to its reference after the steps."""
    from thrustwalk_cli.description.terrain import Terrain
    from thrustwalk_cli.studies.control import control
    from thrustwalk_cli.studies.simulate import simulate

    terrain = Terrain(steps=(0.01, -0.005))
    r = control(walker5, reference="nominal", steps=8, terrain=terrain)
    doc = r.document()
    heights = [0.01, -0.005] + [0.0] * 6
    assert [e["terrain_height"] for e in doc["steps"]] == heights
    assert doc["settings"]["terrain"]["steps"] == [0.01, -0.005]
    assert doc["steps"][-1]["zeta_minus_error"] < 1e-8
    assert doc["steps"][0]["zeta_minus_error"] > 0.1  # the step up threw it off
    zs0 = doc["settings"]["nominal_zeta_star"]
    sim = simulate(walker5, steps=8, thrust=[0.0], thrust_model="ideal", terrain=terrain,
                   zeta0=zs0).document()
    want = [st["zeta_minus"] for st in sim["steps"]]
    assert [st["terrain_height"] for st in sim["steps"]] == heights
    np.testing.assert_allclose([s.x_next for s in r.uncontrolled.steps], want, rtol=1e-8)


def test_control_zero_terrain_is_level_ground(walker5):
    """A terrain of zero heights: the controlled and uncontrolled runs of level ground, step
    for step and bit for bit (with each step's terrain_height 0 beside)."""
    from thrustwalk_cli.description.terrain import Terrain
    from thrustwalk_cli.studies.control import control

    kw = dict(reference="nominal", steps=3, noise=0.01, seed=3)
    a = control(walker5, **kw)
    b = control(walker5, terrain=Terrain(steps=(0.0,)), **kw)
    for x, y in zip(a.controlled.steps + a.uncontrolled.steps,
                    b.controlled.steps + b.uncontrolled.steps):
        assert (x.x_next, x.step_time, x.speed, x.x_meas) == (y.x_next, y.step_time, y.speed,
                                                              y.x_meas)
        assert y.terrain_height == 0.0


def test_control_terrain_cli(cli, tmp_path, monkeypatch):
    """control --terrain from another folder: the steps' heights in JSON and CSV; a terrain
    with a NaN height or a slope beside --slope: one line, exit 2, nothing written."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    (tmp_path / "up.yaml").write_text("description: a step up\nslope: -0.02\nsteps: [0.01]\n")
    out = tmp_path / "out"
    r = cli("control", ROBOT5, GAIT5, "--reference", "nominal", "--steps", "3", "--terrain",
            "../up.yaml", "--out", out, "--quiet", "--formats", "csv")
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "control.json").read_text())
    assert doc["slope"]["angle"] == -0.02
    assert [e["terrain_height"] for e in doc["steps"]] == [0.01, 0.0, 0.0]
    assert "terrain_height_m" in (out / "control_steps.csv").read_text()
    (tmp_path / "bad.yaml").write_text("steps: [.nan]\n")
    for args in (["--terrain", "../bad.yaml"], ["--terrain", "../up.yaml", "--slope", "0.1"]):
        bad_out = tmp_path / "bad_out"
        r = cli("control", ROBOT5, GAIT5, "--reference", "nominal", *args, "--out", bad_out)
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
        assert not bad_out.exists()


# ------------------------------------------------------------------------------ shape
def test_shape_on_a_slope_equals_the_turned_robot(walker5):
    """shape --slope (force mode on the world-frame thruster): every shaped fixed point and
    speed equals the turned robot's limit cycle under the same schedule (plus its gravity
    thrusters) to 1e-12; the climb rate is speed sin(slope); slope 0 is level ground."""
    from thrustwalk_cli.studies.shape import shape

    gamma = -0.04
    kw = dict(knots=[0, 0.3, 0.6, 1], pattern="-k*j", k=[0, 5, 10], field_k=5, mode="force",
              thruster="back")
    r = shape(walker5, slope=gamma, **kw)
    doc = r.document()
    assert r.success and doc["slope"]["angle"] == gamma
    robot2, grav = turned_robot(walker5.robot, gamma)
    w2 = walker_from(load_model(robot2), walker5.gait)
    S = r.schedule
    n, J, _ = S.force.shape
    F2 = np.concatenate([S.force, np.broadcast_to(np.array(grav), (n, J, len(grav)))], axis=2)
    ref = limit_cycles(w2.zd, Schedule(S.knots, F2, S.generalized))
    for e, c in zip(doc["schedules"], ref):
        assert e["zeta_star"]["shaped"] == pytest.approx(c.zeta_star, rel=1e-12)
        assert e["speed"] == pytest.approx(c.speed, rel=1e-12)
        assert e["climb_rate"] == pytest.approx(c.speed * math.sin(gamma), rel=1e-12)
    assert shape(walker5, slope=0.0, **kw).document() == shape(walker5, **kw).document()


# ------------------------------------------------------------------------------ design-gait
@pytest.mark.slow
def test_design_gait_on_a_slope_walks_that_slope(cli, tmp_path, monkeypatch):
    """design-gait --slope (bundled 3-link walker, from another folder): the report and the
    gait file's header say the slope; limit-cycle --slope on the written gait file finds it
    walkable at the reported speed along the ground (1e-9), and the turned robot on level
    ground (independent of the slope code) has the same fixed point; a bad slope is one line,
    exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    gamma = 0.05
    r = cli("design-gait", "three_link", "--target-speed", "0.8", "--clearance", "0",
            "--starts", "1", "--slope", str(gamma), "--out", "d", "--name", "up",
            "--formats", "none", "-q")
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / "d" / "up.report.json").read_text())
    fp = rep["fixed_point"]
    assert rep["feasible"] and rep["slope"]["angle"] == gamma
    assert fp["speed"] == pytest.approx(0.8, rel=1e-6)
    assert fp["climb_rate"] == pytest.approx(fp["speed"] * math.sin(gamma), rel=1e-15)
    text = (tmp_path / "d" / "up.yaml").read_text()
    assert f"# Designed for the slope {gamma!r} rad" in text
    r = cli("limit-cycle", "three_link", "d/up.yaml", "--slope", str(gamma), "--thrust", "0",
            "--out", "lc", "--formats", "", "-q")
    assert r.exit_code == 0, r.output
    c = json.loads((tmp_path / "lc" / "limit_cycles.json").read_text())["cycles"][0]
    assert c["walkable"], c["verdict"]
    assert c["speed"] == pytest.approx(fp["speed"], rel=1e-9)
    assert c["zeta_star"] == pytest.approx(fp["zeta_star"], rel=1e-9)
    w = load_walker("three_link", str(tmp_path / "d" / "up.yaml"))
    ref = _turned_cycle(w, gamma, 0.0)
    assert ref.zeta_star == pytest.approx(fp["zeta_star"], rel=1e-9)
    for bad in ("nan", "1.6", "-inf"):
        r = cli("design-gait", "three_link", "--target-speed", "0.8", "--slope", bad, "--out",
                f"bad{bad}")
        assert r.exit_code == 2 and "--slope" in r.output, r.output
        assert len(r.output.strip().splitlines()) == 1 and not (tmp_path / f"bad{bad}").exists()


# ------------------------------------------------------------------------------ sweeps
def test_sweep_over_slope_equals_limit_cycle_runs(cli, tmp_path, monkeypatch, walker5):
    """A limit-cycle sweep with a `slope` axis (3 values) gives, point by point, the numbers
    of limit-cycle --slope on each slope (bit for bit: the same computation), and its points'
    documents the slope block and climb rate; a level-ground sweep keeps its settings (no
    `slope` key: keys and identity as before)."""
    import shutil

    from thrustwalk_cli.studies.limit_cycle import limit_cycle
    from thrustwalk_cli.studies.sweep import load_sweep

    monkeypatch.chdir(tmp_path)
    for f in (ROBOT5, GAIT5):
        shutil.copy(f, tmp_path)
    slopes = [-0.05, 0.0, 0.05]
    text = ("name: slopes\nstudy: limit-cycle\nrobot: walker5.yaml\n"
            "gait: walker5_thrust.yaml\n"
            "settings:\n  thruster: back\n  thrust: -20\n"
            f"grid:\n  slope: {{values: {slopes}}}\n"
            "collect: [speed, zeta_star, step_time, walkable, min_vertical_force]\n")
    (tmp_path / "s.yaml").write_text(text)
    r = cli("sweep", "s.yaml", "--out", "out", "--workers", "1", "-q", "--formats", "")
    assert r.exit_code == 0, r.output
    recs = sorted((json.loads(p.read_text()) for p in (tmp_path / "out" / "points").glob(
        "*.json")), key=lambda d: d["index"])
    assert len(recs) == 3
    for g, rec in zip(slopes, recs):
        assert rec["values"]["slope"] == g
        want = limit_cycle(walker5, [-20.0], "back", slope=g).document()
        c, f = want["cycles"][0], rec["fields"]
        for key in ("speed", "zeta_star", "step_time", "walkable"):
            assert f[key] == c[key], (g, key)
        assert f["min_vertical_force"] == c["contact"]["min_vertical_force"]
        got = rec["document"]
        assert got.get("slope", {}).get("angle") == (g if g else None)
        if g:
            assert got["cycles"][0]["climb_rate"] == c["climb_rate"]
    flat = load_sweep(str(Path(__file__).resolve().parents[1] / "sweeps" /
                          "thrust_torso_mass.yaml"))
    assert "slope" not in dict(flat.spec.settings)


@pytest.mark.slow  # two gait designs (about 10 s)
def test_gait_library_over_slopes(cli, tmp_path, monkeypatch):
    """A design-gait sweep with a `slope` axis [0, 0.03] (bundled 3-link, from another
    folder): library.csv has the slope column, each gait file's header names its slope, and
    limit-cycle --slope on each written gait file finds it walkable at the speed along the
    ground and the zeta* the library reports (1e-9)."""
    import csv

    monkeypatch.chdir(tmp_path)
    (tmp_path / "lib.yaml").write_text(
        "name: slope_library\nstudy: design-gait\nrobot: three_link\n"
        "settings:\n  target_speed: 0.8\n  clearance: 0\n  starts: 1\n  max_iter: 100\n"
        "grid:\n  slope: {values: [0, 0.03]}\ncollect: [feasible, effort]\n")
    r = cli("sweep", "lib.yaml", "--out", "out", "--workers", "1", "-q", "--formats", "csv")
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(ln for ln in (tmp_path / "out" / "library.csv").read_text()
                               .splitlines() if not ln.startswith("#")))
    assert [float(row["slope_rad"]) for row in rows] == [0.0, 0.03]
    for row in rows:
        assert row["feasible"] == "true"
        gamma, file = float(row["slope_rad"]), tmp_path / "out" / row["file"]
        head = [ln for ln in file.read_text().splitlines() if ln.startswith("#")]
        said = (f"# Designed for the slope {gamma!r} rad" if gamma else
                "# Designed for level ground (slope 0 rad)")
        assert any(ln.startswith(said) for ln in head), head
        out = tmp_path / f"lc{gamma}"
        r = cli("limit-cycle", "three_link", str(file), "--slope", str(gamma), "--thrust", "0",
                "--out", out, "--formats", "", "-q")
        assert r.exit_code == 0, r.output
        c = json.loads((out / "limit_cycles.json").read_text())["cycles"][0]
        assert c["walkable"], c["verdict"]
        assert c["speed"] == pytest.approx(float(row["speed_m_s"]), rel=1e-9)
        assert c["zeta_star"] == pytest.approx(float(row["zeta_star_kg2m4_s2"]), rel=1e-9)


# ------------------------------------------------------------------------------ optimize
@pytest.mark.slow
def test_optimize_on_a_slope_reaches_the_target_on_the_turned_robot(walker5):
    """optimize --slope (uphill, world-frame thruster): the minimum-effort schedule, put on
    the turned robot on level ground (its gravity thrusters held at m_i g sin(slope)), walks at
    the target speed with the reported zeta* (1e-10) and keeps the stance force in the cone;
    the document says the slope and the climb rate; slope 0 is level ground."""
    from thrustwalk_cli.contact.evaluate import evaluate
    from thrustwalk_cli.studies.optimize import optimize_schedule

    gamma, v = 0.05, 0.6
    r = optimize_schedule(walker5, target_speed=v, knots=[0, 0.5, 1], slope=gamma)
    doc = r.document()
    assert r.success and doc["slope"]["angle"] == gamma
    assert doc["climb_rate"] == pytest.approx(doc["speed"] * math.sin(gamma), rel=1e-15)
    robot2, grav = turned_robot(walker5.robot, gamma)
    w2 = walker_from(load_model(robot2), walker5.gait)
    knots = np.array(doc["knots_alpha"])
    F = np.zeros((1, len(knots) - 1, len(robot2.thrusters)))
    F[0, :, 0] = doc["values"]
    F[0, :, 1:] = grav
    sched = Schedule(knots, F, np.zeros((1, len(knots) - 1)))
    lc = limit_cycles(w2.zd, sched)[0]
    assert lc.speed == pytest.approx(v, rel=1e-10)
    assert lc.zeta_star == pytest.approx(doc["zeta_star"], rel=1e-10)
    rep = evaluate(w2.model, w2.zd, sched, mu=walker5.gait.mu, eps=0.0, cycles=[lc],
                   polynomial=False, torque=False, profiles=False)
    assert rep.cases[0].feasible, rep.cases[0].reason
    assert f"# Optimized for the slope {gamma!r} rad" in r.attachments(doc)[r.gait_file]
    a = optimize_schedule(walker5, target_speed=v, knots=[0, 0.5, 1])
    b = optimize_schedule(walker5, target_speed=v, knots=[0, 0.5, 1], slope=0.0)
    assert a.document() == b.document() and "slope" not in a.document()


# ------------------------------------------------------------------------------ rough-ground
_NO_MESH = {"computed": False, "reason": "not asked", "sigmas": []}


def test_rough_ground_on_a_slope_walks_as_simulate_on_it(walker3):
    """rough-ground --slope (the 3-link walker, downhill): a Monte-Carlo trial at sigma 0 is
    ``simulate --slope`` of the same steps from the same fixed point (zeta^- over the run: its
    min and max equal the simulation's, 1e-12), or its failure: with a friction cone the
    slope's stance force leaves, the trial slips on the first step whose simulated friction
    ratio passes mu. The mesh chain is on the slope too: the zeta^- its walk visits brackets
    the slope's simulated zeta^-, far from the level ground's."""
    from thrustwalk_cli.studies.simulate import simulate

    gamma, cap = -0.03, 12
    plan = plan_rough_ground(walker3, sigma=[0.0, 0.0005], strategy=["none"], trials=1,
                             cap=cap, mesh=4, terrain_samples=4, slope=gamma)
    assert plan.settings["slope"] == gamma
    assert all(dict(t.settings)["slope"] == gamma for t in plan.tasks)
    res = run_rough_ground(plan, workers=1)
    doc = res.document()
    assert doc["slope"]["angle"] == gamma and doc["units"]["slope"] == "rad"
    trial = res.records[0]["document"]
    assert trial["sigma"] == 0.0 and trial["outcome"] == "censored", trial["reason"]
    zs = plan.realized[0].zeta_ref
    sim = simulate(walker3, steps=cap, thrust=[0.0], thrust_model="ideal", slope=gamma,
                   zeta0=zs).document()
    assert sim["success"]
    z = [zs] + [st["zeta_minus"] for st in sim["steps"]]
    assert trial["zeta_min"] == pytest.approx(min(z), rel=1e-12)
    assert trial["zeta_max"] == pytest.approx(max(z), rel=1e-12)
    level = simulate(walker3, steps=1, thrust=[0.0], thrust_model="ideal").document()
    z_level = level["steps"][0]["zeta_minus"]
    lo, hi = doc["strategies"][0]["mesh"]["visited"]
    assert lo <= sim["steps"][-1]["zeta_minus"] <= hi and not lo <= z_level <= hi
    # a failure: the cone mu = 0.2 on the steeper slope
    gamma, mu = -0.1, 0.2
    plan = plan_rough_ground(walker3, sigma=[0.0], strategy=["none"], trials=1, cap=cap,
                             mu=mu, slope=gamma, mesh=4, terrain_samples=4)
    trial = run_rough_ground(plan, workers=1, meshes=[_NO_MESH]).records[0]["document"]
    sim = simulate(walker3, steps=cap, thrust=[0.0], thrust_model="ideal", slope=gamma,
                   mu=mu, zeta0=plan.realized[0].zeta_ref).document()
    first = next(st["step"] for st in sim["steps"] if max(
        st["max_friction_ratio"], st["impulse_friction_ratio"]) > mu)
    assert trial["outcome"] == "slipped" and trial["failed_step"] == first, trial["reason"]
    assert trial["failed_height"] == 0.0


def test_rough_ground_slope_zero_is_level_ground(walker3):
    """slope 0: the same trials, keys, settings and identity as without the option (no run),
    and no slope block; a slope changes the identity."""
    kw = dict(sigma=[0.003, 0.005], strategy=["none", "constant:-10"], trials=3, cap=50)
    a, b = plan_rough_ground(walker3, **kw), plan_rough_ground(walker3, slope=0.0, **kw)
    assert a.identity == b.identity and a.settings == b.settings
    assert [t.key for t in a.tasks] == [t.key for t in b.tasks]
    assert "slope" not in a.settings and all("slope" not in dict(t.settings) for t in a.tasks)
    c = plan_rough_ground(walker3, slope=0.02, **kw)
    assert c.identity != a.identity and c.settings["slope"] == 0.02


def test_rough_trial_sweep_on_a_slope_equals_rough_ground(cli, tmp_path, monkeypatch,
                                                          walker3):
    """A rough-trial sweep file with `slope` (bundled 3-link, from another folder): each
    point's record is the rough-ground run's trial of the same (sigma, trial) on the same
    slope, document for document."""
    monkeypatch.chdir(tmp_path)
    gamma, sigma = -0.03, 0.004
    (tmp_path / "s.yaml").write_text(
        "name: rough_slope\nstudy: rough-trial\nrobot: three_link\ngait: three_link_walk\n"
        f"settings:\n  strategy: none\n  sigma: {sigma}\n  cap: 30\n  slope: {gamma}\n"
        "grid:\n  trial: {values: [0, 1]}\n"
        "collect: [outcome, steps_completed, failed_height]\n")
    r = cli("sweep", "s.yaml", "--out", "out", "--workers", "1", "-q", "--formats", "")
    assert r.exit_code == 0, r.output
    recs = sorted((json.loads(p.read_text()) for p in (tmp_path / "out" / "points").glob(
        "*.json")), key=lambda d: d["index"])
    plan = plan_rough_ground(walker3, sigma=[sigma], strategy=["none"], trials=2, cap=30,
                             slope=gamma)
    ref = run_rough_ground(plan, workers=1, meshes=[_NO_MESH])
    assert len(recs) == 2
    for rec, want in zip(recs, ref.records):
        assert rec["values"]["trial"] == want["document"]["trial"]
        assert rec["document"] == want["document"]
        assert rec["fields"] == want["fields"]


def test_rough_ground_cli_on_a_slope(cli, tmp_path, monkeypatch, walker3):
    """rough-ground --slope from another folder: the slope block and settings, and each trial
    record is the study's on that slope."""
    monkeypatch.chdir(tmp_path)
    r = cli("rough-ground", "three_link", "--sigma", "0.004", "--strategy", "none", "--trials",
            "2", "--cap", "20", "--mesh", "4", "--terrain-samples", "4", "--slope", "-0.03",
            "--workers", "1", "--out", "out", "-q", "--formats", "csv")
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "out" / "rough_ground.json").read_text())
    assert doc["slope"]["angle"] == -0.03 and doc["settings"]["slope"] == -0.03
    plan = plan_rough_ground(walker3, sigma=[0.004], strategy=["none"], trials=2, cap=20,
                             mesh=4, terrain_samples=4, slope=-0.03)
    assert doc["identity"] == plan.identity
    ref = run_rough_ground(plan, workers=1, meshes=[_NO_MESH])
    for t, want in zip(plan.tasks, ref.records):
        got = json.loads((tmp_path / "out" / "trials" / f"{t.key[:20]}.json").read_text())
        assert got["document"] == want["document"]


@pytest.mark.slow  # (this session's additions; CI runs every test)
def test_rough_ground_strategies_say_their_orbit_on_a_slope(walker5):
    """The rough-ground document gives each strategy's orbit on the slope (walker5, a user's
    robot, downhill): its step time is the full-order closed loop's, simulated from the
    strategy's fixed point on the same slope with the same thrust (independent: the compiled
    simulation, not the zero dynamics); speed = step length / step time along the ground and
    the rate of climb speed sin(gamma), with their units."""
    from thrustwalk_cli.studies.simulate import simulate

    gamma = -0.02
    plan = plan_rough_ground(walker5, sigma=[1e-9], strategy=["none", "constant:-10"],
                             trials=1, cap=5, mesh=4, terrain_samples=4, slope=gamma)
    # the orbits are the plan's: the mesh chains (checked on a slope above) are not computed
    res = run_rough_ground(plan, workers=1, meshes=[_NO_MESH] * 2)
    doc = res.document()
    assert doc["units"]["climb_rate"] == "m/s" and doc["units"]["step_time"] == "s"
    for k, (s, thrust) in enumerate(zip(doc["strategies"], (0.0, -10.0))):
        o = s["orbit"]
        assert o["exists"] and o["zeta_star"] == s["zeta_ref"]
        sim = simulate(walker5, steps=3, thrust=[thrust], thrust_model="ideal", slope=gamma,
                       zeta0=res.plan.realized[k].zeta_ref).document()
        assert sim["steps"][-1]["step_time"] == pytest.approx(o["step_time"], rel=1e-8)
        assert o["speed"] == pytest.approx(o["step_length"] / o["step_time"], rel=1e-12)
        assert o["climb_rate"] == pytest.approx(o["speed"] * math.sin(gamma), rel=1e-12)
    assert doc["strategies"][1]["orbit"]["speed"] > doc["strategies"][0]["orbit"]["speed"]
