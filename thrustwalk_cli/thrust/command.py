"""A thrust command through the thrusters' dynamics (SPEC 7): :class:`ThrustModel` (the
model's name, its constant command ``F_ss`` or a schedule piecewise in alpha, the dynamics of
:mod:`thrustwalk_cli.thrust.dynamics`), the option values of ``thrust_model`` and the bound on
a thruster's speed. Read by the simulation, the reduced cascade, the Floquet analysis and the
MuJoCo run (``thrustwalk_cli.simulation.closed_loop`` re-exports these names). Units: N, s."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from . import dynamics as thruster_models
from .dynamics import ThrusterDynamics
from .schedule import Schedule

PIECEWISE = "piecewise"  # ideal thrusters commanded by a schedule piecewise in alpha


def thrust_model_names() -> tuple[str, ...]:
    """The values of ``thrust_model``: the models of :data:`thrustwalk_cli.thrust.dynamics.
    MODELS` (ideal, first-order, second-order, ...) and ``piecewise``; the deprecated alias
    ``constant`` (= ideal) is accepted too."""
    return (*thruster_models.model_names(), PIECEWISE)


THRUST_MODELS = thrust_model_names()  # as when this module loaded (see thrust_model_names)

MAX_THRUSTER_RATE = 1000.0  # [1/s] the fastest pole of a thruster model (thruster_rate)


def thruster_rate(kind: str, wn: float, xi: float, tau: float, m: int = 1) -> float:
    """The fastest pole [1/s] of a thruster model: ``1/tau`` (first order), ``wn (xi +
    sqrt(xi^2 - 1))`` when overdamped, else ``wn`` (second order); 0 for ideal thrusters and
    piecewise commands; for any other model of :data:`thrustwalk_cli.thrust.dynamics.MODELS`
    the largest ``|eig(A)|`` of its dynamics for ``m`` thrusters (:meth:`~thrustwalk_cli.
    thrust.dynamics.ThrusterDynamics.matrices`; a model may give each thruster its own)."""
    kind = thruster_models.canonical(kind)
    if kind == "first-order":
        return 1.0 / tau
    if kind == "second-order":
        return wn * (xi + np.sqrt(xi * xi - 1.0)) if xi > 1.0 else wn
    if kind == PIECEWISE or kind not in thruster_models.MODELS:
        return 0.0
    A = thruster_models.make(kind, m, wn=wn, xi=xi, tau=tau).matrices()[0]
    return float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0


def given_dynamics(value: object, m: int, name: str = "thrust_model"
                   ) -> ThrusterDynamics | None:
    """``value`` when it is a :class:`ThrusterDynamics` (a model built once by
    ``tw.thruster_dynamics`` or by hand and passed instead of a model's name), checked for the
    robot's ``m`` thrusters and the speed bound (:data:`MAX_THRUSTER_RATE`); None for a name.
    :class:`InputError` naming ``name`` otherwise."""
    if not isinstance(value, ThrusterDynamics):
        return None
    if value.m != m:
        raise InputError.param(name, f"thruster dynamics for {value.m} thruster(s), but the "
                                     f"robot has {m}")
    A = value.matrices()[0]
    rate = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
    if rate > MAX_THRUSTER_RATE:
        raise InputError.param(name, f"poles up to {rate:.3g} 1/s are faster than "
                                     f"{MAX_THRUSTER_RATE:g} 1/s: on a step's time scale that is "
                                     "the ideal thrust model, and it makes the equations stiff")
    return value


def check_thruster_rate(kind: str, wn: float, xi: float, tau: float, m: int = 1) -> None:
    """A thruster model's fastest pole at most :data:`MAX_THRUSTER_RATE` (a time constant of
    1 ms): a faster thruster follows its command within a thousandth of a walking step, is
    the ``ideal`` model in effect, and makes the equations stiff (the explicit integrator
    would take millions of steps). :class:`InputError` on the model's parameters (``tau``;
    ``wn``, ``xi``). ``m``: the robot's thrusters (:func:`thruster_rate`)."""
    rate = thruster_rate(kind, wn, xi, tau, m)
    if rate > MAX_THRUSTER_RATE:
        params = thruster_models.MODELS[thruster_models.canonical(kind)].params
        names = params[0] if len(params) == 1 else (tuple(params) or "thrust_model")
        raise InputError.param(names, f"a thruster with a {1e3 / rate:.3g} ms time constant "
                                      f"(poles up to {rate:.3g} 1/s) is faster than "
                                      f"{1e3 / MAX_THRUSTER_RATE:g} ms: on a step's time scale it "
                                      "is the ideal thrust model (use that), and it makes the "
                                      "equations stiff")


@dataclass(frozen=True)
class ThrustModel:
    """How the thrust ``F_T`` [N] (one value per thruster) evolves (SPEC 7): a command through
    the thrusters' dynamics (:mod:`thrustwalk_cli.thrust.dynamics`).

    kind: a model of :data:`thrustwalk_cli.thrust.dynamics.MODELS` commanded by the constant
    ``target`` (``ideal``: ``F = F_ss``, alias ``constant``; ``first-order``: ``tau F' = F_ss
    - F``; ``second-order``: ``F'' + 2 xi w F' + w^2 F = w^2 F_ss``, states ``(F, F')``), or
    ``piecewise``: ideal thrusters commanded by ``schedule`` (constant on alpha intervals;
    force [N] or generalised [N m]).
    target: ``F_ss`` per thruster [N]. initial: thrust at t = 0 for the dynamic models [N]
    (the thruster at rest there: ``F'(0) = 0``). wn [rad/s], xi [1], tau [s]: the parameters
    the model takes. dynamics: the thrusters' dynamics (default: built from ``kind`` and the
    parameters).
    """

    kind: str
    target: np.ndarray
    wn: float = 2.0
    xi: float = 1.0
    tau: float = 0.5
    initial: np.ndarray | None = None
    schedule: Schedule | None = None
    dynamics: ThrusterDynamics | None = None

    @property
    def m(self) -> int:
        """The number of thrusters commanded."""
        return int(np.asarray(self.target).size)

    @property
    def piecewise(self) -> bool:
        """The command is a schedule piecewise constant in alpha."""
        return self.kind == PIECEWISE

    @property
    def n_states(self) -> int:
        """The number of thruster states (0 for ideal thrusters; SPEC 7)."""
        return self.dynamics.n_states

    @property
    def time_dependent(self) -> bool:
        """The thrust has states of its own (it depends on time, not on alpha alone)."""
        return self.dynamics.n_states > 0

    def initial_states(self) -> list[float]:
        """The thruster states at rest at the initial thrust ``initial`` [N] (zero when None)."""
        f0 = np.zeros(self.m) if self.initial is None else np.asarray(self.initial, float)
        return self.dynamics.rest(f0).tolist()

    def derivatives(self, z) -> list[float]:
        """``z'`` of the thruster states under the constant command ``F_ss`` (empty for ideal
        thrusters)."""
        return self.dynamics.rates(z, self._target)

    def derivatives_rows(self, Z: np.ndarray) -> np.ndarray:
        """:meth:`derivatives` of every row of ``Z`` (K, nz), bit for bit."""
        return self.dynamics.rates_rows(Z, self._target)

    def force(self, z) -> list[float]:
        """Thrust per thruster [N] under the constant command, from the states ``z``
        (piecewise thrust depends on the alpha interval: see
        :meth:`thrustwalk_cli.simulation.closed_loop.ClosedLoop.force`)."""
        if self.piecewise:
            return self._target
        return self.dynamics.thrust(z, self._target)

    def __post_init__(self):
        object.__setattr__(self, "_target", [float(v) for v in np.asarray(self.target, float)])
        if self.dynamics is None:
            dyn = (thruster_models.ideal(self.m) if self.piecewise else
                   thruster_models.make(self.kind, self.m, wn=self.wn, xi=self.xi,
                                        tau=self.tau))
            object.__setattr__(self, "dynamics", dyn)
