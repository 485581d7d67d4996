"""Thrust schedules (SPEC 4): the one home of thrust as a function of the step.

Thrust is piecewise constant on knots ``alpha_1 = alpha_i < ... < alpha_n = alpha_f`` [rad]
along the step (given as alpha values or as fractions ``s = (alpha - alpha_i)/(alpha_f -
alpha_i)`` of the step); one value per knot interval: thrust ``F_j`` [N] per thruster (force
mode) or the generalised force ``T_j`` on q_N [N m] (generalized mode). Constant thrust is the
schedule with the two knots alpha_i, alpha_f; zero thrust the schedule whose values are 0.

:class:`Schedule` is the type every computation takes (the zero dynamics, shaping, contact,
the optimiser, the simulation, the controller): knots in alpha and arrays of values, batched
(``k`` schedules sharing the knots). A schedule *as written* (a gait file's ``thrust:``
section, a sweep's ``schedule`` setting) is the same schedule in its written form,
:class:`WrittenSchedule`, and :meth:`WrittenSchedule.resolve` is the one step from one form to
the other. The written form cannot be the arrays yet, for two reasons: its knots may be
fractions (alpha_i and alpha_f come from the gait's maps, known only on a walker) and its
values are keyed by thruster name as the user wrote them, possibly wrong (a row of the wrong
length, a name the robot lacks, a key other than ``T`` in generalized mode). Those problems
belong to the file's lines and are reported when the schedule is used, not when the gait is
read (a gait with a bad ``thrust:`` section still serves every command that does not use it).

This layer sits beside the descriptions (it imports numpy and the errors only): the step is
anything with ``alpha_i`` and ``alpha_f`` [rad] (a :class:`~thrustwalk_cli.hzd.zero_dynamics.
ZeroDynamics`), the robot anything with its thrusters' names and limits (a
:class:`~thrustwalk_cli.description.robot.Robot`). Every input problem is collected and
reported as ``file:line: thrust.key.path: message`` (or ``knots: message`` for a parameter);
the core raises :class:`InputError`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import InputError, Problem, Where, locate

MODES = ("generalized", "force")

ALPHA_TOL = 1e-6  # [rad] knots given as alpha values must hit alpha_i / alpha_f this closely

FRACTION_TOL = 1e-9  # [-] a partial schedule's fractions may overshoot 0 / 1 this much


class Step(Protocol):
    """The range of alpha over a step [rad] (a ``ZeroDynamics`` is one)."""

    @property
    def alpha_i(self) -> float: ...

    @property
    def alpha_f(self) -> float: ...


@dataclass(frozen=True)
class Schedule:
    """Thrust piecewise constant in alpha, batched: ``k`` schedules sharing the knots (SPEC 4).

    knots: ``alpha_1 = alpha_i, ..., alpha_n = alpha_f`` [rad].
    force: (k, n-1, m) physical thrust per interval and thruster [N] (the robot's order).
    generalized: (k, n-1) generalised force ``T_j`` on q_N per interval [N m].
    """

    knots: np.ndarray
    force: np.ndarray
    generalized: np.ndarray

    @property
    def size(self) -> int:
        """The number ``k`` of schedules in the batch."""
        return self.force.shape[0]

    @staticmethod
    def constant(step: Step, thrust: np.ndarray) -> Schedule:
        """Constant thrust ``thrust`` [N] of shape (k, m) over the whole step."""
        thrust = np.atleast_2d(np.asarray(thrust, float))
        k = thrust.shape[0]
        return Schedule(
            knots=np.array([step.alpha_i, step.alpha_f]),
            force=thrust[:, None, :],
            generalized=np.zeros((k, 1)),
        )

    @staticmethod
    def on_thruster(step: Step, values, thruster: int | None, m: int) -> Schedule:
        """Constant thrust, one schedule per value of ``values`` [N] on thruster index
        ``thruster`` of ``m`` (the others at 0; None: a robot without thrusters, m = 0)."""
        return Schedule.constant(step, thrust_on(values, thruster, m))

    @staticmethod
    def zero(knots: np.ndarray, m: int) -> Schedule:
        """No thrust on the given knots [rad], ``m`` thrusters (one schedule)."""
        J = len(knots) - 1
        return Schedule(np.asarray(knots, float), np.zeros((1, J, m)), np.zeros((1, J)))

    @staticmethod
    def piecewise(knots: np.ndarray, values: np.ndarray, mode: str, m: int,
                  thruster: int | None = None) -> Schedule:
        """A batch from interval values (k, n-1): ``T_j`` [N m] (generalized mode) or ``F_j``
        [N] of thruster index ``thruster`` of ``m`` (force mode) on the knots [rad]."""
        values = np.atleast_2d(np.asarray(values, float))
        K, J = values.shape
        force = np.zeros((K, J, m))
        gen = np.zeros((K, J))
        if mode == "generalized":
            gen[:] = values
        elif mode == "force":
            force[:, :, thruster] = values
        else:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        return Schedule(np.asarray(knots, float), force, gen)

    def take(self, rows) -> Schedule:
        """The schedules of the batch at ``rows`` (indices or a mask)."""
        return Schedule(self.knots, self.force[rows], self.generalized[rows])

    def without_thrust(self) -> Schedule:
        """The same knots and batch size with every value 0."""
        return Schedule(self.knots, np.zeros_like(self.force), np.zeros_like(self.generalized))

    def check_limits(self, robot, where: Where, key: tuple = ("thrust", "values")) -> None:
        """Every thrust [N] within its thruster's ``limits`` from the robot file;
        :class:`InputError` at ``where`` (one problem per thruster) otherwise."""
        problems = []
        for t, th in enumerate(robot.thrusters):
            lo, hi = th.limits
            F = self.force[..., t]
            bad = F[(F < lo) | (F > hi)]
            if bad.size:
                worst = bad[np.argmax(np.abs(bad))]
                problems.append(locate(where, key + (th.name,),
                                       f"{worst:g} N is outside the limits [{lo:g}, {hi:g}] N "
                                       f"of thruster {th.name} (the robot file's `limits`)"))
        if problems:
            raise InputError(problems)


def thrust_on(values, thruster: int | None, m: int) -> np.ndarray:
    """Thrust per thruster (k, m) [N] with ``values`` on thruster index ``thruster`` (None: a
    robot without thrusters, shape (k, 0))."""
    F = np.zeros((len(values), m))
    if thruster is not None:
        F[:, thruster] = values
    return F


@dataclass(frozen=True)
class WrittenSchedule:
    """A schedule as written (a gait file's ``thrust:`` section; SPEC 4): the written form of
    :class:`Schedule` (module docstring: why it is not the arrays yet).

    knots: alpha values ``alpha_1 < ... < alpha_n`` in the direction of the step, or fractions
    of the step when ``fractions`` is true [rad or 1].
    values: ``(thruster name, one value per interval)`` pairs: thrust [N] (mode ``"force"``)
    or, in mode ``"generalized"``, a single pair ``("T", ...)`` of generalised forces ``T_j``
    on q_N [N m].
    """

    knots: tuple[float, ...]
    values: tuple[tuple[str, tuple[float, ...]], ...]
    mode: str = "force"
    fractions: bool = True

    def resolve(self, step: Step, robot, where: Where, *, pad: bool = False
                ) -> tuple[Schedule, list[float]]:
        """This schedule on alpha: a one-schedule :class:`Schedule` of ``robot``'s thrusters
        on ``step`` (SPEC 4), and its knots as fractions of the step.

        Force mode: one row of ``F_j`` [N] per thruster name; generalized mode: the single key
        ``T`` with ``T_j`` [N m]. Every problem is collected and reported at ``thrust.<key>``
        of ``where`` (a key path of the file the section came from). ``pad``: the knots may
        cover only part of the step; the rest is filled with zero-thrust intervals
        (otherwise they must run from alpha_i to alpha_f).
        """
        problems: list[Problem] = []
        s = None
        try:
            s = check_knots(step, self.knots, fractions=self.fractions, where=where,
                            key=("thrust", "knots"), partial=pad)
        except InputError as e:
            problems += e.problems
        J = len(self.knots) - 1
        names = list(robot.thruster_names)
        force = np.zeros((1, J, len(names)))
        gen = np.zeros((1, J))
        for name, vals in self.values:
            key = ("thrust", "values", name)
            if len(vals) != J:
                problems.append(locate(where, key, f"expected {J} value{'s' * (J != 1)} (one "
                                       f"per interval between {J + 1} knots), got "
                                       f"{len(vals)}"))
                continue
            if self.mode == "generalized":
                if name != "T":
                    problems.append(locate(where, key, "in generalized mode the only key is T "
                                           "(generalised force T_j on q_N, N m)"))
                    continue
                gen[0] = vals
            elif name not in names:
                problems.append(locate(where, key, f"unknown thruster '{name}' (robot "
                                       f"{robot.name} has: {', '.join(names) or 'none'})"))
            else:
                force[0, :, names.index(name)] = vals
        if not self.values:
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
        return Schedule(knots_alpha(step, np.array(s)), force, gen), [float(v) for v in s]


# ------------------------------------------------------------------------------ knots
def check_knots(step: Step, knots: Sequence[float | None], *, fractions: bool,
                where: Where = "knots", key: tuple = (),
                partial: bool = False) -> list[float | None]:
    """Validate knots and return them as fractions ``s`` of the step (``None``: free knot).

    SPEC 4: ``alpha_1 = alpha_i < ... < alpha_n = alpha_f`` along the step. Fractions must start
    at 0 and end at 1; alpha values [rad] must match alpha_i, alpha_f within ``ALPHA_TOL``.
    ``partial``: the knots need only lie inside the step (within ``FRACTION_TOL`` /
    ``ALPHA_TOL``; ends that close are snapped onto 0 and 1), for a schedule that
    :meth:`WrittenSchedule.resolve` pads with zero thrust.
    Raises :class:`InputError` (one line, naming ``where``) otherwise.
    """
    def bad(msg: str) -> InputError:
        return InputError(locate(where, key, msg))

    ks = list(knots)
    if len(ks) < 2:
        raise bad(f"need at least 2 knots (alpha_i and alpha_f), got {len(ks)}")
    if ks[0] is None or ks[-1] is None:
        raise bad("the first and last knots are alpha_i and alpha_f; they cannot be free (?)")
    a_i, a_f = step.alpha_i, step.alpha_f
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


def knots_alpha(step: Step, fractions: np.ndarray) -> np.ndarray:
    """``alpha_j = alpha_i + s_j (alpha_f - alpha_i)`` [rad], endpoints exact."""
    s = np.asarray(fractions, float)
    a = step.alpha_i + s * (step.alpha_f - step.alpha_i)
    a[0], a[-1] = step.alpha_i, step.alpha_f
    return a


def uniform_fractions(n: int) -> list[float]:
    """``n`` knots equally spaced in alpha: ``s_j = (j - 1)/(n - 1)``."""
    return [j / (n - 1) for j in range(n)]
