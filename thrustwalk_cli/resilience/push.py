"""Impulsive pushes (SPEC 12): where a push acts, what it does to the joint rates, and whether
the stance foot stays pinned under it.

A push of impulse ``P`` (a 2-vector, N s) at the point ``p = (1 - at) origin + at end`` of a
link, stance foot pinned, changes the rates by

    Delta q' = D(q)^-1 J_p(q)^T P                                        (SPEC 12)

(the compiled simulation applies exactly this, ``simulation.batch.push_row``). The stance foot
stays pinned only if the impulsive ground reaction it needs is admissible. From the unpinned
model ``q_u = [q; x_1; y_1]`` with the stance-foot constraint ``E_1 q_u' = 0``,
``E_1 = [0, I_2]``, and the push acting at ``J_pu = [J_p, I_2]``:

    D_u Delta q_u' = J_pu^T P + E_1^T F,   E_1 Delta q_u' = 0
    =>  F = -(E_1 D_u^-1 E_1^T)^-1 E_1 D_u^-1 J_pu^T P                  [N s]

linear in ``P`` and independent of the rates (section 5's impact impulse, with the push in
place of the swing foot's constraint). Conditions: ``F^v > 0`` (else the push lifts the stance
foot) and ``|F^h| <= mu F^v`` (else it slips). A push that lasts ``duration`` [s] instead of an
instant is checked, to first order, with the stance force at the push over that time added:
``F + duration F_1`` (``duration`` 0: the impulsive condition of SPEC 12 exactly); the
simulation still applies the push as an impulse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model.compiled import CompiledModel


@dataclass(frozen=True)
class PushPoint:
    """Where a push acts: the point ``(1 - at) origin + at end`` of link ``link`` (index
    ``index`` in the robot's links); ``direction`` the unit vector of a positive impulse in
    the world frame."""

    link: str
    index: int
    at: float
    direction: tuple[float, float]

    def impulse(self, value: float) -> np.ndarray:
        """The impulse vector [N s] of a push of signed size ``value`` [N s]."""
        return float(value) * np.asarray(self.direction, float)


def world_to_slope(P: np.ndarray, gamma: float) -> np.ndarray:
    """A world-frame vector ``P`` (an impulse [N s]) in the frame of the slope ``gamma`` [rad,
    positive uphill] (SPEC 14): ``Rot(-gamma) P``; ``P`` itself on level ground (as
    :func:`~thrustwalk_cli.simulation.batch.push_row` turns the push it applies)."""
    P = np.asarray(P, float)
    if gamma == 0.0:
        return P
    c, s = np.cos(gamma), np.sin(gamma)
    return np.array([c * P[0] + s * P[1], c * P[1] - s * P[0]])


def push_point(model: CompiledModel, link: str | None = None, at: float = 1.0,
               direction=(1.0, 0.0)) -> PushPoint:
    """The push point (default: the end of the stance link: the hip of a one-link
    stance leg, a kneed walker's stance knee, ``Robot.stance_end_text``) and
    the normalised direction of a positive impulse (default: forward, +x)."""
    robot = model.robot
    name = robot.root.name if link is None else link
    if name not in robot.link_names:
        raise InputError.param("push_link", f"unknown link {name!r} (robot {robot.name} has: "
                                            f"{', '.join(robot.link_names)})")
    if not (np.isfinite(at) and 0.0 <= at <= 1.0):
        raise InputError.param("push_at", f"must lie in [0, 1] (0: the link's joint, 1: its "
                                          f"end point; got {at:g})")
    d = np.asarray(direction, float).ravel()
    n = float(np.hypot(*d)) if d.size == 2 and np.all(np.isfinite(d)) else 0.0
    if not n > 0:
        raise InputError.param("push_direction", "a direction is two numbers, not both zero "
                                                 "(e.g. 1,0: forward)")
    return PushPoint(name, robot.link_index(name), float(at), (float(d[0] / n),
                                                               float(d[1] / n)))


def point_jacobian(model: CompiledModel, q: np.ndarray, point: PushPoint) -> np.ndarray:
    """``J_p = dp/dq`` (2, N) of the push point at ``q`` [m] (from the links' frame origins and
    end points, as the simulation's push)."""
    LJ = model.link_points_J(np.asarray(q, float))
    i = 4 * point.index
    return (1.0 - point.at) * LJ[i:i + 2] + point.at * LJ[i + 2:i + 4]


def rate_jump(model: CompiledModel, q: np.ndarray, point: PushPoint,
              P: np.ndarray) -> np.ndarray:
    """``Delta q' = D(q)^-1 J_p(q)^T P`` [rad/s] with the stance foot pinned (SPEC 12)."""
    J = point_jacobian(model, q, point)
    return np.linalg.solve(model.D(np.asarray(q, float)), J.T @ np.asarray(P, float))


def stance_impulse(model: CompiledModel, q: np.ndarray, point: PushPoint,
                   P: np.ndarray) -> np.ndarray:
    """The impulsive ground reaction ``F = (F^h, F^v)`` [N s] on the pinned stance foot
    (module docstring), and with it the unpinned rate jump: returns ``F``."""
    q = np.asarray(q, float)
    N = model.n
    Du = model.D_u(q)
    J = point_jacobian(model, q, point)
    Ju = np.hstack([J, np.eye(2)])
    E1 = np.hstack([np.zeros((2, N)), np.eye(2)])
    DinvE = np.linalg.solve(Du, E1.T)  # (N+2, 2)
    DinvJ = np.linalg.solve(Du, Ju.T @ np.asarray(P, float))
    return -np.linalg.solve(E1 @ DinvE, E1 @ DinvJ)


@dataclass(frozen=True)
class PushCheck:
    """Whether the stance foot stays pinned under a push: ``outcome`` is ``""`` (it does),
    ``lifted`` (``F^v <= 0``) or ``slipped`` (``|F^h| > mu F^v``); ``impulse`` the ground
    reaction [N s] (with the orbit's stance force over ``duration`` added), ``ratio``
    ``|F^h|/F^v`` (None when ``F^v <= 0``)."""

    outcome: str
    reason: str
    impulse: tuple[float, float]
    ratio: float | None


def check_push(F: np.ndarray, mu: float, stance_force: np.ndarray | None = None,
               duration: float = 0.0) -> PushCheck:
    """The SPEC 12 condition on the stance foot's reaction ``F`` [N s] to a push (module
    docstring); ``stance_force`` [N] the ground force at the push (before it), counted over
    ``duration`` [s]."""
    G = np.asarray(F, float) + (duration * np.asarray(stance_force, float)
                                if duration > 0 and stance_force is not None else 0.0)
    h, v = float(G[0]), float(G[1])
    if not v > 0:
        return PushCheck("lifted", f"the push lifts the stance foot: its impulsive ground "
                                   f"reaction has vertical part {v:.4g} N s <= 0", (h, v), None)
    ratio = abs(h) / v
    if ratio > mu:
        return PushCheck("slipped", f"the push makes the stance foot slip: its impulsive "
                                    f"ground reaction has |F^h|/F^v = {ratio:.4g} > mu = "
                                    f"{mu:g}", (h, v), ratio)
    return PushCheck("", "", (h, v), ratio)
