"""Floquet analysis of the full-order closed loop (SPEC 13): the zero-dynamics multiplier, the
two Jacobians, the decoupled thruster, unstable settings, bad options.

Expected values come from computations the stability code does not use: delta_zero^2 from the
angular momentum about the stance foot before and after the impact map (SPEC 5, 10),
``exp(A T)`` of the thruster's own linear dynamics with the zero-dynamics step time (SPEC 3,
quadrature), finite differences of the closed loop's scalar right-hand side.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

import thrustwalk_cli as tw
from thrustwalk_cli.floquet.poincare import Setting
from thrustwalk_cli.floquet.variational import closed_loop, rhs_jacobian
from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
from thrustwalk_cli.simulation.closed_loop import ThrustModel
from thrustwalk_cli.thrust.schedule import Schedule

DATA = Path(__file__).resolve().parent / "data"


def delta_sq_from_momentum(walker) -> float:
    """delta_zero^2 = (sigma^+/sigma^-)^2 from the angular momentum about the stance foot,
    ``sigma = e_N^T D(q) q'``, just before and after the impact map, on Z at alpha_f: the
    rates along ``Phi(alpha_f) = H^-1 [dh_d/dalpha; 1]`` built here from the Bezier
    coefficients (``dh_d/ds(1) = M (a_M - a_{M-1})``)."""
    model, zd = walker.model, walker.zd
    N = model.n
    A = np.asarray(zd.maps.A, float)
    M = A.shape[1] - 1
    span = zd.alpha_f - zd.alpha_i
    dh = M * (A[:, M] - A[:, M - 1]) / span
    H = np.vstack([np.hstack([np.eye(N - 1), np.zeros((N - 1, 1))]), zd.maps.c[None, :]])
    phi = np.linalg.solve(H, np.concatenate([dh, [1.0]]))
    q = zd.maps.q_minus
    sigma_minus = float(model.D(q)[N - 1] @ phi)
    imp = model.impact(q, phi)
    sigma_plus = float(model.D(imp.q_plus)[N - 1] @ imp.dq_plus)
    return (sigma_plus / sigma_minus) ** 2


def test_delta_zero_sq_two_ways(walker3):
    assert delta_sq_from_momentum(walker3) == pytest.approx(walker3.zd.delta_zero_sq,
                                                            rel=1e-10)


@pytest.fixture(scope="module")
def second_order(walker3):
    """Second-order thruster (wn 2 rad/s, xi 0.7) at F_ss = -20 N, the gait's gains."""
    return tw.stability(walker3, thrust_model="second-order", wn=2.0, xi=0.7, thrust=-20.0)


@pytest.mark.slow
def test_high_gains_one_multiplier_is_delta_zero_sq_and_the_others_are_small(walker3):
    res = tw.stability(walker3, thrust_model="constant", thrust=-10.0, kp=2500.0, kd=100.0)
    f = res.cases[0].floquet
    assert f.fixed_point.converged and f.agree, f.reason
    d2 = delta_sq_from_momentum(walker3)
    lam = np.array([m.value for m in f.multipliers])
    i = int(np.argmin(np.abs(lam - d2)))
    assert abs(lam[i] - d2) < 1e-4, lam
    assert f.multipliers[i].kind == "zero dynamics"
    others = np.delete(np.abs(lam), i)
    assert others.size == 2 * walker3.model.n - 2  # 2N - 1 + n_z multipliers, n_z = 0
    assert np.all(others < 1e-3), others
    assert res.verdict == "stable" and res.success


def test_finite_differences_and_variational_equations_agree(second_order):
    f = second_order.cases[0].floquet
    assert f.agree
    assert np.max(np.abs(f.J - f.J_fd)) / max(1.0, np.max(np.abs(f.J))) < 1e-6
    for m in f.multipliers:
        assert abs(m.value - m.finite_difference) < 1e-6, m
    # the finite-difference step was chosen from a converging sweep
    assert f.fd.error < 1e-6 and 1e-6 < f.fd.step < 1e-2
    # the monodromy with saltation carries the flow direction: trivial multiplier 1
    assert abs(f.variational.trivial_multiplier - 1.0) < 1e-6
    doc = second_order.document()
    assert "agree" in doc["cases"][0]["jacobian"]["agreement"]["statement"]


def test_decoupled_thruster_contributes_exactly_the_eigenvalues_of_exp_AT(walker3,
                                                                          second_order):
    """SPEC 13: z' = A z + b F_ss does not depend on the walker, so at the equilibrium thrust
    the Jacobian is block-triangular and the thruster's multipliers are eig(exp(A T*))."""
    f = second_order.cases[0].floquet
    zd = walker3.zd
    T = limit_cycles(zd, Schedule.constant(zd, np.array([[-20.0, 0.0]])))[0].step_time
    wn, xi = 2.0, 0.7
    A = np.array([[0.0, 1.0], [-wn**2, -2 * xi * wn]])  # states (F, F') of one thruster
    expected = np.tile(np.linalg.eigvals(expm(A * T)), 2)  # two thrusters, the same A
    got = [m.value for m in f.multipliers if m.kind == "thruster"]
    assert len(got) == 4
    for g in got:  # each multiplier is an eigenvalue of exp(A T), each one used twice
        k = int(np.argmin(np.abs(expected - g)))
        assert abs(expected[k] - g) < 1e-7, (got, expected)
        expected = np.delete(expected, k)
    # and the zero-dynamics multiplier is still delta_zero^2
    assert abs(f.zero_dynamics_multiplier - delta_sq_from_momentum(walker3)) < 1e-6


def test_section_has_2n_minus_1_plus_nz_dimensions_and_drops_the_trivial_multiplier(
        walker3, second_order):
    f = second_order.cases[0].floquet
    N, nz = walker3.model.n, 4
    B = f.basis
    assert B.shape == (2 * N + nz, 2 * N - 1 + nz)
    assert np.allclose(B.T @ B, np.eye(B.shape[1]), atol=1e-12)
    gq = walker3.model.E_swing(f.fixed_point.x[:N])[1]
    assert np.max(np.abs(gq @ B[:N])) < 1e-12  # tangent to the guard
    # the full-space Jacobian has the same multipliers plus the trivial 0 (normal direction)
    full = np.linalg.eigvals(f.variational.DP)
    assert np.min(np.abs(full)) < 1e-9
    rest = np.sort_complex(np.delete(full, np.argmin(np.abs(full))))
    assert np.allclose(rest, np.sort_complex([m.value for m in f.multipliers]), atol=1e-8)


def test_rhs_jacobian_against_finite_differences_of_the_scalar_right_hand_side(walker3,
                                                                               second_order):
    f = second_order.cases[0].floquet
    setting = Setting(ThrustModel("second-order", np.array([-20.0, 0.0]), wn=2.0, xi=0.7),
                      400.0, 40.0)
    cl = closed_loop(walker3.zd, setting)
    N = walker3.model.n
    x = f.fixed_point.x.copy()
    x[N:2 * N] *= 0.9  # off the orbit too
    x[2 * N] += 3.0
    seg = cl.segment_of((float(cl.c @ x[:N]) - cl.ai) / cl.span)
    f0, J = rhs_jacobian(cl, x, seg)
    assert np.allclose(f0, cl.rhs(0.0, x, seg), rtol=1e-12, atol=1e-9)
    h = 1e-6
    Jfd = np.empty_like(J)
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = h
        Jfd[:, j] = (np.array(cl.rhs(0.0, x + e, seg)) - np.array(cl.rhs(0.0, x - e, seg))) \
            / (2 * h)
    scale = max(1.0, np.max(np.abs(J)))
    assert np.max(np.abs(J - Jfd)) / scale < 1e-7, np.max(np.abs(J - Jfd))


def test_piecewise_thrust_saltation_at_the_knot(walk3, tmp_path):
    """A gait's own thrust: section (force jumps at s = 0.5): the variational Jacobian needs the
    saltation matrix at the knot to agree with the finite differences."""
    text = Path(walk3[1].source_file).read_text().replace(
        "robot: three_link\n", f"robot: {Path(walk3[0].robot.source_file)}\n")
    text += ("thrust:\n  mode: force\n  knots: [0, 0.5, 1]\n  fractions: true\n"
             "  values:\n    hip_x: [-10, -3]\n")
    (tmp_path / "pw.yaml").write_text(text)
    walker = tw.load_walker(walk3[0].robot.source_file, str(tmp_path / "pw.yaml"))
    res = tw.stability(walker)
    f = res.cases[0].floquet
    assert res.thrust_model == "piecewise"
    assert f.agree and f.agreement < 1e-6, f.reason
    assert abs(f.variational.trivial_multiplier - 1.0) < 1e-6
    assert abs(f.zero_dynamics_multiplier - delta_sq_from_momentum(walker)) < 1e-6
    assert res.verdict == "stable"


def test_low_gains_are_unstable_though_the_zero_dynamics_is_stable(walker3):
    """Where the two-time-scale picture breaks: with slow outputs (K_p = 9, K_d = 1) the
    transverse dynamics grow over a step, delta_zero^2 < 1 notwithstanding."""
    res = tw.stability(walker3, thrust_model="constant", kp=9.0, kd=1.0)
    f = res.cases[0].floquet
    assert f.agree and f.fixed_point.converged
    assert f.spectral_radius > 1 and f.verdict == "unstable" and res.verdict == "unstable"
    assert abs(f.zero_dynamics_multiplier - walker3.zd.delta_zero_sq) < 1e-6
    assert f.multipliers[0].kind == "outputs"


def test_no_orbit_is_said_and_never_stable(walker3):
    res = tw.stability(walker3, thrust_model="constant", thrust=40.0)
    f = res.cases[0].floquet
    assert not f.exists and f.verdict == "no orbit" and "no predicted orbit" in f.reason
    assert not res.success and res.verdict == "undetermined"
    doc = res.document()
    assert doc["warnings"] and doc["cases"][0]["multipliers"] == []


@pytest.mark.slow
def test_vary_sweeps_one_parameter(walker3):
    res = tw.stability(walker3, thrust_model="second-order", thrust=-10.0,
                       vary=("wn", [0.5, 20.0]))
    zd = walker3.zd
    T = limit_cycles(zd, Schedule.constant(zd, np.array([[-10.0, 0.0]])))[0].step_time
    for case, wn in zip(res.cases, (0.5, 20.0)):
        thr = [m.value for m in case.floquet.multipliers if m.kind == "thruster"]
        # critically damped (xi = 1): a double eigenvalue exp(-wn T)
        assert np.allclose(np.abs(thr), math.exp(-wn * T), rtol=1e-5), (wn, thr)
    # the slow thruster (wn T ~ 0.3: as slow as a step) dominates the spectral radius
    assert res.cases[0].floquet.spectral_radius == pytest.approx(math.exp(-0.5 * T), rel=1e-5)
    figs = res.figures()
    assert set(figs) == {"multipliers", "spectral_radius"}


@pytest.mark.slow
def test_gait_with_delta_zero_sq_above_one_is_never_called_stable():
    """tests/data/three_link_unstable_walk.yaml: delta_zero^2 > 1 (checked independently);
    its zero-dynamics orbit needs a negative vertical ground force just after impact, so the
    full-order step fails and the verdict is undetermined, never stable."""
    walker = tw.load_walker(str(DATA / "three_link_low_torso.yaml"),
                            str(DATA / "three_link_unstable_walk.yaml"))
    assert delta_sq_from_momentum(walker) > 1.0
    res = tw.stability(walker, thrust_model="constant", thrust=0.0)
    f = res.cases[0].floquet
    assert f.verdict == "undetermined" and not res.success
    assert "vertical ground force" in f.reason


# ------------------------------------------------------------------ agreement on the multipliers
# The user's 5-link knee walker (tests/data/walker5.yaml) and its gait designed by design-gait
# to be feasible over -40..0 N of torso thrust: at 0 N the two Jacobians' entries differed by
# 2.1e-6 (against a fixed 1e-6) while the multipliers agreed to 2.2e-7 and the spectral radius
# was 0.73: called undetermined on main.


@pytest.fixture(scope="module")
def walker5_run(tmp_path_factory, _cache_dir):
    """``thrustwalk stability walker5.yaml walker5_thrust.yaml --thrust 0`` run in-process from
    another folder with relative paths; returns (click result, stability.json, the
    StabilityResult the command computed, kept for independent checks)."""
    import os

    from typer.testing import CliRunner

    import thrustwalk_cli.studies.stability as study
    from thrustwalk_cli.cli import app

    work = tmp_path_factory.mktemp("walker5_stability")
    rel = Path(os.path.relpath(DATA, work))
    kept = []
    real = study.stability

    def keep(*args, **kwargs):
        kept.append(real(*args, **kwargs))
        return kept[-1]

    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(work)
        mp.setattr(study, "stability", keep)
        res = CliRunner().invoke(app, ["stability", str(rel / "walker5.yaml"),
                                       str(rel / "walker5_thrust.yaml"), "--thrust", "0",
                                       "--formats", "csv", "--out", "out"],
                                 catch_exceptions=False)
    text = (work / "out" / "stability.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    return res, json.loads(text), next(k for k in kept if k is not None)  # not the check


@pytest.mark.slow
def test_walker5_designed_gait_is_stable_judged_on_the_multipliers(walker5_run):
    res, doc, result = walker5_run
    assert res.exit_code == 0, res.output
    f = result.cases[0].floquet
    assert f.fixed_point.converged
    assert f.verdict == "stable", f.reason
    # independent estimates of the spectral radius: numpy's eigenvalues of the
    # finite-difference Jacobian, and SPEC 13's identity that one multiplier is delta_zero^2
    # (from the angular momentum across the impact map, not from the zero-dynamics code)
    rho_fd = float(np.max(np.abs(np.linalg.eigvals(f.J_fd))))
    d2 = delta_sq_from_momentum(result.walker)
    assert abs(f.spectral_radius - rho_fd) <= f.radius_error, (f.spectral_radius, rho_fd)
    assert abs(f.zero_dynamics_multiplier - d2) < 1e-6
    assert f.spectral_radius == pytest.approx(d2, abs=1e-6)  # the zero dynamics dominates
    assert f.spectral_radius < 1 - 100 * f.radius_error
    # the verdict: stable, on multipliers within their scaled tolerances
    assert f.verdict == "stable" and "verdict: stable: every case is stable" in res.stdout
    assert doc["verdict"] == "stable" and doc["success"], doc["reason"]
    ag = doc["cases"][0]["jacobian"]["agreement"]
    assert ag["judged_on"] == "multipliers" and ag["agree"]
    assert ag["tolerance_source"] == "scaled" and ag["agreement_tol"] is None
    assert ag["tolerance"] >= 1e-6 and "1e-6" in ag["tolerance_rule"]
    assert ag["jacobian"] > 0 and ag["radius_error"] == pytest.approx(f.radius_error)
    for m in doc["cases"][0]["multipliers"]:
        lam_fd = complex(m["finite_difference"]["re"], m["finite_difference"]["im"])
        assert abs(complex(m["re"], m["im"]) - lam_fd) == pytest.approx(m["difference"])
        assert m["difference"] <= m["tolerance"] and m["agrees"]
        E = doc["cases"][0]["jacobian"]["finite_differences"]["error_estimate"]
        assert m["tolerance"] == pytest.approx(max(1e-6, 10 * m["fd_error_estimate"], E))
    assert doc["settings"]["agreement"]["judged_on"] == "multipliers"
    assert doc["settings"]["agreement_tol"] is None


def test_walker5_fd_error_estimate_carried_to_each_multiplier(walker5_run):
    """e_j: the change of each finite-difference multiplier between the chosen step and the
    neighbouring step, recomputed here from the two Jacobians with numpy."""
    f = walker5_run[2].cases[0].floquet
    fd = f.fd
    assert fd.neighbour is not None and fd.neighbour_step != fd.step
    assert np.max(np.abs(fd.J - fd.neighbour)) == pytest.approx(fd.error)
    mu = np.linalg.eigvals(fd.J)
    nb = np.linalg.eigvals(fd.neighbour)
    checked = 0
    for m in f.multipliers:
        k = int(np.argmin(np.abs(mu - m.finite_difference)))
        assert abs(mu[k] - m.finite_difference) < 1e-12
        gap = np.sort(np.abs(mu - mu[k]))[1]  # to the next eigenvalue
        if gap < 1e-3:
            continue  # the critically damped thruster's double eigenvalue: no unique match
        assert m.fd_error == pytest.approx(float(np.min(np.abs(nb - mu[k]))), rel=1e-9,
                                           abs=1e-15)
        checked += 1
    assert checked >= 1  # the zero-dynamics multiplier (the outputs are within 1e-5 of 0)
    zd = next(m for m in f.multipliers if m.kind == "zero dynamics")
    assert zd.fd_error < 1e-7 and zd.tolerance == 1e-6  # well conditioned: the floor


def _skew_variational(monkeypatch, factor: float) -> None:
    """A constructed disagreement: the variational Jacobian scaled by ``factor``, so each of
    its multipliers is the finite-difference one times ``factor``."""
    from dataclasses import replace

    import thrustwalk_cli.floquet.multipliers as fm

    real = fm.variational_jacobian

    def skewed(*args, **kwargs):
        v = real(*args, **kwargs)
        return replace(v, DP=v.DP * factor)

    monkeypatch.setattr(fm, "variational_jacobian", skewed)


@pytest.mark.slow
def test_disagreement_beyond_the_tolerance_stays_undetermined_with_advice(cli, tmp_path,
                                                                          monkeypatch):
    """Multipliers 1e-4 apart (relative) against a tolerance of 1e-6: undetermined although
    the radius (0.76) is far from 1, and the reason says what to try, with the command's
    flags on the console and parameter names in the JSON; --agreement-tol 1e-3 accepts it."""
    _skew_variational(monkeypatch, 1.0 + 1e-4)
    monkeypatch.chdir(tmp_path)
    base = ["stability", "three_link", "three_link_walk", "--thrust-model", "constant",
            "--thrust", "-10", "--formats", "none"]
    res = cli(*base, "--out", "a")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "a" / "stability.json").read_text())
    c = doc["cases"][0]
    assert c["verdict"] == "undetermined" and doc["verdict"] == "undetermined"
    assert not doc["success"] and not c["jacobian"]["agreement"]["agree"]
    worst = c["jacobian"]["agreement"]["worst"]
    assert worst["difference"] > worst["tolerance"] == pytest.approx(1e-6)
    for text in (c["reason"], doc["reason"]):
        assert "disagree" in text and "`rtol`/`atol`" in text and "`agreement_tol`" in text
    warning = [ln for ln in res.stderr.splitlines() if "disagree" in ln]
    assert len(warning) == 1 and "--rtol/--atol" in warning[0], res.stderr
    assert "--agreement-tol" in warning[0] and "`" not in warning[0]
    assert "--agreement-tol" in res.stdout.split("verdict: undetermined")[-1]
    # a given tolerance above the disagreement: the radius is far from 1, so stable
    res = cli(*base, "--agreement-tol", "1e-3", "--out", "b")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "b" / "stability.json").read_text())
    ag = doc["cases"][0]["jacobian"]["agreement"]
    assert doc["verdict"] == "stable", doc["reason"]
    assert ag["tolerance_source"] == "given" and ag["tolerance"] == 1e-3
    assert doc["settings"]["agreement_tol"] == 1e-3
    rho = doc["cases"][0]["spectral_radius"]
    assert ag["radius_error"] >= ag["multipliers"] > 1e-5 and rho < 1 - ag["radius_error"]


def test_radius_within_the_disagreement_of_one_stays_undetermined(monkeypatch, walker3):
    """A verdict never better than the evidence: multipliers 25 % apart accepted by a loose
    agreement_tol put the radius 0.95 within its error bar of 1."""
    _skew_variational(monkeypatch, 1.25)
    res = tw.stability(walker3, thrust_model="constant", thrust=-10.0, agreement_tol=0.5)
    f = res.cases[0].floquet
    assert f.agree and f.tolerance_source == "given"
    lam_fd = max(abs(m.finite_difference) for m in f.multipliers)
    assert f.spectral_radius == pytest.approx(1.25 * lam_fd, rel=1e-6)
    assert abs(f.spectral_radius - 1) < f.multiplier_agreement <= f.radius_error
    assert f.verdict == "undetermined" and res.verdict == "undetermined"
    assert "error bar" in f.reason and "`rtol`/`atol`" in f.reason


@pytest.mark.parametrize("bad", [0.0, -1e-6, float("nan"), float("inf"), "x"])
def test_agreement_tol_is_validated_before_any_work(walker3, bad):
    with pytest.raises(tw.InputError) as exc:
        tw.stability(walker3, agreement_tol=bad)
    assert exc.value.problems[0].params == ("agreement_tol",)


def test_newton_failure_says_what_to_try():
    """The walking gait (designed for no thrust) at -10 N: the foot lifts off on the first
    full-order step, so there is no fixed point; the reason names settings to change."""
    walker = tw.load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"))
    res = tw.stability(walker, thrust_model="second-order", wn=2.0, xi=0.7, thrust=-10.0)
    f = res.cases[0].floquet
    assert f.verdict == "undetermined" and "Newton" in f.reason
    assert "try another setting" in f.reason and "`kp`" in f.reason


BAD = [
    (["--vary", "foo=1:2:log3"], "option --vary: unknown parameter 'foo'"),
    (["--vary", "wn=0:1:log5"], "option --vary: a log range needs start and stop > 0"),
    (["--vary", "wn"], "option --vary: expected NAME=VALUES"),
    (["--vary", "wn=1:2:logx"], "option --vary: a log range is start:stop:logK"),
    (["--thrust-model", "constant", "--vary", "wn=1,2"],
     "option --vary: wn is a parameter of the second-order thrust model"),
    (["--vary", "tau=1,2"], "option --vary: tau is a parameter of the first-order"),
    (["--vary", "kp=-1,2"], "option --vary: kp must be > 0"),
    (["--thrust", "0,-10"], "option --thrust: one steady thrust per analysis"),
    (["--kp", "-5"], "option --kp: must be > 0"),
    (["--thrust-model", "bogus"], "option --thrust-model: unknown model 'bogus'"),
    (["--thrust", "500"], "is outside the limits"),
    (["--thruster", "nope"], "option --thruster: unknown thruster 'nope'"),
    (["--wn", "0"], "option --wn: must be > 0"),
    (["--rtol", "nan"], "option --rtol: nan is not a usable number"),
    (["--agreement-tol", "0"], "option --agreement-tol: must be a finite number > 0"),
    (["--agreement-tol", "-1e-6"], "option --agreement-tol: must be a finite number > 0"),
    (["--agreement-tol", "nan"], "option --agreement-tol: nan is not a usable number"),
    (["--agreement-tol", "inf"], "option --agreement-tol: inf is not a usable number"),
    (["--agreement-tol", "tight"], "option --agreement-tol: 'tight' is not a valid float"),
]


@pytest.mark.parametrize("args, message", BAD)
def test_bad_options_are_one_line_errors_exit_2_nothing_written(cli, tmp_path, args, message):
    out = tmp_path / "out"
    res = cli("stability", "three_link", *args, "--out", out, "-q")
    assert res.exit_code == 2, (args, res.output)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert message in lines[0], lines[0]
    assert "Traceback" not in res.output
    assert not out.exists()


@pytest.mark.slow
def test_command_writes_the_result_folder(cli, tmp_path):
    from thrustwalk_cli.studies.documents import UNITS

    res = cli("stability", "three_link", "three_link_walk", "--thrust-model", "constant",
              "--thrust", "-10", "--vary", "kp=100:1600:log3", "--out", tmp_path)
    assert res.exit_code == 0, res.output
    for name in ("stability.json", "multipliers.csv", "multipliers.png", "multipliers.pdf",
                 "spectral_radius.png", "spectral_radius.pdf"):
        assert (tmp_path / name).stat().st_size > 0, name
    text = (tmp_path / "stability.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text)
    assert doc["schema_version"] >= 1 and doc["provenance"]["command"].startswith("thrustwalk")
    for key, unit in doc["units"].items():
        assert UNITS[key] == unit, key
    assert doc["settings"]["vary"]["values"] == pytest.approx([100.0, 400.0, 1600.0])
    assert doc["success"] and doc["verdict"] == "stable"
    for c in doc["cases"]:
        assert c["fixed_point"]["newton"]["residual"] <= 1e-9
        assert c["jacobian"]["agreement"]["agree"]
        assert len(c["multipliers"]) == 2 * 3 - 1
        assert abs(c["zero_dynamics"]["difference"]) < 1e-6
    assert "verdict: stable" in res.stdout
    assert (tmp_path / "multipliers.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_documented_slow_output_example_holds(walker3):
    """docs/commands.md: with slow outputs (--kp 9 --kd 1) at -20 N of the slow thruster an
    output multiplier reaches 9.16 and the orbit is unstable although delta_zero^2 < 1 (the
    docs said 6.5, issue 24 item 10)."""
    import re
    from dataclasses import replace

    from thrustwalk_cli.studies.stability import stability
    from thrustwalk_cli.walker import walker_from

    text = (Path(__file__).resolve().parents[1] / "docs" / "commands.md").read_text()
    claimed = float(re.search(r"\(`--kp 9 --kd 1`\) an\s+output multiplier reaches ([\d.]+)",
                              text).group(1))
    w = walker_from(walker3.model, replace(walker3.gait, kp=9.0, kd=1.0))
    res = stability(w, thrust_model="second-order", wn=2.0, xi=0.7, thrust=-20.0)
    f = res.cases[0].floquet
    outputs = [abs(m.value) for m in f.multipliers if m.kind == "outputs"]
    assert f.verdict == "unstable" and walker3.zd.delta_zero_sq < 1
    assert max(outputs) == pytest.approx(claimed, abs=0.005)


@pytest.mark.slow
def test_variational_equations_find_a_slow_touchdown_between_two_integrator_steps():
    """A grazing touchdown (rabbit_grazing: the swing foot reaches the ground at -0.26 mm/s,
    then rises again on the extrapolated constraints) dips below the ground between two
    integrator steps, where no sign change of the foot height shows it. The variational
    integration must stop there, as the simulation behind the finite differences does, not
    at a later crossing (it used to fail, or on a kneed user robot at -0.05 m/s to run on to
    s = 1.46 and report an outputs multiplier of 10 that the finite differences did not
    have). Checked against the zero dynamics: the step time by quadrature (SPEC 3) and
    delta_zero^2 from the angular momentum across the impact, one multiplier of the
    Poincare map on the guard at the predicted fixed point (SPEC 13)."""
    from thrustwalk_cli.floquet.poincare import predicted_state, section_basis
    from thrustwalk_cli.floquet.variational import variational_jacobian

    w = tw.load_walker(None, str(DATA / "rabbit_grazing.yaml"))
    th = ThrustModel("ideal", np.zeros(w.model.n_thrusters))
    setting = Setting(th, w.gait.kp, w.gait.kd)
    x0, lc = predicted_state(w.zd, th)
    var = variational_jacobian(w.zd, setting, x0, rtol=1e-8, atol=1e-8)  # quicker than 1e-11
    assert var.ok, var.reason
    assert var.T == pytest.approx(lc.step_time, rel=1e-5)
    B = section_basis(w.zd, x0, 0)
    mults = np.linalg.eigvals(B.T @ var.DP @ B)
    d2 = delta_sq_from_momentum(w)
    assert np.min(np.abs(mults - d2)) < 1e-4
    assert np.max(np.abs(mults)) < 1.0  # stable: the outputs' multipliers are small


def test_footed_walker_with_critically_damped_gains_is_stable():
    """A user's footed 7-link walker (tests/data/footbot.yaml, imported from footbot.urdf; its
    gait designed by design-gait at 0.5 m/s with a designed torso thrust) has critically
    damped gains kp = 400, kd = 40: a double outputs multiplier near exp(-20 T), about 4e-6,
    which the two methods put a few 1e-6 apart, within the finite-difference entries' own
    error estimate E. Its radius is the zero-dynamics multiplier, delta_zero^2 computed here
    from the angular momentum across the impact (not by the zero-dynamics code): stable,
    each multiplier within max(1e-6, 10 e_j, E)."""
    walker = tw.load_walker(str(DATA / "footbot.yaml"), str(DATA / "footbot_walk.yaml"))
    res = tw.stability(walker)
    f = res.cases[0].floquet
    assert f.verdict == "stable" and res.verdict == "stable", f.reason
    d2 = delta_sq_from_momentum(walker)
    assert f.spectral_radius == pytest.approx(d2, abs=1e-6)
    assert f.spectral_radius < 1 - 100 * f.radius_error
    E = f.fd.error
    for m in f.multipliers:
        assert m.difference <= m.tolerance == pytest.approx(
            max(1e-6, 10 * (m.fd_error or 0.0), E))
    T = f.variational.T
    small = [m for m in f.multipliers if m.kind == "outputs" and m.modulus < 1e-4]
    assert small and all(m.modulus < 100 * np.exp(-20.0 * T) for m in small)
