"""The studies a sweep can run: one registry entry per study, and the point function that
worker processes call.

An entry (:class:`SweepStudy`) names the result fields a sweep may collect (with units), the
function computing one point from the point's walker (or compiled model) and parameters, an
up-front check of the parameters, and what to prepare once before the workers start. A new
study (push trials, control, stability) adds its parameter table to
:data:`thrustwalk_cli.files.sweep_file.STUDY_PARAMETERS` and an entry to :data:`STUDIES`.

:func:`run_point` is the task every worker runs: it builds the point's robot
(:func:`point_robot`, the one place robot parameters become a robot), loads its model through
:func:`thrustwalk_cli.model.compiler.load_model`, runs the study and returns the point's record:
``status`` ``ok`` or ``failed`` with the ``reason`` (bad values for this point, a failed
computation), the collectable ``fields`` and the study's full JSON ``document``.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from .._version import __version__
from ..description.robot import Robot
from ..errors import ComputationError, InputError, param_problem
from ..files.gait_file import load_gait_text
from ..files.output import jsonable
from ..files.robot_file import load_robot_text
from ..model.compiled import CompiledModel
from ..model.compiler import load_model
from ..sweep.runner import chunk_size
from ..sweep.tasks import PointTask, canonical
from ..thrust.schedule import WrittenSchedule
from ..walker import Walker, assemble_walker
from .documents import UNITS


@dataclass(frozen=True)
class PointResult:
    """What a study computes at one point: its JSON ``document``, the collectable ``fields``
    (SI, None when not computed), ``extra`` data (e.g. a designed gait file) and the start a
    continuing point may use (``next_start``)."""

    document: dict
    fields: dict[str, object]
    extra: dict = field(default_factory=dict)
    next_start: dict | None = None


@dataclass(frozen=True)
class SweepStudy:
    """A study a sweep can run.

    fields: collectable result fields, name -> (unit, meaning); point(base, params, start):
    the computation of one point (``base`` a :class:`Walker`, or a :class:`CompiledModel` when
    ``uses_gait`` is false); check(base, params): problems with the parameters of a point,
    ``(parameter, message)`` pairs, found before any work; prepare(base, settings): once in
    the calling process before local workers start (e.g. compile a kernel once, not in every
    worker); continuation: points start from their finished neighbour's result.
    """

    name: str
    fields: dict[str, tuple[str, str]]
    point: Callable[[object, dict, dict | None], PointResult]
    uses_gait: bool = True
    check: Callable[[object, dict], list[tuple[str, str]]] | None = None
    prepare: Callable[[object, dict], None] | None = None
    continuation: bool = False


# ------------------------------------------------------------------------------- helpers
def _schedule(robot: Robot, p: Mapping) -> WrittenSchedule | None:
    """The ``schedule`` setting with the point's ``schedule.j`` values applied."""
    s = p.get("schedule")
    if s is None:
        return None
    values = list(s["values"])
    for k, v in p.items():
        if k.startswith("schedule."):
            values[int(k.split(".")[1]) - 1] = float(v)
    if s["mode"] == "generalized":
        return WrittenSchedule(tuple(s["knots"]), (("T", tuple(values)),), "generalized", True)
    j = robot.driven_thruster(p.get("thruster"))
    if j is None:
        raise InputError.param("schedule", f"robot {robot.name} has no thruster: use mode "
                                           "generalized")
    return WrittenSchedule(tuple(s["knots"]), ((robot.thruster_names[j], tuple(values)),),
                          "force", True)


def _with_gait(walker: Walker, **changes) -> Walker:
    """The walker with gait data that the zero dynamics do not depend on changed (thrust
    schedule, gains, friction coefficient)."""
    gait = replace(walker.gait, **changes)
    return replace(walker, gait=gait, zd=replace(walker.zd, gait=gait))


def _thrust_case(walker: Walker, p: Mapping) -> tuple[Walker, list[float] | None]:
    """The walker and constant-thrust list of a limit-cycle or feasibility point: a schedule
    (setting or axes) replaces the gait's; else the ``thrust`` value; else the gait's own
    schedule; else 0 N."""
    sched = _schedule(walker.robot, p)
    if sched is not None:
        if p.get("thrust") is not None:
            raise InputError.param(("thrust", "schedule"), "give one of them, not both")
        return _with_gait(walker, thrust=sched), None
    if p.get("thrust") is not None:
        return walker, [float(p["thrust"])]
    return walker, (None if walker.gait.thrust is not None else [0.0])


def _first(doc: dict, key: str) -> dict:
    return doc[key][0]


def _pick(entry: dict, names, rename: Mapping[str, str] | None = None) -> dict:
    rename = rename or {}
    return {n: entry.get(rename.get(n, n)) for n in names}


def _check_thrust(base, p: Mapping, name: str = "thrust") -> list[tuple[str, str]]:
    """The thruster exists and the constant thrust ``p["thrust"]`` lies within its limits
    (reported on ``name``)."""
    robot = base.robot
    out = []
    try:
        j = robot.driven_thruster(p.get("thruster"))
    except InputError as exc:
        return [("thruster", exc.problems[0].message)]
    v = p.get("thrust")
    if v is None:
        return out
    if j is None:
        if v != 0:
            out.append((name, f"robot {robot.name} has no thruster: only 0 N"))
        return out
    lo, hi = robot.thrusters[j].limits
    if not lo <= v <= hi:
        out.append((name, f"{v:g} N is outside the limits [{lo:g}, {hi:g}] N of "
                          f"thruster {robot.thruster_names[j]}"))
    return out


def _schedule_problems(walker: Walker, p: Mapping) -> list[tuple[str, str]]:
    """The point's ``schedule`` (with its ``schedule.j`` values) checked against the walker:
    a thruster for force mode, the knots, one value per interval, the thruster's limits.
    Problems name ``schedule.knots`` / ``schedule.values`` (their keys in the sweep file)."""
    def where(key: tuple, message: str):
        return param_problem("schedule." + str(key[1]) if len(key) > 1 else "schedule",
                             message)
    try:
        sched = _schedule(walker.robot, p)
        if sched is not None:
            s = sched.resolve(walker.zd, walker.robot, where, pad=True)[0]
            s.check_limits(walker.robot, where)
    except InputError as exc:
        return [(pr.params[0] if pr.params else "schedule", pr.message) for pr in exc.problems]
    return []


def _check_case(walker: Walker, p: Mapping) -> list[tuple[str, str]]:
    """A limit-cycle or feasibility point: the thruster and thrust, or the schedule, not
    both."""
    out = _check_thrust(walker, p)
    if p.get("schedule") is not None and p.get("thrust") is not None:
        out.append(("thrust", "give `thrust` or a `schedule`, not both"))
    return out + _schedule_problems(walker, p)


# ---------------------------------------------------------------------------- the studies
_LC_FIELDS = {
    "walkable": ("1", "stable periodic orbit, hybrid-invariant gait, swing foot above ground, "
                 "contact-feasible on the orbit (the feasibility study's checks)"),
    "exists": ("1", "a periodic orbit exists"), "stable": ("1", "the orbit is stable"),
    "contact_feasible": ("1", "F^v >= min_vertical_force, friction cone, admissible impact on "
                         "the orbit"),
    "min_vertical_force": (UNITS["force"], "least vertical ground force F_1^v on the orbit"),
    "max_friction_ratio": (UNITS["friction_ratio"], "largest |F_1^h|/F_1^v on the orbit"),
    "delta_zero_sq": (UNITS["delta_zero_sq"], "Poincare eigenvalue delta_zero^2"),
    "zeta_star": (UNITS["zeta"], "fixed point zeta* = V_Z(alpha_f)/(1 - delta_zero^2)"),
    "step_time": (UNITS["step_time"], "step time"),
    "step_length": (UNITS["step_length"], "step length"),
    "speed": (UNITS["speed"], "average speed"),
    "sigma_minus": (UNITS["sigma_N"], "sigma_N just before impact"),
    "sigma_plus": (UNITS["sigma_N"], "sigma_N just after impact"),
    "alpha_dot_minus": (UNITS["alpha_dot"], "alpha' just before impact"),
    "alpha_dot_plus": (UNITS["alpha_dot"], "alpha' just after impact"),
    "min_abs_alpha_dot": (UNITS["alpha_dot"], "least |alpha'| (the potential barrier)"),
    "max_abs_alpha_dot": (UNITS["alpha_dot"], "largest |alpha'|"),
    "min_zeta": (UNITS["zeta"], "least zeta along the step"),
    "touchdown_velocity": (UNITS["velocity"], "swing-foot vertical velocity before impact"),
}


def _limit_cycle_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from .limit_cycle import limit_cycle

    w, thrust = _thrust_case(walker, p)
    # a schedule names its thruster itself (`thruster` drove it into the schedule)
    res = limit_cycle(w, thrust, p.get("thruster") if thrust is not None else None,
                      mu=p.get("mu"), min_vertical_force=p.get("min_vertical_force", 0.0))
    doc = res.document()
    case = _first(doc, "cycles")
    fields = _pick(case, [k for k in _LC_FIELDS if k not in ("contact_feasible",
                                                             "min_vertical_force",
                                                             "max_friction_ratio")])
    ct = case["contact"]
    fields.update(contact_feasible=ct["feasible"], min_vertical_force=ct["min_vertical_force"],
                  max_friction_ratio=ct["max_friction_ratio"])
    return PointResult(doc, fields)


_FE_FIELDS = {
    "feasible": ("1", "every contact condition holds on the orbit"),
    "orbit_exists": ("1", "a periodic orbit exists"),
    "zeta_star": (UNITS["zeta"], "fixed point zeta*"), "speed": (UNITS["speed"], "average speed"),
    "min_vertical_force": (UNITS["force"], "least vertical ground force F_1^v"),
    "max_friction_ratio": (UNITS["friction_ratio"], "largest |F_1^h|/F_1^v"),
    "impact_friction_ratio": (UNITS["friction_ratio"], "|F_2^h|/F_2^v of the impact impulse"),
    "liftoff_velocity": (UNITS["velocity"], "trailing foot's vertical velocity after impact"),
    "touchdown_velocity": (UNITS["velocity"], "swing-foot vertical velocity before impact"),
    "min_swing_foot_height": (UNITS["height"], "lowest swing-foot height along the step"),
    "vertical_force_margin": (UNITS["force"], "min F_1^v - eps"),
    "friction_margin": (UNITS["friction_ratio"], "mu - max |F_1^h|/F_1^v"),
    "impact_friction_margin": (UNITS["friction_ratio"], "mu - |F_2^h|/F_2^v"),
}


def _feasibility_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from .feasibility import feasibility

    w, thrust = _thrust_case(walker, p)
    res = feasibility(w, thrust, thruster=p.get("thruster"), mu=p.get("mu"),
                      min_vertical_force=p["min_vertical_force"], region_shape=(11, 11))
    doc = res.document()
    case = _first(doc, "cases")
    fields = _pick(case, [k for k in _FE_FIELDS if not k.endswith("_margin")])
    m = case.get("margins") or {}
    fields.update(vertical_force_margin=m.get("vertical_force"),
                  friction_margin=m.get("friction"),
                  impact_friction_margin=m.get("impact_friction"))
    return PointResult(doc, fields)


_SIM_FIELDS = {
    "success": ("1", "the run completed its steps"),
    "status": ("", "ok, warning (off the zero-dynamics prediction) or failed"),
    "steps_completed": ("1", "steps completed"),
    "final_zeta_minus": (UNITS["zeta"], "zeta^- of the last step"),
    "final_relative_error": ("1", "(final zeta^- - zeta*) / zeta*"),
    "predicted_zeta_star": (UNITS["zeta"], "zero-dynamics fixed point of the steady thrust"),
    "predicted_speed": (UNITS["speed"], "zero-dynamics average speed"),
    "mean_step_time": (UNITS["step_time"], "mean step time"),
    "min_vertical_force": (UNITS["force"], "least vertical ground force over the steps"),
    "max_friction_ratio": (UNITS["friction_ratio"], "largest |F_1^h|/F_1^v over the steps"),
    "max_abs_torque": (UNITS["torque"], "largest joint torque over the steps"),
    "max_abs_output": (UNITS["output_y"], "largest |y| over the steps"),
}


def _simulate_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from .simulate import simulate

    changes = {k: float(p[k]) for k in ("kp", "kd") if p.get(k) is not None}
    sched = _schedule(walker.robot, p)
    if sched is not None:
        if p["thrust_model"] != "piecewise":
            raise InputError.param("schedule", "a schedule needs `thrust_model` piecewise")
        changes["thrust"] = sched
    w = _with_gait(walker, **changes) if changes else walker
    piecewise = p["thrust_model"] == "piecewise"
    res = simulate(w, steps=int(p["steps"]), thrust_model=p["thrust_model"],
                   thrust=None if piecewise else [float(p["thrust"])],
                   wn=p["wn"], xi=p["xi"], tau=p["tau"], f0=p["f0"],
                   thruster=[p["thruster"]] if p.get("thruster") and not piecewise else None,
                   perturb=p["perturb"], torque_limit=p.get("torque_limit"),
                   rtol=p["rtol"], atol=p["atol"], method=p["method"], mu=p.get("mu"),
                   samples=2)
    doc = res.document()
    run = _first(doc, "runs")
    steps = [s for s in doc["steps"] if s["run"] == 0]

    def agg(key: str, f) -> float | None:
        vals = [s[key] for s in steps if s.get(key) is not None]
        return float(f(vals)) if vals else None

    fields = _pick(run, ["success", "status", "steps_completed", "final_zeta_minus",
                         "final_relative_error"])
    pred = run["predicted"]
    fields.update(predicted_zeta_star=pred["zeta_star"], predicted_speed=pred["speed"],
                  mean_step_time=agg("step_time", np.mean),
                  min_vertical_force=agg("min_vertical_force", min),
                  max_friction_ratio=agg("max_friction_ratio", max),
                  max_abs_torque=agg("max_abs_torque", max),
                  max_abs_output=agg("max_abs_output", max))
    return PointResult(doc, fields)


def _check_simulate(walker: Walker, p: dict) -> list[tuple[str, str]]:
    from ..simulation.closed_loop import PIECEWISE, check_thruster_rate
    from ..thrust.dynamics import canonical

    out = _check_thrust(walker, p)
    model = p["thrust_model"]
    if model == "piecewise" and p.get("schedule") is None and walker.gait.thrust is None:
        out.append(("thrust_model", "piecewise needs a `schedule` or a gait with a thrust: "
                                    "section"))
    if p.get("schedule") is not None and model != "piecewise":
        out.append(("schedule", "a schedule needs `thrust_model` piecewise"))
    out += _schedule_problems(walker, p)
    if canonical(model) not in ("ideal", PIECEWISE):  # a model with thruster states
        out += _check_thrust(walker, {**p, "thrust": p["f0"]}, "f0")
        try:
            check_thruster_rate(model, float(p["wn"]), float(p["xi"]), float(p["tau"]),
                                walker.model.n_thrusters)
        except InputError as exc:
            out += [(pr.params[0], pr.message) for pr in exc.problems]
    return out


def _prepare_simulate(walker: Walker, settings: dict) -> None:
    """Compile the simulation kernel once here, not in every worker at the same time."""
    if settings.get("method") == "compiled":
        from .compile import compile_kernel

        compile_kernel()


_DG_FIELDS = {
    "feasible": ("1", "a gait passing the independent re-check was found"),
    "effort": (UNITS["effort"], "(1/L) int |u|^2 dt on the periodic orbit"),
    "peak_torque": (UNITS["torque"], "max |u_i| on the periodic orbit"),
    "delta_zero_sq": (UNITS["delta_zero_sq"], "Poincare eigenvalue delta_zero^2"),
    "zeta_star": (UNITS["zeta"], "fixed point zeta*"),
    "speed": (UNITS["speed"], "average speed"),
    "step_length": (UNITS["step_length"], "step length"),
    "step_time": (UNITS["step_time"], "step time"),
    "touchdown_velocity": (UNITS["velocity"], "swing-foot vertical velocity before impact"),
    "vertical_force_margin": (UNITS["force"], "min F_1^v - eps"),
    "friction_margin": (UNITS["friction_ratio"], "mu - max |F_1^h|/F_1^v"),
    "impact_friction_margin": (UNITS["friction_ratio"], "mu - |F_2^h|/F_2^v"),
    "clearance_margin": (UNITS["height"], "swing-foot height at mid-step - clearance"),
    "iterations": ("1", "SLSQP iterations over all starts"),
}


def _design_spec(model: CompiledModel, p: Mapping, name: str = "designed_gait"):
    from ..design.spec import DesignSpec

    thrust = None
    if p.get("thrust") is not None:
        j = model.robot.driven_thruster(p.get("thruster"))
        if j is None:
            raise InputError.param("thrust", f"robot {model.robot.name} has no thruster")
        F = [0.0] * model.n_thrusters
        F[j] = float(p["thrust"])
        thrust = tuple(F)
    return DesignSpec(speed=p.get("target_speed"), step_length=p.get("step_length"),
                      mu=p["mu"], order=int(p["order"]), clearance=p["clearance"],
                      max_delta_sq=p["max_delta_sq"],
                      min_vertical_force=p.get("min_vertical_force"),
                      min_touchdown_velocity=p["min_touchdown_velocity"],
                      objective=p["objective"], thrust=thrust, starts=int(p["starts"]),
                      seed=int(p["seed"]), max_iter=int(p["max_iter"]), name=name)


def _design_point(model: CompiledModel, p: dict, start: dict | None) -> PointResult:
    from ..design.solver import WarmStart
    from ..hzd.constraints import gait_maps
    from .design_gait import design_gait

    name = p.get("_gait_name") or "designed_gait"
    spec = _design_spec(model, p, name)
    initial = None
    if p["continuation"] and start is not None:
        initial = WarmStart(tuple(start["q_minus"]), tuple(map(tuple, start["coefficients"])),
                            float(start["zeta_minus"]))
    res = design_gait(model, spec, initial=initial)
    doc = res.document()
    o, m = doc.get("fixed_point") or {}, doc.get("margins") or {}
    cost = doc.get("cost") or {}
    fields = {"feasible": res.success, "effort": cost.get("effort"),
              "peak_torque": cost.get("peak"), "delta_zero_sq": o.get("delta_zero_sq"),
              "zeta_star": o.get("zeta_star"), "speed": o.get("speed"),
              "step_length": o.get("step_length"), "step_time": o.get("step_time"),
              "touchdown_velocity": o.get("touchdown_velocity"),
              "vertical_force_margin": m.get("vertical_force"),
              "friction_margin": m.get("friction"),
              "impact_friction_margin": m.get("impact_friction"),
              "clearance_margin": m.get("clearance_mid_step"),
              "iterations": sum(s["iterations"] for s in doc["starts"])}
    extra, nxt = {}, start
    if res.success:
        from .design_gait import gait_yaml

        header = [f"Gait designed by thrustwalk sweep (thrustwalk {__version__}), "
                  f"{p.get('_label', '')}.".replace(", .", "."),
                  f"Objective ({spec.objective}) {res.design.objective:.6g}; delta_zero^2 = "
                  f"{o['delta_zero_sq']:.4f}; {o['speed']:.4f} m/s; step "
                  f"{o['step_length']:.4f} m; zeta* = {o['zeta_star']:.6g} kg^2 m^4/s^2.",
                  "Every margin: the point's JSON in the sweep folder's points/."]
        extra["gait_yaml"] = gait_yaml(res.design, model, p.get("_robot_ref") or
                                       model.robot.source_file, header)
        maps = gait_maps(model, res.design.gait)
        nxt = {"q_minus": maps.q_minus.tolist(),
               "coefficients": [list(r) for r in res.design.gait.A],
               "zeta_minus": o["zeta_star"]}
    return PointResult(doc, fields, extra, nxt)


def _check_design(model: CompiledModel, p: dict) -> list[tuple[str, str]]:
    out = _check_thrust(model, p)
    if out:
        return out
    try:
        _design_spec(model, p).validate(model)
    except InputError as exc:
        names = {"speed": "target_speed"}
        for pr in exc.problems:
            out.append((names.get(pr.params[0], pr.params[0]) if pr.params else "settings",
                        pr.message))
    return out


# ------------------------------------------------------------------- robustness (SPEC 12)
_STRATEGY_KEYS = ("strategy", "strategy_label", "thruster", "thrust", "schedule", "knots",
                  "max_thrust", "mu", "min_vertical_force")
_RUNNER_KEYS = _STRATEGY_KEYS + ("push_direction", "push_link", "push_at", "push_duration",
                                 "transverse", "steps", "recovery_tol", "output_tol", "rtol",
                                 "atol")


def _nominal(walker: Walker, p: Mapping) -> Walker:
    """The walker a controller was made for: the base robot with the point's gait (the point's
    robot is the plant)."""
    make = p.get("_nominal")
    return walker if make is None else make()


def realized_strategy(walker: Walker, p: Mapping, points: int = 401):
    """The point's strategy made concrete for its walker (kept per process: the trials of a
    strategy share it)."""
    from ..resilience.strategy import from_parameters, realize

    model = _nominal(walker, p)
    mu = walker.gait.mu if p.get("mu") is None else float(p["mu"])
    key = ("realized", id(walker), id(model), canonical({k: p.get(k) for k in _STRATEGY_KEYS}),
           points)
    r = _fresh(key, lambda v: v[0] is walker and v[1] is model, lambda: (
        walker, model, realize(walker.zd, from_parameters(p), mu=mu,
                               eps=float(p["min_vertical_force"]), points=points,
                               model_zd=None if model is walker else model.zd)))
    return r[2], mu


def trial_setup(walker: Walker, p: Mapping):
    """The push point and the index of the transverse output of a push-trial point."""
    from ..resilience.push import push_point

    robot = walker.robot
    act = [c.name for c in robot.coordinates if c.actuated]
    name = p.get("transverse") or act[0]
    if name not in act:
        raise InputError.param("transverse", f"unknown actuated coordinate {name!r} (robot "
                                             f"{robot.name} has: {', '.join(act)})")
    point = push_point(walker.model, p.get("push_link"), float(p["push_at"]),
                       tuple(p["push_direction"]))
    return point, act.index(name)


def _trial_runner(walker: Walker, p: Mapping):
    """The trial runner of the point's strategy and settings (kept per process)."""
    from ..resilience.trials import TrialRunner

    real, mu = realized_strategy(walker, p)
    key = ("runner", id(walker), canonical({k: p.get(k) for k in _RUNNER_KEYS}))

    def make():
        point, transverse = trial_setup(walker, p)
        run = TrialRunner(walker.zd, real, point, steps=int(p["steps"]), mu=mu,
                          eps=float(p["min_vertical_force"]),
                          recovery_tol=float(p["recovery_tol"]),
                          output_tol=float(p["output_tol"]), rtol=float(p["rtol"]),
                          atol=float(p["atol"]), transverse=transverse,
                          duration=float(p["push_duration"]))
        return walker, run

    return _fresh(key, lambda v: v[0] is walker, make)[1]


_PT_FIELDS = {
    "outcome": ("", "recovered, unsettled, fell, slipped, lifted, scuffed, stopped or error"),
    "recovered": ("1", "back within recovery_tol of the orbit after the steps"),
    "converging": ("1", "recovered, or still walking and converging (inside the reduced "
                        "basin, closer each step)"),
    "failed_step": ("1", "the step of a failure (empty when every step was walked)"),
    "steps_completed": ("1", "steps completed"),
    "final_zeta_minus": (UNITS["zeta"], "zeta^- of the last step"),
    "relative_error": ("1", "|zeta^- - zeta_ref| / zeta_ref of the last step"),
    "zeta_ref": (UNITS["zeta"], "the orbit a recovery is measured against"),
    "speed": (UNITS["speed"], "average speed of the last step"),
    "max_friction_ratio": (UNITS["friction_ratio"], "largest |F_1^h|/F_1^v over the steps"),
    "min_vertical_force": (UNITS["force"], "least vertical ground force over the steps"),
    "push_friction_ratio": (UNITS["friction_ratio"], "|F^h|/F^v of the push's impulsive "
                                                     "ground reaction"),
    "push_vertical_impulse": (UNITS["impulse"], "vertical part of the push's impulsive ground "
                                                "reaction"),
}


def _push_trial_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from ..resilience.trials import Trial

    impulse, sigma, rate = (float(p["push_impulse"]), float(p["start_sigma"]),
                            float(p["start_rate"]))
    if impulse != 0.0 and (sigma != 0.0 or rate != 0.0):
        raise InputError.param(("push_impulse", "start_sigma"), "a push trial starts on the "
                                                                "orbit: give a push or a start "
                                                                "off the orbit, not both")
    runner = _trial_runner(walker, p)
    trial = Trial(impulse, float(p["push_phase"]), sigma, rate)
    res = runner.run(trial)
    doc = {"strategy": runner.r.strategy.label,
           "trial": {"push_impulse": impulse, "push_phase": trial.phase,
                     "push_vector": runner.point.impulse(impulse).tolist(),
                     "start_sigma": sigma, "start_rate": rate},
           **res.document()}
    return PointResult(doc, res.fields())


def _check_push_trial(walker: Walker, p: dict) -> list[tuple[str, str]]:
    out = check_strategy(walker, p)
    try:
        walker.robot.check_push("push_impulse", float(p["push_impulse"]))
    except InputError as exc:
        out.append(("push_impulse", exc.problems[0].message))
    try:
        trial_setup(walker, p)
    except InputError as exc:
        out += [(pr.params[0], pr.message) for pr in exc.problems]
    if float(p["push_impulse"]) != 0.0 and (float(p["start_sigma"]) != 0.0
                                            or float(p["start_rate"]) != 0.0):
        out.append(("push_impulse", "a push trial starts on the orbit: give a push or a start "
                                    "off the orbit, not both"))
    return out


def check_strategy(walker: Walker, p: dict) -> list[tuple[str, str]]:
    """The strategy's own problems (thruster, thrust limits, schedule, knots), found before
    any point runs."""
    try:
        if p.get("strategy") == "control" and p.get("max_thrust") is not None:
            robot = walker.robot
            if robot.thrusters:
                robot.check_thrust_bound("max_thrust", float(p["max_thrust"]),
                                         [robot.thruster_index(p.get("thruster"))])
        realized_strategy(walker, p)
    except InputError as exc:
        return [(pr.params[0] if pr.params else "strategy", pr.message) for pr in exc.problems]
    return []


_RW_FIELDS = {
    "walks": ("1", "the point's robot walks under the strategy (stable orbit in its reduced "
                   "basin, swing foot clear; control: the base robot's controller settles)"),
    "zeta_star": (UNITS["zeta"], "the converged zeta^-"),
    "speed": (UNITS["speed"], "the converged average speed"),
    "step_time": (UNITS["step_time"], "the converged step time"),
    "controlled_steps": ("1", "control: steps until the controlled map settled"),
    "basin_exists": ("1", "fixed strategies: the reduced basin contains the orbit"),
    "basin_lower": (UNITS["zeta"], "fixed strategies: lower end of the reduced basin in zeta^-"),
    "basin_upper": (UNITS["zeta"], "fixed strategies: upper end of the reduced basin in zeta^-"),
}


def _reduced_walk_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from ..resilience.strategy import from_parameters
    from ..resilience.uncertainty import controlled_sample, fixed_sample

    s = from_parameters(p)
    mu = walker.gait.mu if p.get("mu") is None else float(p["mu"])
    eps = float(p["min_vertical_force"])
    if s.kind == "control":
        model = _nominal(walker, p)
        real, _ = realized_strategy(model, {**p, "_nominal": None}, int(p["points"]))
        res = controlled_sample(walker.zd, real.planner, real.zeta_ref, s.knots, real.driven,
                                mu=mu, eps=eps)
    else:
        res = fixed_sample(walker.zd, s, mu=mu, eps=eps, points=int(p["points"]))
    doc = {"strategy": s.label, "walks": res.success, "reason": res.reason,
           "robot_parameters": dict(walker.robot.parameters),
           "basin": None if res.basin is None else res.basin.document(), **res.fields()}
    return PointResult(doc, res.fields())


def _prepare_trials(walker: Walker, settings: dict) -> None:
    """Compile the simulation kernel once here, not in every worker at the same time."""
    from .compile import compile_kernel

    compile_kernel()


STUDIES: dict[str, SweepStudy] = {
    "limit-cycle": SweepStudy("limit-cycle", _LC_FIELDS, _limit_cycle_point,
                              check=_check_case),
    "feasibility": SweepStudy("feasibility", _FE_FIELDS, _feasibility_point,
                              check=_check_case),
    "simulate": SweepStudy("simulate", _SIM_FIELDS, _simulate_point, check=_check_simulate,
                           prepare=_prepare_simulate),
    "push-trial": SweepStudy("push-trial", _PT_FIELDS, _push_trial_point,
                             check=_check_push_trial, prepare=_prepare_trials),
    "reduced-walk": SweepStudy("reduced-walk", _RW_FIELDS, _reduced_walk_point,
                               check=check_strategy),
    "design-gait": SweepStudy("design-gait", _DG_FIELDS, _design_point, uses_gait=False,
                              check=_check_design, continuation=True),
}


STEPS_PER_CHUNK = 320  # trial_chunk: simulated steps per task at most (32 ten-step trials)


def trial_chunk(todo: int, workers: int, steps: int) -> int:
    """Trials per engine task for ``todo`` trials of ``steps`` steps on ``workers`` workers:
    :func:`~thrustwalk_cli.sweep.runner.chunk_size`, i.e. ``ceil(todo / (8 workers))`` (at
    least 8 tasks per worker when there are that many trials: balance and progress), at most
    ``STEPS_PER_CHUNK // steps`` trials (320 simulated steps: 32 trials of 10 steps, tens of
    milliseconds of work against the engine's 1-2 ms per task) and at least 1."""
    return chunk_size(todo, workers, most=max(1, STEPS_PER_CHUNK // max(1, int(steps))))


# ------------------------------------------------------------------------- worker side
_CACHE: OrderedDict = OrderedDict()  # this process's robots and walkers (a few, LRU)
CACHE_SIZE = 8


def _cached(key: tuple, make: Callable[[], object]) -> object:
    if key in _CACHE:
        _CACHE.move_to_end(key)
        return _CACHE[key]
    value = make()
    _CACHE[key] = value
    if len(_CACHE) > CACHE_SIZE:
        _CACHE.popitem(last=False)
    return value


def _fresh(key: tuple, valid: Callable[[object], bool], make: Callable[[], object]) -> object:
    """:func:`_cached` for values made from objects of this cache (keyed by their ``id``):
    a value whose objects were evicted and replaced (``valid`` false) is made again."""
    if key in _CACHE and valid(_CACHE[key]):
        _CACHE.move_to_end(key)
        return _CACHE[key]
    _CACHE.pop(key, None)
    return _cached(key, make)


def point_robot(task: PointTask) -> Robot:
    """The robot of one point: the base robot file with the point's ``robot.NAME`` values
    substituted for its named parameters, exactly as if edited into the file. The one place a
    sweep turns robot parameters into a robot; its model comes from
    :func:`~thrustwalk_cli.model.compiler.load_model`, which binds the robot's numbers to the
    model compiled once for the robot's structure (no compile per parameter value)."""
    return load_robot_text(task.robot_text, task.robot_file, task.overrides("robot"))


def point_model(task: PointTask) -> CompiledModel:
    """The compiled model of the point's robot (kept per process): the model of the base
    robot's structure with the point's numbers bound (compiled once for every value)."""
    key = ("model", task.robot_text, task.robot_file,
           tuple(sorted(task.overrides("robot").items())))
    return _cached(key, lambda: load_model(point_robot(task)))


def point_walker(task: PointTask) -> Walker:
    """The point's robot with the base gait (``gait.NAME`` values substituted), its model
    and zero dynamics (kept per process: points that differ only in study parameters share
    it)."""
    key = ("walker", task.robot_text, task.robot_file,
           tuple(sorted(task.overrides("robot").items())), task.gait_text, task.gait_file,
           tuple(sorted(task.overrides("gait").items())))

    def make() -> Walker:
        robot = point_robot(task)
        gait, source = load_gait_text(task.gait_text, task.gait_file, task.overrides("gait"))
        return assemble_walker(robot, gait, source)

    return _cached(key, make)


def _nominal_of(task: PointTask) -> Callable[[], Walker]:
    """The walker of the base robot with the point's gait (a controller's model when the
    point's robot differs: the plant)."""
    base = replace(task, values=tuple((k, v) for k, v in task.values
                                      if not k.startswith("robot.")))
    return lambda: point_walker(base)


def run_point(task: PointTask) -> dict:
    """Compute one point (the task every worker runs) and return its record: ``key``,
    ``index``, ``values``, ``status`` (``ok`` or ``failed``), ``reason``, ``fields``,
    ``document`` (the study's JSON), ``extra``, ``next_start`` and ``seconds`` (wall time
    of the point [s]). Never raises for the point's own problems: they are its result."""
    t0 = time.perf_counter()
    study = STUDIES[task.study]
    doc, fields, extra, nxt = None, {}, {}, task.start
    try:
        if task.version != __version__:
            raise ComputationError(f"this worker runs thrustwalk {__version__}, the sweep "
                                   f"{task.version}")
        base = point_walker(task) if study.uses_gait else point_model(task)
        params = task.parameters
        params.update(_label=task.label, _robot_ref=task.robot_ref, _gait_name=task.name,
                      _nominal=_nominal_of(task) if task.overrides("robot") else None)
        res = study.point(base, params, task.start)
        doc = jsonable(res.document)
        fields = jsonable({k: res.fields.get(k) for k in study.fields})
        extra, nxt = res.extra, jsonable(res.next_start)
        status, reason = "ok", ""
    except InputError as exc:
        status, reason = "failed", "; ".join(str(p) for p in exc.problems)
    except ComputationError as exc:
        status, reason = "failed", f"computation failed: {exc}"
    except Exception as exc:  # noqa: BLE001 - a point's failure never stops the sweep
        status, reason = "failed", f"computation failed ({type(exc).__name__}: {exc})"
    if status != "ok":
        doc, fields, extra = None, dict.fromkeys(study.fields), {}
    return {"key": task.key, "index": task.index, "study": task.study,
            "values": dict(task.values), "status": status, "reason": reason,
            "fields": fields, "document": doc, "extra": extra, "next_start": nxt,
            "seconds": time.perf_counter() - t0}
