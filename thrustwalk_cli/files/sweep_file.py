"""Sweep files: the sweep schema table (one parameter table per study) and loading a
:class:`SweepSpec`.

A sweep file names a study, the base robot and gait, the study's fixed ``settings``, the axes
(``grid``, ``zip``, ``random``) and the result fields to ``collect``. Every problem is reported
as ``file:line: key.path: message`` (all of them, not only the first); the key tables of
``docs/files.md`` are generated from ``sweep_schema`` and ``STUDY_PARAMETERS``. Checks that
need the robot, the gait or the study's result fields are made by the sweep study, at the
lines kept by :class:`SweepSource`.

One idea in one file: the sweep-file format, whose keys are the study parameter tables (every
study's settings and sweepable axes, read and checked by the same loader); split, the format
and its keys would live apart.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..description.sweep import DISTRIBUTIONS, Axis, SweepSpec, range_count, range_values
from ..errors import InputError, Problem, param_problem
from ..thrust.dynamics import ALIASES, model_names
from .bundled import EXPLICITLY, resolve, resolve_inside
from .schema import (
    Kind,
    ValidationResult,
    boolean,
    check,
    choice,
    dict_of,
    expect_kind,
    field,
    integer,
    kind_check,
    list_of,
    mapping,
    null_or,
    number,
    string,
    suggest,
    vector,
)
from .yamlio import load_yaml

MAX_POINTS = 100_000  # points in one sweep
MAX_AXIS_VALUES = 10_000  # values of one axis (as every value-list option)
MAX_KNOTS = 256  # intervals of a thrust schedule (as in a gait file)

# ------------------------------------------------------------------------- study parameters
# One table per study: every parameter a sweep may hold fixed in `settings` (defaults filled
# in) or sweep as an axis (the numeric ones). A new study adds its table here and its point
# function to the registry of thrustwalk_cli.studies.sweep_studies.
_THRUSTER = field("thruster", null_or(string()), "thruster driven by `thrust` and by a force-mode "
                  "`schedule` (default: the first)", default=None)
_SCHEDULE = field("schedule", null_or(mapping(
    field("knots", vector(min_len=2, max_len=MAX_KNOTS + 1, ge=0, le=1), "knots as fractions "
          "of the step, 0 first and 1 last, strictly increasing"),
    field("values", vector(min_len=1, max_len=MAX_KNOTS), "one value per interval between the "
          "knots [N] (force mode, on `thruster`; within its limits) or [N m] (generalized "
          "mode); axis `schedule.j` sweeps interval j (1 = the first)"),
    field("mode", choice("force", "generalized"), "force: thrust [N] of `thruster`; "
          "generalized: T_j on q_N [N m]", default="force"),
)), "piecewise-constant thrust on knots (SPEC 4), analysed instead of a constant `thrust`",
    default=None)
_MU = field("mu", null_or(number("1", gt=0)), "friction coefficient (default: the gait's)",
            default=None)

# the thrust strategy of a push trial or a reduced walk (SPEC 4, 11, 12)
_STRATEGY = (
    field("strategy", choice("none", "constant", "schedule", "control"), "none (no thrust), "
          "constant (`thrust` on `thruster`; no value: the gait's thrust: section, else 0), "
          "schedule (the `schedule`) or control (the step-to-step controller of thrustwalk "
          "control, regulating to the zero-thrust orbit; with robot axes it keeps the base "
          "robot's model)", default="none"),
    field("strategy_label", null_or(string()), "the strategy's name in outputs (default: "
          "from the strategy)", default=None),
    _THRUSTER,
    field("thrust", null_or(number("N")), "constant thrust of the constant strategy (default: "
          "the gait's thrust: section, else 0)", default=None),
    _SCHEDULE,
    field("knots", vector(min_len=2, max_len=MAX_KNOTS + 1, ge=0, le=1), "control: knots as "
          "fractions of the step, 0 first and 1 last, strictly increasing",
          default=[0.0, 0.5, 1.0]),
    field("max_thrust", null_or(number("N", gt=0)), "control: thrust bound, at most the "
          "thruster's limits", default=None),
    _MU,
    field("min_vertical_force", number("N", ge=0), "least vertical ground force F^v (a step "
          "below it is lifted)", default=0.0),
)

# the ground angle of a point (SPEC 14); a slope of 0 is level ground and is left out of a
# sweep's settings (:func:`keyed`), so the keys of level-ground points do not change
_SLOPE = field("slope", number("rad", gt=-0.5 * math.pi, lt=0.5 * math.pi), "ground angle, "
               "positive uphill (SPEC 14: gravity and world-frame thrusters turned into the "
               "slope frame; speed along the ground); 0: level ground", default=0.0)
LEVEL = {"slope": 0.0, "terrain": None}  # left out of a point's settings at these values


def keyed(settings: dict[str, Any]) -> dict[str, Any]:
    """``settings`` without the parameters at their level-ground value (:data:`LEVEL`): a
    sweep or trial on level ground keeps the settings, keys and identity it had before the
    parameter existed."""
    return {k: v for k, v in settings.items() if not (k in LEVEL and v == LEVEL[k])}


STUDY_PARAMETERS: dict[str, Kind] = {
    "limit-cycle": mapping(
        _THRUSTER,
        field("thrust", null_or(number("N")), "constant thrust (default: the gait's thrust: "
              "schedule when it has one, else 0)", default=None),
        _SCHEDULE,
        _MU,
        field("min_vertical_force", number("N", ge=0), "least vertical ground force F^v of "
              "the contact check (walkable needs it)", default=0.0),
        _SLOPE,
    ),
    "feasibility": mapping(
        _THRUSTER,
        field("thrust", null_or(number("N")), "constant thrust (default: the gait's thrust: "
              "schedule when it has one, else 0)", default=None),
        _SCHEDULE,
        _MU,
        field("min_vertical_force", number("N", ge=0), "least vertical ground force F^v",
              default=0.0),
        _SLOPE,
    ),
    "simulate": mapping(
        _THRUSTER,
        field("thrust", number("N"), "steady thrust F_ss", default=0.0),
        field("thrust_model", choice(*model_names(), "piecewise", *ALIASES),
              "thruster model (piecewise: the `schedule`, else the gait's thrust: section; "
              "constant: the deprecated name of ideal)", default="ideal"),
        _SCHEDULE,
        field("steps", integer("1", ge=1, le=10_000), "steps of the full-order run",
              default=10),
        field("wn", number("rad/s", gt=0, le=1000), "natural frequency of the second-order "
              "thruster (a faster one is the ideal model, and makes the equations stiff)",
              default=2.0),
        field("xi", number("1", gt=0), "damping ratio of the second-order thruster",
              default=1.0),
        field("tau", number("s", ge=0.001), "lag of the first-order thruster (a shorter one is "
              "the ideal model, and makes the equations stiff)", default=0.5),
        field("f0", number("N"), "thrust at t = 0 of the dynamic thruster models",
              default=0.0),
        field("perturb", number("1", gt=-1), "start on the predicted orbit with zeta^- scaled "
              "by 1 + perturb", default=0.0),
        field("kp", null_or(number("1/s^2", gt=0)), "output gain Kp of y'' = -Kp y - Kd y' "
              "(default: the gait's)", default=None),
        field("kd", null_or(number("1/s", gt=0)), "output gain Kd (default: the gait's)",
              default=None),
        _MU,
        field("torque_limit", null_or(number("N m", gt=0)), "joint torque bound (saturation "
              "is reported)", default=None),
        field("method", choice("compiled", "scipy"), "compiled (the numba kernel) or scipy "
              "(solve_ivp, the reference)", default="compiled"),
        field("rtol", number("1", gt=0, lt=0.1), "relative integration tolerance", default=1e-9),
        field("atol", number("1", gt=0, lt=0.1), "absolute integration tolerance", default=1e-9),
        _SLOPE,
    ),
    "push-trial": mapping(
        *_STRATEGY,
        field("push_impulse", number("N s"), "signed size of the push along `push_direction` "
              "(0: no push; at most the robot's mass x 10 m/s)", default=0.0),
        field("push_phase", number("1", ge=0, le=1), "phase s of step 1 at which the push acts "
              "(1: just before the impact)", default=0.5),
        field("push_direction", vector(2), "direction of a positive push in the world frame "
              "(normalised; 1,0: forward)", default=[1.0, 0.0]),
        field("push_link", null_or(string()), "link pushed (default: the stance link, whose "
              "end is the hip)", default=None),
        field("push_at", number("1", ge=0, le=1), "point of the link: (1 - at) joint + at end",
              default=1.0),
        field("push_duration", number("s", ge=0, le=1), "duration for the stance foot's "
              "check of the push (0: impulsive, SPEC 12)", default=0.0),
        field("start_sigma", number("1", gt=-1, le=100), "start off the orbit: sigma_N^+ "
              "scaled by 1 + start_sigma (a basin trial; no push then)", default=0.0),
        field("start_rate", number("rad/s", ge=-1000, le=1000), "start off the orbit: the "
              "post-impact rate of the `transverse` output changed by this, sigma_N kept",
              default=0.0),
        field("transverse", null_or(string()), "actuated coordinate whose output rate "
              "`start_rate` perturbs (default: the first)", default=None),
        field("steps", integer("1", ge=1, le=1000), "steps of each trial (the pushed one "
              "included)", default=10),
        field("recovery_tol", number("1", gt=0, lt=1), "recovered: the last zeta^- within "
              "this fraction of the orbit's", default=0.05),
        field("output_tol", number("rad", gt=0), "recovered: max |y| over the last step at "
              "most this", default=1e-3),
        field("rtol", number("1", gt=0, lt=0.1), "relative integration tolerance",
              default=1e-9),
        field("atol", number("1", gt=0, lt=0.1), "absolute integration tolerance", default=1e-9),
        _SLOPE,
        field("terrain", null_or(mapping(
            field("heights", vector(unit="m", min_len=1, max_len=1000, ge=-1, le=1),
                  "step k's swing foot lands heights[k-1] above its stance foot, normal to "
                  "the slope"),
            field("s_max", number("1", gt=1, le=3), "past this s without a touchdown: missed "
                  "footing (the trial fell)", default=1.3))), "the ground the trial walks "
              "(SPEC 14; none: level)", default=None),
    ),
    "rough-trial": mapping(
        *_STRATEGY,
        field("sigma", number("m", ge=0, le=1), "standard deviation of the step heights "
              "(uniform: half width sqrt(3) sigma)", default=0.005),
        field("distribution", choice("normal", "uniform"), "distribution of the step heights",
              default="normal"),
        field("trial", integer("1", ge=0), "the trial's index: its heights come from "
              "SeedSequence([seed, trial])", default=0),
        field("seed", integer("1", ge=0), "seed of the run's terrains", default=0),
        field("cap", integer("1", ge=1, le=1_000_000), "steps at most (a run that reaches it "
              "is censored)", default=1000),
        field("s_max", number("1", gt=1, le=3), "missed footing past this phase s without a "
              "touchdown", default=1.3),
        field("rtol", number("1", gt=0, lt=0.1), "relative integration tolerance",
              default=1e-9),
        field("atol", number("1", gt=0, lt=0.1), "absolute integration tolerance", default=1e-9),
        _SLOPE,
    ),
    "reduced-walk": mapping(
        *_STRATEGY,
        _SLOPE,
        field("points", integer("1", ge=21, le=10_000), "alpha grid points of the contact "
              "conditions", default=401),
    ),
    "design-gait": mapping(
        field("target_speed", null_or(number("m/s", gt=0, le=20)), "target average speed",
              default=None),
        field("step_length", null_or(number("m", gt=0, le=10)), "target step length",
              default=None),
        _THRUSTER,
        field("thrust", null_or(number("N")), "constant thrust of `thruster` held fixed: the "
              "gait is designed to walk under it (the others at 0)", default=None),
        field("mu", number("1", gt=0, le=10), "friction coefficient", default=0.7),
        field("order", integer("1", ge=3, le=12), "Bezier order M", default=6),
        field("starts", integer("1", ge=1, le=1000), "solver starts per point (with "
              "`continuation`, start 0 is the finished neighbour's gait)", default=1),
        field("seed", integer("1", ge=0), "seed of the random starts", default=0),
        field("max_iter", integer("1", ge=1, le=100_000), "SLSQP iterations per start",
              default=150),
        field("clearance", number("m", ge=0, le=1), "swing-foot height at mid-step",
              default=0.03),
        field("max_delta_sq", number("1", gt=0, lt=1), "upper bound on delta_zero^2",
              default=0.9),
        field("min_vertical_force", null_or(number("N", ge=0)), "eps in F_v >= eps (default "
              "10 % of the weight)", default=None),
        field("min_touchdown_velocity", number("m/s", ge=0), "least downward swing-foot "
              "velocity at touchdown", default=0.05),
        field("objective", choice("effort", "peak"), "effort (1/L) int |u|^2 dt [N^2 m s] or "
              "peak max |u| [N m]", default="effort"),
        field("continuation", boolean(), "start each design from its finished neighbour along "
              "the last grid axis (the first grid axis links the chains)", default=True),
        _SLOPE,
    ),
}
STUDIES = tuple(STUDY_PARAMETERS)
WITHOUT_GAIT = ("design-gait",)  # studies that design the gait instead of reading one


def sweepable(study: str) -> dict[str, str]:
    """The numeric parameters of ``study`` that an axis may sweep, with their units."""
    out = {}
    for f in STUDY_PARAMETERS[study].fields:
        kind = f.kind.item if f.kind.tag == "null_or" else f.kind
        if kind is not None and kind.tag in ("number", "integer"):
            out[f.key] = kind.unit
    return out


# ------------------------------------------------------------------------------ sweep schema
_UNIT = field("unit", null_or(string()), "unit of a `robot.NAME` or `gait.NAME` axis (for the "
              "column names and labels; a study parameter has its own)", default=None)
AXIS = mapping(
    field("values", null_or(vector(min_len=1, max_len=MAX_AXIS_VALUES)), "the values, in sweep "
          "order", default=None),
    field("start", null_or(number()), "first value of a range", default=None),
    field("stop", null_or(number()), "last value of a range (included when a whole number of "
          "steps reaches it)", default=None),
    field("step", null_or(number()), "spacing of a range, signed from start to stop",
          default=None),
    field("num", null_or(integer(ge=1, le=MAX_AXIS_VALUES)), "number of evenly spaced values "
          "from start to stop, both included (instead of `step`)", default=None),
    _UNIT,
)
RANDOM_AXIS = mapping(
    field("distribution", choice(*DISTRIBUTIONS), "uniform on [low, high], log-uniform on "
          "[low, high] (low > 0), or normal(mean, std)"),
    field("low", null_or(number()), "lower end (uniform, log-uniform)", default=None),
    field("high", null_or(number()), "upper end (uniform, log-uniform)", default=None),
    field("mean", null_or(number()), "mean (normal)", default=None),
    field("std", null_or(number(gt=0)), "standard deviation (normal)", default=None),
    _UNIT,
)


def sweep_schema(parameters: Kind | None = None) -> Kind:
    """The sweep file's keys; ``parameters``: the ``settings`` table of the chosen study
    (None: a map of parameter -> value, documented per study)."""
    settings = parameters if parameters is not None else mapping()
    return mapping(
        field("name", string(), "sweep name (letters, digits, _ and -)"),
        field("description", string(nonempty=False), "free text", default=""),
        field("study", choice(*STUDIES), "the study run at every point"),
        field("robot", string(), "base robot: bundled name or a path relative to this file "
              "that stays in its folder (absolute paths and paths leaving the folder are "
              "refused: a robot elsewhere is given to the command instead)"),
        field("gait", null_or(string()), "base gait: bundled name or a path relative to this "
              "file that stays in its folder, as `robot`; the gait's own `robot:` must stay "
              "in this folder too (default: the robot's bundled gait; none for design-gait)",
              default=None),
        field("settings", settings, "study parameters held fixed at every point (see the "
              "study's table)", default={}),
        field("grid", dict_of(AXIS, key_name="axis"), "axes combined as a product (the last "
              "varies fastest); an axis is a study parameter, `robot.NAME` or `gait.NAME`",
              default={}),
        field("zip", dict_of(AXIS, key_name="axis"), "axes of equal length varying together "
              "(product with the grid)", default={}),
        field("random", null_or(mapping(
            field("samples", integer("1", ge=1, le=MAX_POINTS), "number of draws"),
            field("seed", integer("1", ge=0), "seed of numpy's default_rng"),
            field("axes", dict_of(RANDOM_AXIS, key_name="axis"), "axes drawn at every sample, "
                  "in file order"),
        )), "seeded random samples (product with the grid and zip)", default=None),
        field("collect", list_of(string(), min_len=1), "result fields for results.csv (the "
              "first is drawn in the heat maps)"),
    )


SWEEP_SCHEMA = sweep_schema()

# --------------------------------------------------------------------------------- loading
_NAME = re.compile(r"[A-Za-z0-9_-]+")
_SCHEDULE_AXIS = re.compile(r"schedule\.(\d+)")


class SweepSource:
    """Validated sweep data kept for the checks made after loading (line numbers included).

    ``root``: the sweep file's folder, inside which the files it names are read;
    ``gait_inside``: the gait is a file the sweep file named (not a bundled gait, not one
    given explicitly), so its own ``robot:`` reference is confined to ``root`` too."""

    def __init__(self, res: ValidationResult, root: Path | None = None,
                 gait_inside: bool = False):
        self.res = res
        self.root = root
        self.gait_inside = gait_inside

    def where(self, key: tuple, message: str) -> Problem:
        """A problem at key path ``key`` of the sweep file (a :data:`~..errors.Where`)."""
        return self.res.problem(key, message)

    def axis_key(self, axis: Axis) -> tuple:
        """The key path of ``axis`` in the file."""
        return ("random", "axes", axis.name) if axis.group == "random" else (axis.group,
                                                                               axis.name)


def _range(a: dict, key: tuple, res: ValidationResult, problems: list[Problem]
           ) -> tuple[float, ...] | None:
    """The values of a grid or zip axis: ``values``, or a range start/stop with step or num."""
    given = [k for k in ("start", "stop", "step", "num") if a[k] is not None]
    if a["values"] is not None:
        if given:
            problems.append(res.problem(key + (given[0],), "give `values` or a range "
                                                          "(start, stop, step or num), not both"))
            return None
        return tuple(a["values"])
    if a["start"] is None or a["stop"] is None or (a["step"] is None) == (a["num"] is None):
        problems.append(res.problem(key, "give `values`, or `start` and `stop` with one of "
                                         "`step` or `num`"))
        return None
    start, stop = a["start"], a["stop"]
    if a["num"] is not None:
        n = a["num"]
        if n == 1 and start != stop:
            problems.append(res.problem(key + ("num",), "one value needs start == stop"))
            return None
        return tuple(float(v) for v in np.linspace(start, stop, n))
    step = a["step"]
    count = range_count(start, stop, step, MAX_AXIS_VALUES)
    if isinstance(count, str):
        many = count.endswith(f"the limit is {MAX_AXIS_VALUES}")
        problems.append(res.problem(key if many else key + ("step",),
                                    count if many or "resolution" in count else
                                    f"{count} (got {step:g})"))
        return None
    return tuple(range_values(start, step, count))


def _random_axis(name: str, a: dict, key: tuple, res: ValidationResult,
                 problems: list[Problem]) -> tuple[float, ...] | None:
    """The distribution's parameters: (low, high) or (mean, std)."""
    dist = a["distribution"]
    need = ("mean", "std") if dist == "normal" else ("low", "high")
    extra = [k for k in ("low", "high", "mean", "std") if k not in need and a[k] is not None]
    if extra:
        problems.append(res.problem(key + (extra[0],), f"not a parameter of the {dist} "
                                    f"distribution (give {' and '.join(need)})"))
    missing = [k for k in need if a[k] is None]
    if missing:
        problems.append(res.problem(key, f"the {dist} distribution needs `{missing[0]}`"))
        return None
    p = tuple(float(a[k]) for k in need)
    if dist != "normal" and not p[0] < p[1]:
        problems.append(res.problem(key + ("high",), f"must be above low ({p[1]:g} <= {p[0]:g})"))
        return None
    if dist == "log-uniform" and not p[0] > 0:
        problems.append(res.problem(key + ("low",), f"must be > 0 for a log-uniform "
                                                    f"distribution, got {p[0]:g}"))
        return None
    return p


def _knot_problems(knots: list[float], key: tuple, res: ValidationResult) -> list[Problem]:
    """Knots as fractions of the step: 0 first, 1 last, strictly increasing."""
    if knots[0] != 0.0 or knots[-1] != 1.0:
        return [res.problem(key, f"knots are fractions of the step: the first must be 0 and the "
                                 f"last 1 (got {knots[0]:g} and {knots[-1]:g})")]
    for i in range(1, len(knots)):
        if not knots[i] > knots[i - 1]:
            return [res.problem(key + (i,), f"knots must increase strictly: knot {i + 1} "
                                            f"({knots[i]:g}) does not follow knot {i} "
                                            f"({knots[i - 1]:g})")]
    return []


def _settings_problems(settings: dict, res: ValidationResult) -> list[Problem]:
    """What the schema cannot say about the settings: the knots of ``schedule`` and of the
    controller (``knots``) in order, and one schedule value per interval between knots."""
    out = []
    sched = settings.get("schedule")
    if sched is not None:
        key = ("settings", "schedule")
        out += _knot_problems(list(sched["knots"]), key + ("knots",), res)
        n = len(sched["knots"]) - 1
        if len(sched["values"]) != n:
            out.append(res.problem(key + ("values",), f"expected {n} value{'s' * (n != 1)} "
                                                      f"(one per interval between {n + 1} "
                                                      f"knots), got {len(sched['values'])}"))
    if settings.get("knots") is not None:
        out += _knot_problems(list(settings["knots"]), ("settings", "knots"), res)
    return out


def value_problem(study: str, name: str, value: float) -> str | None:
    """Why ``value`` is not a value of the study parameter ``name`` (its bounds and, for a
    count, a whole number; from the parameter table), or None. For the values of an axis,
    which the schema reads as plain numbers."""
    for f in STUDY_PARAMETERS[study].fields:
        if f.key != name:
            continue
        kind = f.kind.item if f.kind.tag == "null_or" else f.kind
        if kind is None or kind.tag not in ("number", "integer"):
            return None
        if kind.tag == "integer" and not float(value).is_integer():
            return f"must be a whole number, got {value:g}"
        return kind.bounds.violation(float(value))
    return None


def load_sweep_file(ref: str | Path, robot: str | None = None, gait: str | None = None
                    ) -> tuple[SweepSpec, SweepSource]:
    """Read and validate a sweep file: every key, the axes and their values, the settings
    against the study's parameter table; the robot and gait resolved and read. Raises
    :class:`InputError` with every problem (``file:line: key.path: message``).

    The sweep file's ``robot:`` and ``gait:`` are bundled names or paths inside the sweep
    file's folder (:func:`~.bundled.resolve_inside`: an absolute path or one leaving the folder
    is refused at its line). ``robot`` / ``gait``: files or bundled names given explicitly by
    the caller instead of the file's (a path relative to the working folder, as for every
    command), replacing the file's keys."""
    path = Path(ref)
    doc = load_yaml(path, expect=kind_check("sweep", SWEEP_SCHEMA))
    data = doc.data
    study = data.get("study") if isinstance(data, dict) else None
    table = STUDY_PARAMETERS.get(study) if isinstance(study, str) else None
    if table is None and isinstance(data, dict):  # settings are checked once the study is
        doc = replace(doc, data={k: v for k, v in data.items() if k != "settings"})  # known
    expect_kind(doc, "sweep")
    res = check(doc, sweep_schema(table), parameters_path=None)
    res.raise_if_problems()
    d = res.data
    problems: list[Problem] = []
    if not _NAME.fullmatch(d["name"]):
        problems.append(res.problem(("name",), f"letters, digits, _ and - only (got "
                                               f"{d['name']!r})"))
    study = d["study"]
    settings: dict[str, Any] = dict(d["settings"])
    fixed = data.get("settings") if isinstance(data.get("settings"), dict) else {}
    units = sweepable(study)
    has_schedule = "schedule" in {f.key for f in STUDY_PARAMETERS[study].fields}
    axes: list[Axis] = []
    seen: dict[str, tuple] = {}

    def add(name: str, group: str, a: dict, key: tuple) -> Axis | None:
        if name in seen:
            problems.append(res.problem(key, f"axis '{name}' is also swept at "
                                             f"{'.'.join(map(str, seen[name]))}"))
            return None
        seen[name] = key
        head = name.split(".", 1)[0]
        if head in ("robot", "gait") and "." in name:
            unit = a["unit"] or ""
        else:
            m = _SCHEDULE_AXIS.fullmatch(name)
            if m:
                sched = settings.get("schedule")
                if not has_schedule:
                    problems.append(res.problem(key, f"the {study} study has no thrust schedule"))
                    return None
                if sched is None:
                    problems.append(res.problem(key, "a `schedule.j` axis needs "
                                                     "settings.schedule (its knots and values)"))
                    return None
                n = len(sched["knots"]) - 1
                if not 1 <= int(m.group(1)) <= n:
                    problems.append(res.problem(key, f"the schedule has intervals 1 to {n}"))
                    return None
                unit = "N" if sched["mode"] == "force" else "N m"
            elif name in units:
                unit = units[name]
                if name in fixed:
                    problems.append(res.problem(key, f"'{name}' is swept and also fixed in "
                                                     "settings: remove one"))
            else:
                known = sorted(units) + ["robot.NAME", "gait.NAME"]
                if has_schedule:
                    known.append("schedule.j")
                problems.append(res.problem(key, f"unknown axis '{name}' for the {study} study "
                                                 f"(one of: {', '.join(known)})"
                                                 f"{suggest(name, sorted(units))}"))
                return None
            if a["unit"] is not None and a["unit"] != unit:
                problems.append(res.problem(key + ("unit",), f"'{name}' is in {unit or '1'}: "
                                                             "remove `unit` or write that"))
        return Axis(name, unit, group, ())

    problems += _settings_problems(settings, res)
    for group in ("grid", "zip"):
        for name, a in d[group].items():
            key = (group, name)
            ax = add(name, group, a, key)
            vals = _range(a, key, res, problems)
            if ax is not None and vals is not None:
                axes.append(Axis(ax.name, ax.unit, group, vals))
                bad = next(((v, m) for v in vals if (m := value_problem(study, name, v))), None)
                if bad is not None:
                    problems.append(res.problem(key, f"value {bad[0]:g}: {bad[1]}"))
    zipped = [a for a in axes if a.group == "zip"]
    if len({len(a.values) for a in zipped}) > 1:
        lens = ", ".join(f"{a.name}: {len(a.values)}" for a in zipped)
        problems.append(res.problem(("zip",), f"zipped axes need equal lengths ({lens})"))
    rnd = d["random"]
    if rnd is not None:
        if not rnd["axes"]:
            problems.append(res.problem(("random", "axes"), "no axis to draw"))
        for name, a in rnd["axes"].items():
            key = ("random", "axes", name)
            ax = add(name, "random", a, key)
            par = _random_axis(name, a, key, res, problems)
            if ax is not None and par is not None:
                axes.append(Axis(ax.name, ax.unit, "random", (), a["distribution"], par))
                ends = par if a["distribution"] != "normal" else ()
                bad = next(((v, m) for v in ends if (m := value_problem(study, name, v))), None)
                if bad is not None:  # a normal axis: its draws are checked when drawn
                    problems.append(res.problem(key, f"the range reaches {bad[0]:g}: {bad[1]}"))
    if not axes and not problems:
        problems.append(res.problem(("grid",), "no axis: give at least one of grid, zip or "
                                               "random"))
    for i, name in enumerate(d["collect"]):
        if d["collect"].index(name) != i:
            problems.append(res.problem(("collect", i), f"'{name}' is collected twice"))
    if d["gait"] is not None and study in WITHOUT_GAIT:
        problems.append(res.problem(("gait",), f"the {study} study designs the gait: remove "
                                               "`gait`"))
    if gait is not None and study in WITHOUT_GAIT:
        problems.append(param_problem("gait", f"the {study} study designs the gait: it takes "
                                              "no gait"))
    root = path.parent
    given = {"robot": robot, "gait": gait}
    found: dict[str, Path | None] = {"robot": None, "gait": None}
    how = {"robot": f"{EXPLICITLY} `robot`", "gait": f"{EXPLICITLY} `gait`"}
    for key, kind in (("robot", "robots"), ("gait", "gaits")):
        try:
            if given[key] is not None:
                found[key] = resolve(given[key], kind).resolve()
            elif d[key] is not None:
                found[key] = resolve_inside(d[key], kind, root, how=how[key]).resolve()
        except InputError as exc:
            problems.append(param_problem(key, exc.problems[0].message)
                            if given[key] is not None else
                            res.problem((key,), exc.problems[0].message))
    if problems:
        raise InputError(sorted(problems, key=lambda p: p.line or 0))
    robot_path, gait_path = found["robot"], found["gait"]
    gait_inside = gait is None and gait_path is not None and \
        _within(gait_path, root) and not _bundled_file(gait_path)
    rnd_axes = [a for a in axes if a.group == "random"]
    spec = SweepSpec(
        name=d["name"], study=study, robot=str(robot_path),
        robot_text=read_source(robot_path, "robot"),
        gait=None if gait_path is None else str(gait_path),
        gait_text=None if gait_path is None else read_source(gait_path, "gait"),
        settings=tuple(sorted(keyed(settings).items())), axes=tuple(axes),
        collect=tuple(d["collect"]), samples=rnd["samples"] if rnd_axes else 0,
        seed=rnd["seed"] if rnd_axes else 0, description=d["description"],
        source_file=str(path), source_sha256=doc.sha256)
    if spec.count > MAX_POINTS:
        raise InputError(res.problem(("grid",), f"{spec.count} points: the limit is "
                                                f"{MAX_POINTS}"))
    return spec, SweepSource(res, root, gait_inside)


def _within(p: Path, root: Path) -> bool:
    real, top = Path(os.path.realpath(p)), Path(os.path.realpath(root))
    return real == top or top in real.parents


def _bundled_file(p: Path) -> bool:
    from .bundled import _bundled_dirs

    return any(_within(p, d) for kind in ("robots", "gaits") for d in _bundled_dirs(kind))


def read_source(path: str | Path, kind: str | None = None) -> str:
    """A robot or gait file's text (UTF-8), as :func:`load_yaml` reads it; ``kind``
    (``robot`` or ``gait``): a file of another kind is refused without quoting it."""
    expect = None
    if kind == "robot":
        from .robot_file import ROBOT_SCHEMA

        expect = kind_check("robot", ROBOT_SCHEMA)
    elif kind == "gait":
        from .gait_file import GAIT_SCHEMA

        expect = kind_check("gait", GAIT_SCHEMA)
    return load_yaml(path, expect=expect).text
