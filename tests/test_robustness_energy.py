"""Energy of the robustness trials (SPEC 15, 12; issue 28): a trial's energy against an
independent run of the same start, thrust and push (the step-to-step loop of
``controller.loop`` and ``simulate``, its step energies summed here), the missing models said,
and the mean per recovered push against trials.csv."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.controller.loop import Push, run_loop
from thrustwalk_cli.energetics.run import run_energy, simulation_energy
from thrustwalk_cli.resilience.push import push_point
from thrustwalk_cli.resilience.strategy import Strategy, realize
from thrustwalk_cli.resilience.trials import Trial, TrialRunner
from thrustwalk_cli.simulation.closed_loop import SimConfig
from thrustwalk_cli.studies.trial_studies import trial_energy

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    from thrustwalk_cli.walker import load_walker

    return load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))


def _rel(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


def test_a_pushed_trials_energy_is_that_of_the_same_pushed_run(walker5):
    """none strategy, pushed at s = 0.5: the uncontrolled step-to-step loop (zero thrust,
    the same start and push) with its per-step energies summed here."""
    real = realize(walker5.zd, Strategy("none"), mu=0.7)
    point = push_point(walker5.model, None, 1.0, (1.0, 0.0))
    runner = TrialRunner(walker5.zd, real, point, steps=4)
    res = runner.run(Trial(-2.0, 0.5))
    energy = trial_energy(res)
    assert res.outcome == "recovered" and energy["energy_steps"] == 4
    run = run_loop(walker5.zd, None, label="x", steps=4, x0=real.zeta_ref, refs=None,
                   knots=np.array([walker5.zd.alpha_i, walker5.zd.alpha_f]), driven=[0],
                   dynamics=None, pushes=(Push(1, 0.5, point.impulse(-2.0)),),
                   config=SimConfig(steps=1))
    es = [run_energy(s.energy_input[0], [s.energy_input[1]])[0] for s in run.steps]
    assert len(es) == 4
    legs = sum(sum(e.joint_positive_work) for e in es)
    push = sum(e.push_energy for e in es)
    assert push > 0.0  # the push did work on the walker
    assert _rel(energy["energy_legs_mechanical"], legs) < 1e-9
    assert _rel(energy["push_energy"], push) < 1e-9
    assert energy["energy_thrust_mechanical"] == 0.0


def test_an_unpushed_constant_thrust_trial_is_simulate_and_missing_models_are_none(walker5):
    """constant -20 N, no push: ``tw.simulate`` from the same zeta^- with the same thrust,
    its step energies summed; walker5 has no motor and no power model: None with why."""
    import thrustwalk_cli as tw

    real = realize(walker5.zd, Strategy("constant", thrust=-20.0), mu=0.7)
    point = push_point(walker5.model, None, 1.0, (1.0, 0.0))
    res = TrialRunner(walker5.zd, real, point, steps=3).run(Trial(0.0, 0.5))
    energy = trial_energy(res)
    assert res.outcome == "recovered"
    sim = tw.simulate(walker5, steps=3, thrust=[-20.0], thrust_model="ideal",
                      zeta0=real.zeta_ref)
    es = simulation_energy(sim.outcomes[0].full)
    legs = sum(sum(e.joint_positive_work) for e in es)
    thrust = sum(sum(e.thrust_positive_work) for e in es)
    assert _rel(energy["energy_legs_mechanical"], legs) < 1e-9
    assert _rel(energy["energy_thrust_mechanical"], thrust) < 1e-9
    assert _rel(energy["energy_mechanical"], legs + thrust) < 1e-9
    for key in ("energy_legs_electrical", "energy_thrust_input", "energy_total"):
        assert energy[key] is None
    why = energy["energy_reason"]
    assert "no motor data" in why and "no power model for thruster back" in why


@pytest.mark.slow
def test_the_mean_per_recovered_push_is_that_of_trials_csv(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    cli("robustness", str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"),
        "--push-impulse=-4:4:2", "--push-phase", "0.3:0.6:0.3", "--strategy",
        "none,constant:-20", "--steps", "3", "--basin-grid", "0", "--workers", "1",
        "--formats", "csv,png", "-o", str(out))  # (the PDFs: test_robustness)
    doc = json.loads((out / "robustness.json").read_text())
    with open(out / "trials.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert (out / "push_energy.png").exists()
    for s in doc["strategies"]:
        e = s["push"]["energy"]
        mine = [r for r in rows if r["strategy"] == s["label"] and r["kind"] == "push"
                and r["recovered"] == "true"]
        assert e["recovered_pushes"] == len(mine) > 0
        want = np.mean([float(r["energy_mechanical_J"]) for r in mine])
        assert _rel(e["mean_per_recovered_push"]["energy_mechanical"], want) < 1e-12
        assert e["mean_per_recovered_push"]["energy_total"] is None
        assert "no motor data" in e["reason"]
        zero = [float(r["energy_mechanical_J"]) for r in mine if float(r["push_impulse_Ns"]) == 0]
        assert _rel(e["extra_over_unpushed"]["energy_mechanical"] + zero[0], want) < 1e-12


def test_a_controlled_trials_steps_carry_the_thrust_the_controller_set(walker5):
    """control strategy: each step's energy is integrated with the thrust the controller set
    for it, so the work-energy identity (SPEC 15) holds step by step (a step with thrust work
    included), and the trial's thrust work is their sum."""
    from thrustwalk_cli.energetics.run import run_energy

    real = realize(walker5.zd, Strategy("control"), mu=0.7)
    point = push_point(walker5.model, None, 1.0, (1.0, 0.0))
    res = TrialRunner(walker5.zd, real, point, steps=4).run(Trial(-2.0, 0.5))
    es = [run_energy(cl, [step], seg_force=[force])[0] for cl, force, step in res.energy_input]
    assert len(es) == 4
    assert max(abs(sum(e.thrust_work)) for e in es) > 1e-3  # the controller did thrust
    for e in es:
        assert abs(e.identity_residual) < 1e-8 * (e.kinetic_start + abs(e.potential_start))
    thrust = sum(sum(e.thrust_positive_work) for e in es)
    assert _rel(trial_energy(res)["energy_thrust_mechanical"], thrust) < 1e-12


def test_a_thruster_with_a_power_model_gives_its_input_energy(_cache_dir):
    """kneed4's thruster has a momentum power model, its joints no motor: the trial's
    thruster input energy is simulate's summed; the joints' electrical energy None, why said."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.walker import load_walker

    w = load_walker(str(DATA / "kneed4.yaml"), str(DATA / "kneed4_walk.yaml"))
    real = realize(w.zd, Strategy("constant", thrust=-5.0), mu=0.7)
    res = TrialRunner(w.zd, real, push_point(w.model, None, 1.0, (1.0, 0.0)),
                      steps=3).run(Trial(0.0, 0.5))
    energy = trial_energy(res)
    sim = tw.simulate(w, steps=3, thrust=[-5.0], thrust_model="ideal", zeta0=real.zeta_ref)
    es = simulation_energy(sim.outcomes[0].full)
    assert energy["energy_thrust_input"] > 0.0
    assert _rel(energy["energy_thrust_input"], sum(e.thrust_input for e in es)) < 1e-9
    assert energy["energy_legs_electrical"] is None and energy["energy_total"] is None
    assert "no motor data" in energy["energy_reason"]
    assert "power model" not in energy["energy_reason"]


def _per_trial(runner, res) -> dict:
    """A trial's energies the slow way, independent of the batching: each step alone
    (``run_energy`` with one step) on the closed loop of the thrust it walked, a controlled
    step's built from the controller's values per knot interval (as ``controller.loop``
    builds it), summed here per trial."""
    from thrustwalk_cli.simulation.closed_loop import ClosedLoop, ThrustModel
    from thrustwalk_cli.thrust.schedule import Schedule

    es = []
    for cl, force, step in res.energy_input:
        if force is not None:
            knots = np.asarray(runner.r.knots, float)
            per = np.zeros((1, len(knots) - 1, cl.m))
            for seg, interval in enumerate(runner.seg_int):
                per[0, interval] = force[seg]
            th = ThrustModel("piecewise", np.zeros(cl.m),
                             schedule=Schedule(knots, per, np.zeros((1, len(knots) - 1))))
            cl = ClosedLoop(runner.zd, th, cl.config)
        es.append(run_energy(cl, [step])[0])

    def total(get):
        vals = [get(e) for e in es]
        return None if not es or any(v is None for v in vals) else sum(vals)

    return {"energy_steps": len(es),
            "energy_legs_mechanical": total(lambda e: sum(e.joint_positive_work)),
            "energy_legs_electrical": total(lambda e: e.legs_electrical),
            "energy_thrust_mechanical": total(lambda e: sum(e.thrust_positive_work)),
            "energy_thrust_input": total(lambda e: e.thrust_input),
            "push_energy": total(lambda e: e.push_energy)}


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["walker5", "walker3"])
def test_batched_energies_equal_the_per_trial_path(robot, request):
    """The energies of an engine task's trials computed together (``trial_energies``: the
    steps of every trial of one closed loop in one ``run_energy`` call, a controlled step's
    thrust as data) equal each trial's computed alone, step by step on the closed loop of the
    thrust it walked (relative 1e-12); walker5 (no motor, no power model: None) and the
    bundled 3-link walker (motors: the electrical energy)."""
    from thrustwalk_cli.studies.trial_studies import trial_energies

    w = request.getfixturevalue(robot)
    point = push_point(w.model, None, 1.0, (1.0, 0.0))
    big = 2.0
    results, runners = [], []
    for strategy in (Strategy("none"), Strategy("constant", thrust=-20.0 if robot == "walker5"
                                                else -10.0), Strategy("control")):
        runner = TrialRunner(w.zd, realize(w.zd, strategy, mu=0.7), point, steps=3)
        for impulse in (-big, 0.0, big):
            results.append(runner.run(Trial(impulse, 0.4)))
            runners.append(runner)
    batched = trial_energies(results)
    controlled = [r for r, run in zip(results, runners) if run.seg_int is not None]
    assert sum(len(r.energy_input) for r in controlled) >= 6  # several trials batched
    assert any(r.energy_input[0][1] is not None for r in controlled)
    for run, res, got in zip(runners, results, batched):
        want = _per_trial(run, res)
        for key, value in want.items():
            if value is None:
                assert got[key] is None, key
            else:
                assert _rel(got[key], value) < 1e-12 or abs(got[key] - value) < 1e-12, key
        if want["energy_steps"]:
            lm, tm = want["energy_legs_mechanical"], want["energy_thrust_mechanical"]
            assert _rel(got["energy_mechanical"], lm + tm) < 1e-12
    electrical = [g["energy_legs_electrical"] for g in batched if g["energy_steps"]]
    assert electrical and all((v is None) == (robot == "walker5") for v in electrical)
