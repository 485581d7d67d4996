"""Gait design (``thrustwalk_cli.design``, ``thrustwalk design-gait``): designed gaits re-checked
by the independent limit-cycle, contact and kinematics code paths; infeasible requests name the
blocking constraint; the written YAML reproduces the fixed point; bad input exits 2."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from independent import point, swing_foot

from thrustwalk_cli.contact.evaluate import evaluate
from thrustwalk_cli.design.problem import FAMILIES, Problem, cell_minima, default_alpha
from thrustwalk_cli.design.solver import solve_design
from thrustwalk_cli.design.spec import DesignSpec
from thrustwalk_cli.errors import ComputationError
from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
from thrustwalk_cli.simulation.full_order import Start, simulate
from thrustwalk_cli.thrust.schedule import Schedule
from thrustwalk_cli.walker import load_walker

REPO = Path(__file__).resolve().parents[1]
SPEED = 0.8  # [m/s] 3-link design target (the shipped gait's speed)
# STICK_PDF: a design-gait run below that is not about files draws its stick figure as PNG
# only (--formats png); the default PNG + PDF is written by
# tests/test_robots.py::test_design_gait_for_a_robot_without_thrusters


def _thrust(model, gait) -> np.ndarray:
    F = np.zeros(model.n_thrusters)
    if gait.thrust is not None:
        for name, vals in gait.thrust.values:
            F[model.robot.thruster_names.index(name)] = vals[0]
    return F


@pytest.fixture(scope="module")
def designed3(tmp_path_factory, three_link, cli):
    """One short 3-link design through the CLI: (gait path, report, CLI result)."""
    out = tmp_path_factory.mktemp("design") / "walk3.yaml"
    args = ["design-gait", "three_link", "--target-speed", str(SPEED), "--clearance", "0",
            "--starts", "1", "--seed", "0", "--out", str(out.parent), "--name", "walk3", "-q"]
    with pytest.MonkeyPatch.context() as mp:  # the command line recorded in the provenance
        mp.setattr(sys, "argv", ["thrustwalk", *args])
        res = cli(*args)
    report = json.loads(out.with_name("walk3.report.json").read_text())
    return out, report, res


def _orbit(model, path):
    w = load_walker(None, str(path))
    assert w.model.key == model.key
    gait, zd = w.gait, w.zd
    sched = Schedule.constant(zd, _thrust(model, gait)[None, :])
    return gait, zd, sched, limit_cycles(zd, sched)[0]


@pytest.mark.slow
def test_designed_gait_passes_independent_checks(designed3, three_link):
    """Limit cycle (adaptive quadrature), contact feasibility (polished extremes, mu = 0.7) and
    the swing foot from the independent NumPy kinematics all agree with the design."""
    path, report, res = designed3
    assert res.exit_code == 0, res.output
    assert report["feasible"] and report["blocking_constraint"] is None
    gait, zd, sched, lc = _orbit(three_link, path)
    assert lc.exists and lc.stable, lc.reason
    assert 0 < zd.delta_zero_sq <= 0.9
    assert lc.speed == pytest.approx(SPEED, rel=1e-6)
    assert zd.maps.position_residual < 1e-12 and zd.maps.velocity_residual < 1e-12
    eps = 0.1 * three_link.robot.total_mass * three_link.robot.gravity
    case = evaluate(three_link, zd, sched, mu=0.7, eps=eps, profiles=False).cases[0]
    assert case.feasible, case.reason
    assert all(v >= 0 for v in case.margins.values()), case.margins
    # swing foot >= 0 over the step (touching allowed: straight legs), independent kinematics
    s = np.linspace(0.0, 1.0, 2001)
    q = zd.maps.q_Z(zd.alpha_i + s * (zd.alpha_f - zd.alpha_i))
    h = np.array([swing_foot(three_link.robot, qk)[1] for qk in q])
    assert h.min() >= -1e-6, f"swing foot {h.min():.3g} m below ground at s = {s[h.argmin()]}"
    assert h[1000] >= -1e-6  # clearance 0 at mid-step
    assert lc.step_length == pytest.approx(swing_foot(three_link.robot, zd.maps.q_minus)[0],
                                           rel=1e-12)


@pytest.mark.slow
def test_objective_equals_inverse_dynamics_on_the_orbit(designed3, three_link):
    """effort = (1/L) int |u|^2 dt with u from D q'' + h (q(alpha) differentiated numerically,
    alpha'' = d(alpha'^2/2)/dalpha): a path that uses neither the affine stance terms nor the
    design's quadrature. The unactuated row of D q'' + h must vanish on the orbit."""
    path, report, _ = designed3
    gait, zd, sched, lc = _orbit(three_link, path)
    a = np.linspace(zd.alpha_i, zd.alpha_f, 4001)
    d = 1e-4  # [rad] central differences (q_Z and V_Z extend smoothly past the step's ends)

    def half_adot_sq(x):  # alpha'^2 / 2 = kappa_1^2 zeta
        return zd.terms(x)["kappa1"] ** 2 * (lc.zeta_plus + zd.V_Z(x, sched)[0])

    adot = zd.direction * np.sqrt(2.0 * half_adot_sq(a))
    addot = (half_adot_sq(a + d) - half_adot_sq(a - d)) / (2 * d)
    q, qp, qm = zd.maps.q_Z(a), zd.maps.q_Z(a + d), zd.maps.q_Z(a - d)
    dq_da, d2q_da2 = (qp - qm) / (2 * d), (qp - 2 * q + qm) / d**2
    dq = dq_da * adot[:, None]
    ddq = d2q_da2 * adot[:, None] ** 2 + dq_da * addot[:, None]
    tau = np.einsum("gij,gj->gi", three_link.D(q), ddq) + three_link.h(q, dq)
    assert np.abs(tau[:, -1]).max() < 1e-5 * np.abs(tau[:, :-1]).max()
    u2 = (tau[:, :-1] ** 2).sum(axis=1)
    effort = np.trapezoid(u2 / adot, a) / lc.step_length
    assert report["objective"]["value"] == pytest.approx(effort, rel=1e-4)
    assert report["cost"]["peak"] == pytest.approx(np.abs(tau[:, :-1]).max(), rel=1e-3)


@pytest.mark.slow
def test_written_yaml_reproduces_reported_fixed_point(designed3, three_link):
    path, report, _ = designed3
    text = path.read_text()
    assert text.startswith("# Gait designed by thrustwalk design-gait")
    assert "# command: " in text and "design-gait three_link" in text
    assert "robot: three_link" in text and "invariance: auto" in text
    gait, zd, sched, lc = _orbit(three_link, path)
    fp = report["fixed_point"]
    assert lc.zeta_star == pytest.approx(fp["zeta_star"], rel=1e-9)
    assert lc.speed == pytest.approx(fp["speed"], rel=1e-9)
    assert zd.delta_zero_sq == pytest.approx(fp["delta_zero_sq"], rel=1e-12)
    assert np.allclose(gait.coefficients, report["coefficients"], rtol=0, atol=1e-15)
    assert report["reload_check"]["relative_error"] < 1e-9
    prov = report["provenance"]
    assert "design-gait" in prov["command"] and len(prov["robot"]["sha256"]) == 64
    assert not list(path.parent.glob(".*check*")), "temporary check file left behind"


@pytest.mark.slow
def test_impossible_request_reported_infeasible_with_blocking_constraint(tmp_path, cli):
    """5 m/s with mu = 0.1 is beyond the 3-link walker: exit 3, a report that names the
    family blocking the request, and no gait file."""
    out = tmp_path / "fast.yaml"
    res = cli("design-gait", "three_link", "--target-speed", "5", "--mu", "0.1",
              "--clearance", "0", "--starts", "1", "--max-iter", "60",
              "--out", str(tmp_path), "--name", "fast", "-q")
    assert res.exit_code == 3, res.output
    assert "Traceback" not in res.output
    report = json.loads((tmp_path / "fast.report.json").read_text())
    assert not report["feasible"] and not out.exists()
    fam = report["blocking_constraint"]
    assert fam in FAMILIES
    assert f"blocked by {fam}" in res.output and f"blocked by {fam}" in report["reason"]
    viol = report["solver_violations"]
    assert viol[fam] == max(viol.values()) > 1e-5, viol


@pytest.mark.parametrize("args, needle", [
    (["no_such_robot", "--target-speed", "0.8"], "no_such_robot"),
    (["three_link", "--target-speed", "-1"], "--target-speed"),
    (["three_link", "--mu", "0.7"], "--target-speed/--step-length"),
    (["three_link", "--target-speed", "0.8", "--order", "2"], "--order"),
    (["three_link", "--target-speed", "0.8", "--objective", "fast"], "--objective"),
    (["three_link", "--target-speed", "0.8", "--alpha", "q9:1"], "--alpha"),
    (["three_link", "--target-speed", "0.8", "--max-delta-sq", "1.2"], "--max-delta-sq"),
])
def test_bad_input_one_line_exit_2(tmp_path, args, needle, cli):
    res = cli("design-gait", *args, "--out", str(tmp_path / "g"))
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and needle in lines[0], res.output
    assert "Traceback" not in res.output and not (tmp_path / "g").exists()


def test_out_must_be_a_folder(tmp_path, cli):
    res = cli("design-gait", "three_link", "--target-speed", "0.8", "--out",
              str(tmp_path / "g.yaml"))
    assert res.exit_code == 2 and "option --out: a folder is expected" in res.output
    (tmp_path / "file").write_text("x")
    res = cli("design-gait", "three_link", "--target-speed", "0.8", "--out",
              str(tmp_path / "file"))
    assert res.exit_code == 2 and res.output.startswith("error: option --out: ")
    assert "is a file, not a folder" in res.output


def test_default_alpha_is_the_virtual_stance_leg(rabbit, three_link):
    """RABBIT: alpha = c q equals the forward lean of the line from the stance foot to the
    hip (independent kinematics; tibia and femur have equal length); 3-link: minus q3."""
    c = default_alpha(rabbit)
    names = rabbit.robot.coordinate_names
    assert dict(zip(names, c)) == pytest.approx({"q_sk": 0.5, "q_sh": 1.0, "q_wh": 0.0,
                                                 "q_wk": 0.0, "q_T": -1.0})
    rng = np.random.default_rng(3)
    for q in rng.uniform(-0.4, 0.4, size=(5, rabbit.n)):
        hip = point(rabbit.robot, q, "torso", (0.0, 0.0))
        assert c @ q == pytest.approx(np.arctan2(hip[0], hip[1]), abs=1e-12)
    assert default_alpha(three_link) == pytest.approx([0.0, 0.0, -1.0])


def test_cell_minima_finds_dips_between_samples():
    """A quadratic dip between grid points is recovered exactly (the grid minimum misses it);
    a smooth non-quadratic dip sliding across the grid is tracked closely and continuously."""
    s = np.linspace(0.0, 1.0, 101)
    for centre in (0.503, 0.505, 0.5071):
        h = (s - centre) ** 2 - 1e-5
        assert cell_minima(h).min() == pytest.approx(-1e-5, abs=1e-15)
        assert h[1:-1].min() > -0.9e-5
    centres = np.linspace(0.499, 0.501, 41)
    est = np.array([cell_minima(0.3 * np.sin(20 * (s - c)) ** 2 - 1e-5).min() for c in centres])
    grid = np.array([(0.3 * np.sin(20 * (s - c)) ** 2 - 1e-5)[1:-1].min() for c in centres])
    assert np.abs(est + 1e-5).max() < 2e-6 < np.abs(grid + 1e-5).max()
    assert np.abs(np.diff(est)).max() < 1e-6


@pytest.mark.slow
def test_deterministic_given_seed(three_link):
    spec = DesignSpec(speed=SPEED, clearance=0.0, starts=2, seed=7, max_iter=8)
    p1, p2 = Problem(three_link, spec), Problem(three_link, spec)
    x1 = p1.start(np.random.default_rng(7))
    x2 = p2.start(np.random.default_rng(7))
    assert np.array_equal(x1, x2)
    r1, r2 = solve_design(three_link, spec), solve_design(three_link, spec)
    assert r1.gait.A == r2.gait.A and r1.solver_objective == r2.solver_objective


@pytest.mark.slow
def test_thrust_codesign_written_and_reloaded(tmp_path, three_link, cli):
    """Constant hip thrust designed with the gait: within the robot's limits, written as a
    thrust schedule, and the reloaded gait's orbit (with that thrust) is the reported one."""
    out = tmp_path / "thr.yaml"
    res = cli("design-gait", "three_link", "--target-speed", str(SPEED), "--clearance",
              "0", "--starts", "1", "--design-thrust", "--out", str(tmp_path), "--name", "thr",
              "-q", "--formats", "png")  # the stick figure drawn, no PDF (STICK_PDF)
    assert res.exit_code == 0, res.output
    report = json.loads(out.with_name("thr.report.json").read_text())
    F = report["thrust"]
    assert len(F) == three_link.n_thrusters
    for f, t in zip(F, three_link.robot.thrusters):
        assert t.limits[0] <= f <= t.limits[1], t.name
    gait, zd, sched, lc = _orbit(three_link, out)
    assert gait.thrust is not None and list(_thrust(three_link, gait)) == F
    assert lc.zeta_star == pytest.approx(report["fixed_point"]["zeta_star"], rel=1e-9)
    assert lc.speed == pytest.approx(SPEED, rel=1e-6)


@pytest.mark.slow
def test_thrust_range_feasible_for_every_thrust_in_it(tmp_path, three_link, cli):
    """--thrust-range hip_x:-50:0 is imposed at the two ends (affinity in a constant thrust);
    contact.evaluate on the shifted orbits of 11 thrusts across the range confirms it."""
    out = tmp_path / "robust.yaml"
    res = cli("design-gait", "three_link", "--target-speed", str(SPEED), "--clearance",
              "0", "--starts", "1", "--thrust-range", "hip_x:-50:0",
              "--min-vertical-force", "40", "--out", str(tmp_path), "--name", "robust", "-q",
              "--formats", "png")  # the stick figure drawn, no PDF (STICK_PDF)
    assert res.exit_code == 0, res.output
    gait, zd, _, lc = _orbit(three_link, out)
    assert lc.speed == pytest.approx(SPEED, rel=1e-6)
    F = np.zeros((11, three_link.n_thrusters))
    F[:, 0] = np.linspace(-50.0, 0.0, 11)
    cases = evaluate(three_link, zd, Schedule.constant(zd, F), mu=0.7, eps=40.0,
                             profiles=False).cases
    for f, c in zip(F[:, 0], cases):
        assert c.feasible, f"thrust {f} N: {c.reason}"
    assert cases[0].cycle.speed > 2.0 * SPEED  # the thrust really shifts the orbit


def test_shipped_rabbit_gait_meets_the_design_constraints(rabbit):
    """gaits/rabbit_walk.yaml (made by design-gait): stable, contact-feasible with mu = 0.7,
    swing foot >= 3 cm at mid-step and >= 0 over the step, knees in range."""
    w = load_walker(None, "rabbit_walk")
    robot, gait, zd = w.robot, w.gait, w.zd
    assert "design-gait rabbit" in Path(gait.source_file).read_text()
    sched = Schedule.constant(zd, np.zeros((1, rabbit.n_thrusters)))
    lc = limit_cycles(zd, sched)[0]
    assert lc.stable and zd.delta_zero_sq <= 0.9, lc.reason
    eps = 0.1 * robot.total_mass * robot.gravity
    case = evaluate(rabbit, zd, sched, mu=0.7, eps=eps, profiles=False).cases[0]
    assert case.feasible, case.reason
    s = np.linspace(0.0, 1.0, 1001)
    q = zd.maps.q_Z(zd.alpha_i + s * (zd.alpha_f - zd.alpha_i))
    h = np.array([swing_foot(robot, qk)[1] for qk in q])
    assert h[500] >= 0.03 and h[1:-1].min() > 0
    for j, c in enumerate(robot.coordinates):
        lo, hi = c.range
        assert lo <= q[:, j].min() and q[:, j].max() <= hi, c.name


@pytest.mark.slow
def test_simulated_rabbit_gait_settles_on_the_predicted_fixed_point(rabbit):
    """Full-order closed loop (SPEC 7), started 10 % off the fixed point: 20 steps, zeta^-
    converges to zeta* with the Poincare eigenvalue delta_zero^2."""
    zd = load_walker(None, "rabbit_walk").zd
    run = simulate(zd, ThrustModel("constant", np.zeros(rabbit.n_thrusters)),
                   SimConfig(steps=20, rtol=1e-9, atol=1e-9), Start(perturb=0.1))
    assert run.success and len(run.steps) == 20, run.reason
    zs = run.prediction.zeta_star
    err = np.array([st.zeta_minus for st in run.steps]) - zs
    assert abs(err[-1]) < 1e-3 * zs
    ratio = err[2:8] / err[1:7]
    assert ratio == pytest.approx(zd.delta_zero_sq, abs=0.02)


# ----------------------------------------------------- touchdown, tolerances and messages
DATA = Path(__file__).resolve().parent / "data"


@pytest.mark.slow
def test_designed_gait_meets_the_touchdown_velocity_bound(tmp_path, three_link, cli):
    """--min-touchdown-velocity 0.6 (the default design touches down at -0.2 m/s): the designed
    gait's swing foot moves down at >= 0.6 m/s just before impact, by the limit-cycle code and
    by a central difference of the swing-foot height along q_Z (independent of E_2); the foot
    is on the ground at impact to 1e-12 m (polished, not just to the solver's tolerance)."""
    out = tmp_path / "td.yaml"
    res = cli("design-gait", "three_link", "--target-speed", str(SPEED), "--clearance", "0",
              "--starts", "1", "--min-touchdown-velocity", "0.6", "--out", tmp_path, "--name",
              "td", "-q", "--formats", "png")  # the stick figure drawn, no PDF (STICK_PDF)
    assert res.exit_code == 0, res.output
    report = json.loads(out.with_name("td.report.json").read_text())
    assert report["spec"]["min_touchdown_velocity"] == 0.6
    gait, zd, sched, lc = _orbit(three_link, out)
    assert lc.touchdown_velocity <= -0.6, lc.touchdown_velocity
    h = 1e-6
    y = [swing_foot(three_link.robot, zd.maps.q_Z(np.array(zd.alpha_f + d)))[1] for d in (-h, h)]
    assert (y[1] - y[0]) / (2 * h) * lc.alpha_dot_minus == pytest.approx(lc.touchdown_velocity,
                                                                         rel=1e-6)
    assert report["margins"]["touchdown_velocity"] >= 0
    assert abs(swing_foot(three_link.robot, zd.maps.q_minus)[1]) < 1e-12
    assert "touches down at -0.6" in out.read_text()


def test_polish_puts_the_swing_foot_exactly_on_the_ground(three_link):
    """Problem.polish: Newton on q_N of q^- removes a 1e-6 rad foot-placement error to 1e-13 m
    (the re-check demands 1e-9 m; the solver alone reaches about its 1e-5 tolerance)."""
    prob = Problem(three_link, DesignSpec(speed=SPEED, clearance=0.0))
    x = prob.start(None)
    x[three_link.n - 1] += 1e-6
    assert abs(three_link.p_swing(x[:three_link.n])[1]) > 1e-7
    xp = prob.polish(x)
    assert abs(three_link.p_swing(xp[:three_link.n])[1]) < 1e-13
    assert np.array_equal(xp[three_link.n:], x[three_link.n:])


def test_recheck_prints_the_digits_that_show_a_violation(walker3):
    """delta_zero^2 just above the bound: the re-check fails "stability" and its message shows
    enough digits to see it (not "0.7578 > 0.7578"); a bound just above it passes."""
    from thrustwalk_cli.design.verify import check_gait, show

    assert show(0.9000002, 0.9) == ("0.9000002", "0.9")
    assert show(1.5, 1.5) == ("1.5", "1.5")
    d2 = walker3.zd.delta_zero_sq
    spec = DesignSpec(speed=SPEED, clearance=0.0, max_delta_sq=d2 - 2e-7,
                      min_vertical_force=40.0)
    chk = check_gait(walker3.model, walker3.gait, spec)
    assert "stability" in chk["failed"]
    text = chk["failure_details"]["stability"]
    lhs, rhs = (float(v) for v in text.split("= ")[1].split(" > "))
    assert lhs > rhs and lhs == pytest.approx(d2, abs=1e-6)
    assert rhs == pytest.approx(spec.max_delta_sq, abs=1e-6)
    ok = check_gait(walker3.model, walker3.gait, replace(spec, max_delta_sq=d2 + 2e-7))
    assert "stability" not in ok["failed"]


@pytest.mark.slow
def test_compass_walker_blocked_without_thrust_and_the_hint_helps(tmp_path, cli):
    """A compass walker on flat ground without thrust: design-gait exits 3 naming the violated
    inequality with its numbers and suggesting --design-thrust; with it, a gait is found."""
    args = ["design-gait", DATA / "compass.yaml", "--target-speed", "0.5", "--clearance", "0",
            "--order", "4", "--starts", "1", "--max-iter", "40", "--out", tmp_path, "--name", "c"]
    res = cli(*args)
    assert res.exit_code == 3, res.output
    line = next(ln for ln in res.output.splitlines() if ln.startswith("infeasible:"))
    assert "blocked by orbit" in line and "violated:" in line
    assert "try --design-thrust" in line and "`" not in line, line
    report = json.loads((tmp_path / "c.report.json").read_text())
    assert set(report["failed_check_details"]) == set(report["failed_checks"]), report
    assert cli(*args, "--design-thrust", "-q", "--formats", "png").exit_code == 0  # STICK_PDF


def test_blocking_messages_state_the_violated_inequality():
    """Every violated family's message at a start point of a compass walker states the
    inequality and the numbers that show the violation; the hints name parameters (rendered
    as flags by the command line), with a larger `max_iter` when starts hit the limit."""
    from thrustwalk_cli.design.solver import StartResult, describe, suggestion
    from thrustwalk_cli.files.robot_file import load_robot
    from thrustwalk_cli.model.compiler import load_model

    model = load_model(load_robot(str(DATA / "compass.yaml")))
    prob = Problem(model, DesignSpec(speed=0.5, clearance=0.0, order=4))
    ev = prob.evaluate(prob.start(None))
    for fam in FAMILIES:
        if fam in ev.violations():
            text = describe(fam, ev, prob)
            assert "violated" in text and "`" not in text, (fam, text)
    d2 = ev.info["delta_zero_sq"]
    spec = replace(prob.spec, max_delta_sq=0.5 * d2)
    text = describe("stability", ev, Problem(model, spec))
    a, b = (float(v) for v in text.split("violated: delta_zero^2 = ")[1].split(" > "))
    assert a > b and a == pytest.approx(d2, rel=1e-3)
    stuck = StartResult(0, np.zeros(1), "Iteration limit reached", 1.0, 1.0, 40, 1, 0.1)
    hint = suggestion("orbit", prob, [stuck])
    assert "`thrust_design`" in hint and "`max_iter` = 150" in hint, hint


# ------------------------------------------- a finished search is never lost (item 1)
def test_gait_robot_path_is_relative_to_the_gait_files_folder(tmp_path, monkeypatch):
    """A gait's relative ``robot:`` names a file beside the gait file's folder, also while that
    folder does not exist yet (the reload check of a gait about to be written): never the
    working folder's file of that name."""
    import shutil

    from thrustwalk_cli.files.gait_file import load_gait_text, same_robot_file
    from thrustwalk_cli.files.robot_file import load_robot

    shutil.copy(DATA / "walker5.yaml", tmp_path / "walker5.yaml")
    monkeypatch.chdir(tmp_path)
    robot = load_robot("walker5.yaml")
    text = (DATA / "walker5_walk.yaml").read_text()
    up = text.replace("robot: walker5.yaml", "robot: ../walker5.yaml")
    for file in ("gaits/walker5_walk.yaml", "new/deeper/../walker5_walk.yaml"):
        g = load_gait_text(up, file)[0]
        assert same_robot_file(robot, g.robot), (file, g.robot)
        assert not (tmp_path / Path(file).parent).exists()
    # beside the gait, not in the working folder: gaits/walker5.yaml does not exist
    g = load_gait_text(text, "gaits/walker5_walk.yaml")[0]
    assert not same_robot_file(robot, g.robot), g.robot
    assert Path(g.robot) == Path("gaits/walker5.yaml")
    assert same_robot_file(robot, load_gait_text(text, "walker5_walk.yaml")[0].robot)
    (tmp_path / "gaits").mkdir()  # an existing folder: the operating system resolves '..'
    assert same_robot_file(robot, load_gait_text(up, "gaits/walker5_walk.yaml")[0].robot)


@pytest.mark.slow
def test_robot_file_here_out_in_a_new_subfolder(tmp_path, monkeypatch, cli):
    """The user's run: ``cd mybot && design-gait walker5.yaml ... --out gaits --name X`` (the
    robot file in the working folder, ``--out`` a folder still to be made). The gait is written
    and names the robot as ``../ROBOT.yaml``, which loads the robot file from anywhere; the
    stick figure lies beside it (``--formats png``: no PDF)."""
    import shutil

    shutil.copy(REPO / "robots" / "three_link.yaml", tmp_path / "tl.yaml")
    monkeypatch.chdir(tmp_path)
    res = cli("design-gait", "tl.yaml", "--target-speed", str(SPEED), "--clearance", "0",
              "--starts", "1", "--out", "gaits", "--name", "tl_walk", "--formats", "png", "-q")
    assert res.exit_code == 0, res.output
    gait = tmp_path / "gaits" / "tl_walk.yaml"
    assert "robot: ../tl.yaml\n" in gait.read_text()
    report = json.loads((tmp_path / "gaits" / "tl_walk.report.json").read_text())
    assert report["status"] == "feasible" and report["reload_check"]["relative_error"] < 1e-9
    assert (tmp_path / "gaits" / "tl_walk.stick.png").stat().st_size > 1000
    assert not (tmp_path / "gaits" / "tl_walk.stick.pdf").exists()
    assert not list((tmp_path / "gaits").glob("*.failed*"))
    w = load_walker(None, "gaits/tl_walk.yaml")
    assert Path(w.robot.source_file).resolve() == (tmp_path / "tl.yaml").resolve()
    monkeypatch.chdir(tmp_path / "gaits")
    assert load_walker(None, "tl_walk.yaml").robot.name == "three_link"


@pytest.fixture(scope="module")
def result3(three_link):
    """One short 3-link design through the Python API (1 start) whose chosen start is made to
    end as SLSQP's 'Positive directional derivative for linesearch' (exit code 8), as the
    user's walker5 design did: a feasible design, optimum not certified."""
    from thrustwalk_cli.design import solver
    from thrustwalk_cli.studies.design_gait import design_gait

    real = solver.solve_start

    def linesearch(prob, x0, index=0):
        return replace(real(prob, x0, index), code=8,
                       status="Positive directional derivative for linesearch")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(solver, "solve_start", linesearch)
        res = design_gait(three_link, DesignSpec(speed=SPEED, clearance=0.0, starts=1,
                                                 name="walk3f"))
    assert res.success, res.reason
    return res


@pytest.mark.slow  # the result3 fixture runs one design (~5-10 s)
@pytest.mark.parametrize("failure", ["reload", "bug", "unwritable"])
def test_failure_after_the_search_keeps_the_design(tmp_path, monkeypatch, cli, result3,
                                                   failure):
    """Whatever fails after the search (the reload check, a bug in it, the output folder
    refusing the files), the design is written as NAME.failed.yaml (its first line says it is
    not verified and why; it loads and holds the designed coefficients) and
    NAME.failed.report.json (status failed), exit 1 with one line naming the failure and the
    files; nothing is written under the verified gait's name."""
    import tempfile

    from thrustwalk_cli.files import output
    from thrustwalk_cli.studies import design_gait as study

    monkeypatch.setattr(study, "design_gait", lambda *a, **k: result3)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "gaits"
    spare = tmp_path / "spare"
    spare.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(spare))
    if failure == "reload":
        def boom(*a, **k):
            raise ComputationError("forced reload failure")
        monkeypatch.setattr(study, "reload_check", boom)
        needle = "the reload check failed: forced reload failure"
    elif failure == "bug":
        def boom(*a, **k):
            raise KeyError("zeta_star")
        monkeypatch.setattr(study, "reload_check", boom)
        needle = "the reload check failed: internal error KeyError"
    else:
        real = output.write_bytes_atomic

        def refuse(path, data):
            if Path(path).resolve().parent == out:
                raise OSError(28, "No space left on device", str(path))
            return real(path, data)
        monkeypatch.setattr(output, "write_bytes_atomic", refuse)
        needle = "writing the gait file failed: "
    res = cli("design-gait", "three_link", "--target-speed", str(SPEED), "--clearance", "0",
              "--starts", "1", "--out", "gaits", "--name", "walk3f", "-q")
    assert res.exit_code == 1, res.output
    errors = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1 and needle in errors[0], res.output
    assert "Traceback" not in res.output
    folder = out if failure != "unwritable" else next(spare.glob("thrustwalk-walk3f-*"))
    gait, report = folder / "walk3f.failed.yaml", folder / "walk3f.failed.report.json"
    assert str(gait.relative_to(tmp_path)) in errors[0] or str(gait) in errors[0]
    assert str(report.name) in errors[0]
    assert not (out / "walk3f.yaml").exists() and not (out / "walk3f.report.json").exists()
    first = gait.read_text().splitlines()[0]
    assert first.startswith("# NOT A VERIFIED GAIT: design-gait failed after the search (")
    assert needle in first
    doc = json.loads(report.read_text())
    assert doc["status"] == "failed" and doc["feasible"] is False
    assert doc["recheck_feasible"] is True and needle in doc["error"]
    assert doc["gait_file"] is None
    assert Path(doc["failed_gait_file"]).resolve() == gait.resolve()
    w = load_walker(None, str(gait))
    assert np.allclose(w.gait.coefficients, result3.design.gait.A, rtol=0, atol=1e-15)
    assert w.robot.name == "three_link"


# ---------------------------------------- optimality, unbounded joints, stick figure (item 9)
@pytest.mark.slow  # the result3 fixture runs one design (~5-10 s)
def test_uncertified_optimum_is_said_everywhere(tmp_path, monkeypatch, cli, result3):
    """The chosen start ended with SLSQP exit code 8: the design is feasible (exit 0) but the
    report, the console and the gait header say the optimum is not certified, name the start
    and SLSQP's message, and suggest --starts and --max-iter. The 3-link robot file gives no
    torque limits and no joint ranges: said too, naming the keys to add."""
    from thrustwalk_cli.design.solver import StartResult, optimality
    from thrustwalk_cli.studies import design_gait as study

    monkeypatch.setattr(study, "design_gait", lambda *a, **k: result3)
    monkeypatch.chdir(tmp_path)
    res = cli("design-gait", "three_link", "--target-speed", str(SPEED), "--clearance", "0",
              "--starts", "1", "--out", "gaits", "--name", "walk3f", "--formats", "none")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "gaits" / "walk3f.report.json").read_text())
    opt = doc["optimality"]
    assert opt["certified"] is False and opt["slsqp_code"] == 8 and opt["start"] == 0
    assert doc["feasible"] and doc["starts"][0]["slsqp_code"] == 8
    msg = "Positive directional derivative for linesearch"
    warned = [ln for ln in res.output.splitlines() if ln.startswith("warning:")]
    cert = [ln for ln in warned if "optimum not certified" in ln]
    assert len(cert) == 1 and "start 0" in cert[0] and msg in cert[0], res.output
    assert "--starts" in cert[0] and "--max-iter" in cert[0] and "`" not in cert[0]
    assert any("no torque limits" in ln and "torque_limit" in ln for ln in warned), warned
    assert any("no joint ranges bound q1, q2" in ln and "range" in ln for ln in warned)
    header = [ln for ln in (tmp_path / "gaits" / "walk3f.yaml").read_text().splitlines()
              if ln.startswith("#")]
    assert any(ln.startswith("# WARNING: optimum not certified") and msg in ln
               and "--max-iter" in ln for ln in header), header
    assert any(ln.startswith("# WARNING: no torque limits") for ln in header)
    assert any("optimum not certified" in w for w in doc["warnings"])
    assert not list((tmp_path / "gaits").glob("*.png"))  # --formats none
    # a converged start (SLSQP exit code 0) is certified, with no note
    ok = StartResult(2, np.zeros(1), "Optimization terminated successfully", 1.0, 0.0, 30, 99,
                     1.0, 0)
    assert optimality(ok, result3.design.spec) == {
        "certified": True, "start": 2, "slsqp_code": 0,
        "slsqp_message": "Optimization terminated successfully", "note": None}
    stuck = optimality(replace(ok, code=9, status="Iteration limit reached"),
                       result3.design.spec)
    assert not stuck["certified"] and "`max_iter`" in stuck["note"]


def test_unbounded_joints_named_with_the_keys_to_add():
    """walker5 gives ranges for its knees only and no torque limits: both are named (the
    hips q_sh, q_wh unbounded; every torque), each name once, with the key to add; with every
    key added there is no warning."""
    import re

    from thrustwalk_cli.design.spec import unbounded_warnings
    from thrustwalk_cli.files.robot_file import load_robot, load_robot_text

    def count(name: str, line: str) -> int:
        return len(re.findall(rf"\b{name}\b", line))

    w = unbounded_warnings(load_robot(str(DATA / "walker5.yaml")))
    assert len(w) == 2, w
    assert "no torque limits" in w[0] and "q_sk, q_sh, q_wh, q_wk" in w[0]
    assert "add torque_limit: [N m] to q_sk, q_sh, q_wh, q_wk in coordinates.actuated" in w[0]
    assert all(count(nm, w[0]) == 1 for nm in ("q_sk", "q_sh", "q_wh", "q_wk")), w[0]
    assert w[1].startswith("no joint ranges bound q_sh, q_wh:") and "range: [min, max]" in w[1]
    assert all(count(nm, w[1]) == 1 for nm in ("q_sh", "q_wh")), w[1]
    text = (DATA / "walker5.yaml").read_text()
    for nm in ("q_sh", "q_wh"):
        text = text.replace(f"{{name: {nm}, joint:", f"{{name: {nm}, range: [-2, 2], joint:")
    text = text.replace("joint: swing_thigh}", "joint: swing_thigh, torque_limit: 80}")
    w = unbounded_warnings(load_robot_text(text, str(DATA / "walker5.yaml")))
    assert len(w) == 1 and "3 of its 4 actuated coordinates" in w[0], w
    assert "add torque_limit: [N m] to q_sk, q_sh, q_wk in coordinates.actuated" in w[0], w
    assert all(count(nm, w[0]) == 1 for nm in ("q_sk", "q_sh", "q_wk")), w[0]
    assert count("q_wh", w[0]) == 0, w[0]
    for nm in ("q_sk", "q_sh", "q_wk"):
        text = text.replace(f"{{name: {nm},", f"{{name: {nm}, torque_limit: 80,")
    assert unbounded_warnings(load_robot_text(text, str(DATA / "walker5.yaml"))) == []


def test_stick_frames_follow_the_independent_kinematics():
    """walker5's gait drawn over one step: every drawn link (origin, end) is where the
    independent NumPy kinematics puts it; link lengths are the robot file's and constant; the
    stance foot is at the origin; at s = 1 the configuration is q^- = H^-1 [a_M; alpha_f]
    (from the gait file's numbers) and the drawn swing foot is p_2(q^-) on the ground, at
    s = 0 it is p_2(R q^- + b); the swing-foot path runs between them above the ground."""
    from independent import origins

    from thrustwalk_cli.studies.design_gait import stick_frames

    w = load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"))
    robot, model = w.robot, w.model
    fr = stick_frames(model, w.gait, instants=9)
    links, q = fr["links"], fr["q"]
    assert links.shape == (9, len(robot.links), 2, 2) and fr["s"][[0, -1]].tolist() == [0, 1]
    n = model.n
    H = np.vstack([np.hstack([np.eye(n - 1), np.zeros((n - 1, 1))]), [w.gait.c]])
    q_minus = np.linalg.solve(H, np.append(np.asarray(w.gait.coefficients)[:, -1],
                                           w.gait.alpha_f))
    assert q[-1] == pytest.approx(q_minus, abs=1e-12)
    for k in range(9):
        org = origins(robot, q[k])
        for j, lk in enumerate(robot.links):
            assert links[k, j, 0] == pytest.approx(org[lk.name], abs=1e-12)
            assert links[k, j, 1] == pytest.approx(point(robot, q[k], lk.name, lk.end),
                                                    abs=1e-12)
    lengths = np.linalg.norm(links[:, :, 1] - links[:, :, 0], axis=-1)
    assert lengths == pytest.approx(np.tile([np.hypot(*lk.end) for lk in robot.links], (9, 1)),
                                    abs=1e-12)
    root = [lk.name for lk in robot.links].index(robot.root.name)
    assert links[:, root, 0] == pytest.approx(np.zeros((9, 2)), abs=1e-12)  # stance foot
    foot_end = swing_foot(robot, q_minus)
    assert fr["swing_foot"][-1] == pytest.approx(foot_end, abs=1e-12)
    assert abs(foot_end[1]) < 1e-9 and foot_end[0] > 0.1
    assert links[-1, -1, 1] == pytest.approx(foot_end, abs=1e-12)  # swing shin's end
    q_plus = model.R @ q_minus + model.b
    assert fr["swing_foot"][0] == pytest.approx(swing_foot(robot, q_plus), abs=1e-12)
    path = fr["swing_path"]
    assert path[0] == pytest.approx(fr["swing_foot"][0]) and path[-1] == pytest.approx(foot_end)
    assert path[1:-1, 1].min() > 0


@pytest.mark.slow  # the result3 fixture runs one design (~5-10 s)
def test_design_figures_are_the_stick_figure(result3):
    """DesignGaitResult.figures(): one figure, NAME.stick, axes in metres at equal scale with
    the ground line; none for an infeasible design."""
    figs = result3.figures()
    assert list(figs) == ["walk3f.stick"]
    ax = figs["walk3f.stick"].axes[0]
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"
    assert ax.get_aspect() == 1.0
    assert any(list(ln.get_xdata()) == [0, 1] and list(ln.get_ydata()) == [0, 0]
               for ln in ax.get_lines())  # the ground line (axhline)
    bad = replace(result3, design=replace(result3.design, feasible=False))
    assert bad.figures() == {}


# -------------------------------------------------- batched forward differences (issue 26)
def _walker5():
    return load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml")).model


def _by_columns(self, x):
    """_Cache.jacobian as it was: one evaluation per perturbed point (the reference)."""
    x = np.asarray(x, float)
    if self.jx is None or not np.array_equal(x, self.jx):
        self.jx, self.jac = x.copy(), self.differences(x, batched=False)
    return self.jac


@pytest.mark.parametrize("case", ["walker5", "walker5_thrust_range", "three_link_peak_thrust"])
def test_batched_jacobian_equals_the_column_by_column_one(case, three_link):
    """The forward-difference Jacobian evaluates all its perturbed points in one vectorised
    call (Problem.evaluate_many, a batch axis through Bezier, zero dynamics, stance terms and
    the swing-foot checks); it equals evaluating them one at a time with the single-point
    Problem.evaluate (same steps) to 1e-10 relative, at the default start and off it: on the
    user robot walker5 (effort; with a thrust range over -40..0 N of its thruster `back`) and
    on the 3-link with designed thrust and the peak objective (epigraph rows)."""
    from thrustwalk_cli.design.solver import _Cache

    model, kw = {
        "walker5": (_walker5, dict(speed=0.6)),
        "walker5_thrust_range": (_walker5, dict(speed=0.6, thrust_range=("back", -40.0, 0.0))),
        "three_link_peak_thrust": (lambda: three_link, dict(speed=SPEED, clearance=0.0,
                                                            thrust_design=True,
                                                            objective="peak")),
    }[case]
    prob = Problem(model(), DesignSpec(starts=1, **kw))
    x0 = prob.start(None)
    prob.fix_shapes(prob.evaluate(x0))
    x1 = x0 + np.random.default_rng(3).normal(0.0, 0.02, x0.size)
    for x in (x0, x1):
        cache = _Cache(prob)
        n0 = prob.evaluations
        fast = cache.differences(x)
        assert prob.evaluations - n0 == 1 + x.size  # the point and one per column
        ref = cache.differences(x, batched=False)
        for got, want in zip(fast, ref):
            assert got.shape == want.shape and np.all(np.isfinite(want))
            assert np.abs(got - want).max() <= 1e-10 * max(1.0, np.abs(want).max())


def test_evaluate_many_rows_are_single_evaluations(three_link):
    """Each row of Problem.evaluate_many is Problem.evaluate of that row (values and
    diagnostics), and a row that cannot be evaluated (NaN) fails alone, with the failed-point
    values, while its neighbours keep theirs."""
    prob = Problem(three_link, DesignSpec(speed=SPEED, clearance=0.0, starts=1))
    x0 = prob.start(None)
    prob.fix_shapes(prob.evaluate(x0))
    bad = x0.copy()
    bad[0] = np.nan
    xs = np.array([x0, bad, 1.01 * x0])
    many = prob.evaluate_many(xs, info=True)
    assert [ev.ok for ev in many] == [True, False, True]
    assert many[1].scaled == 1e3 and all(np.all(v == -10.0) for v in many[1].ineq.values())
    for ev, x in zip(many[::2], xs[::2]):
        one = prob.evaluate(x)
        assert ev.scaled == one.scaled and ev.objective == one.objective
        for a, b in ((ev.eq, one.eq), (ev.ineq, one.ineq)):
            assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
        assert ev.info.keys() == one.info.keys()
        assert ev.info["step_time"] == one.info["step_time"] > 0


@pytest.mark.slow
def test_batched_jacobian_designs_the_same_gait(three_link, monkeypatch):
    """3-link from the default start: the design with the batched Jacobian is the design with
    the column-by-column one (SLSQP follows the same path): same iterations and evaluations,
    Bezier coefficients, alpha_f and zeta* to 1e-9."""
    from thrustwalk_cli.design import solver

    spec = DesignSpec(speed=SPEED, clearance=0.0, starts=1, max_iter=25)
    fast = solve_design(three_link, spec)
    monkeypatch.setattr(solver._Cache, "jacobian", _by_columns)
    ref = solve_design(three_link, spec)
    assert fast.starts[0].iterations == ref.starts[0].iterations
    assert fast.evaluations == ref.evaluations
    assert np.abs(np.array(fast.gait.A) - np.array(ref.gait.A)).max() <= 1e-9
    assert fast.gait.alpha_f == pytest.approx(ref.gait.alpha_f, abs=1e-9)
    zf, zr = fast.check["orbit"]["zeta_star"], ref.check["orbit"]["zeta_star"]
    assert zf == pytest.approx(zr, rel=1e-9)


def test_a_speed_or_step_length_just_missed_shows_the_digits_of_the_miss():
    """A design blocked by its speed or step-length target missed by 1e-5 relative (a start
    stopped at its iteration limit) says so with the digits that show the miss (not "speed =
    0.5 m/s violated: reached 0.5 m/s"): the target reads back as itself, the value reached
    closer to the true one than the miss, on the side of the target the miss is."""
    from types import SimpleNamespace

    from thrustwalk_cli.design.solver import describe

    for fam, key, target, got in (("speed", "speed", 0.5, 0.4999931),
                                  ("step_length", "step_length", 0.37, 0.3700052)):
        prob = SimpleNamespace(spec=SimpleNamespace(mu=0.7, **{key: target}))
        ev = SimpleNamespace(ok=True, info={key: got})
        text = describe(fam, ev, prob)
        b, a = (float(part.split()[-2]) for part in text.split(" violated: "))
        assert b == target and (a - b) * (got - target) > 0, text
        assert abs(a - got) < abs(got - target), text


def test_a_scuffing_knee_less_walker_is_told_clearance_0():
    """A compass walker (swing foot on a link jointed to the stance link, legs of equal
    length) cannot lift its swing foot where it passes the stance foot: with hip angle
    (stance leg theta_s, swing leg theta_w from the vertical) the swing foot is at
    x = r (sin theta_w - sin theta_s), y = r (cos theta_s - cos theta_w), and y <= 0 wherever
    x = 0 (checked on a grid). A design blocked by scuffing is told `clearance` 0, not "a
    larger clearance" (which cannot help); a kneed walker (walker5) keeps the old hint, and so
    does the compass walker at clearance 0 already."""
    from thrustwalk_cli.design.solver import suggestion
    from thrustwalk_cli.files.robot_file import load_robot
    from thrustwalk_cli.model.compiler import load_model

    ts = np.linspace(-0.6, 0.6, 241)
    s_, w_ = np.meshgrid(ts, ts)
    x, y = np.sin(w_) - np.sin(s_), np.cos(s_) - np.cos(w_)
    assert y[np.abs(x) < 1e-9].max() <= 1e-12 and (np.abs(x) < 1e-9).sum() > 100

    compass = load_model(load_robot(str(DATA / "compass.yaml")))
    hint = suggestion("scuffing", Problem(compass, DesignSpec(speed=0.5, clearance=0.03)), [])
    assert "`clearance` 0" in hint and "larger" not in hint, hint
    hint = suggestion("scuffing", Problem(compass, DesignSpec(speed=0.5, clearance=0.0)), [])
    assert "a higher `order` or a larger `clearance`" in hint, hint
    kneed = load_model(load_robot(str(DATA / "walker5.yaml")))
    hint = suggestion("scuffing", Problem(kneed, DesignSpec(speed=0.6, clearance=0.03)), [])
    assert "a higher `order` or a larger `clearance`" in hint, hint


def test_a_margin_within_the_tolerance_is_shown_as_0(capsys, monkeypatch):
    """A margin the re-check passes within its tolerance (the 3-link design at clearance 0:
    its swing foot dips 1.5e-8 m below the ground, the tolerance is 1e-6 m) is shown as 0 in
    the summary table and the gait header, never as a negative number next to "feasible" or
    as "-0.00"; a margin beyond the tolerance keeps its sign and digits. The report (the golden
    document of that design, tests/golden/design_gait_three.json) keeps the numbers."""
    import re
    from types import SimpleNamespace

    from thrustwalk_cli.commands.design_gait import _summary
    from thrustwalk_cli.studies.design_gait import yaml_header

    doc = json.loads((REPO / "tests" / "golden" / "design_gait_three.json").read_text())
    m, sw = doc["margins"], doc["swing_foot"]
    assert doc["feasible"] and -1e-6 < m["min_swing_height"] < 0  # the case the user saw
    assert -1e-6 * 1000 < sw["min_height_window"] * 1000 < 0  # was "-0.00 mm"
    monkeypatch.setenv("COLUMNS", "200")
    _summary(doc, Path("g.yaml"), Path("g.report.json"), [Path("g.yaml")])
    cells = {ln.split("│")[1].strip(): ln.split("│")[2].strip()
             for ln in capsys.readouterr().out.splitlines() if ln.startswith("│")}
    assert cells["margin min_swing_height"] == "0", cells
    assert cells["margin clearance_mid_step"] == "0", cells  # 6.2e-8 m: within 1e-6 m too
    assert cells["margin vertical_force"] == f"{m['vertical_force']:.5g}", cells
    assert cells["margin friction"] == f"{m['friction']:.5g}", cells
    assert not any(v.startswith("-") for k, v in cells.items() if k.startswith("margin")), cells

    s = doc["spec"]
    res = SimpleNamespace(
        spec=DesignSpec(speed=s["speed"], clearance=s["clearance"], starts=s["starts"]),
        check={"orbit": doc["fixed_point"], "margins": m, "contact": doc["contact"],
               "swing": sw, "cost": doc["cost"]},
        objective=doc["objective"]["value"], eps=s["min_vertical_force"], warnings=())
    head = yaml_header(res, {"version": "0", "created_utc": "now", "command": "x"}, "g.json")
    assert not any(re.search(r"-0\.0+(?![0-9])", ln) for ln in head), head  # no "-0.00"
    swing = next(ln for ln in head if ln.startswith("Swing foot:"))
    assert swing.startswith("Swing foot: 0.00 cm at mid-step (>= 0 cm), >= 0.00 mm for s in"), \
        swing


def test_the_margin_formatter_shows_0_within_the_tolerance_and_never_minus_0():
    """fmt_margin: |x| <= tol is 0, a value rounding to zero at the shown precision is unsigned,
    every other value keeps its sign and digits (Python's own format of it)."""
    from thrustwalk_cli.studies.documents import fmt_margin

    assert fmt_margin(-9e-8, ".5g", 1e-6) == "0" and fmt_margin(9e-8, ".5g", 1e-6) == "0"
    assert fmt_margin(-2e-6, ".5g", 1e-6) == format(-2e-6, ".5g")
    assert fmt_margin(-4e-3, ".2f") == "0.00" and fmt_margin(-0.0, ".3f") == "0.000"
    assert fmt_margin(-1e-9, ".2e") == "-1.00e-09"  # not zero at that precision
    assert fmt_margin(-0.006, ".2f") == "-0.01" and fmt_margin(0.25, ".3f") == "0.250"
    assert fmt_margin(None) == "—"


# ------------------------------------------------------- feasibility restoration (footbot)
def _walker5_walk_point():
    """The design problem of walker5 at 0.6 m/s and the decision vector of its gait
    walker5_walk.yaml (designed by design-gait for that speed): q^- from the gait file's last
    Bezier column and alpha_f, zeta^- the fixed point of its zero dynamics."""
    w = load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"))
    model, gait, zd = w.model, w.gait, w.zd
    n = model.n
    A = np.asarray(gait.coefficients, float)
    H = np.vstack([np.hstack([np.eye(n - 1), np.zeros((n - 1, 1))]), [gait.c]])
    q_minus = np.linalg.solve(H, np.append(A[:, -1], gait.alpha_f))
    zs = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, model.n_thrusters))))[0].zeta_star
    spec = DesignSpec(speed=0.6, starts=1, max_iter=3)
    prob = Problem(model, spec)
    return model, spec, prob, prob.warm_start(q_minus, A, zs)


def test_a_start_ending_near_feasible_is_restored_onto_the_constraints():
    """When SLSQP stops a little off the constraints (here: 3 iterations from walker5_walk's
    point moved by 0.01 in every variable, normalised violation ~0.1; on a footed walker SLSQP
    ended 1e-5..1e-4 off after hundreds of iterations), solve_start projects its point onto the
    constraints (min |x - x_end|^2 subject to all of them, no slacks) and keeps the projection:
    the start is then feasible by the solver's tolerance, SLSQP's exit code (9, iteration
    limit: no certified optimum) still stands, and the gait passes the independent re-check
    (adaptive zero dynamics, limit_cycles, contact evaluation), whose speed from the orbit's
    step length and time is the target 0.6 m/s, with the swing foot on the ground at impact
    by the independent kinematics. The moved point itself fails that re-check."""
    from independent import swing_foot

    from thrustwalk_cli.design.solver import solve_start
    from thrustwalk_cli.design.spec import FEAS_TOL
    from thrustwalk_cli.design.verify import verify

    model, spec, prob, x = _walker5_walk_point()
    prob.fix_shapes(prob.evaluate(x))
    assert prob.evaluate(x).max_violation <= FEAS_TOL  # the gait file's point is feasible
    d = np.random.default_rng(1).normal(size=x.size)
    x_end = x + 0.01 * d / np.abs(d).max()
    assert prob.evaluate(x_end).max_violation > 1e3 * FEAS_TOL
    assert not verify(model, prob.gait(prob.polish(x_end)), spec, prob.unpack(x_end)[2],
                      prob.eps)["feasible"]
    r = solve_start(prob, x_end, 0)
    assert r.code == 9 and r.iterations == 3  # SLSQP alone stopped at its iteration limit
    assert r.max_violation <= FEAS_TOL
    assert r.restored and 0 < r.restoration <= 30
    xp = prob.polish(r.x)
    chk = verify(model, prob.gait(xp), spec, prob.unpack(xp)[2], prob.eps)
    assert chk["feasible"], chk["failed"]
    orbit = chk["orbit"]
    assert orbit["step_length"] / orbit["step_time"] == pytest.approx(0.6, rel=1e-5)
    q_minus = xp[:model.n]
    assert swing_foot(model.robot, q_minus)[1] == pytest.approx(0.0, abs=1e-9)


def test_restoration_leaves_a_feasible_point_alone_and_keeps_slsqps_point_when_it_fails():
    """restore() returns a point that already meets every constraint unchanged (0 iterations);
    a start whose restoration does not reach the solver's tolerance keeps SLSQP's point and
    says so (restored False)."""
    import thrustwalk_cli.design.solver as solver
    from thrustwalk_cli.design.solver import restore, solve_start

    _, _, prob, x = _walker5_walk_point()
    prob.fix_shapes(prob.evaluate(x))
    xr, k = restore(prob, x)
    assert k == 0 and np.array_equal(xr, x)
    d = np.random.default_rng(1).normal(size=x.size)
    x_end = x + 0.01 * d / np.abs(d).max()
    slsqp_only = solve_start(prob, x_end, 0)
    with pytest.MonkeyPatch.context() as mp:  # a restoration that gives up at once
        mp.setattr(solver, "restore", lambda p, xe, cache=None: (xe, 0))
        r = solver.solve_start(prob, x_end, 0)
    assert not r.restored and r.restoration == 0
    assert r.max_violation == prob.evaluate(r.x).max_violation > 1e-5
    assert slsqp_only.restored and slsqp_only.max_violation < r.max_violation
