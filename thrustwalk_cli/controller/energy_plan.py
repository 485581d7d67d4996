"""The energy objective of the per-step plan (SPEC 11 with SPEC 15 "Energy-optimal thrust",
issue 28): ``control --objective energy``.

With ideal thrust on knots ``alpha_1 < ... < alpha_n`` the plan's values ``u`` (interval-major,
``u[j * m_d + t]``: interval ``j``, driven thruster ``t``) are the thrust [N]. The step they
drive, predicted from the measured ``x_k`` by the affine step model (:mod:`.step_model`),

    zeta_k(alpha) = delta_zero^2 x_k + V_0(alpha) + Gamma(alpha) u

has ``|alpha'| = |kappa_1| sqrt(2 zeta_k)`` and ``dt = d|alpha| / |alpha'|``. The plan minimises
the driven thrusters' input energy over that predicted step [J]

    E(u) = sum_t sum_j int_{interval j} P_t(u_{j,t}, V_t(alpha)) dt,
           V_t = sign(u_{j,t}) d_t . p_t' = sign(u_{j,t}) b_t(alpha) |alpha'|

(``P_t`` the thruster's ``power:`` model, :mod:`..energetics.power`; a ``fuel`` model without
a heating value: its fuel mass [kg]) under exactly the constraints of the effort plan. The
objective is the one of :mod:`..optimize.min_energy` on the predicted step instead of a
periodic orbit: for the orbit frozen at an iterate (time weights ``r = 1/|alpha'|``, ``b_t``)
it is separable and convex (one :class:`~..optimize.min_energy.EnergyObjective` per driven
thruster, :class:`StepEnergy` stacks them); the plan is found by the same sequential convex
programme (:func:`~..optimize.min_energy.sequential_convex`: interior point with an
active-set finish for ``momentum``, HiGHS for the piecewise-linear kinds), whose fixed point
carries the orbit's dependence on ``u`` (the gradient term ``dE/dzeta dzeta/du``) and so is a
KKT point of ``E(u)`` itself, checked by :func:`~..optimize.min_energy.energy_kkt`.

Units: thrust [N], energy [J] (fuel mass [kg]), zeta [kg^2 m^4/s^2], alpha [rad].
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..hzd.zero_dynamics import ZeroDynamics
from ..optimize.min_energy import (
    EnergyObjective,
    EnergySolve,
    OrbitAtRest,
    Rows,
    check_power,
    objective_quantity,
    sample_orbits,
    sequential_convex,
)
from ..optimize.qp import normalise_rows

OBJECTIVES = ("effort", "energy")
FEASIBLE_TOL = 1e-9  # the energy plan's rows, relative to 1 + |b| (else the effort plan)


def energy_powers(zd: ZeroDynamics, driven: list[int], *, dynamic: bool = False,
                  tracking_weight: float | None = None, rate_weight: float = 0.0) -> list:
    """The driven thrusters' power models for ``objective = "energy"``, or
    :class:`InputError` (parameter ``objective``, or the clashing option): a thruster without
    a ``power:`` model, a non-convex table, models of different kinds (or quantities) or
    different tables, a thruster with dynamics (its thrust is not the plan's value), a finite
    ``tracking_weight`` or a ``rate_weight`` (terms of the effort objective)."""
    model = zd.model
    powers = [check_power(model, t) for t in driven]
    names = [model.robot.thrusters[t].name for t in driven]
    kinds = {(p.kind, objective_quantity(p)) for p in powers}
    if len(kinds) > 1:
        raise InputError.param("objective", "energy: the driven thrusters' power models must "
                                            "be of one kind and quantity (got " + ", ".join(
                                                f"{n}: {p.kind}" for n, p in zip(names, powers))
                               + ")")
    if powers[0].kind == "table" and any(
            not (np.array_equal(p.thrust, powers[0].thrust)
                 and np.array_equal(p.power, powers[0].power)) for p in powers[1:]):
        raise InputError.param("objective", "energy: driven thrusters with power tables must "
                                            "share one table")
    if dynamic:
        raise InputError.param("objective", "energy needs ideal thrust (`thrust_model` "
                                            "ideal): a thruster with dynamics does not deliver "
                                            "the plan's values")
    if tracking_weight is not None:
        raise InputError.param("tracking_weight", "not with objective energy: the energy plan "
                                                  "puts tracking first (x_{k+1} = x_ref, as "
                                                  "an equality)")
    if rate_weight != 0.0:
        raise InputError.param("rate_weight", "not with objective energy: the energy plan "
                                              "minimises the input energy alone (use "
                                              "`rate_limit` to bound the change)")
    return powers


class StepEnergy:
    """The driven thrusters' input energy over the predicted step with the orbit frozen: a
    separable convex function of ``u`` (interval-major), one
    :class:`~..optimize.min_energy.EnergyObjective` per driven thruster on its own
    :class:`~..optimize.min_energy.FrozenOrbit` (the same nodes, times and zeta, its own
    ``b_t``). The methods of an ``EnergyObjective`` over the plan's variables, so the solver
    and the KKT check of :mod:`..optimize.min_energy` take it as they are."""

    def __init__(self, powers: list, orbits: list):
        self.objs = [EnergyObjective(p, o) for p, o in zip(powers, orbits)]
        self.md = len(self.objs)
        self.kind = self.objs[0].kind
        n_int = len(orbits[0].w)
        self.dt = np.array([self.objs[v % self.md].dt[v // self.md]
                            for v in range(n_int * self.md)])
        if self.kind in ("linear", "fuel"):
            self.c = np.array([self.objs[v % self.md].c for v in range(self.n)])
        elif self.kind == "table":
            self.T, self.P, self.slope = self.objs[0].T, self.objs[0].P, self.objs[0].slope

    @property
    def n(self) -> int:
        return len(self.dt)

    def branch(self, v: int, t: float, sigma: float) -> tuple[float, float, float]:
        return self.objs[v % self.md].branch(v // self.md, t, sigma)

    def _split(self, x: np.ndarray) -> list[np.ndarray]:
        return [np.asarray(x, float)[c::self.md] for c in range(self.md)]

    def interval_values(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros(self.n)
        for c, (o, xc) in enumerate(zip(self.objs, self._split(x))):
            out[c::self.md] = o.interval_values(xc)
        return out

    def value(self, x: np.ndarray) -> float:
        return float(np.sum(self.interval_values(x)))

    def subgradient(self, x: np.ndarray, tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = np.zeros(self.n), np.zeros(self.n)
        for c, (o, xc) in enumerate(zip(self.objs, self._split(x))):
            lo[c::self.md], hi[c::self.md] = o.subgradient(xc, tol)
        return lo, hi

    def orbit_gradient(self, x: np.ndarray) -> np.ndarray:
        """``dE/dzeta . dzeta/du`` [J/N] (every thruster's energy depends on every value
        through the step's orbit)."""
        return sum(o.orbit_gradient(xc) for o, xc in zip(self.objs, self._split(x)))


def step_energy(zd: ZeroDynamics, thrust, powers: list, x_meas: float, u: np.ndarray
                ) -> StepEnergy:
    """The frozen objective on the step predicted from ``x_meas`` with values ``u``
    (:class:`~.step_model.IdealThrust` ``thrust``); :class:`~..optimize.min_energy.
    OrbitAtRest` when that step comes to rest."""
    d2 = zd.delta_zero_sq
    kn = thrust.knots
    u = np.asarray(u, float)

    def zeta_at(a: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
        _, _, I0, Iu = thrust.parts(a, np.full(a.size, j))
        return d2 * x_meas + zd.V0(a) + I0 + Iu @ u, Iu

    return StepEnergy(powers, sample_orbits(zd.model, zd, kn, thrust.driven, zeta_at))


def predicted_energy(zd: ZeroDynamics, thrust, powers: list, x_meas: float, u: np.ndarray
                     ) -> float | None:
    """The input energy [J] (fuel mass [kg]) of the step predicted from ``x_meas`` with
    values ``u``; None when that step comes to rest."""
    try:
        return step_energy(zd, thrust, powers, x_meas, u).value(u)
    except OrbitAtRest:
        return None


class Bounds:
    """Per-variable thrust bounds [N] (the piecewise-linear solver's box)."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray):
        self.lo, self.hi = lo, hi


def energy_plan(zd: ZeroDynamics, thrust, powers: list, x_meas: float, A: np.ndarray,
                b: np.ndarray, g: np.ndarray, rhs: float, u0: np.ndarray, bounds: Bounds
                ) -> tuple[np.ndarray | None, EnergySolve | None, str]:
    """The energy plan under ``A u <= b`` and ``g u = rhs`` (the effort plan's rows and its
    ``x_{k+1}`` target) from the effort plan ``u0`` (feasible). Returns ``(u, solve,
    words)``: ``u`` None when no verified, feasible energy plan was found (``words`` say
    why; the caller keeps the effort plan)."""
    An, bn, norms, const = normalise_rows(A, b)
    keep = np.flatnonzero(~const)
    s = float(np.linalg.norm(g)) or 1.0
    rows = Rows(An[keep], bn[keep], g / s, rhs / s, keep, norms[keep])
    try:
        es = sequential_convex(lambda x: step_energy(zd, thrust, powers, x_meas, x), rows,
                               bounds, u0)
    except OrbitAtRest as exc:
        return None, None, f"the energy iteration met a step that comes to rest ({exc})"
    u = es.x
    viol = float(np.max((A @ u - b) / (1.0 + np.abs(b)), initial=0.0))
    eq = abs(float(g @ u) - rhs) / (1.0 + abs(rhs))
    if viol > FEASIBLE_TOL or eq > FEASIBLE_TOL:
        return None, es, (f"the energy plan misses its rows (by {max(viol, eq):.2e} relative): "
                          "the effort plan is applied")
    if not (es.converged and es.kkt_ok):
        status, why = es.verdict("", True)
        return None, es, f"{status}: the effort plan is applied ({why.rstrip('; ')})"
    return u, es, "optimal"
