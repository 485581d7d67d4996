"""References of the step-to-step controller (SPEC 11): the reference of each step from a
profile over steps, and the zeta^- reference of a speed.

A speed reference is tracked as a speed. A step's speed is the step length over its step time,
and with shaped thrust the step time depends on the schedule, not on zeta^- alone: the same
zeta^- walks at different speeds under different thrust. The controller's steady state at ``x_k
= x_{k+1} = x`` is the QP's own least-effort thrust under the contact conditions (with their
cutting planes, :meth:`~thrustwalk_cli.controller.planner.Planner.steady`), so its speed
``v(x)`` is exactly what the closed loop walks at once it has settled on ``x``; ``x_ref``
solves ``v(x_ref) = v_ref`` by a bracketed root find (Brent,
:meth:`~thrustwalk_cli.hzd.zero_dynamics.ZeroDynamics.zeta_for_speed`) over the interval of
``x`` that some thrust holds in steady state. This is exact at the fixed point and robust (a
bracketed scalar root of a continuous function; a speed outside ``v`` of that interval is
reported out of reach and held at the nearest end). The alternative, the step's speed inside
the QP (the step time is convex in zeta(alpha), which is affine in ``(x_k, u)``, so a
linearised SQP would do), would add a second equality to a problem of two or three variables
and leave little room for the contact rows; it would also make the steady state depend on the
linearisation. An earlier version used the unconstrained minimum-effort steady schedule for
``v(x)``: where contact shaped the QP's schedule, the walker settled at another speed (walker5,
0.8 m/s at mu = 0.7: 0.904 m/s) while the zeta^- error read 1e-11.

Units: zeta [kg^2 m^4/s^2], speed [m/s], thrust [N].
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ComputationError, InputError
from ..hzd.zero_dynamics import ZeroDynamics, limit_cycles
from ..thrust.schedule import Schedule
from .planner import Planner


def reference_values(profile: Sequence[tuple[float, float]], steps: int, ramp: bool
                     ) -> np.ndarray:
    """The profile's value at steps 1..steps: held from each point until the next (or linear
    between points with ``ramp``), the first value before the first point, the last after."""
    st = np.array([p[0] for p in profile], float)
    val = np.array([p[1] for p in profile], float)
    k = np.arange(1, steps + 1, dtype=float)
    if ramp and len(st) > 1:
        return np.interp(k, st, val)
    j = np.clip(np.searchsorted(st, k, side="right") - 1, 0, len(st) - 1)
    return val[j]



SPEED_SCAN = 9  # samples of the steady speed over the steady-feasible zeta^- range
EDGE_MARGIN = 1e-4  # an out-of-reach speed's zeta^-: this far inside the range (of its half)


@dataclass(frozen=True)
class SpeedReference:
    """The zeta^- reference of a speed reference (SPEC 11): ``zeta_minus`` [kg^2 m^4/s^2] is the
    controller's own steady state walking at ``steady_speed`` [m/s] (``= speed`` to 1e-12 when
    ``reachable``; otherwise the steady state closest to it, at an end of the range the
    contact conditions and thrust limits allow), with its thrust ``thrust`` [N]."""

    speed: float
    zeta_minus: float
    steady_speed: float
    reachable: bool
    thrust: tuple[float, ...]


def steady_speed(planner: Planner, zd: ZeroDynamics, x: float
                 ) -> tuple[float | None, np.ndarray | None]:
    """Average speed [m/s] (step length over the zero-dynamics step time of the periodic orbit)
    of the controller's steady state at zeta^- = ``x`` (:meth:`Planner.steady`: the thrust it
    settles on, contact rows and cutting planes included), and that thrust; None when no
    thrust holds ``x``."""
    u, _ = planner.steady(x)
    if u is None:
        return None, None
    th = planner.thrust
    md = len(th.driven)
    force = np.zeros((1, th.n_int, zd.model.n_thrusters))
    force[0][:, th.driven] = np.asarray(u).reshape(-1, md)
    lc = limit_cycles(zd, Schedule(th.knots, force, np.zeros((1, th.n_int))))[0]
    return (float(lc.speed) if lc.exists else None), u


def speed_references(planner: Planner, zd: ZeroDynamics, speeds: Sequence[float],
                     x_nominal: float) -> dict[float, SpeedReference]:
    """The zeta^- reference of each speed [m/s] (SPEC 11): the ``x`` whose steady state under
    ``planner`` (ideal thrust on the control knots) walks at that speed, so that the closed
    loop, which settles on that steady state (deadbeat in zeta^-), walks at the speed the user
    asked for. The steady states exist on an interval of ``x`` (:meth:`Planner.
    steady_range`, on the grid rows; the cutting planes shrink it a little); the steady speed
    is sampled at ``SPEED_SCAN`` points over it, and a sign change of ``v(x) - v_ref`` between
    neighbours (or, without one, between an end of the steady states, located by bisection,
    and its nearest sample) is refined by Brent's method (the bracket nearest ``x_nominal``
    when there are several). Without one the speed is out of reach: the
    reference is the steady state whose speed is closest, at an end of the interval (located
    by bisection on the steady state's existence), ``EDGE_MARGIN`` of the half interval
    inside it."""
    rng = planner.steady_range()
    if rng is None:
        raise InputError.param("profile", "no steady state holds any zeta^- within the contact "
                                          "conditions and thrust limits: no speed can be "
                                          "tracked")
    lo, hi = rng
    lo = max(lo, 1e-9 * hi)
    pad = 1e-9 * (hi - lo)
    xs = np.linspace(lo + pad, hi - pad, SPEED_SCAN)
    vs = [steady_speed(planner, zd, float(x))[0] for x in xs]
    ok = [i for i, v in enumerate(vs) if v is not None]
    if not ok:
        raise InputError.param("profile", "the controller has no steady state that walks "
                                          "(contact conditions, thrust limits)")

    def edge(inside: int, outside: int) -> tuple[float, float]:
        """The last steady state between a sample that has one and one that has not."""
        a, b = xs[inside], xs[outside]
        va = vs[inside]
        for _ in range(60):
            m = 0.5 * (a + b)
            vm = steady_speed(planner, zd, m)[0]
            if vm is None:
                b = m
            else:
                a, va = m, vm
            if abs(b - a) <= 1e-10 * abs(a):
                break
        return float(a), float(va)

    points = [(float(xs[i]), vs[i]) for i in ok]
    ends: list[tuple[float, float]] = []

    def locate_ends() -> None:
        """The ends of the steady states (bisection where an end sample has none), added to
        the points: a speed between an end and the nearest sample is bracketed there."""
        if ends:
            return
        for i, out_i in ((ok[0], ok[0] - 1), (ok[-1], ok[-1] + 1)):
            ends.append(edge(i, out_i) if 0 <= out_i < len(xs) else (float(xs[i]), vs[i]))
        points[:] = sorted(set(points) | set(ends))

    def brackets(v: float) -> list[tuple[float, float]]:
        return [(p[0], q[0]) for p, q in zip(points[:-1], points[1:])
                if (p[1] - v) * (q[1] - v) <= 0]

    out = {}
    for v in sorted(set(map(float, speeds))):
        found = brackets(v)
        if not found:
            locate_ends()
            found = brackets(v)
        if found:
            a, b = min(found, key=lambda br: abs(0.5 * (br[0] + br[1]) - x_nominal))

            def speed_of(x: float) -> float:
                vx = steady_speed(planner, zd, x)[0]
                if vx is None:  # the steady states form an interval: only round-off gets here
                    raise ComputationError(f"the controller's steady state at zeta^- = {x:.6g} "
                                           f"kg^2 m^4/s^2 could not be computed")
                return vx

            fa, fb = speed_of(a) - v, speed_of(b) - v
            if fa == 0 or fb == 0:
                x = a if fa == 0 else b
            else:
                x = zd.zeta_for_speed(v, speed_of, a, b, xtol=1e-13 * b, rtol=1e-12)
            vx, u = steady_speed(planner, zd, x)
            out[v] = SpeedReference(v, float(x), float(vx), True, tuple(map(float, u)))
        else:
            x_end, _ = min(ends, key=lambda e: abs(e[1] - v))
            # inside the range by EDGE_MARGIN of it: at its very end the steady state is a
            # single thrust, and the step that reaches it from just below would saturate
            x = x_end + EDGE_MARGIN * (0.5 * (ends[0][0] + ends[1][0]) - x_end)
            vx, u = steady_speed(planner, zd, x)
            if vx is None:
                x, vx = x_end, steady_speed(planner, zd, x_end)[0]
                u = steady_speed(planner, zd, x)[1]
            out[v] = SpeedReference(v, float(x), float(vx), False, tuple(map(float, u)))
    return out
