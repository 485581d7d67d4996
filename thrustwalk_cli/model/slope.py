"""The robot on a slope (SPEC 14): the compiled model in the slope frame.

The slope frame has x along the ground (rising along +x when the slope ``gamma`` [rad] is
positive, uphill) and y normal to it. Every formula of SPEC 1-13 holds unchanged there, with
gravity ``g_s = g (-sin gamma, -cos gamma)``. D, C, the swing foot, the guard and the impact do
not change; what changes is linear in ``(cos gamma, sin gamma)``:

    V_s(q)   = cos(gamma) V(q) + sin(gamma) M g x_com(q)                         [J]
    G_s(q)   = cos(gamma) G(q) + sin(gamma) G_x(q),   G_x = g D_u[x-row, :N]     [N m]
    G_u,s    = [G_s; M g sin(gamma); M g cos(gamma)]   (the stance-foot rows)     [N]
    B_F,s    = J_k^T Rot(-gamma) d_k  for a thruster fixed in the world          [m]
             = cos(gamma) J_k^T d_k + sin(gamma) J_k^T d_k^perp,  d^perp = (d_y, -d_x)
    B_F,s    = B_F for a thruster fixed in its link (its direction turns with the link)

(``D_u``'s foot rows are ``d(sum m_i p_i)/dq``, so ``g D_u[N, :N]`` is the gradient of
``M g x_com``.) ``J_k`` of a thruster point comes from its link's frame origin and end point
(``link_points_J``): a point ``p`` of a rigid link is ``o + a (e - o) + b perp(e - o)`` with
constant ``a, b``, so ``J_p = J_o + a (J_e - J_o) + b perp(J_e - J_o)`` exactly.

:func:`slope_model` returns a :class:`SlopeModel`, a :class:`CompiledModel` whose ``G``,
``h``, ``V``, ``h_u``, ``B_F``, ``B_Fu`` and ``thruster_dirs`` (and their list-in, list-out
``_s`` forms, which the SciPy simulation calls) are those of the slope frame; everything else
is the flat model's. Its instruction tape is refused (a caller taking it would silently run
level ground): the compiled simulation takes the flat model's tape and the slope as a
parameter instead and evaluates it at the turned posture ``q_N + gamma``
(``simulation/kernel.tilted``: the level-ground model of the robot turned rigidly by
``gamma`` is the slope-frame model, an independent route to the same numbers).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ComputationError, InputError, check_number
from .compiled import CompiledModel

MAX_SLOPE = 0.5 * math.pi  # [rad] |gamma| must stay below: beyond it the ground is a wall


def check_slope(value: object, name: str = "slope") -> float:
    """``value`` as a slope angle [rad] with ``|gamma| < pi/2``; :class:`InputError` naming
    ``name`` otherwise (NaN, infinite, not a number, a wall or an overhang)."""
    v = check_number(name, value, unit="rad")
    if not abs(v) < MAX_SLOPE:
        raise InputError.param(name, f"a slope is an angle in radians with |slope| < pi/2 "
                                     f"(1.5708), got {v:g}")
    return float(v)


class SlopeParts:
    """The parts of the slope-frame model that multiply ``sin(gamma)`` (module docstring),
    from a flat compiled model: ``G_x(q)`` [N m], ``M g x_com(q)`` [J], ``J_k^T d_k^perp``
    [m] of the world-frame thrusters (zero columns for link-frame ones) and their directions
    ``d_k^perp``; ``world`` marks the world-frame thrusters."""

    def __init__(self, model: CompiledModel):
        self.model = model
        robot = model.robot
        self.mg = robot.total_mass * robot.gravity
        self.g = robot.gravity
        self.world = np.array([t.frame == "world" for t in robot.thrusters], bool)
        self._points = []
        for t in robot.thrusters:
            self._points.append(_point_coefficients(robot, t.link, t.point)
                                if t.frame == "world" else None)
        if len(self.world):
            self._check()

    def G_x(self, q: np.ndarray) -> np.ndarray:
        """``d(M g x_com)/dq`` [N m], shape ``q.shape``."""
        q = np.asarray(q, float)
        n = self.model.n
        return self.g * self.model.D_u(q)[..., n, :n]

    def V_x(self, q: np.ndarray) -> np.ndarray:
        """``M g x_com(q)`` [J], shape ``q.shape[:-1] + (1,)`` (as ``V``)."""
        return self.mg * self.model.p_com(np.asarray(q, float))[..., :1]

    def thruster_jacobian(self, q: np.ndarray, k: int) -> np.ndarray:
        """``J_k = dp_k/dq`` (..., 2, N) of world-frame thruster ``k`` [m]."""
        idx, a, b = self._points[k]
        LJ = self.model.link_points_J(np.asarray(q, float))
        Jo, Je = LJ[..., 4 * idx:4 * idx + 2, :], LJ[..., 4 * idx + 2:4 * idx + 4, :]
        u = Je - Jo
        perp = np.stack([-u[..., 1, :], u[..., 0, :]], axis=-2)
        return Jo + a * u + b * perp

    def B_perp(self, q: np.ndarray) -> np.ndarray:
        """``J_k^T d_k^perp`` per world thruster, zero for link thrusters: (..., N, m) [m]."""
        q = np.asarray(q, float)
        m = self.model.n_thrusters
        out = np.zeros(q.shape + (m,))
        dirs = self.model.robot.thrusters
        for k in range(m):
            if self.world[k]:
                d = np.asarray(dirs[k].direction, float)
                J = self.thruster_jacobian(q, k)
                out[..., k] = np.einsum("...rn,r->...n", J, np.array([d[1], -d[0]]))
        return out

    def dirs_perp(self, q: np.ndarray) -> np.ndarray:
        """``d_k^perp`` of world thrusters (zero for link ones) as columns: (..., 2, m)."""
        q = np.asarray(q, float)
        m = self.model.n_thrusters
        out = np.zeros(q.shape[:-1] + (2, m))
        for k, t in enumerate(self.model.robot.thrusters):
            if self.world[k]:
                out[..., 0, k], out[..., 1, k] = t.direction[1], -t.direction[0]
        return out

    def _check(self) -> None:
        """The reconstructed ``J_k^T d_k`` equals the compiled ``B_F`` column (one posture
        away from every symmetry): the point coefficients are those of the model."""
        model = self.model
        q = 0.3 + 0.17 * np.arange(model.n)
        BF = model.B_F(q)
        for k, t in enumerate(model.robot.thrusters):
            if not self.world[k]:
                continue
            col = self.thruster_jacobian(q, k).T @ np.asarray(t.direction, float)
            if not np.allclose(col, BF[:, k], rtol=1e-10, atol=1e-12 * (1 + np.abs(BF).max())):
                raise ComputationError(f"thruster {t.name}: its point Jacobian does not "
                                       "reproduce B_F; the slope frame cannot rotate it")


def _point_coefficients(robot, link: str, point) -> tuple[int, float, float]:
    """``(link index, a, b)`` with ``p = a e + b perp(e)`` for the link's end point ``e``
    (local coordinates, from the link's frame origin)."""
    idx = robot.link_index(link)
    lk = robot.links[idx]
    e = np.asarray(lk.end, float)
    ee = float(e @ e)
    if not ee > 0.0:
        raise InputError.param("slope", f"link {link!r} has its end point at its joint, so "
                                        "the direction of its world-frame thruster cannot be "
                                        "turned into the slope frame")
    p = np.asarray(point, float)
    return idx, float(p @ e) / ee, float(e[0] * p[1] - e[1] * p[0]) / ee


class SlopeModel(CompiledModel):
    """A :class:`CompiledModel` in the frame of a slope ``gamma`` [rad] (module docstring).
    ``slope`` is the angle; ``flat`` the level-ground model it is made from."""

    slope: float
    flat: CompiledModel

    @property
    def tape(self):  # noqa: D401 - a refusal, not a value
        raise ComputationError("a slope-frame model has no instruction tape: the compiled "
                               "simulation takes the level-ground tape and the slope")

    @tape.setter
    def tape(self, value) -> None:  # the copied instance dictionary holds the flat tape
        pass


def slope_model(model: CompiledModel, gamma: float, parts: SlopeParts | None = None
                ) -> CompiledModel:
    """``model`` in the frame of the slope ``gamma`` [rad] (module docstring); ``model`` itself
    when ``gamma == 0`` (level ground, bit for bit)."""
    gamma = check_slope(gamma)
    if gamma == 0.0:
        return getattr(model, "flat", model)
    flat = getattr(model, "flat", model)
    return gravity_frame_model(flat, math.cos(gamma), math.sin(gamma), parts, gamma)


def gravity_frame_model(flat: CompiledModel, c: float, s: float,
                        parts: SlopeParts | None = None, gamma: float | None = None
                        ) -> SlopeModel:
    """``flat`` with gravity ``g (-s, -c)`` and world thrusters turned by ``(c, s)`` (module
    docstring with ``c = cos(gamma)``, ``s = sin(gamma)``); ``c = 0, s = 1`` is the part of
    every quantity that multiplies ``sin(gamma)`` (gravity along the ground only), which the
    slope map (``contact/slope_map.py``) combines with the level-ground part."""
    parts = parts or SlopeParts(flat)
    if gamma is None:
        gamma = math.atan2(s, c)
    cw = np.where(parts.world, c, 1.0)  # per thruster: world ones turn, link ones do not
    n = flat.n
    sm = SlopeModel.__new__(SlopeModel)
    sm.__dict__.update({k: v for k, v in flat.__dict__.items() if k != "tape"})
    sm.slope, sm.flat, sm.parts = gamma, flat, parts

    def G(q):
        return c * flat.G(q) + s * parts.G_x(q)

    def h(q, dq):
        return flat.h(q, dq) - flat.G(q) + G(q)

    def V(q):
        return c * flat.V(q) + s * parts.V_x(q)

    def h_u(q, dq_u):
        q = np.asarray(q, float)
        out = flat.h_u(q, dq_u).copy()
        out[..., :n] += G(q) - flat.G(q)
        out[..., n] += parts.mg * s
        out[..., n + 1] += parts.mg * (c - 1.0)
        return out

    def B_F(q):
        return flat.B_F(q) * cw + s * parts.B_perp(q) if len(cw) else flat.B_F(q)

    def dirs(q):
        return flat.thruster_dirs(q) * cw + s * parts.dirs_perp(q) if len(cw) else \
            flat.thruster_dirs(q)

    def B_Fu(q):
        return np.concatenate([B_F(q), dirs(q)], axis=-2)

    for name, fn in (("G", G), ("h", h), ("V", V), ("h_u", h_u), ("B_F", B_F),
                     ("B_Fu", B_Fu), ("thruster_dirs", dirs)):
        sm.__dict__[name] = fn
        sm.__dict__[name + "_s"] = _scalar(fn)
    return sm


def _scalar(fn):
    """The list-in, list-out form of ``fn`` (one state; outputs flat, row-major), as the
    compiled model's ``_s`` functions."""
    def f(*args):
        return np.asarray(fn(*(np.asarray(a, float) for a in args)), float).ravel().tolist()
    return f
