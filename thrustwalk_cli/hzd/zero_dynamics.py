"""Hybrid zero dynamics, Poincare map and limit cycles (SPEC sections 3 and 4).

On the zero-dynamics manifold Z, with sigma_N = e_N^T D(q) q' (angular momentum about the
stance foot, [kg m^2/s]):

    kappa_1(alpha) = 1 / (e_N^T D(q_Z) Phi(alpha))         [1/(kg m^2)]
    kappa_2(alpha) = -dV/dq_N (q_Z(alpha))                  [N m]
    beta(alpha)    = b_N(q_Z(alpha))                        [m]   (1 x m)
    alpha' = kappa_1 sigma_N,   sigma_N' = kappa_2 + beta F_T

With zeta = sigma_N^2 / 2 [kg^2 m^4/s^2] and thrust piecewise constant in alpha:

    zeta(alpha) = zeta^+ + V_Z(alpha)
    V_Z(alpha)  = int_{alpha_i}^{alpha} (kappa_2 + beta F_T) / kappa_1 dtau
    rho(zeta^-) = delta_zero^2 zeta^- + V_Z(alpha_f)
    zeta* = V_Z(alpha_f) / (1 - delta_zero^2)                      (SPEC 3, 4)

SPEC 4 erratum: the paper's ``zeta* = zeta_0* + sum_j b_F T_j`` omits ``1/(1 - delta_zero^2)``;
this module implements the true fixed point (``paper_one_step_shift`` gives the paper's value).

Integrals are spectral (Chebyshev-Lobatto, :mod:`quadrature`); the node count doubles until the
nested error estimate is below ``rtol`` relative, and the estimate is reported. Extrema along
the orbit (minimum and maximum ``|alpha'|``, minimum ``zeta``) are located on a grid and polished
by Newton iterations on their stationarity conditions (:func:`_orbit_extrema`), so they are exact
to about 1e-12, not grid-limited.

One idea in one file (above 600 lines): the zero dynamics and their Poincare map, from the
thrust-independent integrals to the map's fixed points and orbits for a batch of schedules
(:func:`limit_cycles`, which reads the same series through :class:`_OrbitBasis`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..description.gait import Gait
from ..errors import InputError, check_count, check_instance
from ..model.compiled import CompiledModel
from ..thrust.schedule import Schedule
from .constraints import GaitMaps, gait_maps
from .extrema import neighbours
from .quadrature import ChebSeries, cumulative_with_error, integrate, lobatto

RTOL = 1e-9

GRAZING_VELOCITY = 0.01  # [m/s] a touchdown slower than this is reported as grazing


MAX_NODES = 4097
INVARIANCE_TOL = 1e-8  # [rad], [1]: impact residuals above this: the gait is not invariant


@dataclass(frozen=True)
class LimitCycle:
    """The periodic orbit of the zero dynamics for one thrust schedule (SPEC 3).

    Every number is SI: zeta [kg^2 m^4/s^2], sigma [kg m^2/s], alpha' [rad/s], step time [s],
    step length [m], speed [m/s]. Fields are ``None`` when ``exists`` is false; ``reason``
    says why. ``orbit`` holds the sampled phase-plane curve (alpha, alpha', sigma_N).
    ``min_abs_alpha_dot``/``alpha_at_min`` (the potential-energy barrier),
    ``max_abs_alpha_dot``/``alpha_at_max`` and ``min_zeta``/``alpha_at_min_zeta`` [rad] are the
    exact extrema along the step (grid, then Newton). ``touchdown_velocity``: vertical
    velocity of the swing foot just before impact [m/s], negative when it moves down; near 0
    the foot grazes the ground and a full-order simulation can miss the strike.
    """

    exists: bool
    stable: bool
    reason: str
    delta_zero_sq: float
    V_f: float
    zeta_star: float | None = None
    zeta_plus: float | None = None
    sigma_minus: float | None = None
    sigma_plus: float | None = None
    alpha_dot_minus: float | None = None
    alpha_dot_plus: float | None = None
    step_time: float | None = None
    step_time_error: float | None = None
    step_length: float | None = None
    speed: float | None = None
    min_abs_alpha_dot: float | None = None
    alpha_at_min: float | None = None
    max_abs_alpha_dot: float | None = None
    alpha_at_max: float | None = None
    min_zeta: float | None = None
    alpha_at_min_zeta: float | None = None
    touchdown_velocity: float | None = None
    orbit: Mapping[str, np.ndarray] | None = field(default=None, repr=False)

    @property
    def missing(self) -> str:
        """Why there is no orbit, starting "no periodic orbit" once ("" when it exists)."""
        if self.exists:
            return ""
        r = self.reason
        return r if r.startswith("no periodic orbit") else f"no periodic orbit: {r}"


@dataclass
class ZeroDynamics:
    """Thrust-independent part of the zero dynamics of one gait on one model (SPEC 3)."""

    model: CompiledModel
    gait: Gait
    maps: GaitMaps
    nodes: int
    V0: ChebSeries  # int kappa_2/kappa_1 from alpha_i          [kg^2 m^4/s^2]
    Gamma: ChebSeries  # int beta/kappa_1, one column per thruster  [kg^2 m^4/s^2 per N]
    B: ChebSeries  # int 1/kappa_1 (generalised mode b_F)          [kg m^2 rad per N m]
    integral_error: float
    integral_scale: float
    delta_zero: float
    kappa1_ok: bool
    kappa1_reason: str
    E: ChebSeries | None = None  # e_N^T D Phi = 1/kappa_1 interpolated on the nodes [kg m^2]
    slope: float = 0.0  # [rad] ground angle, positive uphill (SPEC 14); 0: level ground

    def __repr__(self) -> str:
        return (f"ZeroDynamics(gait={self.gait.name!r}, alpha_i={self.alpha_i:.6g}, "
                f"alpha_f={self.alpha_f:.6g}, delta_zero_sq={self.delta_zero_sq:.6g}, "
                f"nodes={self.nodes}, valid={self.valid})")

    @property
    def invariant(self) -> bool:
        """The impact maps Z into Z (SPEC 2): both residuals within ``INVARIANCE_TOL``."""
        return (self.maps.position_residual <= INVARIANCE_TOL
                and self.maps.velocity_residual <= INVARIANCE_TOL)

    @property
    def valid(self) -> bool:
        """The zero dynamics describe a walking orbit: hybrid-invariant, kappa_1 regular."""
        return self.kappa1_ok and self.invariant

    @property
    def invalid_reason(self) -> str:
        """Why the zero-dynamics orbit is not a walking orbit ('' when :attr:`valid`)."""
        if not self.invariant:
            mp = self.maps
            return (f"the gait is not hybrid-invariant (impact residuals: position "
                    f"{mp.position_residual:.3g} rad, velocity {mp.velocity_residual:.3g}, "
                    f"tolerance {INVARIANCE_TOL:g}): after impact the walker leaves the "
                    "zero-dynamics manifold, so no zero-dynamics orbit is a walking orbit; "
                    "`invariance: auto` in the gait file computes columns 0 and 1 so that it is")
        return self.kappa1_reason

    @property
    def alpha_i(self) -> float:
        """alpha at the start of the step, at ``q^+`` [rad] (SPEC 2, 3)."""
        return self.maps.alpha_i

    @property
    def alpha_f(self) -> float:
        """alpha at the end of the step, at ``q^-`` [rad] (SPEC 2, 3)."""
        return self.maps.alpha_f

    @property
    def delta_zero_sq(self) -> float:
        """``delta_zero^2`` [1]: the impact maps ``zeta^-`` to ``zeta^+ = delta_zero^2 zeta^-``
        (SPEC 3)."""
        return self.delta_zero**2

    @property
    def direction(self) -> float:
        """+1 if alpha increases over the step, -1 if it decreases."""
        return float(np.sign(self.alpha_f - self.alpha_i))

    def on_slope(self, gamma: float) -> ZeroDynamics:
        """The zero dynamics of the same gait on the slope ``gamma`` [rad, positive uphill]
        (SPEC 14): ``self`` for ``gamma == 0``. In the slope frame only gravity and the
        world-frame thrusters turn, so the integrals are explicit in ``(cos gamma, sin
        gamma)``:

            V_0(gamma)   = cos(gamma) V_0 + sin(gamma) V_x,   V_x = int kappa_2x / kappa_1
            Gamma(gamma) = c_k Gamma + sin(gamma) Gamma_perp  (c_k = cos(gamma) for a world
                                                               thruster, 1 for a link one)

        with ``kappa_2x = -dV_x/dq_N`` (``V_x = M g x_com``) and ``Gamma_perp = int
        beta_perp / kappa_1`` (``beta_perp`` the last row of ``J_k^T d_k^perp``). ``V_x`` and
        ``Gamma_perp`` are computed once per gait (:meth:`slope_series`); each slope then
        costs a few array operations. ``b_F``, ``kappa_1``, ``delta_zero`` (the impact) and
        the guard do not depend on the slope. The returned object's ``model`` is the
        slope-frame model (:func:`~thrustwalk_cli.model.slope.slope_model`), so the contact
        terms computed from it are normal and tangential to the slope."""
        from ..model.slope import check_slope, slope_model

        gamma = check_slope(gamma)
        if gamma == self.slope:
            return self
        flat = self.flat
        if gamma == 0.0:
            return flat
        Vx, Gp, err_x = flat.slope_series()
        c, s = math.cos(gamma), math.sin(gamma)
        world = flat.__dict__["_slope_parts"].world
        cw = np.where(world, c, 1.0)
        rows = max(flat.V0.coef.shape[0], Vx.coef.shape[0])

        def pad(coef: np.ndarray) -> np.ndarray:
            out = np.zeros((rows,) + coef.shape[1:])
            out[:coef.shape[0]] = coef
            return out

        a, b = flat.alpha_i, flat.alpha_f
        V0 = ChebSeries(a, b, c * pad(flat.V0.coef) + s * pad(Vx.coef))
        Gamma = ChebSeries(a, b, pad(flat.Gamma.coef) * cw + s * pad(Gp.coef))
        model = slope_model(flat.model, gamma, flat.__dict__["_slope_parts"])
        zd = ZeroDynamics(model, flat.gait, flat.maps, flat.nodes, V0, Gamma, flat.B,
                          abs(c) * flat.integral_error + abs(s) * err_x, flat.integral_scale,
                          flat.delta_zero, flat.kappa1_ok, flat.kappa1_reason, flat.E,
                          slope=gamma)
        zd.__dict__["_flat"] = flat
        return zd

    @property
    def flat(self) -> ZeroDynamics:
        """The level-ground zero dynamics this one was turned from (``self`` on level
        ground)."""
        return self.__dict__.get("_flat", self)

    def slope_series(self, rtol: float = RTOL) -> tuple[ChebSeries, ChebSeries, float]:
        """``(V_x, Gamma_perp, error estimate)``: the parts of the zero-dynamics integrals
        that multiply ``sin(gamma)`` on a slope (:meth:`on_slope`), on level ground's
        Lobatto nodes (doubled until the nested error estimate is below ``rtol`` relative);
        computed once and kept."""
        cached = self.__dict__.get("_slope_series")
        if cached is not None:
            return cached
        from ..model.slope import SlopeParts

        parts = self.__dict__.get("_slope_parts") or SlopeParts(self.model)
        self.__dict__["_slope_parts"] = parts
        a, b, n, N = self.alpha_i, self.alpha_f, self.nodes, self.model.n
        while True:
            alpha = lobatto(a, b, n)
            q = self.maps.q_Z(alpha)
            inv = self.terms(alpha)["eDPhi"]
            vals = np.column_stack([-parts.G_x(q)[:, N - 1] * inv,
                                    parts.B_perp(q)[:, N - 1, :] * inv[:, None]])
            series, err = cumulative_with_error(a, b, vals)
            scale = float(np.max(np.abs(series(alpha)), axis=0).max()) or 1.0
            if err <= rtol * scale or n >= MAX_NODES:
                break
            n = 2 * n - 1
        Vx = ChebSeries(a, b, series.coef[:, 0])
        Gp = ChebSeries(a, b, series.coef[:, 1:])
        self.__dict__["_slope_series"] = out = (Vx, Gp, float(err))
        return out

    def terms(self, alpha: np.ndarray) -> dict[str, np.ndarray]:
        """Direct model evaluation on Z: q_Z, Phi, kappa_1, kappa_2, beta (SPEC 3)."""
        return zero_dynamics_terms(self.model, self.maps, alpha)

    @property
    def sigma_sign(self) -> float:
        """Sign of sigma_N on the orbit: alpha' = kappa_1 sigma_N moves alpha forward
        (kappa_1 at alpha_i: kinematics only, the same on every slope; computed once)."""
        v = self.__dict__.get("_sigma_sign")
        if v is None:
            k1 = self.terms(np.array([self.alpha_i]))["kappa1"][0]
            v = self.__dict__["_sigma_sign"] = self.direction * float(np.sign(k1))
        return v

    def V_Z(self, alpha: np.ndarray, schedule: Schedule) -> np.ndarray:
        """``V_Z(alpha)`` for each schedule in the batch; shape (k,) + alpha.shape."""
        alpha = np.asarray(alpha, float)
        kn = schedule.knots
        out = np.broadcast_to(self.V0(alpha), (schedule.size,) + alpha.shape).copy()
        lo, hi = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
        for j in range(len(kn) - 1):
            a = np.clip(alpha, lo[j], hi[j])
            dG = self.Gamma(a) - self.Gamma(kn[j])  # alpha.shape + (m,)
            dB = self.B(a) - self.B(kn[j])
            out += np.einsum("...m,km->k...", dG, schedule.force[:, j, :])
            out += schedule.generalized[:, j].reshape((-1,) + (1,) * alpha.ndim) * dB
        return out

    def interval_integrals(self, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per interval: ``b_F(alpha_{j+1}, alpha_j) = int 1/kappa_1`` and
        ``Gamma_j = int beta/kappa_1`` (SPEC 4); shapes (n-1,) and (n-1, m)."""
        kn = np.asarray(knots, float)
        return np.diff(self.B(kn)), np.diff(self.Gamma(kn), axis=0)

    def extrema_series(self) -> ChebSeries:
        """Columns ``[V_0', Gamma', b_F', V_0'', Gamma'', b_F'', E, E', E'']`` (derivatives in
        alpha; ``E = e_N^T D Phi = 1/kappa_1`` interpolated on the quadrature nodes) as one
        series: what the polishing of orbit extrema needs, computed once per walker."""
        cached = self.__dict__.get("_extrema_series")
        if cached is None:
            a, b = self.V0.a, self.V0.b
            base = ChebSeries(a, b, np.column_stack([self.V0.coef, self.Gamma.coef,
                                                     self.B.coef]))
            E = self.E if self.E is not None else ChebSeries.from_values(
                a, b, self.terms(lobatto(a, b, self.nodes))["eDPhi"])
            n = base.coef.shape[0]
            ecoef = np.zeros((n, 1))
            ecoef[:E.coef.shape[0], 0] = E.coef
            e = ChebSeries(a, b, ecoef)
            cached = ChebSeries(a, b, np.hstack([base.derivative(1).coef,
                                                 base.derivative(2).coef, e.coef,
                                                 e.derivative(1).coef, e.derivative(2).coef]))
            self.__dict__["_extrema_series"] = cached
        return cached

    @property
    def step_length(self) -> float:
        """Horizontal distance from the stance foot to the swing foot at impact [m]."""
        v = self.__dict__.get("_step_length")
        if v is None:
            v = self.__dict__["_step_length"] = float(self.model.p_swing(self.maps.q_minus)[0])
        return v

    def touchdown_velocity(self, alpha_dot_minus: float) -> float:
        """Vertical swing-foot velocity just before impact [m/s] on Z:
        ``E_2y(q^-) Phi(alpha_f) alpha'^-`` (negative: the foot moves down onto the ground)."""
        per = self.__dict__.get("_touchdown_per_alpha_dot")
        if per is None:
            phi = self.maps.Phi(np.array(self.alpha_f))
            per = float(self.model.E_swing(self.maps.q_minus)[1] @ phi)
            self.__dict__["_touchdown_per_alpha_dot"] = per
        return per * float(alpha_dot_minus)

    # -- the fixed point, the nominal orbit and the speed (SPEC 3, 4) ------------------------
    def fixed_point_of(self, V_f):
        """``zeta* = V_f / (1 - delta_zero^2)`` [kg^2 m^4/s^2] for ``V_f = V_Z(alpha_f)`` (a
        float or an array), the Poincare map's fixed point (SPEC 3, 4); for a change of
        ``V_Z(alpha_f)`` the shift of the fixed point (the SPEC 4 erratum: not the change
        itself). Arrays give inf or NaN (no warning) where ``delta_zero^2 = 1``."""
        if isinstance(V_f, np.ndarray):
            with np.errstate(divide="ignore", invalid="ignore"):
                return V_f / (1.0 - self.delta_zero_sq)
        return V_f / (1.0 - self.delta_zero_sq)

    def fixed_point(self, schedule: Schedule | None = None):
        """``zeta* = V_Z(alpha_f) / (1 - delta_zero^2)`` [kg^2 m^4/s^2] (SPEC 3, 4): of each
        schedule of a batch (shape (k,)), or without one of zero thrust (``zeta_0* =
        V_0(alpha_f) / (1 - delta_zero^2)``, a float). No existence check: see
        :func:`limit_cycles` (zeta* <= 0: no orbit)."""
        af = np.array(self.alpha_f)
        if schedule is None:
            return self.fixed_point_of(float(self.V0(af)))
        return self.fixed_point_of(self.V_Z(af, schedule))

    def nominal_cycle(self, knots: np.ndarray | None = None) -> LimitCycle:
        """The periodic orbit without thrust (SPEC 3), :func:`limit_cycles` of the zero
        schedule on ``knots`` [rad] (default: alpha_i, alpha_f)."""
        m = self.model.n_thrusters
        sched = (Schedule.constant(self, np.zeros((1, m))) if knots is None else
                 Schedule.zero(knots, m))
        return limit_cycles(self, sched)[0]

    def zeta_for_speed(self, speed: float, speed_of: Callable[[float], float], lo: float,
                       hi: float, *, xtol: float, rtol: float, maxiter: int = 100) -> float:
        """The fixed point ``zeta*`` [kg^2 m^4/s^2] at which a family of thrust schedules
        walks at ``speed`` [m/s] (SPEC 3: step length over the step time of the periodic
        orbit): the root of ``speed_of(zeta*) - speed`` in ``[lo, hi]`` (a sign change),
        by Brent's method (``scipy.optimize.brentq`` with ``xtol``, ``rtol``, ``maxiter``).

        ``speed_of(zeta*)`` is the family's speed at that fixed point (it raises where the
        family has no orbit). The three searches of the package are this one with their own
        family and bracket: the minimum-norm thrust of shaping
        (:func:`~thrustwalk_cli.hzd.shaping.solve_target_speed`), the minimum-effort QP
        (:func:`~thrustwalk_cli.optimize.min_effort.optimize`) and the controller's steady
        state (:func:`~thrustwalk_cli.controller.references.speed_references`)."""
        from scipy.optimize import brentq

        return brentq(lambda z: speed_of(z) - speed, lo, hi, xtol=xtol, rtol=rtol,
                      maxiter=maxiter)

    def poincare(self, zeta_minus: np.ndarray, schedule: Schedule) -> np.ndarray:
        """``rho(zeta^-) = delta_zero^2 zeta^- + V_Z(alpha_f)`` (SPEC 3); NaN-free, unchecked
        domain: see :func:`limit_cycles` for the existence conditions."""
        return self.delta_zero_sq * np.asarray(zeta_minus) + self.V_Z(
            np.array(self.alpha_f), schedule)


class ZetaAt:
    """``zeta_i(alpha_i) = zeta^+_i + V_Z(alpha_i; schedule i)`` for alpha values of each
    schedule of a batch (a search that moves each schedule's points on their own): ``alpha``
    of shape (k,) or (k, p), with V_0, Gamma and b_F stacked into one Chebyshev series (one
    evaluation per call) [kg^2 m^4/s^2]."""

    def __init__(self, zd: ZeroDynamics, sched: Schedule):
        self.sched = sched
        self.m = zd.Gamma.coef.shape[1]
        coef = np.column_stack([zd.V0.coef, zd.Gamma.coef, zd.B.coef])
        self.series = ChebSeries(zd.V0.a, zd.V0.b, coef)
        kn = sched.knots
        self.lo, self.hi = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
        self.at_knots = self.series(kn)  # (n+1, 2+m)

    def __call__(self, zeta_plus: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        alpha = np.asarray(alpha, float)
        a2 = alpha.reshape(alpha.shape[0], -1)  # (k, p)
        pts = np.concatenate([a2[None], np.clip(a2[None], self.lo[:, None, None],
                                                self.hi[:, None, None])])
        v = self.series.at_few(pts)  # (1+n, k, p, 2+m)
        m = self.m
        dG = v[1:, ..., 1:1 + m] - self.at_knots[:-1, None, None, 1:1 + m]  # (n, k, p, m)
        dB = v[1:, ..., -1] - self.at_knots[:-1, None, None, -1]  # (n, k, p)
        z = (np.asarray(zeta_plus, float).reshape(-1, 1) + v[0, ..., 0]
             + np.einsum("jkpm,kjm->kp", dG, self.sched.force)
             + np.einsum("jkp,kj->kp", dB, self.sched.generalized))
        return z.reshape(alpha.shape)


def zero_dynamics_terms(model: CompiledModel, maps: GaitMaps, alpha: np.ndarray) -> dict:
    """q_Z, Phi, kappa_1 = 1/(e_N^T D Phi), kappa_2 = -dV/dq_N, beta = b_N on Z (SPEC 3)."""
    alpha = np.asarray(alpha, float)
    q = maps.q_Z(alpha)
    phi = maps.Phi(alpha)
    D = model.D(q)
    N = model.n
    eDPhi = np.einsum("...j,...j->...", D[..., N - 1, :], phi)
    with np.errstate(divide="ignore"):
        kappa1 = 1.0 / eDPhi
    kappa2 = -model.G(q)[..., N - 1]
    beta = model.B_F(q)[..., N - 1, :]
    return {"q": q, "Phi": phi, "kappa1": kappa1, "kappa2": kappa2, "beta": beta, "eDPhi": eDPhi}


def _kappa1_check(k1: np.ndarray, alpha: np.ndarray) -> tuple[bool, str]:
    if not np.all(np.isfinite(k1)):
        bad = alpha[~np.isfinite(k1)][0]
        return False, f"kappa_1 is singular (e_N^T D Phi = 0) near alpha = {bad:.6g} rad"
    sign = np.sign(k1)
    if np.any(sign != sign[0]) or np.any(sign == 0):
        j = int(np.argmax(sign != sign[0]))
        return False, (f"kappa_1 changes sign near alpha = {alpha[j]:.6g} rad: alpha stops being "
                       "monotonic and the zero dynamics are singular")
    return True, ""


def zero_dynamics(model: CompiledModel, gait: Gait, rtol: float = RTOL,
                  nodes: int = 65) -> ZeroDynamics:
    """Precompute the thrust-independent integrals V_0, Gamma, b_F and delta_zero (SPEC 3, 4).

    ``delta_zero = e_N^T D(q^+) R Delta_q'(q^-) Phi(alpha_f) kappa_1(alpha_f)``.
    """
    maps = gait_maps(model, gait)
    a, b = maps.alpha_i, maps.alpha_f
    n = nodes
    while True:
        alpha = lobatto(a, b, n)
        t = zero_dynamics_terms(model, maps, alpha)
        ok, why = _kappa1_check(t["kappa1"], alpha)
        inv = t["eDPhi"]  # 1/kappa_1, finite everywhere
        vals = np.column_stack([t["kappa2"] * inv, t["beta"] * inv[:, None], inv])
        series, err = cumulative_with_error(a, b, vals)
        scale = float(np.max(np.abs(series(alpha)), axis=0).max()) or 1.0
        if err <= rtol * scale or n >= MAX_NODES or not ok:
            break
        n = 2 * n - 1
    m = model.n_thrusters
    V0 = ChebSeries(a, b, series.coef[:, 0])
    Gamma = ChebSeries(a, b, series.coef[:, 1:1 + m])
    B = ChebSeries(a, b, series.coef[:, 1 + m])
    _, _, Delta = model.impact_maps(maps.q_minus)
    tf = zero_dynamics_terms(model, maps, np.array([b]))
    N = model.n
    D_plus = model.D(maps.q_plus)
    delta = float(D_plus[N - 1, :] @ model.R @ Delta @ tf["Phi"][0] * tf["kappa1"][0])
    E = ChebSeries.from_values(a, b, inv)  # interpolation error ~1e-14 relative (tested)
    return ZeroDynamics(model, gait, maps, n, V0, Gamma, B, err, scale, delta, ok, why, E)


LOCAL_POINTS = 10  # Chebyshev points per grid bracket of the local interpolants (degree 9)


class _Orbit(Mapping):
    """The sampled phase-plane curve of one orbit (``alpha`` [rad], ``alpha_dot`` [rad/s],
    ``sigma`` [kg m^2/s], ``zeta`` [kg^2 m^4/s^2]), built when first read: a sweep of
    thousands of orbits that writes none of them never samples them."""

    def __init__(self, grid: np.ndarray, k1: np.ndarray, zeta: np.ndarray, sgn: float):
        self._args = (grid, k1, zeta, sgn)
        self._data: dict[str, np.ndarray] | None = None

    def _built(self) -> dict[str, np.ndarray]:
        if self._data is None:
            grid, k1, zeta, sgn = self._args
            sigma = sgn * np.sqrt(2.0 * zeta)
            self._data = {"alpha": grid, "alpha_dot": k1 * sigma, "sigma": sigma,
                          "zeta": zeta}
        return self._data

    def __getitem__(self, key: str) -> np.ndarray:
        return self._built()[key]

    def __iter__(self):
        return iter(("alpha", "alpha_dot", "sigma", "zeta"))

    def __len__(self) -> int:
        return 4


class _OrbitBasis:
    """Everything :func:`limit_cycles` needs that does not depend on the thrust values, for
    one gait, one set of knots and one grid (SPEC 3, 4), computed once and kept on the
    :class:`ZeroDynamics`:

    * the grid (``samples`` points plus the knots), ``kappa_1`` on it, and ``V_0``, the
      per-interval increments of ``Gamma`` and ``b_F`` on it and at ``alpha_f``, so that
      ``V_Z(grid)`` of a batch is one tensor contraction with the thrust values;
    * the Lobatto nodes of each knot interval for the step time, with ``kappa_1`` and the
      same increments there (per node count, on demand);
    * per grid point, degree-9 Chebyshev interpolants on its bracket (the neighbouring grid
      points) of ``V_0, Gamma, b_F``, their first two derivatives and ``E = 1/kappa_1`` with
      its two derivatives (from the spectral series of :meth:`ZeroDynamics.extrema_series`):
      the Newton polish of the orbit extrema evaluates these (ten terms) instead of the whole
      series; on a bracket of two grid spacings they agree with it to rounding.
    """

    def __init__(self, zd: ZeroDynamics, knots: np.ndarray, samples: int):
        a_i, a_f = zd.alpha_i, zd.alpha_f
        kn = np.asarray(knots, float)
        self.knots = kn
        grid = np.unique(np.concatenate([np.linspace(a_i, a_f, samples), kn]))
        if a_f < a_i:
            grid = grid[::-1]
        self.grid = grid
        self.k1 = zd.terms(grid)["kappa1"]
        self.m = m = zd.Gamma.coef.shape[1]
        self.w = 2 + m
        self.lo, self.hi = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
        zs = ChebSeries(zd.V0.a, zd.V0.b, np.column_stack([zd.V0.coef, zd.Gamma.coef,
                                                           zd.B.coef]))
        self.zseries = zs
        self.at_knots = zs(kn)  # (n, 2 + m): V_0, Gamma, b_F at the knots
        self.V0g, self.dGg, self.dBg = self._pieces(zs(grid), grid)
        self.V0f, dGf, dBf = self._pieces(zs(np.array([a_f])), np.array([a_f]))
        self.dGf, self.dBf = dGf[:, 0], dBf[:, 0]
        self.nodes: dict[tuple[int, int], tuple] = {}
        self.zd = zd
        # local interpolants on the bracket of every grid point
        lo, hi = neighbours(grid, np.arange(grid.size))
        self.blo, self.bhi = lo, hi
        L = LOCAL_POINTS
        theta = np.pi * (np.arange(L) + 0.5) / L
        t = np.cos(theta)
        pts = 0.5 * (lo + hi)[:, None] + 0.5 * (hi - lo)[:, None] * t[None, :]  # (g, L)
        vals = np.concatenate([zd.extrema_series()(pts), zs(pts)], axis=-1)  # (g, L, C)
        T = np.cos(np.outer(np.arange(L), theta)) * (2.0 / L)  # DCT-II: values -> coef
        T[0] *= 0.5
        self.local = np.einsum("rl,glc->grc", T, vals)  # (g, L, C)

    def _pieces(self, v: np.ndarray, alpha: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``V_0`` (p,) and per knot interval j the increments ``Gamma(clip(alpha)) -
        Gamma(knot_j)`` (n-1, p, m) and of ``b_F`` (n-1, p) from series values ``v``."""
        m, zs = self.m, self.zseries
        dG, dB = [], []
        for j in range(len(self.knots) - 1):
            inside = (alpha >= self.lo[j]) & (alpha <= self.hi[j])
            c = zs(np.clip(alpha, self.lo[j], self.hi[j]))
            c[inside] = v[inside]
            dG.append(c[:, 1:1 + m] - self.at_knots[j, 1:1 + m])
            dB.append(c[:, 1 + m] - self.at_knots[j, 1 + m])
        return (v[:, 0], np.array(dG).reshape(len(dB), alpha.size, m),
                np.array(dB).reshape(len(dB), alpha.size))

    @staticmethod
    def combine(V0: np.ndarray, dG: np.ndarray, dB: np.ndarray, sched: Schedule
                ) -> np.ndarray:
        """``V_Z`` (k, p) of every schedule from the pieces (SPEC 3, 4)."""
        return (V0[None, :] + np.einsum("jpm,kjm->kp", dG, sched.force)
                + np.einsum("jp,kj->kp", dB, sched.generalized))

    def step_nodes(self, j: int, n: int) -> tuple:
        """Lobatto nodes of knot interval ``j`` with ``kappa_1`` and the ``V_Z`` pieces."""
        key = (j, n)
        if key not in self.nodes:
            p = lobatto(self.knots[j], self.knots[j + 1], n)
            self.nodes[key] = (p, self.zd.terms(p)["kappa1"],
                               *self._pieces(self.zseries(p), p))
        return self.nodes[key]

    def evaluate(self, coef: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray
                 ) -> np.ndarray:
        """The local interpolants ``coef`` (P, L, C) (gathered for the points' brackets
        ``[lo, hi]``) at ``x`` (P,): ``sum_r c_r T_r(t)``, ``t`` the point mapped to [-1, 1]
        (the ``T_r(t)`` by their three-term recurrence, bounded by 1 on the bracket), then one
        contraction: (P, C)."""
        span = np.where(hi > lo, hi - lo, 1.0)
        t = (2.0 * x - (lo + hi)) / span
        L = coef.shape[1]
        Tv = np.empty((t.size, L))
        Tv[:, 0] = 1.0
        if L > 1:
            Tv[:, 1] = t
        for r in range(2, L):
            Tv[:, r] = 2.0 * t * Tv[:, r - 1] - Tv[:, r - 2]
        return np.einsum("pl,plc->pc", Tv, coef)


def orbit_basis(zd: ZeroDynamics, knots: np.ndarray, samples: int = 201) -> _OrbitBasis:
    """The thrust-independent :class:`_OrbitBasis` of ``zd`` for ``knots`` and a grid of
    ``samples`` points, computed on first use and kept."""
    cache = zd.__dict__.setdefault("_orbit_bases", {})
    key = (tuple(np.asarray(knots, float).tolist()), int(samples))
    basis = cache.get(key)
    if basis is None:
        if len(cache) > 64:
            cache.clear()
        basis = cache[key] = _OrbitBasis(zd, knots, samples)
    return basis


def _step_times(zd: ZeroDynamics, schedule: Schedule, zeta_plus: np.ndarray,
                basis: _OrbitBasis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``T = int dalpha / alpha'`` for a batch, per knot interval (spectral, nested estimate).

    Nodes double on each interval until the estimate is below ``0.1 RTOL`` relative for the
    whole batch. Returns (T, error estimate, ok) with ok false where zeta <= 0 on a node.
    """
    kn = schedule.knots
    k = schedule.size
    sgn = zd.sigma_sign
    T, T_err, ok = np.zeros(k), np.zeros(k), np.ones(k, bool)
    for j in range(len(kn) - 1):
        n_p = 33
        while True:
            p, k1p, V0, dG, dB = basis.step_nodes(j, n_p)
            zpnl = zeta_plus[:, None] + basis.combine(V0, dG, dB, schedule)
            bad = np.any(zpnl <= 0, axis=1)
            f = 1.0 / (k1p * sgn * np.sqrt(2.0 * np.where(zpnl > 0, zpnl, 1.0)))
            val, err = integrate(p[0], p[-1], f)
            good = ~bad
            if np.all(err[good] <= 0.1 * RTOL * np.abs(val[good])) or n_p >= MAX_NODES:
                break
            n_p = 2 * n_p - 1
        T += val
        T_err += err
        ok &= good
    return T, T_err, ok


def limit_cycles(zd: ZeroDynamics, schedule: Schedule, samples: int = 201) -> LimitCycles:
    """Fixed points, stability and orbits for a batch of thrust schedules (SPEC 3, 4).

    Exists  <=>  the gait is hybrid-invariant, kappa_1 keeps its sign, 0 < delta_zero^2 != 1,
    zeta* > 0 and delta_zero^2 zeta* + min V_Z > 0. Stable  <=>  exists and delta_zero^2 < 1.
    The step time ``T = int dalpha / alpha'`` is integrated per knot interval (spectral, with a
    nested error estimate); alpha' = kappa_1 sigma_N, sigma_N = sgn sqrt(2 zeta).
    Everything that does not depend on the thrust values is computed once per gait and knots
    (:func:`orbit_basis`); the rest is vectorised over the batch and the sampled orbits are
    built when read (:class:`LimitCycles`, a sequence of :class:`LimitCycle`), so a sweep
    costs little more than one orbit.
    """
    check_instance("zd", zd, ZeroDynamics, "a ZeroDynamics (walker.zd)")
    check_instance("schedule", schedule, Schedule, "a Schedule (e.g. Schedule.constant)")
    samples = check_count("samples", samples, ge=3, le=100_000)
    arrays = (schedule.knots, schedule.force, schedule.generalized)
    if not all(np.all(np.isfinite(np.asarray(a, float))) for a in arrays):
        raise InputError.param("schedule", "knots and thrust values must be finite numbers")
    d2 = zd.delta_zero_sq
    kn = schedule.knots
    basis = orbit_basis(zd, kn, samples)
    grid, k1 = basis.grid, basis.k1
    Vf = (basis.V0f[0] + np.einsum("jm,kjm->k", basis.dGf, schedule.force)
          + np.einsum("j,kj->k", basis.dBf, schedule.generalized))  # (k,)
    VZ = basis.combine(basis.V0g, basis.dGg, basis.dBg, schedule)  # (k, g)
    zstar = zd.fixed_point_of(Vf)
    zp = d2 * zstar
    zeta = zp[:, None] + VZ
    jmin = np.argmin(zeta, axis=1)
    zmin = zeta[np.arange(len(Vf)), jmin]
    candidates = zd.valid and 0.0 < d2 != 1.0
    live = np.nonzero((zstar > 0) & (zmin > 0))[0] if candidates else np.array([], int)
    T = np.full(len(Vf), np.nan)
    T_err = np.full(len(Vf), np.nan)
    T_ok = np.zeros(len(Vf), bool)
    if live.size:
        sub = schedule.take(live)
        T[live], T_err[live], T_ok[live] = _step_times(zd, sub, zp[live], basis)
    ext = _orbit_extrema(zd, schedule.take(live),
                         zp[live], grid, k1, zeta[live], basis) if live.size else {}
    return LimitCycles(zd, grid, k1, Vf, zstar, zp, zeta, zmin, jmin, T, T_err, T_ok, live,
                       ext)


class LimitCycles(Sequence):
    """The limit cycles of a batch of schedules (what :func:`limit_cycles` returns): a
    sequence of :class:`LimitCycle`, each built from the batch's arrays when first read."""

    def __init__(self, zd, grid, k1, Vf, zstar, zp, zeta, zmin, jmin, T, T_err, T_ok, live,
                 ext):
        self._zd, self._grid, self._k1 = zd, grid, k1
        self._arrays = (Vf, zstar, zp, zeta, zmin, jmin, T, T_err, T_ok)
        self._pos = {int(i): r for r, i in enumerate(live)}
        self._ext = ext
        self._built: dict[int, LimitCycle] = {}

    def __len__(self) -> int:
        return len(self._arrays[0])

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        n = len(self)
        i = int(i)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError("limit cycle index out of range")
        lc = self._built.get(i)
        if lc is None:
            lc = self._built[i] = self._build(i)
        return lc

    def _build(self, i: int) -> LimitCycle:
        zd, grid, k1 = self._zd, self._grid, self._k1
        Vf, zstar, zp, zeta, zmin, jmin, T, T_err, T_ok = self._arrays
        d2 = zd.delta_zero_sq
        base = dict(delta_zero_sq=d2, V_f=float(Vf[i]))
        zs = float(zstar[i])
        if not zd.valid:
            return LimitCycle(False, False, zd.invalid_reason, **base)
        if d2 == 1.0 or d2 <= 0.0:
            return LimitCycle(False, False, f"delta_zero^2 = {d2:.6g}: no isolated fixed point",
                              **base)
        if zs <= 0.0:
            why = (f"no periodic orbit: zeta* = V_Z(alpha_f)/(1 - delta_zero^2) = {zs:.6g} <= 0"
                   if d2 < 1 else
                   f"no periodic orbit with zeta* > 0 (delta_zero^2 = {d2:.6g} >= 1, "
                   f"V_Z(alpha_f) = {Vf[i]:.6g})")
            return LimitCycle(False, False, why, **base)
        if zmin[i] <= 0.0:
            return LimitCycle(
                False, False,
                f"the walker stops before the end of the step: zeta reaches 0 near alpha = "
                f"{grid[jmin[i]]:.6g} rad (delta_zero^2 zeta* + min V_Z = {zmin[i]:.6g} <= 0)",
                zeta_star=zs, **base)
        if not T_ok[i]:
            return LimitCycle(False, False, "the walker stops inside the step (zeta <= 0 "
                              "between grid points)", zeta_star=zs, **base)
        if not (np.isfinite(T[i]) and T[i] > 0):
            return LimitCycle(False, False, f"step time integral failed (T = {T[i]})",
                              zeta_star=zs, **base)
        r = self._pos[i]
        ext = self._ext
        sgn = zd.sigma_sign
        s_minus = sgn * math.sqrt(2.0 * zs)
        s_plus = zd.delta_zero * s_minus
        stable = d2 < 1.0
        reason = "stable periodic orbit" if stable else (
            f"periodic orbit exists but is unstable (delta_zero^2 = {d2:.6g} >= 1)")
        k1f = float(k1[-1])
        step_length = zd.step_length
        return LimitCycle(
            exists=True, stable=stable, reason=reason, zeta_star=zs, zeta_plus=float(zp[i]),
            sigma_minus=s_minus, sigma_plus=s_plus,
            alpha_dot_minus=k1f * s_minus, alpha_dot_plus=float(k1[0]) * s_plus,
            step_time=float(T[i]), step_time_error=float(T_err[i]),
            step_length=step_length, speed=step_length / float(T[i]),
            min_abs_alpha_dot=float(ext["min_adot"][r]), alpha_at_min=float(ext["a_min"][r]),
            max_abs_alpha_dot=float(ext["max_adot"][r]), alpha_at_max=float(ext["a_max"][r]),
            min_zeta=float(ext["min_zeta"][r]), alpha_at_min_zeta=float(ext["a_zeta"][r]),
            touchdown_velocity=zd.touchdown_velocity(k1f * s_minus),
            orbit=_Orbit(grid, k1, zeta[i], sgn), **base)


def _orbit_extrema(zd: ZeroDynamics, sched: Schedule, zeta_plus: np.ndarray, grid: np.ndarray,
                   k1: np.ndarray, zeta: np.ndarray, basis: _OrbitBasis,
                   iterations: int = 8) -> dict[str, np.ndarray]:
    """Exact min/max of ``|alpha'| = |kappa_1| sqrt(2 zeta)`` and min of ``zeta`` along the step
    for a batch of orbits (``zeta``: (k, g) on ``grid``).

    Each is located on the grid, then polished by safeguarded Newton iterations on its
    stationarity condition between the neighbouring grid points: ``h = zeta' E - 2 zeta E'``
    (``d/dalpha (zeta / E^2)`` up to a positive factor; ``E = e_N^T D Phi = 1/kappa_1``) for
    ``|alpha'|``, ``h = zeta'`` for ``zeta``. ``zeta', zeta''`` come from the integrands' series
    (V_0, Gamma, b_F differentiated, with the thrust of the point's knot interval), ``E`` and
    its derivatives from ``1/kappa_1`` interpolated on the quadrature nodes (spectrally
    accurate), all through the local interpolants of :class:`_OrbitBasis` on each point's
    bracket. The reported values are never worse than the grid's."""
    k = zeta.shape[0]
    m, w = basis.m, basis.w
    ks = (np.asarray(sched.knots, float) - zd.alpha_i) / (zd.alpha_f - zd.alpha_i)
    rows = np.arange(k)
    # three problems stacked: min |alpha'|, max |alpha'|, min zeta
    adot = np.abs(k1)[None, :] * np.sqrt(2.0 * np.maximum(zeta, 0.0))
    j = np.concatenate([np.argmin(adot, 1), np.argmax(adot, 1), np.argmin(zeta, 1)])
    lo, hi = basis.blo[j], basis.bhi[j]
    coef = basis.local[j]  # (3k, L, C): the interpolants of each point's bracket
    x = grid[j]
    rr = np.tile(rows, 3)
    F, T = sched.force[rr], sched.generalized[rr]
    zp3 = np.asarray(zeta_plus, float)[rr]
    e = np.arange(3 * k)
    is_speed = e < 2 * k
    kn_at = basis.at_knots
    lo_j, hi_j = basis.lo, basis.hi

    def zeta_of(v: np.ndarray) -> np.ndarray:
        """``zeta = zeta^+ + V_Z(x)`` from the local values ``v`` of V_0, Gamma, b_F at x."""
        z = zp3 + v[:, 0]
        for jj in range(len(lo_j)):
            below, above = x < lo_j[jj], x > hi_j[jj]
            c = np.where(below[:, None], edge_lo[jj], np.where(above[:, None], edge_hi[jj],
                                                                v[:, 1:]))
            z = z + np.einsum("em,em->e", c[:, :m] - kn_at[jj, 1:1 + m], F[:, jj, :]) \
                + (c[:, m] - kn_at[jj, 1 + m]) * T[:, jj]
        return z

    kn_at_alpha = np.asarray(sched.knots, float)
    # V_0, Gamma, b_F at the low and high end of each knot interval (for clipped points)
    ends_lo = np.where((kn_at_alpha[:-1] <= kn_at_alpha[1:])[:, None], kn_at[:-1], kn_at[1:])
    ends_hi = np.where((kn_at_alpha[:-1] <= kn_at_alpha[1:])[:, None], kn_at[1:], kn_at[:-1])
    edge_lo, edge_hi = ends_lo[:, 1:], ends_hi[:, 1:]
    c_ext = 2 * w + 3  # columns of the extrema series, then V_0, Gamma, b_F
    for _ in range(iterations):
        s = (x - zd.alpha_i) / (zd.alpha_f - zd.alpha_i)
        jj = np.clip(np.searchsorted(ks, s, side="right") - 1, 0, len(ks) - 2)
        vall = basis.evaluate(coef, x, lo, hi)
        v = vall[:, :c_ext]
        Fj, Tj = F[e, jj], T[e, jj]  # thrust of each point's knot interval
        d1 = v[:, 0] + np.einsum("em,em->e", v[:, 1:1 + m], Fj) + v[:, 1 + m] * Tj
        d2 = v[:, w] + np.einsum("em,em->e", v[:, w + 1:w + 1 + m], Fj) + v[:, w + 1 + m] * Tj
        e0, e1, e2 = v[:, 2 * w], v[:, 2 * w + 1], v[:, 2 * w + 2]
        z = zeta_of(vall[:, c_ext:])
        h = np.where(is_speed, d1 * e0 - 2.0 * z * e1, d1)
        dh = np.where(is_speed, d2 * e0 - d1 * e1 - 2.0 * z * e2, d2)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(dh != 0, h / dh, 0.0)
        step = np.where(np.isfinite(step), step, 0.0)
        x_new = np.clip(x - step, lo, hi)  # an extremum at a bracket end stays there
        moved = np.abs(x_new - x)
        x = x_new
        if np.all(moved <= 1e-14 * (1.0 + np.abs(x))):
            break
    vall = basis.evaluate(coef, x, lo, hi)
    z_exact = zeta_of(vall[:, c_ext:])
    E = vall[:, 2 * w]
    speed = np.sqrt(2.0 * np.maximum(z_exact[:2 * k], 0.0)) / np.abs(E[:2 * k])
    zmin = z_exact[2 * k:]
    xs, xz = x[:2 * k], x[2 * k:]
    g_min, g_max = adot[rows, j[:k]], adot[rows, j[k:2 * k]]
    g_z = zeta[rows, j[2 * k:]]
    take = speed[:k] < g_min
    a_min, v_min = np.where(take, xs[:k], grid[j[:k]]), np.where(take, speed[:k], g_min)
    take = speed[k:] > g_max
    a_max, v_max = np.where(take, xs[k:], grid[j[k:2 * k]]), np.where(take, speed[k:], g_max)
    take = zmin < g_z
    a_z, z_min = np.where(take, xz, grid[j[2 * k:]]), np.where(take, zmin, g_z)
    return {"a_min": a_min, "min_adot": v_min, "a_max": a_max, "max_adot": v_max,
            "a_zeta": a_z, "min_zeta": z_min}


def grazing_warning(lc: LimitCycle) -> str | None:
    """A warning when the orbit's swing foot moves down onto the ground slower than
    ``GRAZING_VELOCITY`` at touchdown (or not at all): the strike is (nearly) tangential and a
    full-order simulation can miss it. None otherwise (or without an orbit)."""
    v = lc.touchdown_velocity
    if v is None or v < -GRAZING_VELOCITY:
        return None
    return (f"grazing touchdown: the swing foot reaches the ground at vertical velocity "
            f"{v:.3g} m/s (moving down slower than {GRAZING_VELOCITY:g} m/s); a full-order "
            "simulation can miss the strike")


def paper_one_step_shift(zd: ZeroDynamics, schedule: Schedule) -> np.ndarray:
    """The paper's ``sum_j b_F T_j`` (+ force terms): the change of zeta^- in ONE step for a
    fixed zeta^+, not the fixed-point shift (SPEC 4 erratum)."""
    nominal = schedule.without_thrust()
    return (zd.V_Z(np.array(zd.alpha_f), schedule) - zd.V_Z(np.array(zd.alpha_f), nominal))


def fixed_point_shift(zd: ZeroDynamics, schedule: Schedule) -> np.ndarray:
    """True shift ``Delta zeta* = sum_j b_F T_j / (1 - delta_zero^2)`` (SPEC 4)."""
    return zd.fixed_point_of(paper_one_step_shift(zd, schedule))
