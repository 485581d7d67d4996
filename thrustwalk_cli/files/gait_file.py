"""Gait files: the gait schema table, loading a :class:`Gait`, checking it against its robot
and locating problems found later (``file:line: key.path``) (SPEC 2, 4).

A gait file is parsed once: :func:`load_gait` returns the gait as written and a
:class:`GaitSource` that keeps the line numbers, so that checks done after loading (the
coordinates against the robot, a thrust schedule against the zero dynamics) point at the line.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..description.gait import Gait
from ..description.robot import Robot
from ..errors import InputError, Problem, Where
from ..thrust.schedule import WrittenSchedule
from .bundled import resolve
from .schema import (
    boolean,
    check,
    choice,
    dict_of,
    expect_kind,
    field,
    kind_check,
    list_of,
    mapping,
    null_or,
    number,
    override_parameters,
    parameters,
    string,
    vector,
)
from .yamlio import format_path, load_yaml, load_yaml_text

# ------------------------------------------------------------------------------ gait schema
MAX_BEZIER_ORDER = 20  # columns M + 1 <= 21; design-gait itself stays at 3..12
MAX_KNOTS = 256  # thrust-schedule intervals

GAIT_SCHEMA = mapping(
    field("name", string(), "gait name"),
    field("description", string(nonempty=False), "free text (how the gait was made)",
          default=""),
    field("robot", string(), "bundled robot name or path relative to this file"),
    field("parameters", parameters(), "named numbers usable in numeric fields", default={}),
    field("alpha", mapping(
        field("c", dict_of(number("1"), key_name="coordinate"), "alpha = c q: coefficient "
              "per coordinate name (missing = 0); must involve q_N"),
        field("final", number("rad"), "alpha_f, the value of alpha just before impact"),
    ), "gait-timing variable; alpha_i follows from the relabelling: c (R q- + b)"),
    field("bezier", mapping(
        field("invariance", choice("auto", "given"), "auto: columns 0 and 1 are computed for "
              "hybrid invariance (write them as ~); given: all columns as written",
              default="auto"),
        field("coefficients", dict_of(list_of(null_or(number("rad")), min_len=4,
                                              max_len=MAX_BEZIER_ORDER + 1),
                                      key_name="coordinate"),
              "one row of M+1 values per actuated coordinate: column 0 at s = 0 (after "
              "impact) ... column M at s = 1 (before impact)"),
    ), "Bezier virtual constraints h_d(s), s = (alpha - alpha_i)/(alpha_f - alpha_i)"),
    field("controller", mapping(
        field("kp", number("1/s^2", gt=0), "output PD gain Kp", default=400.0),
        field("kd", number("1/s", gt=0), "output PD gain Kd", default=40.0),
    ), "y'' = -Kp y - Kd y' (full-order simulation)", default={}),
    field("mu", number("1", gt=0), "friction coefficient for feasibility checks", default=0.7),
    field("thrust", null_or(mapping(
        field("mode", choice("force", "generalized"), "force: newtons per thruster; "
              "generalized: T_j on q_N in N m", default="force"),
        field("knots", vector(min_len=2, max_len=MAX_KNOTS + 1),
              "knots as fractions of the step (0 ... 1) or alpha values (see `fractions`)"),
        field("fractions", boolean(), "knots are fractions of the step", default=True),
        field("values", dict_of(vector(unit="N or N m", max_len=MAX_KNOTS),
                                key_name="thruster"),
              "per thruster (force mode) or `T` (generalized mode): one value per interval"),
    )), "optional piecewise-constant thrust schedule (SPEC 4)", default=None),
)


# ------------------------------------------------------------------------------ gaits
class GaitSource:
    """Validated gait data kept for checks against the robot (line numbers included).

    :meth:`where` (``res.problem``) builds a ``file:line: key.path`` problem for later checks.
    """

    def __init__(self, res, rows: dict, c: dict):
        self.res, self.rows, self.c = res, rows, c

    def where(self, key: tuple, message: str) -> Problem:
        """A problem at key path ``key`` of this gait file (a :data:`Where`)."""
        return self.res.problem(key, message)


def load_gait(ref: str, parameters: Mapping[str, float] | None = None
              ) -> tuple[Gait, GaitSource]:
    """Read and validate a gait file (a path or a bundled name). Returns the gait (``c`` and
    ``A`` empty until :func:`bind_gait` checks it against its robot) and its validated data.
    The gait's ``robot`` is resolved relative to the gait file. ``parameters``: numbers
    replacing the file's named ``parameters:``, as if edited into the file."""
    path = resolve(ref, "gaits")
    return parse_gait(load_yaml(path, expect=kind_check("gait", GAIT_SCHEMA)), path, parameters)


def load_gait_text(text: str, file: str, parameters: Mapping[str, float] | None = None
                   ) -> tuple[Gait, GaitSource]:
    """:func:`load_gait` for YAML text that is not (yet) a file; ``file`` names it in
    messages and anchors a relative ``robot:`` path."""
    return parse_gait(load_yaml_text(text, file, expect=kind_check("gait", GAIT_SCHEMA)),
                      Path(file), parameters)


def anchor_robot_ref(ref: str, gait_file: Path) -> str:
    """A gait file's ``robot:`` reference as seen from the working folder: a relative path is
    relative to the gait file's folder, always (never to the working folder); when that folder
    does not exist yet (a gait about to be written) the path is normalised lexically
    (``gaits/../walker5.yaml`` -> ``walker5.yaml``), otherwise the operating system resolves
    ``..`` (symbolic links included). A bundled robot name (no ``/``, no ``.yaml`` ending) stays
    a name unless a file of that name lies beside the gait file. Absolute paths are kept."""
    rp = Path(ref)
    if rp.is_absolute():
        return ref
    folder = Path(gait_file).parent
    if "/" not in ref and not ref.endswith((".yaml", ".yml")) and not (folder / rp).is_file():
        return ref
    if folder.is_dir():
        return str(folder / rp)
    return os.path.normpath(folder / rp)


def parse_gait(doc, path: Path, parameters: Mapping[str, float] | None = None
               ) -> tuple[Gait, GaitSource]:
    """Validate a parsed gait document (with ``parameters`` replaced, see :func:`load_gait`)
    against ``GAIT_SCHEMA`` (every problem at once)."""
    doc = override_parameters(doc, parameters)
    expect_kind(doc, "gait", GAIT_SCHEMA)
    res = check(doc, GAIT_SCHEMA)
    res.raise_if_problems()
    d = res.data
    robot_ref = anchor_robot_ref(d["robot"], path)
    sched = None
    if d["thrust"] is not None:
        t = d["thrust"]
        vals = t["values"]
        sched = WrittenSchedule(tuple(t["knots"]), tuple((k, tuple(v)) for k, v in vals.items()),
                               t["mode"], t["fractions"])
    rows = d["bezier"]["coefficients"]
    gait = Gait(
        name=d["name"], robot=robot_ref, c=(), alpha_f=d["alpha"]["final"], A=(),
        invariance=d["bezier"]["invariance"], kp=d["controller"]["kp"],
        kd=d["controller"]["kd"], mu=d["mu"], thrust=sched, source_file=str(path),
        source_sha256=doc.sha256,
        given_A=tuple(tuple(r) for r in rows.values()),
    )
    return gait, GaitSource(res, rows, d["alpha"]["c"])


def gait_file_where(ref: str) -> Where:
    """Locate problems in the gait-format file ``ref`` (``file:line: key.path``) without
    keeping it open: the file is read again only when a problem is reported; if it cannot be
    read, the problem names the file and key path without a line."""
    def where(key: tuple, message: str) -> Problem:
        try:
            return load_gait(ref)[1].where(key, message)
        except InputError:
            return Problem(ref, None, format_path(key), message)
    return where


def same_robot_file(robot: Robot, ref: str) -> bool:
    """Whether the reference ``ref`` names the file ``robot`` was read from (no parsing).
    ``ref`` is a gait's ``robot`` as loaded (:func:`anchor_robot_ref`: a relative path is
    already relative to the working folder, having been anchored at the gait file's folder)."""
    try:
        return resolve(ref, "robots").resolve() == Path(robot.source_file).resolve()
    except (InputError, OSError):
        return False


def bind_gait(gait: Gait, source: GaitSource, robot: Robot) -> Gait:
    """Check a gait against its robot (coordinate names, one Bezier row per actuated
    coordinate, equal row lengths, ``~`` only where ``invariance: auto`` computes the value)
    and return it with ``c`` and ``A`` as arrays in the robot's coordinate order (columns 0
    and 1 are 0 until hybrid invariance is applied, SPEC 2). Every problem names the gait
    file's line and key path."""
    res = source.res
    problems: list[Problem] = []
    act = [c.name for c in robot.coordinates if c.actuated]
    names = robot.coordinate_names
    for k in source.c:
        if k not in names:
            problems.append(res.problem(("alpha", "c", k), f"unknown coordinate '{k}' "
                                        f"(robot {robot.name} has: {', '.join(names)})"))
    c = np.array([source.c.get(nm, 0.0) for nm in names], float)
    if not abs(c[-1]) > 1e-9 * max(1.0, float(np.abs(c).max())):
        problems.append(res.problem(("alpha", "c"), f"alpha must depend on the unactuated "
                                    f"coordinate '{names[-1]}' (H = [H_0; c] is singular)"))
    for k in source.rows:
        if k not in act:
            problems.append(res.problem(("bezier", "coefficients", k),
                                        f"unknown actuated coordinate '{k}' (expected: "
                                        f"{', '.join(act)})"))
    for k in act:
        if k not in source.rows:
            problems.append(res.problem(("bezier", "coefficients"),
                                        f"missing row for actuated coordinate '{k}'"))
    if problems:
        raise InputError(problems)
    rows = [source.rows[k] for k in act]
    lens = {len(r) for r in rows}
    if len(lens) != 1:
        raise InputError(res.problem(("bezier", "coefficients"),
                                     "all rows need the same number of columns (M + 1)"))
    auto = gait.invariance == "auto"
    for k, r in zip(act, rows):
        for j, v in enumerate(r):
            if v is None and not (auto and j < 2):
                problems.append(res.problem(("bezier", "coefficients", k, j),
                                            "missing value (only columns 0 and 1 may be ~, "
                                            "and only with invariance: auto)"))
            if v is not None and auto and j < 2:
                problems.append(res.problem(("bezier", "coefficients", k, j),
                                            "with invariance: auto, columns 0 and 1 are "
                                            "computed: write ~"))
    if problems:
        raise InputError(problems)
    A = tuple(tuple(0.0 if v is None else float(v) for v in r) for r in rows)
    return replace(gait, c=tuple(c.tolist()), A=A, robot=robot.name)


# --- writing -----------------------------------------------------------------------------

def number_text(v: float) -> str:
    """A number as a gait file writes it: an integer without a decimal point, otherwise the
    shortest text that reads back as the same float (``repr``)."""
    v = float(v)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def text_scalar(s: str) -> str:
    """``s`` as a YAML scalar that reads back as the same string: plain when it does, else
    double-quoted (JSON's escaping is YAML's)."""
    import json

    import yaml

    s = str(s)
    try:
        if yaml.safe_load(f"k: {s}") == {"k": s} and "\n" not in s:
            return s
    except yaml.YAMLError:
        pass
    return json.dumps(s)


def _seq(values) -> str:
    return "[" + ", ".join("~" if v is None else number_text(v) for v in values) + "]"


def gait_text(gait: Gait, robot: Robot, *, robot_ref: str, description: str,
              mu: float | None = None, invariance: str = "given",
              header: list[str] | tuple[str, ...] = (),
              thrust: tuple[str, list[float], Mapping[str, list[float]], str] | None = None,
              thrust_comment: str = "") -> str:
    """``gait`` as a gait file (the schema of :data:`GAIT_SCHEMA`), the one writer of gait
    files (design-gait, optimize, the gait-library sweep).

    ``robot_ref``: how the file names its robot (:func:`robot_reference`); ``header``: lines
    written as ``#`` comments; ``invariance``: ``"given"`` writes every Bezier column,
    ``"auto"`` writes columns 0 and 1 as ``~`` (recomputed for hybrid invariance on loading,
    SPEC 4); ``mu``: the friction coefficient (default the gait's); ``thrust``: ``(mode,
    knots as fractions of the step, {key: one value per interval}, unit)`` written as the
    file's ``thrust:`` section, or None for none. Numbers are written so that they read back
    bit for bit (:func:`number_text`)."""
    if invariance not in ("given", "auto"):
        raise ValueError(f"invariance is 'given' or 'auto', not {invariance!r}")
    names = robot.coordinate_names
    act = [c.name for c in robot.coordinates if c.actuated]
    c_map = ", ".join(f"{nm}: {number_text(v)}" for nm, v in zip(names, gait.c) if v != 0.0)
    lines = [f"# {line}" for h in header for line in str(h).splitlines() or [""]]
    lines += [f"name: {text_scalar(gait.name)}", f"description: {text_scalar(description)}",
              f"robot: {text_scalar(robot_ref)}",
              "parameters:",
              f"  af: {number_text(gait.alpha_f)}   # [rad] alpha_f = c q^-, the value of "
              "alpha at impact",
              "alpha:", f"  c: {{{c_map}}}   # alpha = c q [rad]", "  final: af",
              "bezier:", f"  invariance: {invariance}",
              "  coefficients:   # [rad]; column k at s = k/M, s = 0 after impact, "
              "s = 1 before impact"]
    for nm, row in zip(act, gait.A):
        row = [float(v) for v in row]
        lines.append(f"    {nm}: " + _seq([None, None, *row[2:]] if invariance == "auto"
                                           else row))
    lines += ["controller:", f"  kp: {number_text(gait.kp)}   # [1/s^2]",
              f"  kd: {number_text(gait.kd)}   # [1/s]",
              f"mu: {number_text(gait.mu if mu is None else mu)}"]
    if thrust is not None:
        mode, knots, values, unit = thrust
        lines += ["thrust:" + (f"   # {thrust_comment}" if thrust_comment else ""),
                  f"  mode: {mode}", f"  knots: {_seq(knots)}   # fractions of the step",
                  "  fractions: true", "  values:"]
        lines += [f"    {text_scalar(key)}: {_seq(v)}   # [{unit}] one value per interval"
                  for key, v in values.items()]
    return "\n".join(lines) + "\n"


def robot_reference(robot: Robot, given: str | None = None, out: Path | None = None) -> str:
    """How a gait file names its robot. With ``given`` (the robot as the user named it) and
    ``out`` (the gait file's path): the bundled name when it was given by name, otherwise the
    robot file's path relative to the gait file's folder. Without them: the bundled name when
    the robot is the bundled one of that name, otherwise the robot file's absolute path."""
    if given is not None and out is not None:
        p = Path(given)
        if not p.is_file() and "/" not in given and not given.endswith((".yaml", ".yml")):
            return given
        return os.path.relpath(Path(robot.source_file).resolve(), Path(out).resolve().parent)
    if not robot.source_file:
        return robot.name
    try:
        bundled = resolve(robot.name, "robots").resolve() == Path(robot.source_file).resolve()
    except InputError:
        bundled = False
    return robot.name if bundled else str(Path(robot.source_file).resolve())
