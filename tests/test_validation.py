"""Bad input that is refused up front (issue 30, items 5-8), table-driven.

* The Python API: every public study called with a wrong type, NaN, inf, a huge value, a
  negative or zero count for each of its parameters raises ``tw.InputError`` naming that
  parameter (never TypeError, ValueError, OverflowError or KeyError), before any work.
* The command line: every numeric option of every command with nan, inf, +-1e308, a 5e-324
  range step, negative and zero counts ends with exit 2, one line naming the option, and
  nothing at ``--out`` (the corpus runner of tests/test_bad_inputs.py).
* Sweep files: values only a running point used to catch (steps 0, start_sigma -1, a bad
  ``settings.schedule``) are refused before the first task, at the sweep file's line.

The expected parameter and option names are written here by hand, from the promise.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from test_bad_inputs import Case, check_case

import thrustwalk_cli as tw

DATA = Path(__file__).parent / "data"
NAN, INF = math.nan, math.inf

# -- bad values by kind of parameter -----------------------------------------------------------
NUMBER = ["1.0", [0.0], NAN, INF, -INF, 1e308, -1e308, True]
POSITIVE = NUMBER + [0.0, -1.0]
NONNEG = NUMBER + [-1.0]
COUNT = ["3", 2.5, NAN, INF, -1, 10**30, True]
POS_COUNT = COUNT + [0]
NUMBERS = ["0,1", 5.0, [NAN], [INF], [1e308], ["a"], {"a": 1.0}]
TEXT = [5, [""], ""]
CHOICE = [5, "bogus"]
FLAG = ["yes", 2, None]
CALLBACK = [5, "print"]
WALKER = ["walker5", 5, None]


def _cases(table: dict[str, list]) -> list[tuple[str, object]]:
    return [(name, v) for name, values in table.items() for v in values]


# study -> (call(walker, model, sweep, **kwargs), {parameter: bad values}, base kwargs, and
# the parameter each problem must name when it differs from the keyword)
STUDIES = {
    "limit_cycle": (lambda w, **kw: tw.limit_cycle(**{"walker": w, **kw}), {
        "walker": WALKER, "thrust": NUMBERS, "thruster": TEXT, "max_output": POSITIVE,
        "mu": POSITIVE, "min_vertical_force": NONNEG, "slope": NUMBER + [1.6, -2.0]}, {}),
    "shape": (lambda w, **kw: tw.shape(**{"walker": w, **kw}), {
        "walker": WALKER, "knots": NUMBERS, "alpha_knots": FLAG,
        "n_knots": POS_COUNT + [1, 10**6], "pattern": [5, ["k"]], "k": NUMBERS,
        "field_k": NUMBER, "mode": CHOICE, "thruster": TEXT, "target_zeta": NUMBER,
        "target_speed": NUMBER, "progress": CALLBACK, "max_output": POSITIVE, "bogus": [1.0],
        "slope": NUMBER + [1.6, -2.0]},
        {}),
    "feasibility": (lambda w, **kw: tw.feasibility(**{"walker": w, **kw}), {
        "walker": WALKER, "thrust": NUMBERS, "schedule": [5, [1.0]], "thruster": TEXT,
        "mu": POSITIVE, "min_vertical_force": NONNEG, "degree": POS_COUNT + [31],
        "fit_tol": POSITIVE + [1.0, 2.0],
        "region_shape": ["11", (11,), (0, 11), (NAN, 11), (2.5, 11), (11, 10**9)],
        "slope": NUMBER + [math.pi / 2]}, {}),
    "slope_map": (lambda w, **kw: tw.slope_map(**{"walker": w, **kw}), {
        "walker": WALKER, "slopes": NUMBERS + [[0.0, 1.6], []], "thrust": NUMBERS + [[500.0]],
        "thruster": TEXT, "mu": POSITIVE, "min_vertical_force": NONNEG}, {}),
    "optimize_schedule": (lambda w, **kw: tw.optimize_schedule(**{"walker": w, **kw}), {
        "walker": WALKER, "knots": NUMBERS, "target_speed": POSITIVE, "max_thrust":
        NUMBER + [-1.0, 1e6], "mu": POSITIVE, "min_vertical_force": NONNEG,
        "zeta_min": POSITIVE, "thruster": TEXT, "mode": CHOICE, "weights": CHOICE,
        "slope": NUMBER + [1.6, -2.0]},
        {"target_speed": 0.6}),
    "simulate": (lambda w, **kw: tw.simulate(**{"walker": w, **kw}), {
        "walker": WALKER, "steps": POS_COUNT, "thrust_model": CHOICE, "thrust": NUMBERS,
        "wn": POSITIVE + [1e6], "xi": POSITIVE, "tau": POSITIVE, "f0": NUMBER,
        "thruster": [5, "", [5], ["back", ""]], "perturb": NUMBER + [-1.0], "zeta0": POSITIVE,
        "q0": NUMBERS, "dq0": NUMBERS, "start": CHOICE, "torque_limit": POSITIVE,
        "rtol": POSITIVE + [0.5], "atol": POSITIVE, "method": CHOICE, "integrator": TEXT,
        "samples": POS_COUNT + [1], "scuff_tol": NONNEG, "min_impact_s": NUMBER,
        "impact_s_tol": POSITIVE, "zeta_tol": POSITIVE, "reduced": FLAG, "mu": POSITIVE,
        "progress": CALLBACK, "config": [5, "steps=2"]}, {"steps": 2, "thrust": [-10.0]}),
    "control": (lambda w, **kw: tw.control(**{"walker": w, **kw}), {
        "walker": WALKER, "reference": CHOICE,
        "profile": ["0:0.8", 5, [(0, NAN)], [(0,)], [("a", 1)]], "ramp": FLAG,
        "knots": NUMBERS, "steps": POS_COUNT, "thrust_model": CHOICE, "wn": POSITIVE,
        "xi": POSITIVE, "tau": POSITIVE, "thruster": [5, "", [5], ["back", ""]],
        "push": ["2:0.5:10", 5, [(NAN, 0.5, 10)], [(2, 0.5, NAN)], [(2, 0.5, 1e300)],
                 [(2, 0.5, 1e6)], [(2.5, 0.5, 1)], [(2, 0.5)], [(2, "a", 1)]],
        "plant_scale": ["MT=1.1", {"MT": NAN}, {"MT": -1.0}, {"MT": "x"}, {5: 1.0}],
        "noise": NUMBER + [-1.0], "seed": COUNT, "mu": POSITIVE,
        "min_vertical_force": NONNEG, "zeta_min": POSITIVE, "max_thrust": POSITIVE + [1e6],
        "rate_limit": POSITIVE, "tracking_weight": POSITIVE, "effort_weight": NUMBER,
        "rate_weight": NUMBER, "terms": CHOICE, "fit_tol": POSITIVE + [1.0],
        "points": POS_COUNT + [20], "zeta0": POSITIVE, "compare": FLAG,
        "progress": CALLBACK, "config": [5, "steps=2"], "start": [5, "nominal"]},
        {"reference": "nominal", "steps": 3}),
    "stability": (lambda w, **kw: tw.stability(**{"walker": w, **kw}), {
        "walker": WALKER, "thrust_model": CHOICE, "thrust": NUMBER, "thruster": TEXT,
        "wn": POSITIVE + [1e6], "xi": POSITIVE, "tau": POSITIVE, "kp": POSITIVE,
        "kd": POSITIVE, "vary": ["wn=1:2", ("wn",), ("wn", [NAN]), ("wn", "1,2"),
                                 ("wn", [1.0, 1e300]), ("wn", [1.0, 1e6]), (5, [1.0])],
        "rtol": POSITIVE, "atol": POSITIVE, "agreement_tol": POSITIVE,
        "progress": CALLBACK}, {"thrust_model": "second-order"}),
    "robustness": (lambda w, **kw: tw.robustness(**{"walker": w, **kw}), {
        "walker": WALKER, "workers": POS_COUNT + [10**6],
        "scheduler": [5, "x", "tcp://127.0.0.1:99999", "tcp://127.0.0.1"],
        "progress": CALLBACK, "push_impulse": NUMBERS + [[1e6]], "push_phase": NUMBERS,
        "strategy": ["none", 5, [5]], "steps": POS_COUNT, "push_direction": NUMBERS + [[1.0]],
        "push_link": TEXT, "push_at": NUMBER, "push_duration": NUMBER,
        "recovery_tol": NUMBER, "output_tol": NUMBER, "mu": NUMBER,
        "min_vertical_force": NUMBER, "thruster": TEXT, "knots": NUMBERS,
        "max_thrust": POSITIVE + [1e6], "basin_grid": COUNT + [1000], "basin_sigma":
        NUMBERS + [[0.0]], "basin_rate": NUMBER, "basin_joint": TEXT, "uncertainty": [5],
        "samples": POS_COUNT, "rtol": NUMBER, "atol": NUMBER, "bogus": [1.0],
        "slope": NUMBER + [1.6, -2.0]},
        {"push_impulse": [1.0], "push_phase": [0.5], "strategy": ["none"], "basin_grid": 0}),
    "rough_ground": (lambda w, **kw: tw.rough_ground(**{"walker": w, **kw}), {
        "walker": WALKER, "workers": POS_COUNT + [10**6], "scheduler": [5, "x"],
        "progress": CALLBACK, "sigma": NUMBERS + [[-0.001], [2.0]],
        "strategy": ["none", 5, [5], ["fly"]], "trials": POS_COUNT, "cap": POS_COUNT,
        "seed": COUNT, "distribution": CHOICE, "mesh": POS_COUNT + [5, 2], "terrain_samples":
        POS_COUNT + [7], "s_max": POSITIVE + [1.0, 5.0], "mu": POSITIVE,
        "min_vertical_force": NONNEG, "thruster": TEXT, "knots": NUMBERS,
        "max_thrust": POSITIVE + [1e6], "target": NUMBER + [0.5], "rtol": NUMBER,
        "atol": NUMBER, "bogus": [1.0]},
        {"sigma": [0.004], "strategy": ["none"], "trials": 1, "cap": 5, "mesh": 4,
         "terrain_samples": 4}),
    "design_gait": (lambda w, model, **kw: tw.design_gait(**{"robot_or_walker": model, **kw}), {
        "robot_or_walker": ["walker5", 5], "spec": ["x", {"speed": 0.6}], "compare": ["x", 5],
        "progress": CALLBACK, "initial": [5], "slope": NUMBER + [1.6]}, {"spec": "SPEC"}),
    "DesignSpec": (lambda w, model, **kw: tw.design_gait(model, tw.DesignSpec(**kw)), {
        "speed": POSITIVE, "step_length": POSITIVE, "mu": POSITIVE, "order": POS_COUNT,
        "clearance": NONNEG, "max_delta_sq": POSITIVE, "min_vertical_force": NONNEG,
        "min_liftoff": NUMBER, "min_touchdown_velocity": NONNEG, "min_zeta_ratio": NUMBER,
        "objective": CHOICE, "thrust_design": FLAG, "thrust_weight": NONNEG,
        "thrust_range": ["back:0:1", ("back", NAN, 1.0), (5, 0.0, 1.0), ("back", 0.0)],
        "thrust": NUMBERS, "alpha_c": NUMBERS, "starts": POS_COUNT, "seed": COUNT,
        "max_iter": POS_COUNT, "nodes": POS_COUNT, "name": TEXT}, {"speed": 0.6}),
    "inspect_state": (lambda w, model, **kw: tw.inspect_state(
        **{"robot_or_walker": model, **kw}), {
        "robot_or_walker": ["walker5", 5, None], "q": ["a,b", 5, [NAN, 0, 0, 0, 0], [1.0]],
        "dq": ["a", 5, [INF, 0, 0, 0, 0]], "thrust": ["x", 5, [NAN]]},
        {"q": [0.1, 0.2, 0.3, -0.2, 0.1]}),
    "load_walker": (lambda w, **kw: tw.load_walker(**kw), {
        "robot": [5, [""], ""], "gait": [5, [""]],
        "robot_parameters": ["MT=1", {"MT": NAN}, {"MT": "x"}, {5: 1.0}],
        "gait_parameters": ["a=1", {"a": INF}]}, {}),
    "load_robot": (lambda w, **kw: tw.load_robot(**kw), {
        "ref": [5, None, ""], "parameters": ["MT=1", {"MT": NAN}],
        "scale": [{"MT": 0.0}, {"MT": NAN}, "MT=2"]}, {"ref": str(DATA / "walker5.yaml")}),
    "load_model": (lambda w, **kw: tw.load_model(**kw), {
        "robot": ["walker5", 5], "rebuild": ["yes", 1]}, {"robot": "ROBOT"}),
    "compile_robot": (lambda w, **kw: tw.compile_robot(**kw), {
        "robot": [5, None, ""], "rebuild": ["yes", 1]}, {"robot": str(DATA / "walker5.yaml")}),
    "thruster_dynamics": (lambda w, **kw: tw.thruster_dynamics(**kw), {
        "kind": CHOICE, "m": COUNT + [10**6], "tau": POSITIVE + [1e300], "bogus": [1.0]},
        {"kind": "first-order", "m": 1, "tau": 0.5}),
    "zd_limit_cycles": (lambda w, **kw: tw.zd_limit_cycles(**kw), {
        "zd": ["walker5", 5], "schedule": ["x", "NAN_SCHEDULE"],
        "samples": POS_COUNT + [2]}, {"zd": "ZD", "schedule": "SCHEDULE"}),
    "load_sweep": (lambda w, **kw: tw.load_sweep(**kw), {"path": [5, None, ""]}, {}),
    "run_sweep": (lambda w, sweep, **kw: tw.run_sweep(**{"sweep": sweep, **kw}), {
        "sweep": [5, "sweep.yaml"], "workers": POS_COUNT,
        "scheduler": [5, "tcp://127.0.0.1:99999"], "finished": [5, ["a"]],
        "on_point": CALLBACK, "library": [5], "chunk": POS_COUNT}, {}),
    "mujoco_run": (lambda w, **kw: tw.mujoco_run(**{"walker": w, **kw}), {
        "walker": WALKER, "steps": POS_COUNT + [10**6], "thrust_model": [5, "bogus"],
        "thrust": NUMBERS, "wn": POSITIVE, "xi": POSITIVE, "tau": POSITIVE, "f0": NUMBER,
        "thruster": [5, "", [5], ["back", ""]], "push": ["2:0.5:10", 5, [(NAN, 0.5, 10)],
                                            [(2, 0.5, 1e6)], [(2.5, 0.5, 1)], [(9, 0.5, 1)]],
        "mu": POSITIVE + [11.0], "contact": [5, "rubber"], "perturb": NUMBER + [-1.0],
        "min_impact_s": NUMBER, "zeta_tol": POSITIVE, "slip_tol": POSITIVE,
        "samples": POS_COUNT + [1], "fps": NUMBER + [-1.0, 61.0], "progress": CALLBACK},
        {"steps": 2}),
    "import_urdf": (lambda w, **kw: tw.import_urdf(**kw), {
        "urdf": [5, None, "", str(DATA / "missing.urdf")], "stance_foot": [5, "left_foot"],
        "swing_foot": [5, "right_foot:a,b,c"], "plane": [5, "bogus"], "thrusters": [5, [5]],
        "side": [5], "unactuated": [5], "name": [5], "out": [5, None]},
        {"urdf": str(DATA / "urdf" / "rabbit.urdf"), "stance_foot": "left_foot:0,0,0",
         "swing_foot": "right_foot:0,0,0", "side": str(DATA / "urdf" / "rabbit_side.yaml"),
         "out": "OUT"}),
    "robot_to_urdf": (lambda w, **kw: tw.robot_to_urdf(**kw), {"robot": ["walker5", 5, None]},
                      {"robot": "ROBOT"}),
    "energy": (lambda w, **kw: tw.energy(**{"walker": w, **kw}), {
        "walker": WALKER, "thrust": NUMBERS + [[0.0, 500.0]], "thruster": TEXT,
        "slope": NUMBER + [1.6, -2.0],
        "library": [5, "", str(DATA / "no_such_library"), str(DATA)]}, {}),
    "robot_to_mjcf": (lambda w, **kw: tw.robot_to_mjcf(**kw), {
        "robot": ["walker5", 5, None], "mu": POSITIVE + [11.0], "contact": [5, "soft"],
        "keyframe": [5, "x", ([NAN] * 5, [0.0] * 5), ([0.0] * 2, [0.0] * 5)],
        "notes": [5, [5]]}, {"robot": "ROBOT"}),
}
# the parameter a problem names when it is not the keyword's own name
NAMED = {("DesignSpec", "speed"): "speed", ("robustness", "bogus"): "bogus",
         ("thruster_dynamics", "kind"): "thrust_model"}

CASES = [(study, name, value) for study, (_, table, _) in STUDIES.items()
         for name, value in _cases(table)]


def test_every_public_study_is_in_the_table():
    """The studies of the package's docstring (its "Studies", "Loading" and "Sweeps" lists)."""
    functions = {n for n in tw.__all__ if n[0].islower() and n != "limit_cycle_result"}
    assert functions - {"__version__"} <= set(STUDIES), functions - set(STUDIES)


@pytest.fixture(scope="module")
def api(_cache_dir):
    """The walker, its model, a loaded sweep and the stand-ins of the table's base values."""
    import numpy as np

    walker = tw.load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))
    folder = Path(_cache_dir).parent / "api-sweep"
    folder.mkdir(exist_ok=True)
    sweep_file = _with_walker5(folder) / "api-sweep.yaml"
    sweep_file.write_text(_sweep("limit-cycle", "grid:\n  thrust: {values: [0, -10]}\n"
                                                "collect: [speed]\n"))
    zd = walker.zd
    good = tw.Schedule.constant(zd, np.zeros((1, walker.model.n_thrusters)))
    stand_in = {"SPEC": tw.DesignSpec(speed=0.6), "ROBOT": walker.robot, "ZD": zd,
                "SCHEDULE": good, "walker5": "walker5",
                "NAN_SCHEDULE": tw.Schedule.constant(zd, np.full((1, 1), np.nan)),
                "OUT": str(folder / "imported.yaml")}
    return walker, walker.model, tw.load_sweep(sweep_file), stand_in


def _outcome(api, study: str, name: str, value) -> str | None:
    """None when ``study`` called with ``name=value`` raises InputError naming ``name``, else
    what happened instead."""
    walker, model, sweep, stand_in = api
    call, _, base = STUDIES[study]
    kwargs = {k: stand_in.get(v, v) if isinstance(v, str) else v for k, v in base.items()}
    kwargs[name] = stand_in.get(value, value) if isinstance(value, str) else value
    extra = {"design_gait": {"model": model}, "DesignSpec": {"model": model},
             "inspect_state": {"model": model}, "run_sweep": {"sweep": sweep}}.get(study, {})
    if study == "run_sweep" and name == "sweep":
        extra = {"sweep": kwargs.pop("sweep")}
    if study in ("design_gait", "inspect_state") and name == "robot_or_walker":
        extra = {"model": kwargs.pop(name)}
    try:
        call(walker, **extra, **kwargs)
    except tw.InputError as exc:
        named = {p for pr in exc.problems for p in pr.params}
        if NAMED.get((study, name), name) in named:
            return None
        return f"InputError naming {sorted(named) or 'nothing'}: {exc}"
    except Exception as exc:  # noqa: BLE001 - the finding
        return f"{type(exc).__name__}: {exc}"
    return "no error"


@pytest.mark.parametrize("study", sorted(STUDIES))
def test_a_bad_argument_is_an_input_error_naming_it(api, study):
    """Every bad value of every parameter of ``study`` (one test per study: each call is
    refused in about a millisecond, before any work)."""
    found = [f"{name}={value!r:.40}: {what}" for s, name, value in CASES if s == study
             if (what := _outcome(api, study, name, value)) is not None]
    assert not found, f"{study}:\n" + "\n".join(found)


def _sweep(study: str, body: str) -> str:
    """A sweep file over the test robot, whose robot and gait files lie beside it
    (:func:`_with_walker5`: a sweep file reads no file outside its folder)."""
    gait = "" if study == "design-gait" else "gait: walker5_thrust.yaml\n"
    return f"name: s\nstudy: {study}\nrobot: walker5.yaml\n{gait}{body}"


def _with_walker5(folder: Path) -> Path:
    """``folder`` with copies of the test robot and its thrust gait (for a sweep file there)."""
    for name in ("walker5.yaml", "walker5_thrust.yaml"):
        (folder / name).write_bytes((DATA / name).read_bytes())
    return folder


# -- the command line -------------------------------------------------------------------------
W5, W5T = str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml")
CLI: dict[str, Case] = {}


def cli_case(name: str, argv, option: str, message: str = "", **kw) -> None:
    assert name not in CLI, name
    CLI[name] = Case(tuple(argv), "error: options? [-/a-z]*" + re.escape(option)
                     + "[-/a-z]*: " + message, **kw)


# every command's numeric options (typer's FLOAT and INT options and the options that hold
# numbers as text), with the arguments that make the rest of the command line valid
COMMANDS = {
    "limit-cycle": [W5, W5T], "shape": [W5, W5T], "feasibility": [W5, W5T],
    "optimize": [W5, W5T, "--target-speed", "0.6"], "simulate": [W5, W5T, "--steps", "2"],
    "control": [W5, W5T, "--reference", "nominal", "--steps", "3"],
    "stability": [W5, W5T, "--thrust-model", "second-order"],
    "robustness": [W5, W5T, "--push-impulse", "1", "--push-phase", "0.5", "--basin-grid",
                   "0", "--strategy", "none"],
    "design-gait": [W5, "--target-speed", "0.6"],
}
FLOATS = {
    "limit-cycle": ["--max-output", "--mu", "--min-vertical-force"],
    "feasibility": ["--mu", "--min-vertical-force", "--fit-tol"],
    "optimize": ["--target-speed", "--target-zeta", "--max-thrust", "--mu",
                 "--min-vertical-force", "--zeta-min"],
    "simulate": ["--wn", "--xi", "--tau", "--f0", "--perturb", "--zeta0", "--torque-limit",
                 "--mu", "--rtol", "--atol", "--scuff-tol", "--min-impact-s",
                 "--impact-s-tol", "--zeta-tol"],
    "control": ["--wn", "--xi", "--tau", "--noise", "--mu", "--min-vertical-force",
                "--zeta-min", "--max-thrust", "--rate-limit", "--tracking-weight",
                "--effort-weight", "--rate-weight", "--fit-tol"],
    "stability": ["--wn", "--xi", "--tau", "--kp", "--kd", "--rtol", "--atol",
                  "--agreement-tol"],
    "robustness": ["--push-at", "--push-duration", "--recovery-tol", "--output-tol", "--mu",
                   "--min-vertical-force", "--max-thrust", "--basin-rate", "--rtol",
                   "--atol"],
    "design-gait": ["--target-speed", "--step-length", "--mu", "--clearance",
                    "--max-delta-sq", "--thrust-weight", "--min-vertical-force",
                    "--min-touchdown-velocity"],
}
# (option, bad values): counts that are never negative and, but for seeds and the basin grid,
# never zero
INTS = {
    "shape": [("--n-knots", ("0", "-1"))], "feasibility": [("--degree", ("0", "-1"))],
    "simulate": [("--steps", ("0", "-1")), ("--samples", ("0", "-1"))],
    "control": [("--steps", ("0", "-1")), ("--seed", ("-1",)), ("--points", ("0", "-1"))],
    "robustness": [("--steps", ("0", "-1")), ("--basin-grid", ("-1",)),
                   ("--samples", ("0", "-1")), ("--workers", ("0", "-1"))],
    "design-gait": [("--order", ("0", "-1")), ("--starts", ("0", "-1")), ("--seed", ("-1",)),
                    ("--max-iter", ("0", "-1"))],
}
# options holding numbers as text: (option, a template with X for the bad number)
TEXTS = {
    "limit-cycle": [("--thrust", "X"), ("--thrust", "0,X")],
    "feasibility": [("--thrust", "X")],
    "shape": [("--k", "0,X"), ("--knots", "0,X,1"), ("--field-k", "X"),
              ("--target-zeta", "X"), ("--target-speed", "X")],
    "optimize": [("--knots", "0,X,1")],
    "simulate": [("--thrust", "X"), ("--q0", "X,0,0,0,0")],
    "control": [("--knots", "0,X,1"), ("--push", "2:0.5:X"), ("--push", "X:0.5:1"),
                ("--push", "2:X:1"), ("--plant-scale", "MT=X"), ("--profile", "0:X")],
    "stability": [("--thrust", "X"), ("--vary", "wn=1,X"), ("--vary", "wn=1:X:log3")],
    "robustness": [("--push-impulse", "X"), ("--push-phase", "X"), ("--knots", "0,X,1"),
                   ("--basin-sigma", "0:X"), ("--push-direction", "1,X")],
    "design-gait": [("--alpha", "X,0,0,0,1"), ("--thrust-range", "back:0:X")],
}
# each option once, the bad values taking turns (one check serves every float option)
_BAD = ("nan", "inf", "-1e308", "1e308", "-inf")
_turn = 0
for _cmd, _opts in FLOATS.items():
    for _opt in _opts:
        _v, _turn = _BAD[_turn % len(_BAD)], _turn + 1
        cli_case(f"{_cmd}{_opt}={_v}", [_cmd, *COMMANDS[_cmd], _opt, _v, "--out", "{out}"],
                 _opt)
for _cmd, _opts in INTS.items():
    for _opt, _values in _opts:
        for _v in (*_values, str(10**30)):
            cli_case(f"{_cmd}{_opt}={_v}", [_cmd, *COMMANDS[_cmd], _opt, _v, "--out", "{out}"],
                     _opt)
for _cmd, _opts in TEXTS.items():
    for _opt, _tmpl in _opts:
        _v, _turn = _BAD[_turn % len(_BAD)], _turn + 1
        cli_case(f"{_cmd}{_opt}={_tmpl.replace('X', _v)}",
                 [_cmd, *COMMANDS[_cmd], _opt, _tmpl.replace("X", _v), "--out", "{out}"], _opt)
# ranges: a step of 5e-324 (the count overflows), huge counts, a step against the direction
for _cmd, _opt, _ranges in (
        ("limit-cycle", "--thrust", ("0:1:5e-324", "1e8:1e9:1e-3", "0:-1:1")),
        ("robustness", "--push-impulse", ("0:1e9:1e-300", "0:1:5e-324")),
        ("robustness", "--push-phase", ("0:1:5e-324",)), ("simulate", "--thrust", ("0:1:5e-324",)),
        ("stability", "--vary", ("0:1:5e-324", "1e8:1e9:1e-3"))):
    for _r in _ranges:
        _arg = ("wn=" if _opt == "--vary" else "") + _r
        cli_case(f"range-{_cmd}{_opt}={_arg}", [_cmd, *COMMANDS[_cmd], _opt, _arg, "--out",
                                                 "{out}"], _opt)
# physically absurd magnitudes, bounded with a stated limit (item 7)
cli_case("control-push-1e300", ["control", *COMMANDS["control"], "--push", "2:0.5:1e300",
                                "--out", "{out}"], "--push")
cli_case("control-push-huge", ["control", *COMMANDS["control"], "--push", "2:0.5:1e5",
                               "--out", "{out}"], "--push", r".*at most \d+ N s")
cli_case("control-max-thrust", ["control", *COMMANDS["control"], "--max-thrust", "1e6",
                                "--out", "{out}"], "--max-thrust",
         r"1e\+06 N is more than thruster back can give \(100 N")
cli_case("optimize-max-thrust", ["optimize", *COMMANDS["optimize"], "--max-thrust", "1e6",
                                 "--out", "{out}"], "--max-thrust",
         r"1e\+06 N is more than thruster back")
cli_case("robustness-max-thrust", ["robustness", *COMMANDS["robustness"], "--max-thrust",
                                   "1e6", "--out", "{out}"], "--max-thrust",
         r"1e\+06 N is more than thruster back")
cli_case("robustness-push-huge", ["robustness", *COMMANDS["robustness"], "--push-impulse",
                                  "-1e5,0", "--out", "{out}"], "--push-impulse",
         "an impulse of 100000 N s")
cli_case("stability-vary-huge", ["stability", *COMMANDS["stability"], "--vary",
                                 "wn=1:1e300:log3", "--out", "{out}"], "--vary")
cli_case("stability-vary-stiff", ["stability", *COMMANDS["stability"], "--vary",
                                  "wn=1:1e6:log3", "--out", "{out}"], "--vary",
         r"wn = 1e\+06: a thruster with a 0\.001 ms time constant")
cli_case("simulate-stiff-wn", ["simulate", *COMMANDS["simulate"], "--wn", "1e6", "--out",
                               "{out}"], "--wn", "a thruster with a 0.001 ms")
cli_case("simulate-stiff-tau", ["simulate", *COMMANDS["simulate"], "--thrust-model",
                                "first-order", "--tau", "1e-5", "--out", "{out}"], "--tau")
cli_case("control-stiff", ["control", *COMMANDS["control"], "--thrust-model", "second-order",
                           "--knots", "0,1", "--wn", "1e6", "--out", "{out}"], "--wn")
# the option the problem is about, not another one (item 7)
cli_case("simulate-zeta0-negative", ["simulate", *COMMANDS["simulate"], "--zeta0", "-5",
                                     "--out", "{out}"], "--zeta0", "must be > 0")
cli_case("control-seed-negative", ["control", *COMMANDS["control"], "--seed", "-1", "--out",
                                   "{out}"], "--seed", "must be >= 0")
cli_case("control-push-nan-step", ["control", *COMMANDS["control"], "--push", "nan:0.5:10",
                                   "--out", "{out}"], "--push")
# the slopes (SPEC 14), after the rotation above so that the other options keep their values
COMMANDS["slope"] = [W5, W5T]
FLOATS["limit-cycle"].append("--slope")
FLOATS["feasibility"].append("--slope")
FLOATS["slope"] = ["--mu", "--min-vertical-force"]
for _cmd, _opt, _v, _msg in (
        ("limit-cycle", "--slope", "nan", ""), ("feasibility", "--slope", "-inf", ""),
        ("limit-cycle", "--slope", "1.6", "a slope is an angle in radians with |slope| < pi/2"),
        ("feasibility", "--slope", "-1.5708", "a slope is an angle"),
        ("slope", "--mu", "inf", ""), ("slope", "--min-vertical-force", "nan", ""),
        ("slope", "--slope", "0,nan", ""), ("slope", "--slope", "0:1:5e-324", ""),
        ("slope", "--slope", "-1.6:0:0.1", "a slope is an angle"),
        ("slope", "--thrust", "0,1e308", ""),
        ("slope", "--thrust", "0:-500:-100", "-200 N is outside")):
    cli_case(f"slope-{_cmd}{_opt}={_v}", [_cmd, *COMMANDS[_cmd], _opt, _v, "--out", "{out}"],
             _opt, _msg)
# the energy command (SPEC 15), after the rotations above
COMMANDS["energy"] = [W5, W5T]
FLOATS["energy"] = ["--slope"]
for _opt, _v, _msg in (("--slope", "nan", ""), ("--slope", "1.6", "a slope is an angle"),
                       ("--thrust", "0,nan", ""), ("--thrust", "0:1:5e-324", ""),
                       ("--thrust", "0,-500", "-500 N is outside"),
                       ("--library", str(DATA), ".* is not a gait library"),
                       ("--library", str(DATA / "no_such_library"), ".* is not a folder")):
    cli_case(f"energy{_opt}={_v}", ["energy", *COMMANDS["energy"], _opt, _v, "--out", "{out}"],
             _opt, _msg)
# the rough-ground command (SPEC 14), after the rotations above
COMMANDS["rough-ground"] = [W5, W5T, "--sigma", "0.004", "--strategy", "none", "--trials", "2",
                            "--cap", "10", "--mesh", "4", "--terrain-samples", "4"]
FLOATS["rough-ground"] = ["--s-max", "--target", "--mu", "--min-vertical-force",
                          "--max-thrust", "--rtol", "--atol", "--slope"]
INTS["rough-ground"] = [("--trials", ("0", "-1")), ("--cap", ("0", "-1")), ("--seed", ("-1",)),
                        ("--mesh", ("0", "-1", "5")), ("--terrain-samples", ("0", "-1", "3")),
                        ("--workers", ("0", "-1"))]
for _i, _opt in enumerate(FLOATS["rough-ground"]):
    _v = _BAD[_i % len(_BAD)]
    cli_case(f"rough-ground{_opt}={_v}", ["rough-ground", *COMMANDS["rough-ground"], _opt, _v,
                                          "--out", "{out}"], _opt)
for _opt, _vals in INTS["rough-ground"]:
    for _v in _vals:
        cli_case(f"rough-ground{_opt}={_v}", ["rough-ground", *COMMANDS["rough-ground"], _opt,
                                              _v, "--out", "{out}"], _opt)
for _opt, _v, _msg in (("--sigma", "nan", ""), ("--sigma", "0,inf", ""),
                       ("--sigma", "-0.001", ""), ("--sigma", "0:1:5e-324", ""),
                       ("--sigma", "2", ""), ("--knots", "0,nan,1", ""),
                       ("--distribution", "cauchy", ""), ("--strategy", "fly", "unknown")):
    cli_case(f"rough-ground{_opt}={_v}", ["rough-ground", *COMMANDS["rough-ground"], _opt, _v,
                                          "--out", "{out}"], _opt, _msg)
# the full-order commands on a slope (SPEC 14)
for _cmd in ("simulate", "stability", "control"):
    FLOATS[_cmd].append("--slope")
    for _v, _msg in (("nan", ""), ("-inf", ""), ("1.6", "a slope is an angle")):
        cli_case(f"slope-{_cmd}={_v}", [_cmd, *COMMANDS[_cmd], "--slope", _v, "--out", "{out}"],
                 "--slope", _msg)
# slope on every remaining command (issue 27)
for _cmd in ("robustness", "shape", "design-gait", "optimize"):
    FLOATS.setdefault(_cmd, []).append("--slope")
    for _v, _msg in (("nan", ""), ("inf", ""), ("1.6", "a slope is an angle")):
        cli_case(f"slope-{_cmd}={_v}", [_cmd, *COMMANDS[_cmd], "--slope", _v, "--out", "{out}"],
                 "--slope", _msg)
# item 5: the executor options of the commands that write a folder incrementally are checked
# before the folder exists (robustness and sweep)
for _args, _opt, _msg in ((["--workers", "0"], "--workers", "must be 1..1024"),
                          (["--workers", "-3"], "--workers", "must be 1..1024"),
                          (["--workers", "5000"], "--workers", "must be 1..1024"),
                          (["--scheduler", "tcp://127.0.0.1:99999"], "--scheduler",
                           "the port must be a number 1 ... 65535"),
                          (["--scheduler", "tcp://127.0.0.1"], "--scheduler", "the port"),
                          (["--scheduler", "udp://127.0.0.1:8786"], "--scheduler",
                           "expected tcp://HOST:PORT"),
                          (["--scheduler", "tcp://:8786"], "--scheduler", "expected"),
                          (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"],
                           "--workers/--scheduler", "give one of them")):
    cli_case(f"executor-robustness{'='.join(_args)}",
             ["robustness", *COMMANDS["robustness"], *_args, "--out", "{out}"], _opt, _msg)
    cli_case(f"executor-sweep{'='.join(_args)}",
             ["sweep", "{file}", *_args, "--out", "{out}"], _opt, _msg,
             text=_sweep("limit-cycle", "grid:\n  thrust: {values: [0]}\ncollect: [speed]\n"))


def test_the_command_line_corpus_covers_every_numeric_option():
    """Every FLOAT and INT option of the commands in the table is in it (a new option is
    added to the table, not forgotten)."""
    import typer

    from thrustwalk_cli.cli import app

    group = typer.main.get_command(app)
    skip = {"--max-output"}  # in MB: checked as every float (nan, inf, 1e308)
    for cmd in COMMANDS:
        for p in group.commands[cmd].params:
            longs = [o for o in getattr(p, "opts", ()) if o.startswith("--")]
            kind = getattr(p.type, "name", "")
            if not longs or kind not in ("float", "integer") or longs[0] in skip:
                continue
            ints = [o for o, _ in INTS.get(cmd, [])]
            assert longs[0] in FLOATS.get(cmd, []) + ints, f"{cmd} {longs[0]} not in the table"


# -- sweep files: every point's settings before the first task (item 6) -----------------------


SWEEPS = {
    # name: (study, body, key path of the problem (a regular expression), message)
    "steps-0": ("simulate", "grid:\n  steps: {values: [2, 0]}\ncollect: [status]\n",
                r"grid\.steps", "value 0: must be >= 1"),
    "steps-not-whole": ("push-trial", "random:\n  samples: 3\n  seed: 1\n  axes:\n    steps: "
                        "{distribution: uniform, low: 1, high: 3}\ncollect: [outcome]\n",
                        r"random\.axes\.steps", "value .*: must be a whole number"),
    "start-sigma-minus-1": ("push-trial", "grid:\n  start_sigma: {values: [0, -1]}\n"
                            "collect: [outcome]\n", r"grid\.start_sigma", "value -1: must be >"),
    "knots-decreasing": ("limit-cycle", "settings:\n  schedule: {knots: [0, 0.6, 0.4, 1], "
                         "values: [0, -10, 0]}\ngrid:\n  schedule.1: {values: [0, -5]}\n"
                         "collect: [speed]\n", r"settings\.schedule\.knots\[2\]",
                         "knots must increase strictly"),
    "knots-not-to-1": ("feasibility", "settings:\n  schedule: {knots: [0, 0.5], values: [-10]}"
                       "\ngrid:\n  schedule.1: {values: [0, -5]}\ncollect: [feasible]\n",
                       r"settings\.schedule\.knots", "the first must be 0 and the last 1"),
    "knots-beyond-1": ("limit-cycle", "settings:\n  schedule: {knots: [0, 1.5, 1], values: "
                       "[0, 0]}\ngrid:\n  schedule.1: {values: [0]}\ncollect: [speed]\n",
                       r"settings\.schedule\.knots\[1\]", "must be <= 1"),
    "values-count": ("limit-cycle", "settings:\n  schedule: {knots: [0, 0.5, 1], values: "
                     "[0, -10, -20]}\ngrid:\n  schedule.1: {values: [0, -5]}\ncollect: [speed]\n",
                     r"settings\.schedule\.values", "expected 2 values"),
    "schedule-axis-beyond-limits": ("limit-cycle", "settings:\n  schedule: {knots: [0, 0.5, 1], "
                                    "values: [0, -10]}\ngrid:\n  schedule.2: {values: [0, "
                                    "-500]}\ncollect: [speed]\n", r"grid\['schedule\.2'\]",
                                    "-500 N is outside the limits"),
    "schedule-without-piecewise": ("simulate", "settings:\n  steps: 2\n  schedule: {knots: [0, "
                                   "1], values: [-10]}\ngrid:\n  kp: {values: [100, 400]}\n"
                                   "collect: [status]\n", r"settings\.schedule",
                                   "a schedule needs `thrust_model` piecewise"),
    "thrust-and-schedule": ("limit-cycle", "settings:\n  thrust: -10\n  schedule: {knots: "
                            "[0, 1], values: [-10]}\ngrid:\n  mu: {values: [0.7, 0.8]}\n"
                            "collect: [speed]\n", r"settings\.thrust", "not both"),
    "push-and-start-off-orbit": ("push-trial", "grid:\n  push_impulse: {values: [0, 5]}\n  "
                                 "start_sigma: {values: [0, 0.1]}\ncollect: [outcome]\n",
                                 r"grid\.push_impulse", "give a push or a start off the orbit, "
                                 r"not both \(at start_sigma = 0\.1\)"),
    "push-huge": ("push-trial", "grid:\n  push_impulse: {values: [0, 1e5]}\ncollect: "
                  "[outcome]\n", r"grid\.push_impulse", r"an impulse of 100000 N s"),
    "control-max-thrust": ("push-trial", "settings:\n  strategy: control\n  max_thrust: 1e6\n"
                           "grid:\n  push_impulse: {values: [0, 1]}\ncollect: [outcome]\n",
                           r"settings\.max_thrust", "1e\\+06 N is more than thruster back"),
    "control-knots": ("reduced-walk", "settings:\n  strategy: control\n  knots: [0, 0.7, 0.5, "
                      "1]\ngrid:\n  mu: {values: [0.7, 0.8]}\ncollect: [walks]\n",
                      r"settings\.knots\[2\]", "knots must increase strictly"),
    "rtol-beyond-what-runs": ("simulate", "settings:\n  rtol: 0.5\ngrid:\n  steps: {values: "
                              "[1, 2]}\ncollect: [status]\n", r"settings\.rtol", "must be < 0.1"),
    "stiff-thruster": ("simulate", "settings:\n  thrust_model: second-order\n  xi: 900\ngrid:\n"
                       "  wn: {values: [1, 2]}\ncollect: [status]\n", r"grid\.wn",
                       "a thruster with a .* ms time constant"),
    "f0-beyond-limits": ("simulate", "settings:\n  thrust_model: first-order\n  f0: -500\n"
                         "grid:\n  thrust: {values: [0, -10]}\ncollect: [status]\n",
                         r"settings\.f0", "-500 N is outside the limits"),
    "tiny-step": ("limit-cycle", "grid:\n  thrust: {start: 0, stop: -1, step: -5e-324}\n"
                  "collect: [speed]\n", r"grid\.thrust\.step", "below the resolution"),
    "design-order": ("design-gait", "grid:\n  order: {values: [6, 2.5]}\n  target_speed: "
                     "{values: [0.6]}\ncollect: [feasible]\n", r"grid\.order",
                     "value 2.5: must be a whole number"),
}
for _name, (_study, _body, _key, _msg) in SWEEPS.items():
    CLI[f"sweep-file-{_name}"] = Case(("sweep", "{file}", "--workers", "1", "--out", "{out}"),
                                      r"error: \{file\}:\d+: " + _key + ": .*" + _msg,
                                      text=_sweep(_study, _body))


def test_thruster_beside_a_schedule_drives_it(tmp_path, monkeypatch, one_command, walker5_thrust):
    """``thruster:`` names the thruster of a force-mode ``schedule`` (the sweep table says
    so): every point runs. A schedule of equal values on every interval is the constant
    thrust: its speed is tw.limit_cycle's for that constant thrust."""
    import json

    import pandas as pd

    monkeypatch.chdir(tmp_path)
    (_with_walker5(tmp_path) / "s.yaml").write_text(_sweep(
        "limit-cycle", "settings:\n  thruster: back\n  schedule: {knots: [0, 0.5, 1], values: "
        "[-10, -10]}\ngrid:\n  schedule.2: {values: [-10, -20]}\ncollect: [speed]\n"))
    res = one_command("sweep", "s.yaml", "--workers", "1", "--out", "o", "--formats", "csv",
                      "-q")
    assert res.exit_code == 0, res.stderr
    doc = json.loads((tmp_path / "o" / "sweep.json").read_text())
    assert doc["failures"] == [] and doc["counts"]["done"] == 2
    table = pd.read_csv(tmp_path / "o" / "results.csv", comment="#")
    speed = dict(zip(table["schedule_2_N"], table["speed_m_s"]))
    ref = tw.limit_cycle(walker5_thrust, thrust=[-10.0], thruster="back").cycles[0].speed
    assert speed[-10.0] == pytest.approx(ref, rel=1e-9)
    assert speed[-20.0] > speed[-10.0]  # more forward thrust (back points -x), a faster walk


@pytest.fixture(scope="module")
def walker5_thrust(_cache_dir):
    return tw.load_walker(W5, W5T)


# -- a slow thruster whose step nearly stops (item 7) ------------------------------------------
@pytest.mark.slow
def test_slow_thruster_towards_a_stop_is_an_outcome_not_a_traceback(walker5_thrust):
    """A zeta reference far below the orbit's under a second-order thruster: the controller's
    step prediction (its time map) reaches zeta = 0 where the walker would stop. The run is a
    result whose every number is finite or None (on main: ValueError, NaN in the time map)."""
    import json

    # control's settings["nominal_zeta_star"]: the zero-thrust orbit's zeta* (controller.planner)
    low = 0.08 * walker5_thrust.zd.nominal_cycle().zeta_star
    res = tw.control(walker5_thrust, reference="zeta", profile=[(0, low)], knots=[0, 1],
                     steps=4, thrust_model="second-order", compare=False)
    json.dumps(res.document(), allow_nan=False)  # no NaN anywhere
    assert res.status in ("ok", "warning", "failed") and res.reason


@pytest.fixture(scope="module")
def one_command():
    """The ``cli`` fixture with only the command run (as ``thrustwalk`` itself does: typer
    builds every command's options on each run of the whole app, 0.1 s, more than a refused
    option costs)."""
    from typer.testing import CliRunner

    from thrustwalk_cli.cli import invoked_app

    runner = CliRunner()

    def run(*args: str):
        args = [str(a) for a in args]
        return runner.invoke(invoked_app(args), args, catch_exceptions=False)
    return run


@pytest.mark.parametrize("name", sorted(CLI))
def test_bad_option(name, tmp_path, one_command, monkeypatch, _cache_dir):
    monkeypatch.chdir(tmp_path)
    if CLI[name].argv[0] == "sweep":
        _with_walker5(tmp_path)
    check_case(name, CLI[name], tmp_path, one_command)


@pytest.mark.slow  # (this session's additions; CI runs every test)
def test_one_thruster_name_is_taken_as_a_list_of_one(walker5_thrust):
    """``thruster="back"`` in simulate and control (which take several names) is
    ``["back"]``, as limit_cycle and robustness take one name: the same runs, bit for bit."""
    a = tw.simulate(walker5_thrust, steps=2, thrust=[-10.0], thrust_model="ideal",
                    thruster="back").document()
    b = tw.simulate(walker5_thrust, steps=2, thrust=[-10.0], thrust_model="ideal",
                    thruster=["back"]).document()
    assert a["runs"] == b["runs"]
    # accepted with the other options (before: an InputError on `thruster`)
    assert tw.control(walker5_thrust, reference="nominal", steps=2, thruster="back",
                      check_only=True) is None
