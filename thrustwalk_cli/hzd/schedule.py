"""Piecewise-constant thrust schedules from user input (SPEC 4).

Knots ``alpha_1 = alpha_i, ..., alpha_n = alpha_f`` [rad] along the step, given as alpha values
or as fractions ``s = (alpha - alpha_i)/(alpha_f - alpha_i)`` of the step; one value per knot
interval: thrust ``F_j`` [N] per thruster (force mode) or the generalised force ``T_j`` on q_N
[N m] (generalized mode). This module validates knots (a ``knots`` parameter and a gait
file's ``thrust:`` section) and builds the :class:`~thrustwalk_cli.hzd.zero_dynamics.Schedule`
that the zero dynamics, shaping, feasibility and simulation all consume: a gait file's ``thrust:``
section is converted in exactly one place, :func:`schedule_from_gait`.

Every input problem is collected and reported as ``file:line: thrust.key.path: message`` (or
``knots: message`` for a parameter); the core raises :class:`InputError`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..description.gait import ThrustSchedule
from ..errors import InputError, Problem, Where, locate
from .zero_dynamics import Schedule, ZeroDynamics

MODES = ("generalized", "force")


ALPHA_TOL = 1e-6  # [rad] knots given as alpha values must hit alpha_i / alpha_f this closely


FRACTION_TOL = 1e-9  # [-] a partial schedule's fractions may overshoot 0 / 1 this much


# ------------------------------------------------------------------------------ knots
def check_knots(zd: ZeroDynamics, knots: Sequence[float | None], *, fractions: bool,
                where: Where = "knots", key: tuple = (),
                partial: bool = False) -> list[float | None]:
    """Validate knots and return them as fractions ``s`` of the step (``None``: free knot).

    SPEC 4: ``alpha_1 = alpha_i < ... < alpha_n = alpha_f`` along the step. Fractions must start
    at 0 and end at 1; alpha values [rad] must match alpha_i, alpha_f within ``ALPHA_TOL``.
    ``partial``: the knots need only lie inside the step (within ``FRACTION_TOL`` /
    ``ALPHA_TOL``; ends that close are snapped onto 0 and 1), for a schedule that
    :func:`schedule_from_gait` pads with zero thrust.
    Raises :class:`InputError` (one line, naming ``where``) otherwise.
    """
    def bad(msg: str) -> InputError:
        return InputError(locate(where, key, msg))

    ks = list(knots)
    if len(ks) < 2:
        raise bad(f"need at least 2 knots (alpha_i and alpha_f), got {len(ks)}")
    if ks[0] is None or ks[-1] is None:
        raise bad("the first and last knots are alpha_i and alpha_f; they cannot be free (?)")
    a_i, a_f = zd.alpha_i, zd.alpha_f
    span = a_f - a_i
    s = list(ks) if fractions else [None if v is None else (v - a_i) / span for v in ks]
    if partial:
        tol = FRACTION_TOL if fractions else ALPHA_TOL / abs(span)
        if s[0] < -tol or s[-1] > 1 + tol:
            raise bad(f"knots must lie inside the step (fractions 0 ... 1, alpha from "
                      f"{a_i:.6g} to {a_f:.6g} rad; got {ks[0]:g} ... {ks[-1]:g})")
        s[0] = 0.0 if s[0] <= tol else s[0]
        s[-1] = 1.0 if s[-1] >= 1 - tol else s[-1]
    elif fractions:
        if ks[0] != 0.0 or ks[-1] != 1.0:
            raise bad(f"knots are fractions of the step: the first must be 0 and the last 1 "
                      f"(got {ks[0]:g} and {ks[-1]:g})")
    else:
        if abs(ks[0] - a_i) > ALPHA_TOL or abs(ks[-1] - a_f) > ALPHA_TOL:
            raise bad(f"knots in alpha [rad] must start at alpha_i = {a_i:.10g} and end at "
                      f"alpha_f = {a_f:.10g} (got {ks[0]:.10g} and {ks[-1]:.10g})")
        s[0], s[-1] = 0.0, 1.0
    given = [(i, v) for i, v in enumerate(s) if v is not None]
    for (i0, v0), (i1, v1) in zip(given, given[1:]):
        if not v1 > v0:
            unit = "" if fractions else " rad"
            raise bad(f"knots must increase strictly along the step: knot {i1 + 1} "
                      f"({ks[i1]:g}{unit}) does not follow knot {i0 + 1} ({ks[i0]:g}{unit})")
    return s


def knots_alpha(zd: ZeroDynamics, fractions: np.ndarray) -> np.ndarray:
    """``alpha_j = alpha_i + s_j (alpha_f - alpha_i)`` [rad], endpoints exact."""
    s = np.asarray(fractions, float)
    a = zd.alpha_i + s * (zd.alpha_f - zd.alpha_i)
    a[0], a[-1] = zd.alpha_i, zd.alpha_f
    return a


def uniform_fractions(n: int) -> list[float]:
    """``n`` knots equally spaced in alpha: ``s_j = (j - 1)/(n - 1)``."""
    return [j / (n - 1) for j in range(n)]


# --------------------------------------------------------------------------- schedules
def make_schedule(zd: ZeroDynamics, knots: np.ndarray, values: np.ndarray, mode: str,
                  thruster: int | None = None) -> Schedule:
    """Batched schedule from interval values (K, n-1): ``T_j`` [N m] (generalized mode) or
    ``F_j`` [N] of thruster index ``thruster`` (force mode); SPEC 4."""
    values = np.atleast_2d(np.asarray(values, float))
    K, J = values.shape
    m = zd.model.n_thrusters
    force = np.zeros((K, J, m))
    gen = np.zeros((K, J))
    if mode == "generalized":
        gen[:] = values
    elif mode == "force":
        force[:, :, thruster] = values
    else:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    return Schedule(np.asarray(knots, float), force, gen)


def nominal_schedule(knots: np.ndarray, m: int) -> Schedule:
    """No thrust, on the given knots."""
    J = len(knots) - 1
    return Schedule(np.asarray(knots, float), np.zeros((1, J, m)), np.zeros((1, J)))


def schedule_from_gait(zd: ZeroDynamics, thrust: ThrustSchedule, where: Where,
                       *, pad: bool = False) -> tuple[Schedule, list[float]]:
    """A gait file's ``thrust:`` section as a one-schedule :class:`Schedule` (SPEC 4).

    Force mode: one row of ``F_j`` [N] per thruster name; generalized mode: the single key ``T``
    with ``T_j`` [N m]. Every problem is collected and reported at ``thrust.<key>`` of ``where``
    (a key path of the gait file the section came from). ``pad``: the knots may cover only part
    of the step; the rest is filled with zero-thrust intervals (otherwise they must run from
    alpha_i to alpha_f).
    Returns the schedule and its knots as fractions of the step.
    """
    problems: list[Problem] = []
    s = None
    try:
        s = check_knots(zd, thrust.knots, fractions=thrust.fractions, where=where,
                        key=("thrust", "knots"), partial=pad)
    except InputError as e:
        problems += e.problems
    J = len(thrust.knots) - 1
    names = zd.model.robot.thruster_names
    force = np.zeros((1, J, len(names)))
    gen = np.zeros((1, J))
    for name, vals in thrust.values:
        key = ("thrust", "values", name)
        if len(vals) != J:
            problems.append(locate(where, key, f"expected {J} values (one per interval "
                                   f"between {J + 1} knots), got {len(vals)}"))
            continue
        if thrust.mode == "generalized":
            if name != "T":
                problems.append(locate(where, key, "in generalized mode the only key is T "
                                       "(generalised force T_j on q_N, N m)"))
                continue
            gen[0] = vals
        elif name not in names:
            problems.append(locate(where, key, f"unknown thruster '{name}' (robot "
                                   f"{zd.model.robot.name} has: {', '.join(names) or 'none'})"))
        else:
            force[0, :, names.index(name)] = vals
    if not thrust.values:
        problems.append(locate(where, ("thrust", "values"), "no values"))
    if problems:
        raise InputError(problems)
    if s[0] > 0.0:  # only with pad: zero thrust before the first knot
        s = [0.0] + s
        force = np.concatenate([np.zeros((1, 1, len(names))), force], axis=1)
        gen = np.concatenate([np.zeros((1, 1)), gen], axis=1)
    if s[-1] < 1.0:  # ... and after the last
        s = s + [1.0]
        force = np.concatenate([force, np.zeros((1, 1, len(names)))], axis=1)
        gen = np.concatenate([gen, np.zeros((1, 1))], axis=1)
    return Schedule(knots_alpha(zd, np.array(s)), force, gen), [float(v) for v in s]


def check_limits(zd: ZeroDynamics, schedule: Schedule, where: Where,
                 key: tuple = ("thrust", "values")) -> None:
    """Every thrust of ``schedule`` [N] within its thruster's ``limits`` from the robot file;
    :class:`InputError` at ``where`` (one problem per thruster) otherwise."""
    problems = []
    for t, th in enumerate(zd.model.robot.thrusters):
        lo, hi = th.limits
        F = schedule.force[..., t]
        bad = F[(F < lo) | (F > hi)]
        if bad.size:
            worst = bad[np.argmax(np.abs(bad))]
            problems.append(locate(where, key + (th.name,),
                                   f"{worst:g} N is outside the limits [{lo:g}, {hi:g}] N of "
                                   f"thruster {th.name} (the robot file's `limits`)"))
    if problems:
        raise InputError(problems)
