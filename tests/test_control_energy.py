"""``control --objective energy`` (issue 28; SPEC 11 with SPEC 15 "Energy-optimal thrust"): each
step's plan minimises the driven thrusters' input energy over the predicted step under the
effort plan's constraints.

Independent computations: the input energy of a plan is evaluated here from the thruster's
power model (``energetics.power.input_power``) applied on the predicted step, with zeta along
the step from the zero-dynamics code (``ZeroDynamics.V_Z`` of the plan's schedule, not the
planner's rows), ``|alpha'| = |kappa_1| sqrt(2 zeta)`` from ``ZeroDynamics.terms`` and
Gauss-Legendre quadrature (not the solver's Clenshaw-Curtis nodes); its gradient by central
differences. The KKT conditions are checked with multipliers fitted here (bounded least
squares) on the plan's own rows. A run's thruster input energy comes from the full-order
simulation's dense output (``energetics.run``), not from the planner.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from thrustwalk_cli.controller.planner import regulator
from thrustwalk_cli.energetics.power import input_power
from thrustwalk_cli.thrust.schedule import Schedule

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def kneed4(_cache_dir):
    """The user robot with a momentum rotor model (tests/data/kneed4.yaml) and its gait."""
    from thrustwalk_cli.walker import load_walker

    return load_walker(str(DATA / "kneed4.yaml"), str(DATA / "kneed4_walk.yaml"))


def _knots(zd, fractions):
    return zd.alpha_i + np.array(fractions) * (zd.alpha_f - zd.alpha_i)


def _energy(zd, kn, driven, x, u, nodes=120):
    """Input energy [J] of values ``u`` (interval-major) over the step that starts at
    zeta^- = ``x``: the power model on the zero-dynamics step, Gauss-Legendre in alpha."""
    model, maps = zd.model, zd.maps
    md, m = len(driven), model.n_thrusters
    force = np.zeros((1, len(kn) - 1, m))
    force[0][:, driven] = np.asarray(u, float).reshape(-1, md)
    sched = Schedule(kn, force, np.zeros((1, len(kn) - 1)))
    xg, wg = np.polynomial.legendre.leggauss(nodes)
    total = 0.0
    for j in range(len(kn) - 1):
        lo, hi = sorted((kn[j], kn[j + 1]))
        a = lo + 0.5 * (xg + 1.0) * (hi - lo)
        w = 0.5 * wg * (hi - lo)
        zeta = zd.delta_zero_sq * x + zd.V_Z(a, sched)[0]
        adot = np.abs(zd.terms(a)["kappa1"]) * np.sqrt(2.0 * zeta)
        qd = maps.Phi(a) * (zd.direction * adot)[:, None]
        dp = np.einsum("gnm,gn->gm", model.B_F(maps.q_Z(a)), qd)  # d_t . p_t'
        for t in driven:
            F = float(force[0, j, t])
            P = input_power(model.robot.thrusters[t].power, np.full(a.size, F),
                            np.sign(F) * dp[:, t])
            total += float(w @ (P / adot))
    return total


def _gradient(zd, kn, driven, x, u):
    h = 1e-4 * max(1.0, np.abs(u).max())
    return np.array([(_energy(zd, kn, driven, x, u + h * e) - _energy(zd, kn, driven, x,
                                                                       u - h * e)) / (2 * h)
                     for e in np.eye(len(u))])


def _rows(pl, plan):
    """The plan's rows ``A u <= b`` (grid, measurement band, bounds) and its x_{k+1} row."""
    A, b, fam = pl.constraints(plan.rows, *plan.x_band, None, rate=False)
    g = plan.rows.Zu[-1]
    rhs = plan.x_target - pl.d2 * plan.x_meas - plan.rows.z0[-1]
    return A, b, fam, g, rhs


def _kkt_residual(grad, A, b, g, u):
    """``min |grad + A_act^T lam + nu g| / |grad|`` over ``lam >= 0`` (rows active to 1e-9)."""
    act = np.flatnonzero(b - A @ u <= 1e-9 * (1.0 + np.abs(b)))
    M = np.column_stack([A[act].T, g])
    lb = np.r_[np.zeros(act.size), -np.inf]
    res = lsq_linear(M, -grad, bounds=(lb, np.full(act.size + 1, np.inf)))
    return float(np.linalg.norm(M @ res.x + grad) / np.linalg.norm(grad)), act


CASES = [  # (robot, knot fractions, max_thrust, reference / zeta*)
    ("three_link", (0.0, 0.5, 1.0), 14.0, 1.3),  # a thrust bound active
    ("kneed4", (0.0, 1 / 3, 2 / 3, 1.0), None, 0.85),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_energy_plan_meets_the_kkt_conditions(case, walker3, kneed4):
    """(1) KKT at one step's energy plan: the gradient of the independently evaluated energy
    (finite differences) is balanced by nonnegative multipliers of the active rows and the
    x_{k+1} = x_ref row; the effort plan of the same state is not (the check can fail)."""
    name, fr, max_thrust, ref = case
    walker = walker3 if name == "three_link" else kneed4
    zd = walker.zd
    kn = _knots(zd, fr)
    pl, lc0 = regulator(zd, kn, [0], mu=0.7, max_thrust=max_thrust, continuous=True,
                        objective="energy")
    zs = lc0.zeta_star
    plan = pl.plan(zs, ref * zs, np.zeros(pl.nu))
    assert plan.status == "tracking" and plan.energy["status"] == "optimal", plan.energy
    A, b, fam, g, rhs = _rows(pl, plan)
    assert np.all(A @ plan.u <= b + 1e-9 * (1 + np.abs(b)))
    assert g @ plan.u == pytest.approx(rhs, rel=1e-10)
    grad = _gradient(zd, kn, [0], zs, plan.u)
    r, act = _kkt_residual(grad, A, b, g, plan.u)
    assert r < 1e-6, r
    if max_thrust is not None:  # the bound is active and carries a multiplier
        assert set(fam[act]) == {"thrust_bounds"} and np.abs(plan.u).max() == pytest.approx(
            max_thrust, rel=1e-12)
    # the planner's own energy is the independent one
    assert plan.energy["energy"] == pytest.approx(_energy(zd, kn, [0], zs, plan.u), rel=1e-9)
    eff, _ = regulator(zd, kn, [0], mu=0.7, max_thrust=max_thrust, continuous=True)
    p_eff = eff.plan(zs, ref * zs, np.zeros(eff.nu))
    r_eff, _ = _kkt_residual(_gradient(zd, kn, [0], zs, p_eff.u), A, b, g, p_eff.u)
    assert r_eff > 1e-3


@pytest.mark.parametrize("name", ["three_link", "kneed4"])
def test_energy_plan_uses_no_more_than_the_effort_plan(name, walker3, kneed4):
    """(2) For the same measured state and reference, the energy plan's input energy
    (independent evaluation) is at most the effort plan's, both plans meeting their rows and
    reaching the same x_{k+1}; a state whose reference is out of reach saturates in both
    (the same attainable x_{k+1})."""
    walker = walker3 if name == "three_link" else kneed4
    zd = walker.zd
    kn = _knots(zd, (0.0, 0.5, 1.0))
    en, lc0 = regulator(zd, kn, [0], mu=0.7, max_thrust=20.0, continuous=True,
                        objective="energy")
    ef, _ = regulator(zd, kn, [0], mu=0.7, max_thrust=20.0, continuous=True)
    zs = lc0.zeta_star
    saturated = 0
    for x, ref in ((zs, 1.2 * zs), (1.1 * zs, 0.9 * zs), (0.9 * zs, zs), (zs, 3.0 * zs)):
        p_en = en.plan(x, ref, np.zeros(en.nu))
        p_ef = ef.plan(x, ref, np.zeros(ef.nu))
        assert p_en.status == p_ef.status != "infeasible"
        saturated += p_en.status == "saturated"
        assert p_en.x_next == pytest.approx(p_ef.x_next, rel=1e-8)
        for pl, p in ((en, p_en), (ef, p_ef)):
            A, b, _, g, rhs = _rows(pl, p)
            assert np.all(A @ p.u <= b + 1e-9 * (1 + np.abs(b)))
        e_en = _energy(zd, kn, [0], x, p_en.u)
        e_ef = _energy(zd, kn, [0], x, p_ef.u)
        assert e_en <= e_ef * (1 + 1e-12), (x / zs, ref / zs, e_en, e_ef)
        assert p_en.energy["effort_plan_energy"] == pytest.approx(e_ef, rel=1e-9)
    assert saturated == 1


@pytest.mark.slow
def test_energy_run_tracks_like_the_effort_run_with_less_input_energy(kneed4):
    """(3) 8 full-order steps on the user robot with a zeta reference that needs thrust on
    every step (above the orbit's, then below it): both runs reach every reference (deadbeat),
    and the energy run's thruster input energy from the simulation (energetics.run, the dense
    output) is at most the effort run's; its planned energy is what the simulation consumed."""
    from thrustwalk_cli.studies.control import control
    from thrustwalk_cli.studies.control_result import step_energy

    zs = kneed4.zd.nominal_cycle().zeta_star
    prof = [(0, 1.2 * zs), (4, 0.9 * zs)]
    runs = {obj: control(kneed4, reference="zeta", profile=prof, steps=8, compare=False,
                         objective=obj) for obj in ("effort", "energy")}
    used = {}
    for obj, r in runs.items():
        assert r.status == "ok", r.reason
        assert len(r.controlled.steps) == 8
        assert r.zeta_errors().max() < 1e-8
        used[obj] = sum(step_energy(s).thrust_input for s in r.controlled.steps)
    assert used["energy"] <= used["effort"]
    doc = runs["energy"].document()
    assert doc["settings"]["objective"] == "energy"
    assert "least-input-energy" in doc["reason"]
    assert doc["summary"]["planned_input_energy"] == pytest.approx(used["energy"], rel=1e-6)
    assert all(e["qp"]["energy"]["status"] == "optimal" for e in doc["steps"])
    assert "objective" not in runs["effort"].document()["settings"]


def test_a_run_that_needs_no_thrust_is_optimal_not_a_warning(kneed4):
    """On the nominal reference the effort plans spend (to rounding) no input energy; the
    input power is >= 0, so they are optimal energy plans: every step's plan is ``optimal``
    and the run ``ok`` (before: the degenerate KKT check at zero thrust failed on a step,
    the effort plan was applied and the run was called a warning)."""
    from thrustwalk_cli.studies.control import control

    r = control(kneed4, reference="nominal", steps=4, compare=False, objective="energy")
    doc = r.document()
    assert r.status == "ok", r.reason
    assert [e["qp"]["energy"]["status"] for e in doc["steps"]] == ["optimal"] * 4
    weight_length = kneed4.robot.weight * kneed4.zd.step_length
    for e in doc["steps"]:
        en = e["qp"]["energy"]
        assert en["energy"] <= en["effort_plan_energy"] + 1e-12 * weight_length


def test_cli_energy_without_a_power_model_exits_two(tmp_path, monkeypatch, cli):
    """(4) walker5's thruster has no `power:` model: one error line naming it, exit 2,
    nothing written (before anything is computed)."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    res = cli("control", str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"),
              "--reference", "nominal", "--steps", "3", "--objective", "energy", "--out",
              "out", "-q")
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in res.output, res.output
    assert "option --objective:" in lines[0] and "thruster back" in lines[0], lines[0]
    assert not out.exists()


@pytest.mark.parametrize("args, message", [
    (["--objective", "power"], "option --objective:"),
    (["--objective", "energy", "--tracking-weight", "10"], "option --tracking-weight:"),
    (["--objective", "energy", "--rate-weight", "1"], "option --rate-weight:"),
    (["--objective", "energy", "--thrust-model", "first-order", "--knots", "0,1"],
     "option --objective: energy needs ideal thrust"),
])
def test_cli_energy_bad_combinations_exit_two(tmp_path, cli, args, message):
    out = tmp_path / "bad"
    res = cli("control", "--reference", "nominal", "--steps", "2", *args, "--out", str(out),
              "-q")
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and message in lines[0], res.output
    assert not out.exists()


def test_cli_energy_document(tmp_path, monkeypatch, cli):
    """The command on the user robot from another folder: the document records the objective,
    each step's planned input energy, and the summary line says it."""
    monkeypatch.chdir(tmp_path)
    res = cli("control", str(DATA / "kneed4.yaml"), str(DATA / "kneed4_walk.yaml"),
              "--reference", "speed", "--profile", "0:0.55", "--steps", "2", "--objective",
              "energy", "--formats", "csv", "--out", "out")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "out" / "control.json").read_text())
    assert doc["settings"]["objective"] == "energy"
    for e in doc["steps"]:
        q = e["qp"]["energy"]
        assert q["status"] == "optimal" and q["energy"] <= q["effort_plan_energy"]
    assert "least input energy" in res.output
    import pandas as pd

    df = pd.read_csv(tmp_path / "out" / "control_steps.csv")
    assert "planned_input_energy_J" in df.columns


def test_fuel_without_heating_value_plans_in_kg_and_says_so(tmp_path, monkeypatch, cli):
    """A `fuel` model without `heating_value` minimises the fuel mass [kg]: the summary line,
    `control_steps.csv`'s columns and `summary.planned_input_energy_unit` say kg (they said J).
    Physical identity: with a heating value H the same plan's input energy is H times its
    fuel mass (walker5's torso thruster given a fuel model, run from another folder)."""
    H = 4.3e7  # [J/kg]
    base = (DATA / "walker5.yaml").read_text()
    old = "limits: [-100, 100]}"
    assert old in base
    for name, extra in (("mass", ""), ("heat", f", heating_value: {H}")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "walker5.yaml").write_text(base.replace(
            old, "limits: [-100, 100], power: {kind: fuel, tsfc: 3.0e-5" + extra + "}}"))
        (tmp_path / name / "w.yaml").write_text((DATA / "walker5_thrust.yaml").read_text())
    monkeypatch.chdir(tmp_path)
    docs, outs = {}, {}
    for name in ("mass", "heat"):
        res = cli("control", f"{name}/walker5.yaml", f"{name}/w.yaml", "--reference", "zeta",
                  "--profile", "0:380", "--knots", "0,0.5,1", "--steps", "3",
                  "--objective", "energy", "--out", f"o_{name}", "--formats", "csv")
        assert res.exit_code == 0, res.output
        outs[name] = " ".join(res.output.split())  # the title may wrap
        docs[name] = json.loads((tmp_path / f"o_{name}" / "control.json").read_text())
    kg, joule = docs["mass"]["summary"], docs["heat"]["summary"]
    assert kg["planned_input_energy_unit"] == "kg"
    assert joule["planned_input_energy_unit"] == "J"
    assert joule["planned_input_energy"] == pytest.approx(H * kg["planned_input_energy"],
                                                          rel=1e-6)
    head = (tmp_path / "o_mass" / "control_steps.csv").read_text().splitlines()[0].split(",")
    assert "planned_input_energy_kg" in head and "effort_plan_input_energy_kg" in head
    assert not any(c.endswith("energy_J") for c in head)
    assert " kg planned" in outs["mass"] and " J planned" not in outs["mass"]
    assert " J planned" in outs["heat"]
