"""Optimal thrust schedules (SPEC 6): exact QP (KKT, random feasible competitors, two
independent solvers), infeasibility reported with the violated family, and the ``optimize``
command."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import linprog

from thrustwalk_cli.contact.terms import impact_data
from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.optimize import min_effort as opt
from thrustwalk_cli.optimize import qp
from thrustwalk_cli.thrust.schedule import Schedule
from thrustwalk_cli.walker import load_walker

FRACTIONS = np.array([0.0, 0.25, 0.5, 0.75, 1.0])


# ------------------------------------------------------------------ the solvers on toy QPs
@pytest.mark.parametrize("solver", ["ldp", "active"])
def test_solvers_on_hand_solved_qps(solver):
    """min x1^2 + x2^2, x1 + x2 = 2, x1 <= 0.5  ->  (0.5, 1.5)  (x1 = x2 = 1 is cut off);
    min x1^2 + 3 x2^2, x1 + x2 = 4: Lagrange 2 x1 = 6 x2 -> (3, 1); with x1 <= 2 -> (2, 2)."""
    def solve(A, b, a, c, w):
        if solver == "ldp":
            return qp.ldp_qp(A, b, a, c, w)
        ok, x0 = qp.lp_feasible(A, b, a, c)
        assert ok
        return qp.active_set_qp(A, b, a, c, w, x0)

    one = np.array([1.0, 1.0])
    x = solve(np.array([[1.0, 0.0]]), np.array([0.5]), one, 2.0, np.ones(2))
    assert np.allclose(x, [0.5, 1.5], atol=1e-12)
    x = solve(np.array([[0.0, 1.0]]), np.array([10.0]), one, 4.0, np.array([1.0, 3.0]))
    assert np.allclose(x, [3.0, 1.0], atol=1e-12)
    x = solve(np.array([[1.0, 0.0]]), np.array([2.0]), one, 4.0, np.array([1.0, 3.0]))
    assert np.allclose(x, [2.0, 2.0], atol=1e-12)


def test_lp_detects_infeasible_toy():
    ok, _ = qp.lp_feasible(np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, -2.0]),
                            None, None)
    assert not ok


# ------------------------------------------------------------------------- the real problem
@pytest.fixture(scope="module")
def setup(walk3):
    """Problem, its reachable zeta* range (two LPs) and the nominal fixed point."""
    model, gait, zd = walk3
    lim = model.robot.thrusters[0].limits
    n = len(FRACTIONS) - 1
    prob = opt.build_problem(model, zd, FRACTIONS, mu=0.7, zeta_min_rel=0.01,
                             bounds=(np.full(n, lim[0]), np.full(n, lim[1])))
    zlo, zhi, _ = opt.zeta_range(prob)
    z0 = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, 2))))[0].zeta_star
    assert zlo < z0 < zhi, "the nominal orbit must be reachable"
    return model, gait, zd, prob, zlo, zhi, z0


@pytest.fixture(scope="module")
def solved(setup):
    model, gait, zd, prob, zlo, zhi, z0 = setup
    target = z0 + 0.6 * (zhi - z0)
    res = opt.optimize(model, zd, FRACTIONS, target_zeta=target, mu=0.7)
    assert res.feasible, res.reason
    return res, target


def test_optimum_satisfies_kkt(solved):
    res, target = solved
    p = res.problem
    A, b, ae, be = p.at(res.zeta_star_target)
    k = qp.kkt(A, b, ae, be, p.weights, res.values)
    assert k["stationarity_relative"] < 1e-8
    assert k["primal_infeasibility"] < 1e-9
    assert k["equality_residual"] < 1e-9
    assert k["min_multiplier"] >= 0.0
    assert k["complementarity"] < 1e-8
    # stationarity by hand: 2 W x + nu a_eq + A_act^T lambda = 0 (multipliers in row units)
    act = k["active"]
    g = 2 * p.weights * res.values + k["nu"] * ae \
        + A[act].T @ k["multipliers"]
    assert np.linalg.norm(g) < 1e-8 * np.linalg.norm(2 * p.weights * res.values)


def test_fixed_point_and_contact_of_the_optimum(solved, walk3):
    """The schedule's own limit cycle (zero_dynamics, independent of the QP rows) has the
    target zeta*, and the continuous contact check holds between grid points."""
    res, target = solved
    model, gait, zd = walk3
    lc = limit_cycles(zd, res.problem.schedule(res.values, model.n_thrusters))[0]
    assert lc.exists and lc.zeta_star == pytest.approx(target, rel=1e-9)
    c = res.contact
    assert c.feasible, c.reason
    assert c.max_friction_ratio <= 0.7 and c.min_vertical_force >= 0.0


def test_optimum_beats_random_feasible_schedules(solved):
    """Feasible competitors: random points on segments from the optimum (in the equality's
    null space, up to the first constraint) and convex combinations of LP vertices found with
    random costs. None has a smaller objective (seeded)."""
    res, _ = solved
    p = res.problem
    A, b, ae, be = p.at(res.zeta_star_target)
    x0, f0 = res.values, float(p.weights @ res.values**2)
    rng = np.random.default_rng(2024)
    N = np.linalg.svd(ae[None, :])[2][1:].T  # null-space basis of the equality
    tried = 0
    for _ in range(200):
        d = N @ rng.normal(size=N.shape[1])
        Ad = A @ d
        slack = b - A @ x0
        with np.errstate(divide="ignore"):
            steps = np.where(Ad > 1e-12, slack / Ad, np.inf)
        tmax = steps.min()
        if not np.isfinite(tmax) or tmax <= 0:
            continue
        x = x0 + rng.uniform(0.05, 1.0) * tmax * d
        assert np.all(A @ x <= b + 1e-9 * (1 + np.abs(b)))
        assert p.weights @ x**2 >= f0 - 1e-12 * f0
        tried += 1
    verts = []
    for _ in range(8):
        r = linprog(rng.normal(size=p.n), A_ub=A, b_ub=b, A_eq=ae[None, :], b_eq=[be],
                    bounds=[(None, None)] * p.n, method="highs")
        assert r.status == 0
        verts.append(r.x)
    for _ in range(50):
        lam = rng.dirichlet(np.ones(len(verts)))
        x = lam @ np.array(verts)
        assert p.weights @ x**2 >= f0 - 1e-9 * f0
        tried += 1
    assert tried > 100


def test_two_solvers_agree(solved):
    res, _ = solved
    p = res.problem
    A, b, ae, be = p.at(res.zeta_star_target)
    ok, x0 = qp.lp_feasible(A, b, ae, be)
    assert ok
    xa = qp.active_set_qp(A, b, ae, be, p.weights, x0)
    xl = qp.ldp_qp(A, b, ae, be, p.weights)
    assert np.allclose(xa, xl, rtol=0, atol=1e-7 * (1 + np.abs(xl).max()))


@pytest.mark.slow
def test_target_speed_is_met(setup):
    model, gait, zd, prob, zlo, zhi, z0 = setup
    v0 = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, 2))))[0].speed
    res = opt.optimize(model, zd, FRACTIONS, target_speed=1.1 * v0, mu=0.7)
    assert res.feasible, res.reason
    lc = limit_cycles(zd, res.problem.schedule(res.values, model.n_thrusters))[0]
    assert lc.speed == pytest.approx(1.1 * v0, rel=1e-8)


def test_time_weights_are_the_nominal_interval_times(setup):
    """sum_j w_j = the nominal step time from limit_cycles (independent quadrature)."""
    model, gait, zd, *_ = setup
    w = opt._interval_times(zd, zd.alpha_i + FRACTIONS * (zd.alpha_f - zd.alpha_i))
    lc = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, 2))))[0]
    assert w.sum() == pytest.approx(lc.step_time, rel=1e-7)


# ------------------------------------------------------------------------------ infeasible
def test_tiny_thrust_with_far_target_names_thrust_bounds(setup):
    model, gait, zd, prob, zlo, zhi, z0 = setup
    res = opt.optimize(model, zd, FRACTIONS, target_zeta=z0 + 0.6 * (zhi - z0), mu=0.7,
                       max_thrust=0.01)
    assert not res.feasible and res.status == "infeasible"
    assert "thrust_bounds" in res.violated
    assert "thrust bounds" in res.reason


def test_low_friction_names_the_friction_family(setup):
    """mu just above the impact's friction ratio (so the impact is admissible) and a target
    beyond what that mu allows: infeasible, with friction among the causes."""
    model, gait, zd, prob, zlo, zhi, z0 = setup
    mu = 1.02 * impact_data(model, zd).friction_ratio
    n = len(FRACTIONS) - 1
    low = opt.build_problem(model, zd, FRACTIONS, mu=mu, zeta_min_rel=0.01,
                            bounds=(np.full(n, -100.0), np.full(n, 100.0)))
    _, zmax, limits = opt.zeta_range(low)
    assert "friction" in limits["max"]
    res = opt.optimize(model, zd, FRACTIONS, target_zeta=1.05 * zmax, mu=mu)
    assert not res.feasible
    assert any("friction" in v for v in res.violated), res.violated


def test_inadmissible_impact_is_reported(setup):
    model, gait, zd, *_ = setup
    res = opt.optimize(model, zd, FRACTIONS, target_zeta=1000.0, mu=0.01)
    assert not res.feasible and res.violated == ("impact",)
    assert "impact" in res.reason


def test_unreachable_speed_names_the_limit(setup):
    model, gait, zd, *_ = setup
    res = opt.optimize(model, zd, FRACTIONS, target_speed=50.0, mu=0.7)
    assert not res.feasible and res.violated
    assert "outside the reachable range" in res.reason


# ------------------------------------------------------------------------------------- CLI


@pytest.mark.slow
def test_cli_optimize_writes_outputs_and_the_gait_loads_back(setup, tmp_path, cli):
    model, gait, zd, prob, zlo, zhi, z0 = setup
    target = z0 + 0.3 * (zhi - z0)
    out = tmp_path / "o"
    res = cli("optimize", "--target-zeta", repr(target), "--knots", "0,0.5,1",
                              "--out", str(out), "-q")
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "optimal_schedule.json").read_text())
    for key in ("values", "objective", "active_constraints", "zeta_star", "kkt", "feasible"):
        assert key in doc, key
    assert doc["feasible"] and len(doc["values"]) == 2
    for name in doc["files"]:
        assert (out / name).stat().st_size > 0, name
    g2 = load_walker(None, str(out / "three_link_walk_optimal.yaml")).gait
    assert np.allclose(np.array(g2.A), np.array(gait.A), rtol=0, atol=0)
    sched = g2.thrust.resolve(zd, zd.model.robot, "schedule", pad=True)[0]
    lc = limit_cycles(zd, sched)[0]
    assert lc.zeta_star == pytest.approx(target, rel=1e-9)


def test_cli_infeasible_exits_zero(tmp_path, cli):
    out = tmp_path / "inf"
    res = cli("optimize", "--target-zeta", "1500", "--max-thrust", "0.001",
                              "--out", str(out), "-q")
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "optimal_schedule.json").read_text())
    assert doc["feasible"] is False and doc["status"] == "infeasible"
    assert doc["violated_families"]
    assert doc["files"] == ["optimal_schedule.json"]


@pytest.mark.parametrize("args, message", [
    ([], "give exactly one"),
    (["--target-speed", "1", "--target-zeta", "100"], "give exactly one"),
    (["--target-speed", "-1"], "--target-speed"),
    (["--target-zeta", "100", "--knots", "0,0.6,0.4,1"], "--knots"),
    (["--target-zeta", "100", "--knots", "0.1,1"], "--knots"),
    (["--target-zeta", "100", "--mode", "sideways"], "--mode"),
    (["--target-zeta", "100", "--mode", "generalized"], "--max-thrust"),
    (["--target-zeta", "100", "--weights", "mass"], "--weights"),
    (["--target-zeta", "100", "--mu", "0"], "--mu"),
    (["--target-zeta", "100", "--zeta-min", "-3"], "--zeta-min"),
    (["--target-zeta", "100", "--thruster", "nozzle"], "--thruster"),
])
def test_cli_bad_input_exits_two(walk3, tmp_path, args, message, cli):
    res = cli("optimize", *args, "--out", str(tmp_path / "bad"), "-q")
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert "Traceback" not in res.output


def test_the_optimal_gait_names_its_robot_relative_to_its_folder(tmp_path, monkeypatch, cli):
    """As design-gait's: `robot: ../walker5.yaml`, not the absolute path, so that the folder
    can move (and a sweep file beside the robot may name the gait: it refuses absolute
    paths). Run from another folder, the robot given by a relative path."""
    import os
    import shutil
    from pathlib import Path

    data = Path(__file__).parent / "data"
    proj = tmp_path / "proj"
    proj.mkdir()
    for name in ("walker5.yaml", "walker5_walk.yaml"):
        shutil.copy(data / name, proj / name)
    monkeypatch.chdir(tmp_path)
    res = cli("optimize", "proj/walker5.yaml", "proj/walker5_walk.yaml", "--knots", "0,0.5,1",
              "--target-speed", "0.7", "--max-thrust", "30", "--out", "proj/o", "-q",
              "--formats", "none")
    assert res.exit_code == 0, res.output
    text = (proj / "o" / "walker5_walk_optimal.yaml").read_text()
    want = os.path.relpath(proj / "walker5.yaml", proj / "o")
    assert f"\nrobot: {want}\n" in text and want == os.path.join("..", "walker5.yaml")
    moved = tmp_path / "moved"
    proj.rename(moved)
    w = load_walker(None, str(moved / "o" / "walker5_walk_optimal.yaml"))
    assert Path(w.robot.source_file).resolve() == (moved / "walker5.yaml").resolve()


@pytest.mark.parametrize("formats, figures", [("none", []), ("pdf", ["optimal_orbit.pdf"])])
def test_files_and_the_wrote_line_name_only_the_files_written(tmp_path, monkeypatch, cli,
                                                               formats, figures):
    """`--formats none` writes no figure: optimal_schedule.json's `files` and the summary's
    `wrote ...` line must not name optimal_orbit.png/.pdf (they used to, whatever --formats
    said). Checked against the folder's listing; run from another folder (walker5)."""
    from pathlib import Path

    data = Path(__file__).parent / "data"
    monkeypatch.chdir(tmp_path)
    res = cli("optimize", str(data / "walker5.yaml"), str(data / "walker5_thrust.yaml"),
              "--knots", "0,0.5,1", "--target-zeta", "370", "--out", "o",
              "--formats", formats)
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "o" / "optimal_schedule.json").read_text())
    on_disk = sorted(p.name for p in (tmp_path / "o").iterdir() if not p.name.startswith("."))
    assert sorted(doc["files"]) == on_disk
    assert on_disk == sorted(["optimal_schedule.json", "walker5_thrust_optimal.yaml"] + figures)
    assert ".png" not in res.output
    assert ("optimal_orbit.pdf" in res.output) == bool(figures)
