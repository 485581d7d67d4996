"""Thrust strategies compared by the robustness analyses (SPEC 4, 11, 12): what the thrusters do
while the walker recovers.

* ``none``: no thrust;
* ``constant``: a constant thrust [N] on one thruster, or (no value) the gait's own ``thrust:``
  section (0 N when it has none);
* ``schedule``: a piecewise-constant schedule on knots (force [N] or generalized [N m] mode);
* ``control``: the step-to-step controller of SPEC 11 (:mod:`thrustwalk_cli.controller`),
  regulating to the zero-thrust orbit (``thrustwalk control --reference nominal``).

A :class:`Strategy` is plain data (it travels to sweep workers); :func:`realize` makes it
concrete for one walker: its thrust over a step, the orbit it walks on, the reference a
recovery is measured against and the exact basin of its reduced walker.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..controller.planner import Planner, regulator
from ..errors import InputError
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics, limit_cycles
from ..simulation.closed_loop import ThrustModel
from ..thrust.schedule import Schedule, WrittenSchedule, knots_alpha
from .basin import ReducedBasin, controlled_basin, reduced_basin

KINDS = ("none", "constant", "schedule", "control")
CONTROL_KNOTS = (0.0, 0.5, 1.0)


@dataclass(frozen=True)
class Strategy:
    """One thrust strategy (module docstring). ``thruster``: the thruster that ``constant``,
    ``schedule`` (force mode) and ``control`` drive (default: the first); ``thrust`` [N]
    (``constant``; None: the gait's ``thrust:`` section); ``schedule``: ``(knots as fractions
    of the step, values per interval, mode)``; ``knots`` (``control``): fractions of the step,
    ``max_thrust`` [N] its bound within the thruster's limits; ``name``: the label shown."""

    kind: str
    thruster: str | None = None
    thrust: float | None = None
    schedule: tuple[tuple[float, ...], tuple[float, ...], str] | None = None
    knots: tuple[float, ...] = CONTROL_KNOTS
    max_thrust: float | None = None
    name: str = ""

    @property
    def label(self) -> str:
        """The label shown: ``name`` when given, else ``constant:F`` (F [N]), ``constant (gait)``
        or the kind."""
        if self.name:
            return self.name
        if self.kind == "constant":
            return "constant (gait)" if self.thrust is None else f"constant:{self.thrust:g}"
        return self.kind

    def parameters(self) -> dict:
        """The strategy as study parameters (plain values; :func:`from_parameters`)."""
        sched = None if self.schedule is None else {
            "knots": list(self.schedule[0]), "values": list(self.schedule[1]),
            "mode": self.schedule[2]}
        return {"strategy": self.kind, "strategy_label": self.label, "thruster": self.thruster,
                "thrust": self.thrust, "schedule": sched, "knots": list(self.knots),
                "max_thrust": self.max_thrust}


def from_parameters(p: dict) -> Strategy:
    """The strategy of a study's parameters (``strategy``, ``thruster``, ``thrust``,
    ``schedule``, ``knots``, ``max_thrust``, ``strategy_label``)."""
    kind = p.get("strategy", "none")
    if kind not in KINDS:
        raise InputError.param("strategy", f"unknown strategy {kind!r} (choose from "
                                           f"{', '.join(KINDS)})")
    s = p.get("schedule")
    sched = None if s is None else (tuple(map(float, s["knots"])),
                                    tuple(map(float, s["values"])), s.get("mode", "force"))
    if kind == "schedule" and sched is None:
        raise InputError.param("schedule", "the schedule strategy needs a `schedule` (knots "
                                           "and values)")
    thrust = p.get("thrust")
    return Strategy(kind, p.get("thruster"), None if thrust is None else float(thrust), sched,
                    tuple(map(float, p.get("knots") or CONTROL_KNOTS)), p.get("max_thrust"),
                    p.get("strategy_label") or "")


def schedule_of_file(thrust: WrittenSchedule, zd: ZeroDynamics) -> tuple[tuple, tuple, str, str]:
    """A gait file's ``thrust:`` section as a strategy schedule: ``(knots as fractions,
    values, mode, thruster)``; one thruster in force mode (or ``T`` in generalized mode)."""
    if len(thrust.values) != 1:
        names = ", ".join(n for n, _ in thrust.values)
        raise InputError.param("strategy", f"a schedule drives one thruster; this one has "
                                           f"{len(thrust.values)} ({names})")
    name, values = thrust.values[0]
    sched, fractions = thrust.resolve(zd, zd.model.robot, "strategy")
    if len(fractions) != len(thrust.knots):  # padded: the knots did not span the step
        raise InputError.param("strategy", "a schedule's knots must run from the start of the "
                                           "step to its end")
    return (tuple(fractions), tuple(map(float, values)), thrust.mode,
            name if thrust.mode == "force" else "")


@dataclass(frozen=True)
class Realized:
    """A strategy made concrete for one walker (SI units).

    ``schedule``: the thrust over a step (a one-schedule batch; ``control``: zero thrust on its
    knots, the controller sets the values step by step); ``thrust``: the simulation's thrust
    model; ``cycle``: the orbit the trials start on (``control``: the zero-thrust orbit);
    ``zeta_ref`` [kg^2 m^4/s^2]: the fixed point a recovery is measured against (None: no
    orbit); ``basin``: the exact basin of the reduced walker; ``planner``: the SPEC 11
    controller (``control``); ``driven`` thruster indices; ``notes``: what the user should
    know (a strategy that is the same as another)."""

    strategy: Strategy
    schedule: Schedule
    thrust: ThrustModel
    cycle: LimitCycle
    zeta_ref: float | None
    basin: ReducedBasin
    planner: Planner | None
    driven: list[int]
    knots: np.ndarray
    notes: tuple[str, ...] = ()


def _driven(zd: ZeroDynamics, s: Strategy) -> list[int]:
    j = zd.model.robot.driven_thruster(s.thruster)
    return [] if j is None else [j]


def realize(zd: ZeroDynamics, s: Strategy, *, mu: float, eps: float = 0.0,
            points: int = 401, model_zd: ZeroDynamics | None = None) -> Realized:
    """Make ``s`` concrete for the walker of ``zd`` (module docstring): its thrust, orbit,
    reference and reduced basin (SPEC 12, with friction coefficient ``mu`` [1] and least
    vertical force ``eps`` [N] on ``points`` alpha grid points). ``model_zd``: the walker the
    controller was made for (default: ``zd`` itself), for a plant that differs from the
    controller's model; its orbit, reference and basin are then the model's."""
    model = zd.model
    m = model.n_thrusters
    robot = model.robot
    notes: list[str] = []
    full = np.array([zd.alpha_i, zd.alpha_f])
    if s.kind == "control":
        if not robot.thrusters:
            raise InputError.param("strategy", f"robot {robot.name} has no thruster: the "
                                               "control strategy needs one")
        driven = _driven(zd, s)
        fr = np.asarray(s.knots, float)
        if len(fr) < 2 or fr[0] != 0.0 or fr[-1] != 1.0 or np.any(np.diff(fr) <= 0):
            raise InputError.param("knots", f"knots are fractions of the step, 0 first, 1 "
                                            f"last, strictly increasing (got "
                                            f"{', '.join(f'{v:g}' for v in fr)})")
        if s.max_thrust is not None and not s.max_thrust > 0:
            raise InputError.param("max_thrust", f"must be > 0 N (got {s.max_thrust:g})")
        kn = knots_alpha(zd, fr)
        mz = zd if model_zd is None else model_zd
        planner, lc0 = regulator(mz, knots_alpha(mz, fr), driven, mu=mu, eps=eps,
                                 max_thrust=s.max_thrust, points=points)
        sched = Schedule.zero(kn, m)
        thrust = ThrustModel("piecewise", np.zeros(m), schedule=sched)
        zs = float(lc0.zeta_star)
        return Realized(s, sched, thrust, lc0, zs, controlled_basin(planner, zs), planner,
                        driven, kn, ())
    driven = []
    if s.kind == "none":
        sched = Schedule.constant(zd, np.zeros((1, m)))
        thrust = ThrustModel("ideal", np.zeros(m))
    elif s.kind == "constant" and s.thrust is not None:
        j = robot.driven_thruster(s.thruster)
        if j is None:
            robot.check_no_thrust([s.thrust], "strategy")
        F = np.zeros(m)
        if j is not None:
            F[j] = s.thrust
            driven = [j]
        sched = Schedule.constant(zd, F[None, :])
        sched.check_limits(zd.model.robot, "strategy")
        thrust = ThrustModel("ideal", F)
    elif s.kind == "constant":
        g = zd.gait.thrust
        if g is None:
            notes.append(f"the gait {zd.gait.name} has no thrust: section, so the strategy "
                         "`constant` without a value is 0 N (the same as none); give one, e.g. "
                         "constant:-20")
            sched = Schedule.constant(zd, np.zeros((1, m)))
            thrust = ThrustModel("ideal", np.zeros(m))
        else:
            sched, _ = g.resolve(zd, zd.model.robot, "strategy", pad=True)
            sched.check_limits(zd.model.robot, "strategy")
            thrust = ThrustModel("piecewise", np.zeros(m), schedule=sched)
    else:  # schedule
        fr, values, mode = s.schedule
        fr_a = np.asarray(fr, float)
        if len(fr_a) < 2 or fr_a[0] != 0.0 or fr_a[-1] != 1.0 or np.any(np.diff(fr_a) <= 0):
            raise InputError.param("schedule", "knots are fractions of the step, 0 first, 1 "
                                               "last, strictly increasing")
        if len(values) != len(fr_a) - 1:
            n = len(fr_a) - 1
            raise InputError.param("schedule", f"expected {n} value{'s' * (n != 1)} (one per "
                                               f"interval), got {len(values)}")
        if mode not in ("force", "generalized"):
            raise InputError.param("schedule", f"unknown mode {mode!r} (force, generalized)")
        j = None
        if mode == "force":
            j = robot.thruster_index(s.thruster, "strategy")
            driven = [j]
        sched = Schedule.piecewise(knots_alpha(zd, fr_a), np.asarray(values, float)[None, :],
                                    mode, m, j)
        sched.check_limits(zd.model.robot, "strategy")
        thrust = ThrustModel("piecewise", np.zeros(m), schedule=sched)
    cycle = limit_cycles(zd, sched)[0]
    basin = reduced_basin(zd, sched, mu=mu, eps=eps, points=points)
    zs = float(cycle.zeta_star) if cycle.exists else None
    return Realized(s, sched, thrust, cycle, zs, basin, None, driven,
                    sched.knots if sched.knots.size else full, tuple(notes))


def labels_unique(strategies: Sequence[Strategy]) -> None:
    """Every strategy of a comparison has its own label."""
    seen: set[str] = set()
    for s in strategies:
        if s.label in seen:
            raise InputError.param("strategy", f"strategy {s.label} is given twice")
        seen.add(s.label)
