"""Energy along full-order runs (SPEC 15, 7; issue 28): the step energies of ``simulate``
against independent computations: the work-energy identity from the model's D(q) and V(q) at
the step's ends, the impact's kinetic-energy loss from the impact map, the zero-dynamics
orbit's energies (``orbit_energy``: exact quadrature on Z) for a run started on the orbit, the
SciPy method against the compiled one, and missing models said, never zero."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from test_energy import _robot_text

from thrustwalk_cli.energetics.run import simulation_energy
from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
from thrustwalk_cli.simulation.full_order import simulate
from thrustwalk_cli.walker import load_walker

DATA = Path(__file__).resolve().parent / "data"
ROBOT5, GAIT5 = DATA / "walker5.yaml", DATA / "walker5_thrust.yaml"


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return load_walker(str(ROBOT5), str(GAIT5))


def _kinetic(model, q, dq):
    q, dq = np.asarray(q, float), np.asarray(dq, float)
    return 0.5 * dq @ model.D(q) @ dq


def _check_identity_and_impact(res, model):
    """Per step: ``Delta K + Delta V = int (u^T q_b' + q'^T B_F F_T) dt`` with K and V from
    the model at the step's start (the dense solution's first state) and at ``q^-``; the
    impact's ``K^- - K^+ >= 0`` from the impact map."""
    N = model.n
    energies = simulation_energy(res)
    assert [e.step for e in energies] == [st.step for st in res.steps]
    for st, e in zip(res.steps, energies):
        seg = next(s for s in res.segments if s.step == st.step)
        x0 = np.asarray(seg.sol(seg.t0), float)
        qm, dqm = np.array(st.q_minus), np.array(st.dq_minus)
        E0 = _kinetic(model, x0[:N], x0[N:2 * N]) + float(model.V(x0[:N])[0])
        E1 = _kinetic(model, qm, dqm) + float(model.V(qm)[0])
        work = sum(e.joint_work) + sum(e.thrust_work) + e.generalized_work
        scale = sum(e.joint_absolute_work) + sum(map(abs, e.thrust_work)) + abs(E1 - E0)
        assert work == pytest.approx(E1 - E0, abs=1e-8 * scale), st.step
        imp = model.impact(qm, dqm)
        loss = _kinetic(model, qm, dqm) - _kinetic(model, imp.q_plus, imp.dq_plus)
        assert loss >= 0.0
        assert e.impact_loss == pytest.approx(loss, rel=1e-12, abs=1e-12)
        # positive work between net and absolute, a push-free run adds no energy
        for net, pos, ab in zip(e.joint_work, e.joint_positive_work, e.joint_absolute_work):
            assert max(net, 0.0) - 1e-12 <= pos <= ab + 1e-12
        assert e.push_energy == 0.0
        assert e.step_time == pytest.approx(st.step_time, rel=1e-12)


@pytest.mark.parametrize("case", ["three_link", "rabbit_second_order", "walker5",
                                  "walker5_slope", "walker5_scipy"])
def test_work_energy_identity_and_impact_loss(case, walker3, walker_rabbit, walker5):
    w, thrust, cfg, slope = {
        "three_link": (walker3, ThrustModel("ideal", np.array([-5.0, -8.0])), {}, 0.0),
        "rabbit_second_order": (walker_rabbit, ThrustModel(
            "second-order", np.array([-10.0]), wn=3.0, xi=0.7), {}, 0.0),
        "walker5": (walker5, ThrustModel("ideal", np.array([-20.0])), {}, 0.0),
        "walker5_slope": (walker5, ThrustModel("ideal", np.array([-20.0])), {}, 0.04),
        "walker5_scipy": (walker5, ThrustModel("ideal", np.array([-20.0])),
                          {"method": "scipy"}, 0.0),
    }[case]
    zd = w.zd.on_slope(slope) if slope else w.zd
    res = simulate(zd, thrust, SimConfig(steps=3, **cfg))
    assert res.success, res.reason
    _check_identity_and_impact(res, zd.model)


def test_run_on_the_orbit_has_the_orbits_energies(tmp_path, _cache_dir):
    """A run started on the periodic orbit: every step's energies (net, positive and absolute
    joint work, clipped electrical energy with a lossy gearbox, thrust work, the rotor's input
    energy at the axial inflow, step time, distance, impact loss, CoT) equal the orbit's exact
    quadrature on Z (``orbit_energy``) to 1e-6; the compiled and the SciPy method agree per
    step to 1e-7."""
    from thrustwalk_cli.energetics.orbit import orbit_energy
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule

    (tmp_path / "w.yaml").write_text(_robot_text().replace("gearbox_efficiency: 1",
                                                           "gearbox_efficiency: 0.8"))
    w = load_walker(str(tmp_path / "w.yaml"), str(GAIT5))
    zd = w.zd
    F = -20.0
    sched = Schedule.on_thruster(zd, [F], 0, 1)
    (orb,) = orbit_energy(zd, sched, limit_cycles(zd, sched))
    runs = {m: simulate(zd, ThrustModel("ideal", np.array([F])),
                        SimConfig(steps=2, rtol=1e-11, atol=1e-11, method=m))
            for m in ("compiled", "scipy")}
    fields = ("joint_work", "joint_positive_work", "joint_absolute_work", "joint_electrical",
              "thrust_work", "thrust_positive_work", "thruster_input")
    for res in runs.values():
        assert res.success, res.reason
        for e in simulation_energy(res):
            for f in fields:
                got, want = np.array(getattr(e, f), float), np.array(getattr(orb, f), float)
                assert np.allclose(got, want, rtol=1e-6, atol=1e-6 * np.abs(want).max()), f
            assert e.step_time == pytest.approx(orb.step_time, rel=1e-6)
            assert e.distance == pytest.approx(orb.distance, rel=1e-6)
            assert e.impact_loss == pytest.approx(orb.impact_loss, rel=1e-6)
            for k, v in orb.cot().items():
                assert e.cot()[k] == pytest.approx(v, rel=1e-6), k
    a, b = (simulation_energy(runs[m]) for m in ("compiled", "scipy"))
    for ea, eb in zip(a, b):
        for f in fields:
            assert np.allclose(getattr(ea, f), getattr(eb, f), rtol=1e-7, atol=1e-9), f


def test_compiled_and_scipy_agree_with_a_lagging_thruster(walker5):
    """Second-order thrust (the thrust varies along the step): the SciPy method's per-step
    energies equal the compiled kernel's to 1e-7 relative."""
    out = {}
    for m in ("compiled", "scipy"):
        res = simulate(walker5.zd, ThrustModel("second-order", np.array([-20.0]), wn=4.0,
                                               xi=0.8, initial=np.array([-5.0])),
                       SimConfig(steps=2, method=m))
        assert res.success, res.reason
        out[m] = simulation_energy(res)
    for ea, eb in zip(out["compiled"], out["scipy"]):
        for f in ("joint_work", "joint_positive_work", "joint_absolute_work", "thrust_work",
                  "thrust_positive_work"):
            assert np.allclose(getattr(ea, f), getattr(eb, f), rtol=1e-7, atol=1e-7), f
        assert ea.impact_loss == pytest.approx(eb.impact_loss, rel=1e-7)


@pytest.mark.slow
def test_missing_models_are_said_in_json_and_csv(cli, tmp_path, monkeypatch):
    """walker5 has no motor and no power model: the electrical and input energies and the
    total CoT are None (JSON) / empty (CSV) with the reason in the run's ``missing`` list and
    a note of steps.csv (``tables``); the mechanical parts are numbers."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "sim"
    r = cli("simulate", str(ROBOT5), str(GAIT5), "--steps", "2", "--thrust", "-20",
            "--out", str(out), "--formats", "csv,png")  # no PDF: drawn all the same
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "simulation.json").read_text())
    run = doc["runs"][0]["energy"]
    assert any("no motor data" in m for m in run["missing"])
    assert any("no power model for thruster back" in m for m in run["missing"])
    assert run["totals"]["legs_electrical"] is None and run["totals"]["thrust_input"] is None
    assert run["mean_cot"]["total"] is None and run["mean_cot"]["mechanical"] > 0
    for st in doc["steps"]:
        en = st["energy"]
        assert en["per_step"]["joint_electrical"] == [None] * 4
        assert en["per_step"]["thruster_input"] == [None]
        assert en["cot"]["total"] is None and en["cot"]["mechanical"] > 0
    notes = doc["tables"]["steps.csv"]["notes"]
    assert any(ln.startswith("energy: no motor data") for ln in notes)
    rows = list(csv.DictReader((out / "steps.csv").read_text().splitlines()))
    assert rows and all(r["legs_electrical_J"] == "" and r["cot_total"] == "" for r in rows)
    assert all(float(r["cot_mechanical"]) > 0 for r in rows)


def test_a_failed_step_has_no_energy(walker5):
    """A run that falls: energies for the completed steps only."""
    res = simulate(walker5.zd, ThrustModel("ideal", np.array([-20.0])),
                   SimConfig(steps=3, torque_limit=5.0))
    assert not res.success
    assert len(simulation_energy(res)) == len(res.steps)


@pytest.mark.slow
def test_control_steps_carry_their_energy_and_the_push(cli, tmp_path, monkeypatch):
    """control (controlled and uncontrolled runs): every step has its energies; the work-energy
    balance closes with the push's energy at the pushed step only (zero elsewhere), the impact
    loses kinetic energy."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "ctl"
    r = cli("control", "three_link", "three_link_walk", "--reference", "speed", "--profile",
            "0:0.8,4:1.0", "--knots", "0,0.5,1", "--steps", "4", "--push", "3:0.5:-10",
            "--out", str(out), "--formats", "csv,png")  # no PDF: drawn all the same
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "control.json").read_text())
    for st in doc["steps"]:
        en = st["energy"]
        works = sum(map(abs, en["per_step"]["joint_work"])) + sum(
            map(abs, en["per_step"]["thrust_work"]))
        assert abs(en["work_energy_residual"]) <= 1e-7 * works
        assert (en["push_energy"] != 0.0) == st["pushed"]
        assert en["per_step"]["impact_loss"] > 0
    assert doc["summary"]["energy"]["steps"] == len(doc["steps"])
    assert doc["uncontrolled"]["energy"]["steps"] == doc["uncontrolled"]["steps_completed"]
