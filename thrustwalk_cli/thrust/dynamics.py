"""Thruster dynamics (SPEC 7, 11, 13): one linear family, as plain data.

Each thruster has its own linear dynamics from its command ``u`` [N] (the steady thrust
``F_ss``, or a schedule's value in alpha) to the thrust it delivers ``F`` [N], with ``n``
states ``z`` (none for an ideal thruster). In the standard form

    z' = A z + B u,    F = C z + D u

and, as stored and evaluated, in the *servo form*

    E z' = P z + q (u - k.z),    F = c.z + d u,    A = E^-1 (P - q k^T),  B = E^-1 q

(``E`` diagonal: a time constant [s] per state, or 1). The family:

==============  ======================================  ======================================
model           equation                                servo form (per thruster)
==============  ======================================  ======================================
ideal           ``F = u`` (no state)                    ``d = 1``
first-order     ``tau F' = u - F``,  ``z = F``          ``E = tau, P = 0, q = 1, k = c = 1``
second-order    ``F'' + 2 xi wn F' + wn^2 F = wn^2 u``  ``E = 1, P = [[0, 1], [0, -2 xi wn]],``
                ``z = (F, F')``                         ``q = (0, wn^2), k = c = (1, 0)``
==============  ======================================  ======================================

Why the servo form and not (A, B) alone: the compiled kernel and the Python paths evaluate a
state's rate row by row as ``(sum q e + sum P z) / E`` with the command error ``e = u - k.z``
computed first, which are exactly the operations of the classic models (a lag divides the
error by its time constant, the second-order thruster multiplies it by ``wn^2``), so their
numbers do not depend on the family that now holds them. A model given in the standard form
only (:func:`state_space`) is the servo form with ``E = 1, P = A, q = B, k = 0``.

Commands are not dynamics: constant over a run (``F_ss`` per thruster) or piecewise constant
in alpha (:mod:`thrustwalk_cli.thrust.schedule`); the simulation's ``ThrustModel`` pairs a
command with a :class:`ThrusterDynamics`. The states of all thrusters are stacked state index
first: state ``i`` of every thruster that has one, in the robot's thruster order, then state
``i + 1`` (``F`` of every thruster, then ``F'`` of every thruster): :attr:`ThrusterDynamics.
layout`; the stacked system (block diagonal) is :meth:`ThrusterDynamics.matrices`, what the
Floquet analysis reads (``eig(exp(A T))``, SPEC 13), and :meth:`ThrusterDynamics.kernel_data`
what the compiled kernel integrates.

Adding a thruster model (docs/architecture.md): a function ``build(m, **parameters)`` that
returns a :class:`ThrusterDynamics` (one :class:`Servo` per thruster) and an entry in
:data:`MODELS` naming its parameters. The simulation (numba kernel and SciPy path), the
reduced cascade, the Floquet analysis and the controller's step model read the data; only an
option for a new parameter goes into the option tables (``commands/``, the sweep file).

Units: SI (thrust N, time s, wn rad/s, xi 1).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, check_choice, check_count, check_number


@dataclass(frozen=True, eq=False)
class Servo:
    """The linear dynamics of one thruster in the servo form (module docstring):
    ``E z' = P z + q (u - k.z)``, ``F = c.z + d u``, ``n`` states.

    ``labels``: a name per state, ``{}`` standing for the thruster's name (``"F_{}"``,
    ``"F_{}'"``). ``rest``: the states at rest per unit command (``z = rest u``; None: the
    model has no unique rest state). ``response``: the closed form ``t -> (Phi (g, n), Psi
    (g,))`` of :meth:`response`, or None (then the matrix exponential)."""

    E: np.ndarray
    P: np.ndarray
    q: np.ndarray
    k: np.ndarray
    c: np.ndarray
    d: float
    labels: tuple[str, ...]
    rest: np.ndarray | None
    closed_form: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = field(
        default=None, repr=False)

    @property
    def n(self) -> int:
        """The number of states of this thruster."""
        return int(self.E.size)

    @property
    def A(self) -> np.ndarray:
        """``E^-1 (P - q k^T)`` (n, n) [1/s]."""
        return (self.P - np.outer(self.q, self.k)) / self.E[:, None]

    @property
    def B(self) -> np.ndarray:
        """``E^-1 q`` (n,) [1/s]."""
        return self.q / self.E

    def response(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(Phi, Psi)`` at times ``t`` (g,) [s]: ``F(t) = Phi(t) z_0 + Psi(t) u`` for a
        command ``u`` held from ``t = 0``, with ``Phi = c e^{A t}`` (g, n) and ``Psi = c
        int_0^t e^{A s} ds B + d`` (g,) (SPEC 11): the closed form when the model has one,
        else the matrix exponential of ``[[A, B], [0, 0]] t``."""
        t = np.asarray(t, float)
        if self.closed_form is not None:
            return self.closed_form(t)
        from scipy.linalg import expm

        n = self.n
        M = np.zeros((n + 1, n + 1))
        M[:n, :n], M[:n, n] = self.A, self.B
        Phi, Psi = np.empty((t.size, n)), np.empty(t.size)
        for i, ti in enumerate(t.ravel()):
            X = expm(M * ti)
            Phi[i], Psi[i] = self.c @ X[:n, :n], self.c @ X[:n, n] + self.d
        return Phi, Psi


def ideal_servo() -> Servo:
    """``F = u``: no state."""
    z = np.zeros(0)
    return Servo(z, np.zeros((0, 0)), z, z, z, 1.0, (), z)


def first_order_servo(tau: float) -> Servo:
    """``tau F' = u - F`` (z = F), ``tau`` [s]."""
    tau = float(tau)

    def closed_form(t):
        e = np.exp(-t / tau)
        return e[:, None], 1.0 - e

    one = np.ones(1)
    return Servo(np.array([tau]), np.zeros((1, 1)), one, one, one, 0.0, ("F_{}",), one,
                 closed_form)


def second_order_servo(wn: float, xi: float) -> Servo:
    """``F'' + 2 xi wn F' + wn^2 F = wn^2 u`` (z = (F, F')), ``wn`` [rad/s], ``xi`` [1]."""
    wn, xi = float(wn), float(xi)
    w2, d = wn * wn, 2.0 * xi * wn

    def closed_form(t):
        """The free response ``h(t; F_0, F'_0)`` of ``F'' + 2 xi wn F' + wn^2 F = 0`` (under-,
        critically or over-damped): ``Phi = [h(t; 1, 0), h(t; 0, 1)]``, ``Psi = 1 -
        h(t; 1, 0)``."""
        w = wn
        if abs(xi - 1.0) < 1e-9:
            e = np.exp(-w * t)
            h10, h01 = e * (1.0 + w * t), e * t
        elif xi < 1.0:
            wd = w * np.sqrt(1.0 - xi * xi)
            e = np.exp(-xi * w * t)
            c, sn = np.cos(wd * t), np.sin(wd * t)
            h10, h01 = e * (c + xi * w / wd * sn), e * sn / wd
        else:
            r = w * np.sqrt(xi * xi - 1.0)
            r1, r2 = -xi * w + r, -xi * w - r
            e1, e2 = np.exp(r1 * t), np.exp(r2 * t)
            h10 = (-r2 * e1 + r1 * e2) / (r1 - r2)
            h01 = (e1 - e2) / (r1 - r2)
        return np.stack([h10, h01], axis=-1), 1.0 - h10

    sel = np.array([1.0, 0.0])
    return Servo(np.ones(2), np.array([[0.0, 1.0], [0.0, -d]]), np.array([0.0, w2]), sel,
                 sel, 0.0, ("F_{}", "F_{}'"), sel, closed_form)


def state_space_servo(A, B, C, D: float = 0.0, labels: Sequence[str] | None = None) -> Servo:
    """One thruster given in the standard form ``z' = A z + B u``, ``F = C z + D u`` (the
    servo form with ``E = 1, P = A, q = B, k = 0``). ``labels``: state names (``{}``: the
    thruster's name; default ``z1_{}, z2_{}, ...``)."""
    A = np.atleast_2d(np.asarray(A, float))
    n = A.shape[0]
    B, C = np.asarray(B, float).reshape(n), np.asarray(C, float).reshape(n)
    try:
        rest = -np.linalg.solve(A, B) if n else np.zeros(0)
    except np.linalg.LinAlgError:
        rest = None
    return Servo(np.ones(n), A, B, np.zeros(n), C, float(D),
                 tuple(labels) if labels is not None else tuple(f"z{i + 1}_{{}}"
                                                                for i in range(n)), rest)


@dataclass(frozen=True, eq=False)
class ThrusterDynamics:
    """The dynamics of a robot's thrusters: ``kind`` (the model's name) and one
    :class:`Servo` per thruster (the robot's order); their states stacked state index first
    (module docstring, :attr:`layout`)."""

    kind: str
    servos: tuple[Servo, ...]

    @property
    def m(self) -> int:
        """The number of thrusters."""
        return len(self.servos)

    @property
    def layout(self) -> tuple[tuple[int, ...], ...]:
        """Per thruster, the positions of its states in the stacked state ``z``."""
        cached = self.__dict__.get("_layout")
        if cached is None:
            pos: list[list[int]] = [[] for _ in self.servos]
            nmax = max((s.n for s in self.servos), default=0)
            j = 0
            for i in range(nmax):
                for t, s in enumerate(self.servos):
                    if s.n > i:
                        pos[t].append(j)
                        j += 1
            cached = tuple(tuple(p) for p in pos)
            object.__setattr__(self, "_layout", cached)
        return cached

    @property
    def n_states(self) -> int:
        """The number of states of all thrusters, stacked in ``z`` (SPEC 7, 13)."""
        return sum(s.n for s in self.servos)

    def state_names(self, thrusters: Sequence[str]) -> list[str]:
        """The names of the stacked states for thrusters named ``thrusters``."""
        out = [""] * self.n_states
        for name, s, pos in zip(thrusters, self.servos, self.layout):
            for label, j in zip(s.labels, pos):
                out[j] = label.format(name)
        return out

    def rest(self, u: Sequence[float]) -> np.ndarray:
        """The stacked states at rest under the commands ``u`` [N] (one per thruster): the
        thrust ``F = u`` held (``F' = 0``). :class:`InputError` for a model without a unique
        rest state."""
        z = np.zeros(self.n_states)
        for t, (s, pos) in enumerate(zip(self.servos, self.layout)):
            if s.n and s.rest is None:
                raise InputError.param("thrust_model", f"the {self.kind} thruster model has no "
                                                       "unique rest state")
            for r, j in zip(() if s.rest is None else s.rest, pos):
                z[j] = float(u[t]) * r if r != 0.0 else 0.0
        return z

    @property
    def _lists(self) -> list[tuple]:
        """Per thruster with states: (index, positions, k, P, q, E, c, d) as Python floats."""
        cached = self.__dict__.get("_py")
        if cached is None:
            cached = [(t, list(pos), s.k.tolist(), s.P.tolist(), s.q.tolist(), s.E.tolist(),
                       s.c.tolist(), float(s.d))
                      for t, (s, pos) in enumerate(zip(self.servos, self.layout))]
            object.__setattr__(self, "_py", cached)
        return cached

    def rates(self, z: Sequence[float], u: Sequence[float]) -> list[float]:
        """``z'`` of the stacked states ``z`` under the commands ``u`` (Python floats, the
        servo form's operations in the kernel's order: the command error, then per state
        ``(sum q e + sum P z) / E``)."""
        out = [0.0] * self.n_states
        for t, pos, k, P, q, E, _, _ in self._lists:
            if not pos:
                continue
            zs = [z[j] for j in pos]
            acc = 0.0
            for kk, zz in zip(k, zs):
                acc += kk * zz
            e = u[t] - acc
            for i, j in enumerate(pos):
                acc = 0.0 + q[i] * e
                for pij, zz in zip(P[i], zs):
                    acc += pij * zz
                out[j] = acc / E[i]
        return out

    def rates_rows(self, Z: np.ndarray, u: Sequence[float]) -> np.ndarray:
        """:meth:`rates` of every row of ``Z`` (K, nz): ``z'`` (K, nz), with the same
        operations in the same order as :meth:`rates` (so equal to it bit for bit)."""
        Z = np.asarray(Z, float)
        out = np.zeros((Z.shape[0], self.n_states))
        for t, pos, k, P, q, E, _, _ in self._lists:
            if not pos:
                continue
            zs = [Z[:, j] for j in pos]
            acc = np.zeros(Z.shape[0])
            for kk, zz in zip(k, zs):
                acc = acc + kk * zz
            e = u[t] - acc
            for i, j in enumerate(pos):
                acc = 0.0 + q[i] * e
                for pij, zz in zip(P[i], zs):
                    acc = acc + pij * zz
                out[:, j] = acc / E[i]
        return out

    def thrust(self, z: Sequence[float], u: Sequence[float]) -> list[float]:
        """The delivered thrust ``F = c.z + d u`` [N] per thruster."""
        out = []
        for t, pos, _, _, _, _, c, d in self._lists:
            acc = 0.0
            for cc, j in zip(c, pos):
                acc += cc * z[j]
            out.append(acc + d * u[t])
        return out

    def thrust_rows(self, Z: np.ndarray, u: Sequence[float]) -> np.ndarray:
        """:meth:`thrust` of every row of ``Z`` (K, nz): ``F`` (K, m) [N], with the same
        operations in the same order as :meth:`thrust` (so equal to it bit for bit)."""
        Z = np.asarray(Z, float)
        out = np.empty((Z.shape[0], self.m))
        for t, pos, _, _, _, _, c, d in self._lists:
            acc = np.zeros(Z.shape[0])
            for cc, j in zip(c, pos):
                acc = acc + cc * Z[:, j]
            out[:, t] = acc + d * u[t]
        return out

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The stacked standard form ``(A, B, C, D)``: ``z' = A z + B u``, ``F = C z + D u``,
        shapes (nz, nz), (nz, m), (m, nz), (m, m)."""
        nz, m = self.n_states, self.m
        A, B, C, D = np.zeros((nz, nz)), np.zeros((nz, m)), np.zeros((m, nz)), np.zeros((m, m))
        for t, (s, pos) in enumerate(zip(self.servos, self.layout)):
            p = list(pos)
            A[np.ix_(p, p)] = s.A
            B[p, t] = s.B
            C[t, p] = s.c
            D[t, t] = s.d
        return A, B, C, D

    def kernel_data(self) -> dict[str, np.ndarray]:
        """The stacked servo form for the compiled kernel: ``E`` (nz,), ``P`` (nz, nz),
        ``Q`` (nz, m), ``K`` (m, nz), ``C`` (m, nz), ``D`` (m, m) (zeros between thrusters),
        with ``E z' = P z + Q (u - K z)``, ``F = C z + D u``."""
        nz, m = self.n_states, self.m
        out = {"E": np.ones(nz), "P": np.zeros((nz, nz)), "Q": np.zeros((nz, m)),
               "K": np.zeros((m, nz)), "C": np.zeros((m, nz)), "D": np.zeros((m, m))}
        for t, (s, pos) in enumerate(zip(self.servos, self.layout)):
            p = list(pos)
            out["E"][p] = s.E
            out["P"][np.ix_(p, p)] = s.P
            out["Q"][p, t] = s.q
            out["K"][t, p] = s.k
            out["C"][t, p] = s.c
            out["D"][t, t] = s.d
        return out


# ------------------------------------------------------------------------------ the models
def ideal(m: int) -> ThrusterDynamics:
    """``m`` ideal thrusters: the thrust is the command."""
    return ThrusterDynamics("ideal", tuple(ideal_servo() for _ in range(m)))


def first_order(m: int, tau: float) -> ThrusterDynamics:
    """``m`` first-order lags ``tau F' = u - F``, ``tau`` [s]."""
    return ThrusterDynamics("first-order", tuple(first_order_servo(tau) for _ in range(m)))


def second_order(m: int, wn: float, xi: float) -> ThrusterDynamics:
    """``m`` second-order thrusters ``F'' + 2 xi wn F' + wn^2 F = wn^2 u`` (the paper's slow
    thruster), ``wn`` [rad/s], ``xi`` [1]."""
    return ThrusterDynamics("second-order",
                            tuple(second_order_servo(wn, xi) for _ in range(m)))


@dataclass(frozen=True)
class Model:
    """A named model of the family: the option names of its parameters and its builder
    ``build(m, **parameters)``; ``equation`` for help and documents."""

    params: tuple[str, ...]
    build: Callable[..., ThrusterDynamics]
    equation: str


# the option table of thruster models: name -> parameters and builder
MODELS: dict[str, Model] = {
    "ideal": Model((), ideal, "F = u (the thrust is the command)"),
    "first-order": Model(("tau",), first_order, "tau F' = u - F"),
    "second-order": Model(("wn", "xi"), second_order, "F'' + 2 xi wn F' + wn^2 F = wn^2 u"),
}
ALIASES = {"constant": "ideal"}  # deprecated option values (one release)


def canonical(kind: str) -> str:
    """The model's name for ``kind`` (an alias replaced); unknown names (and values that are
    not strings) unchanged."""
    return ALIASES.get(kind, kind) if isinstance(kind, str) else kind


def model_names() -> tuple[str, ...]:
    """The names of the models, in table order."""
    return tuple(MODELS)


def check_model(value: object, extra: Sequence[str] = (), name: str = "thrust_model") -> str:
    """``value`` a model's name (an alias accepted: the model's name returned) or one of
    ``extra`` (e.g. ``piecewise``, a command rather than dynamics); :class:`InputError`
    naming ``name`` otherwise (:func:`~thrustwalk_cli.errors.check_choice`)."""
    return check_choice(name, canonical(value) if isinstance(value, str) else value,
                        (*model_names(), *extra))


def make(kind: str, m: int, **values: float) -> ThrusterDynamics:
    """The dynamics of ``m`` thrusters of model ``kind`` (a name of :data:`MODELS` or an
    alias) from the parameter values ``values`` (e.g. ``wn``, ``xi``, ``tau``; those the
    model does not take are ignored). :class:`InputError` naming ``thrust_model`` for an
    unknown model."""
    name = canonical(kind)
    model = MODELS.get(name)
    if model is None:
        raise InputError.param("thrust_model", f"unknown model {kind!r} (choose from "
                                               f"{', '.join(MODELS)})")
    return model.build(m, **{p: values[p] for p in model.params if p in values})


UNITS = {"tau": "s", "wn": "rad/s", "xi": ""}  # the parameters of the models, > 0 each


def thruster_dynamics(kind: str, m: int, **parameters: float) -> ThrusterDynamics:
    """The public constructor (``tw.thruster_dynamics``): the dynamics of ``m`` thrusters of
    model ``kind`` (``ideal``; ``first-order`` with ``tau`` [s]; ``second-order`` with ``wn``
    [rad/s] and ``xi`` [1]; module docstring, SPEC 7, 13), every parameter of the model
    given and > 0. :class:`InputError` naming ``thrust_model`` (an unknown model), ``m`` or
    the parameter. ``.matrices()`` is the stacked (A, B, C, D) whose ``eig(expm(A T))`` are
    the thrusters' Floquet multipliers over a step of duration T."""
    name = check_model(kind)
    m = check_count("m", m, ge=0, le=64)
    model = MODELS[name]
    for p in parameters:
        if p not in model.params:
            raise InputError.param(p, f"not a parameter of the {name} model (it takes "
                                      f"{', '.join(model.params) or 'none'})")
    values = {}
    for p in model.params:
        if p not in parameters:
            raise InputError.param(p, f"required by the {name} model")
        values[p] = check_number(p, parameters[p], gt=0, largest=1e6, unit=UNITS.get(p, ""))
    return model.build(m, **values)
