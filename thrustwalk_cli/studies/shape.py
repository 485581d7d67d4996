"""The ``shape`` study: center-manifold shaping with piecewise-constant thrust (SPEC 4).

One family of schedules (a pattern sweep, a target, or the gait's schedule; the keyword
arguments of :func:`shape`) -> nominal and shaped limit cycles, the shifts (true and the
paper's one-step value, SPEC 4 erratum), vector fields, and the records rendered from them.
The mathematics lives in :mod:`thrustwalk_cli.hzd.shaping`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import (
    InputError,
    check_callable,
    check_choice,
    check_count,
    check_flag,
    check_instance,
    check_number,
    check_numbers,
    check_text,
)
from ..files import expr
from ..hzd.shaping import (
    DEFAULT_FIELD_K,
    DEFAULT_PATTERN,
    intervals,
    one_step_change,
    solve_knots,
    solve_target_speed,
    solve_target_zeta,
)
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics, limit_cycles
from ..model.slope import check_slope
from ..thrust.schedule import MODES, Schedule, check_knots, knots_alpha, uniform_fractions
from ..walker import Walker, check_walker
from .shape_result import ShapeResult, around


# ---------------------------------------------------------------------------- pattern
def pattern_values(text: str, intervals: int, ks: Sequence[float],
                   where: str = "pattern") -> np.ndarray:
    """Interval values ``P[k, j-1] = pattern(j, k)``, j = 1 .. n-1 [N m or N], shape (K, n-1).

    The pattern is the safe arithmetic of :mod:`thrustwalk_cli.files.expr` (numbers,
    + - * / **, parentheses, sin, cos, sqrt, pi) in the names ``j`` (interval index, 1-based)
    and ``k`` (swept value); never ``eval``. Raises :class:`InputError` naming ``where``.
    """
    try:
        ex = expr.parse(text)
    except expr.ExprError as e:
        raise InputError.param(where, f"{e.message} at column {e.column + 1} of {text!r}"
                               ) from None
    unknown = sorted(ex.names() - {"j", "k"})
    if unknown:
        raise InputError.param(where, f"unknown name {', '.join(map(repr, unknown))} in "
                               f"{text!r}: a pattern may use j (interval 1..n-1) and k (the "
                               "swept value)")
    j = np.arange(1, intervals + 1, dtype=float)[None, :]
    k = np.asarray(ks, float)[:, None]
    try:
        vals = ex.evaluate_array({"j": j, "k": k})
    except expr.ExprError as e:
        raise InputError.param(where, f"{e.message} in {text!r} (j = 1..{intervals}, "
                               f"k = {', '.join(f'{v:g}' for v in ks)})") from None
    return np.broadcast_to(vals, (k.size, intervals)).astype(float) + 0.0  # no -0.0


@dataclass(frozen=True)
class ShapeRequest:
    """Options of ``thrustwalk shape`` as plain values, validated on creation (the keyword
    arguments of :func:`shape`; ``ks`` is its ``k``). Passing one to :func:`shape` as ``req``
    is deprecated (one release): give the keywords.

    knots: fractions of the step (or alpha [rad] with ``alpha_knots``), ``None`` = free;
    ks: swept pattern values; field_k: pattern value of the vector-field figure;
    target_zeta [kg^2 m^4/s^2]; target_speed [m/s].
    """

    knots: tuple[float | None, ...] | None = None
    alpha_knots: bool = False
    n_knots: int = 4
    pattern: str | None = None
    ks: tuple[float, ...] | None = None
    field_k: float | None = None
    mode: str | None = None
    thruster: str | None = None
    target_zeta: float | None = None
    target_speed: float | None = None

    def __post_init__(self) -> None:
        """Every field of the right kind (:class:`InputError` naming it; ``ks`` is ``k``)."""
        if self.knots is not None:
            if isinstance(self.knots, (str, bytes)) or not hasattr(self.knots, "__iter__"):
                raise InputError.param("knots", f"must be a sequence of numbers or None (a "
                                                f"free knot), got {self.knots!r:.40}")
            check_numbers("knots", [k for k in self.knots if k is not None], min_len=0,
                          max_len=MAX_KNOTS + 1)
        check_flag("alpha_knots", self.alpha_knots)
        check_count("n_knots", self.n_knots, ge=2, le=MAX_KNOTS + 1)
        if self.pattern is not None and not isinstance(self.pattern, str):
            raise InputError.param("pattern", f"must be a string (arithmetic in j and k), got "
                                              f"{type(self.pattern).__name__}")
        check_numbers("k", self.ks, optional=True, min_len=0)
        check_number("field_k", self.field_k, optional=True)
        check_choice("mode", self.mode, MODES, optional=True)
        check_text("thruster", self.thruster, optional=True)
        check_number("target_zeta", self.target_zeta, optional=True)
        check_number("target_speed", self.target_speed, optional=True)

    def keywords(self) -> dict:
        """The request as the keyword arguments of :func:`shape` (``ks`` is ``k``)."""
        return {("k" if f == "ks" else f): getattr(self, f)
                for f in self.__dataclass_fields__}


MAX_KNOTS = 256  # knot intervals of a shaped schedule (as in a gait file)


def default_ks() -> tuple[float, ...]:
    """k = 0, 2, ..., 50 (the paper's figure: k from 0 to 50, black lines every 10)."""
    return tuple(float(k) for k in range(0, 51, 2))


def gait_base(walker: Walker) -> Schedule | None:
    """The gait's thrust when it is constant over the whole step (one interval, e.g. a gait
    designed with a constant thrust): patterns are shaped around it. None otherwise."""
    ts = walker.gait.thrust
    if ts is None or len(ts.knots) != 2:
        return None
    sched = ts.resolve(walker.zd, walker.zd.model.robot, walker.where)[0]
    return sched if len(sched.knots) == 2 else None


def resolve(zd: ZeroDynamics, req: ShapeRequest, base: Schedule | None = None
            ) -> tuple[str, str, int | None]:
    """Source, mode and driven thruster of a request; :class:`InputError` on the parameter
    when parameters conflict. With a constant gait thrust ``base`` the gait's schedule is the
    base of the patterns, not a schedule to show by itself."""
    err = InputError.param
    if req.target_zeta is not None and req.target_speed is not None:
        raise err("target_speed", "give either `target_zeta` or `target_speed`, not both")
    if req.target_zeta is not None and not req.target_zeta > 0:
        raise err("target_zeta", f"must be > 0 [kg^2 m^4/s^2], got {req.target_zeta:g}")
    if req.target_speed is not None and not req.target_speed > 0:
        raise err("target_speed", f"must be > 0 [m/s], got {req.target_speed:g}")
    if req.n_knots < 2:
        raise err("n_knots", f"need at least 2 knots, got {req.n_knots}")
    if req.pattern is not None and not req.pattern.strip():
        raise err("pattern", "empty: give interval values as arithmetic in j and k, e.g. "
                             "'k*(j-2)'")
    if req.mode is not None and req.mode not in MODES:
        raise err("mode", f"must be one of {', '.join(MODES)}, got {req.mode!r}")
    target = req.target_zeta is not None or req.target_speed is not None
    gait_thrust = zd.gait.thrust if base is None else None
    if target:
        name = "target_zeta" if req.target_zeta is not None else "target_speed"
        for opt, v in (("pattern", req.pattern), ("k", req.ks), ("field_k", req.field_k)):
            if v is not None:
                raise err(opt, f"cannot be combined with `{name}` (the solver chooses the "
                               "values)")
        if req.knots is not None and any(v is None for v in req.knots):
            raise err("knots", "free knots (?) are only solved for a shape-only `pattern`")
        source = name.replace("_", "-")
    elif req.pattern is None and gait_thrust is not None:
        for opt, v in (("knots", req.knots), ("k", req.ks), ("field_k", req.field_k)):
            if v is not None:
                raise err(opt, "the gait file's thrust: section fixes the schedule; pass "
                               "`pattern` to replace it")
        source = "gait"
    else:
        source = "pattern"
    if source == "gait":
        if req.mode is not None and req.mode != gait_thrust.mode:
            raise err("mode", f"the gait's thrust: section is in {gait_thrust.mode} mode")
        if req.thruster is not None:
            raise err("thruster", "the gait's thrust: section names its thrusters")
        return source, gait_thrust.mode, None
    mode = req.mode or "generalized"
    if mode == "generalized":
        if req.thruster is not None:
            raise err("thruster", "only used with `mode` force")
        return source, mode, None
    robot = zd.model.robot
    if not robot.thrusters:
        raise err("mode", f"robot {robot.name} has no thruster: force mode needs one (use "
                          "mode generalized, a generalised force T_j on q_N in N m)")
    return source, mode, robot.thruster_index(req.thruster)


def _cycles(zd: ZeroDynamics, schedule: Schedule,
            progress: Callable[[int], None] | None) -> tuple[LimitCycle, ...]:
    """limit_cycles (vectorised over the batch) in at most 5 chunks, reporting progress."""
    K = schedule.size
    step = max(1, -(-K // 5))
    out: list[LimitCycle] = []
    for i in range(0, K, step):
        sl = slice(i, min(K, i + step))
        out += limit_cycles(zd, schedule.take(sl))
        if progress is not None:
            progress(sl.stop - sl.start)
    return tuple(out)


def schedule_count(walker: Walker, req: ShapeRequest) -> int:
    """How many shaped schedules :func:`shape` computes (for a progress bar)."""
    if resolve(walker.zd, req, gait_base(walker))[0] == "pattern":
        return len(req.ks if req.ks is not None else default_ks())
    return 1


def shape(walker: Walker, *deprecated_req: ShapeRequest,
          knots: Sequence[float | None] | None = None, alpha_knots: bool = False,
          n_knots: int = 4, pattern: str | None = None, k: Sequence[float] | None = None,
          field_k: float | None = None, mode: str | None = None, thruster: str | None = None,
          target_zeta: float | None = None, target_speed: float | None = None,
          progress: Callable[[int], None] | None = None, max_output: float = 100e6,
          slope: float = 0.0, **deprecated: ShapeRequest) -> ShapeResult:
    """Shape the limit cycle of ``walker`` (SPEC 4): resolve the schedule family, solve knots or
    targets, compute nominal and shaped limit cycles and the shifts.

    The family, one of: a ``pattern`` in ``j`` (interval 1..n-1) and ``k`` (default the
    paper's ``k*(j-2)``), swept over the values ``k`` (default 0, 2, ..., 50), on ``knots``
    (fractions of the step, or alpha [rad] with ``alpha_knots``; ``None`` = a free knot solved
    so that the fixed point is unchanged; default ``n_knots`` knots, the interior ones free),
    ``field_k`` the value of the vector-field figure; the minimum-norm values reaching
    ``target_zeta`` [kg^2 m^4/s^2] or ``target_speed`` [m/s]; or, with none of these, the gait
    file's ``thrust:`` section. ``mode``: ``generalized`` (T_j [N m] on q_N) or ``force``
    (F_j [N] of ``thruster``).
    ``progress(n)`` is called as schedules finish. Problems in the gait's ``thrust:`` section
    are located in the gait file. Raises :class:`InputError` for bad parameters; solver
    failures come back as ``success = False`` with a reason. ``max_output`` [bytes]: a sweep
    whose CSV table would be larger is refused before any work. ``req`` (a
    :class:`ShapeRequest`, positional or keyword) is deprecated: give the keywords.

    ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground angle (SPEC 14,
    :meth:`Walker.on_slope`): b_F, Gamma_j, the fixed points and the orbits are those of the
    slope frame (the zero dynamics explicit in cos/sin of the slope, world-frame thrusters
    turned, link-frame ones not); speeds are along the ground, each orbit gains its climb
    rate, the document the ``slope`` block. 0: level ground, bit for bit."""
    import warnings

    from .limit_cycle import ORBIT_SAMPLES, ROW_BYTES

    check_walker(walker)
    walker = walker.on_slope(check_slope(slope))
    unknown = sorted(set(deprecated) - {"req"})
    if unknown:
        raise InputError.param(unknown[0], "not a parameter of shape")
    if len(deprecated_req) + len(deprecated) > 1:
        raise InputError.param("req", "one ShapeRequest at most (deprecated: give keywords)")
    req = deprecated.get("req", deprecated_req[0] if deprecated_req else None)
    given = dict(knots=knots, alpha_knots=alpha_knots, n_knots=n_knots, pattern=pattern,
                 ks=k, field_k=field_k, mode=mode, thruster=thruster,
                 target_zeta=target_zeta, target_speed=target_speed)
    if req is not None:
        warnings.warn("shape(walker, req=ShapeRequest(...)) is deprecated: pass its fields as "
                      "keywords, shape(walker, pattern=..., k=[...], ...) (ks is k)",
                      DeprecationWarning, stacklevel=2)
        check_instance("req", req, ShapeRequest, "a ShapeRequest")
        if any(v is not None for f, v in given.items() if f not in ("alpha_knots", "n_knots")
               ) or alpha_knots is not False or n_knots != 4:
            raise InputError.param("req", "give either a ShapeRequest or keywords, not both")
    else:
        req = ShapeRequest(**{f: tuple(v) if f in ("knots", "ks") and v is not None
                              and not isinstance(v, (str, bytes)) and hasattr(v, "__iter__")
                              else v for f, v in given.items()})
    check_callable("progress", progress)
    max_output = check_number("max_output", max_output, gt=0, largest=1e15)
    n = len(req.ks) if req.ks is not None else 1
    size = (n + 1) * (ORBIT_SAMPLES + 2) * ROW_BYTES
    if size > max_output:
        raise InputError.param("max_output", f"{n} values of k make a CSV table of about "
                                             f"{size / 1e6:.0f} MB, above the limit of "
                                             f"{max_output / 1e6:g} MB: sweep fewer values or "
                                             "raise the limit")
    zd = walker.zd
    base = gait_base(walker)
    source, mode, th = resolve(zd, req, base)
    if source != "pattern":
        base = None  # a target's minimum-norm thrust is the whole thrust
    m = zd.model.n_thrusters
    knots_req = req.knots
    if source == "gait":
        sched, fr = zd.gait.thrust.resolve(zd, zd.model.robot, walker.where)
        sched.check_limits(zd.model.robot, walker.where)
        knots = sched.knots
        labels, values, P_field, ksol, target = ("gait thrust",), None, None, None, None
    else:
        if knots_req is None:
            knots_req = ((0.0,) + (None,) * (req.n_knots - 2) + (1.0,) if source == "pattern"
                         else tuple(uniform_fractions(req.n_knots)))
        fr = check_knots(zd, knots_req, fractions=not req.alpha_knots)
    nominal = None
    if source == "pattern":
        pattern = req.pattern or DEFAULT_PATTERN
        ks = tuple(req.ks) if req.ks is not None else default_ks()
        fk = DEFAULT_FIELD_K if req.field_k is None else float(req.field_k)
        P = pattern_values(pattern, len(fr) - 1, ks + (fk,))
        ksol = None
        if any(v is None for v in fr):
            ksol = solve_knots(zd, fr, P, mode, th)
            if not ksol.success:
                knots = knots_alpha(zd, np.array([0.0 if v is None else v for v in fr]))
                nominal = zd.nominal_cycle(knots)
                return ShapeResult(walker, False, ksol.reason, source, mode, th, pattern, nominal,
                                  knot_solution=ksol)
            fr = list(ksol.fractions)
        knots = knots_alpha(zd, np.array(fr, float))
        sched = around(Schedule.piecewise(knots, P[:-1], mode, m, th), base)
        sched.check_limits(zd.model.robot, ("pattern", "k"), ())
        labels, values, P_field, target = tuple(f"k = {k:g}" for k in ks), ks, P[-1:], None
    elif source != "gait":
        pattern = None
        knots = knots_alpha(zd, np.array(fr, float))
        if source == "target-zeta":
            target = solve_target_zeta(zd, knots, req.target_zeta, mode, th)
        else:
            target = solve_target_speed(zd, knots, req.target_speed, mode, th)
        ksol, labels, values, P_field = None, ("minimum-norm",), None, None
        if not target.success:
            nominal = zd.nominal_cycle(knots)
            return ShapeResult(walker, False, target.reason, source, mode, th, None, nominal,
                              target=target)
        sched = Schedule.piecewise(knots, target.values[None, :], mode, m, th)
        try:
            sched.check_limits(zd.model.robot, "the minimum-norm thrust", ())
        except InputError as exc:
            nominal = zd.nominal_cycle(knots)
            return ShapeResult(walker, False, f"the target needs more thrust than the thruster "
                              f"gives: {exc}", source, mode, th, None, nominal, target=target)
    else:
        pattern = None
    nom_sched = around(Schedule.zero(knots, m), base)
    nominal = limit_cycles(zd, nom_sched)[0]
    cycles = _cycles(zd, sched, progress)
    if P_field is not None:
        fsched = around(Schedule.piecewise(knots, P_field, mode, m, th), base)
        fsched.check_limits(zd.model.robot, "field_k", ())
        flabel = f"k = {fk:g}"
    else:
        fsched, flabel = sched, labels[0]
    fcycle = limit_cycles(zd, fsched)[0]
    one_step = one_step_change(zd, sched) - one_step_change(zd, nom_sched)[0]
    bad = [(lab, c) for lab, c in zip(labels, cycles) if not (c.exists and c.stable)]
    if bad:
        success, reason = False, (
            f"no stable shaped orbit for {len(bad)} of {len(cycles)} schedule(s) "
            f"({', '.join(lab for lab, _ in bad[:5])}{', ...' if len(bad) > 5 else ''}): "
            f"{bad[0][1].reason}")
    elif walker.warnings:
        success, reason = False, f"shaped limit cycles computed, but {walker.warnings[0]}"
    else:
        success, reason = True, "a stable shaped limit cycle for every schedule"
    return ShapeResult(walker, success, reason, source, mode, th, pattern,
                      nominal, labels, values, ksol, target, intervals(zd, knots), sched, cycles,
                      one_step, zd.fixed_point_of(one_step), flabel, fsched, fcycle,
                      base)


