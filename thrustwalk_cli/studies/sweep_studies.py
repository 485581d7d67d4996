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
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from .._version import __version__
from ..description.robot import Robot
from ..errors import ComputationError, InputError, param_problem
from ..files.output import jsonable
from ..model.compiled import CompiledModel
from ..sweep.tasks import PointTask
from ..thrust.schedule import WrittenSchedule
from ..walker import Walker
from .documents import UNITS
from .sweep_points import PointResult, SweepStudy, nominal_of, point_model, point_walker
from .trial_studies import TRIAL_STUDIES


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


def _slope(p: Mapping) -> float:
    """The point's ground angle [rad] (SPEC 14; a level-ground point has none: 0)."""
    return float(p.get("slope") or 0.0)


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
                      mu=p.get("mu"), min_vertical_force=p.get("min_vertical_force", 0.0),
                      slope=_slope(p))
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
                      min_vertical_force=p["min_vertical_force"], region_shape=(11, 11),
                      slope=_slope(p))
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
                   samples=2, slope=_slope(p))
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
    res = design_gait(model, spec, initial=initial, slope=_slope(p))
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
        if _slope(p) != 0.0:
            header.insert(1, f"Designed for the slope {_slope(p)!r} rad (positive uphill; "
                             f"SPEC 14): speed and step length along the ground, climb rate "
                             f"{o['climb_rate']:.4g} m/s.")
        elif "slope" in p:  # a level point of a library over slopes says so too
            header.insert(1, "Designed for level ground (slope 0 rad).")
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


STUDIES: dict[str, SweepStudy] = {
    "limit-cycle": SweepStudy("limit-cycle", _LC_FIELDS, _limit_cycle_point,
                              check=_check_case),
    "feasibility": SweepStudy("feasibility", _FE_FIELDS, _feasibility_point,
                              check=_check_case),
    "simulate": SweepStudy("simulate", _SIM_FIELDS, _simulate_point, check=_check_simulate,
                           prepare=_prepare_simulate),
    **TRIAL_STUDIES,
    "design-gait": SweepStudy("design-gait", _DG_FIELDS, _design_point, uses_gait=False,
                              check=_check_design, continuation=True, verdict="feasible"),
}




def _failure(exc: Exception) -> str:
    """A point's failure as its record's ``reason``."""
    if isinstance(exc, InputError):
        return "; ".join(str(p) for p in exc.problems)
    if isinstance(exc, ComputationError):
        return f"computation failed: {exc}"
    return f"computation failed ({type(exc).__name__}: {exc})"


def _compute(task: PointTask) -> tuple[PointResult | None, str]:
    """The study's result of one point (its ``pending`` part not yet finished), or None and
    the reason it failed."""
    study = STUDIES[task.study]
    try:
        if task.version != __version__:
            raise ComputationError(f"this worker runs thrustwalk {__version__}, the sweep "
                                   f"{task.version}")
        base = point_walker(task) if study.uses_gait else point_model(task)
        params = task.parameters
        params.update(_label=task.label, _robot_ref=task.robot_ref, _gait_name=task.name,
                      _nominal=nominal_of(task) if task.overrides("robot") else None)
        return study.point(base, params, task.start), ""
    except Exception as exc:  # noqa: BLE001 - a point's failure never stops the sweep
        return None, _failure(exc)


def _finish(study: SweepStudy, results: list[PointResult | None]
            ) -> list[tuple[PointResult | None, str]]:
    """``study.finish`` on the points computed (together; should that raise, point by point,
    so that only a point whose own part fails is failed)."""
    done: list[tuple[PointResult | None, str]] = [(r, "") for r in results]
    todo = [i for i, r in enumerate(results) if r is not None]
    if study.finish is None or not todo:
        return done
    try:
        for i, r in zip(todo, study.finish([results[i] for i in todo])):
            done[i] = (r, "")
    except Exception:  # noqa: BLE001 - find the point that fails, alone
        for i in todo:
            try:
                done[i] = (study.finish([results[i]])[0], "")
            except Exception as exc:  # noqa: BLE001
                done[i] = (None, _failure(exc))
    return done


def _record(task: PointTask, res: PointResult | None, reason: str, seconds: float) -> dict:
    study = STUDIES[task.study]
    doc, fields, extra, nxt = None, dict.fromkeys(study.fields), {}, task.start
    status = "failed"
    if res is not None:
        try:
            doc = jsonable(res.document)
            fields = jsonable({k: res.fields.get(k) for k in study.fields})
            extra, nxt = res.extra, jsonable(res.next_start)
            status = "ok"
            if isinstance(doc, dict) and doc.get(study.verdict) is False:  # computed, says no
                reason = str(doc.get("reason") or "")  # (not walkable, fell, infeasible)
        except Exception as exc:  # noqa: BLE001
            doc, fields, extra, nxt = None, dict.fromkeys(study.fields), {}, task.start
            reason = _failure(exc)
    return {"key": task.key, "index": task.index, "study": task.study,
            "values": dict(task.values), "status": status, "reason": reason,
            "fields": fields, "document": doc, "extra": extra, "next_start": nxt,
            "seconds": seconds}


def run_point(task: PointTask) -> dict:
    """Compute one point (the task every worker runs) and return its record: ``key``,
    ``index``, ``values``, ``status`` (``ok`` or ``failed``), ``reason``, ``fields``,
    ``document`` (the study's JSON), ``extra``, ``next_start`` and ``seconds`` (wall time
    of the point [s]). Never raises for the point's own problems: they are its result."""
    return run_points([task])[0]


def run_points(tasks: list[PointTask]) -> list[dict]:
    """The records of several points (a chunk of one engine task, in order), each the same as
    :func:`run_point`'s: the points are computed one by one, then a study's ``finish``
    completes its points together (e.g. the push trials' energies in a few batched calls;
    ``seconds``: the point's own time and its share of the batch)."""
    out: list[tuple[PointResult | None, str]] = []
    secs: list[float] = []
    for task in tasks:
        t0 = time.perf_counter()
        out.append(_compute(task))
        secs.append(time.perf_counter() - t0)
    for name in dict.fromkeys(t.study for t in tasks):
        idx = [i for i, t in enumerate(tasks) if t.study == name]
        t0 = time.perf_counter()
        fin = _finish(STUDIES[name], [out[i][0] for i in idx])
        share = (time.perf_counter() - t0) / len(idx)
        for i, (r, why) in zip(idx, fin):
            out[i] = (r, why or out[i][1])
            secs[i] += share
    return [_record(t, r, why, s) for t, (r, why), s in zip(tasks, out, secs)]
