"""Center-manifold shaping with piecewise-constant thrust (SPEC section 4).

Knots ``alpha_1 = alpha_i, ..., alpha_n = alpha_f`` (in the direction of the step; given as alpha
values [rad] or as fractions ``s = (alpha - alpha_i)/(alpha_f - alpha_i)`` of the step) split the
step into intervals ``j = 1 .. n-1``, ``[alpha_j, alpha_{j+1})``, with constant thrust on each:

    generalized mode (the paper's T_j):  beta F_T = T_j [N m]
        b_F(alpha_{j+1}, alpha_j) = int_{alpha_j}^{alpha_{j+1}} dtau / kappa_1     [kg m^2 rad]
    force mode (physical thrust):        F_T = F_j [N] per thruster
        Gamma_j = int_{alpha_j}^{alpha_{j+1}} beta / kappa_1 dtau                 [kg m^3 rad]

    one-step change (the paper's value):  c = sum_j b_F T_j + sum_j Gamma_j . F_j  [kg^2 m^4/s^2]
    true fixed-point shift:               Delta zeta* = c / (1 - delta_zero^2)

**SPEC 4 erratum.** The paper's ``zeta* = zeta_0* + sum_j b_F T_j`` omits ``1/(1 - delta_zero^2)``:
it is the change of zeta^- in one step for a fixed zeta^+, not the shift of the fixed point.
This module reports both, labelled, and uses the true shift everywhere.

Solvers: (a) :func:`solve_target_zeta` / :func:`solve_target_speed`: minimum-Euclidean-norm
interval values reaching a target zeta* (exactly: the fixed point is affine in the values), or a
target average speed (bracketing root finder on zeta*); (b) :func:`solve_knots`: free interior
knots making a thrust pattern shape-only (``sum_j b_F T_j = 0`` for every swept value), so that
zeta^- and zeta^+ are unchanged while the orbit between the knots changes.

Knot validation and schedule building (a gait file's ``thrust:`` section included) live in
:mod:`thrustwalk_cli.thrust.schedule`.

zeta = sigma_N^2 / 2 [kg^2 m^4/s^2]; sigma_N [kg m^2/s]; alpha [rad]; alpha' [rad/s].
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import chebyshev as C
from scipy.optimize import brentq, linprog

from ..thrust.schedule import Schedule, knots_alpha
from .quadrature import ChebSeries
from .zero_dynamics import LimitCycle, ZeroDynamics, limit_cycles

DEFAULT_PATTERN = "k*(j-2)"  # the paper's example: T = (-k, 0, k) on n = 4 knots


DEFAULT_K = "0:50:2"


DEFAULT_FIELD_K = 60.0


def _alpha_at(zd: ZeroDynamics, s: float) -> float:
    return zd.alpha_i + s * (zd.alpha_f - zd.alpha_i)


def generalized_input(zd: ZeroDynamics, schedule: Schedule, alpha: np.ndarray) -> np.ndarray:
    """``u(alpha) = T_j + beta(alpha) F_j`` on ``[alpha_j, alpha_{j+1})`` [N m], the thrust term
    of ``sigma_N' = kappa_2 + u`` (SPEC 3, 4); shape (K,) + alpha.shape."""
    alpha = np.asarray(alpha, float)
    s_kn = zd.maps.s(schedule.knots)
    j = np.clip(np.searchsorted(s_kn, zd.maps.s(alpha), side="right") - 1, 0, len(s_kn) - 2)
    beta = zd.terms(alpha)["beta"]  # alpha.shape + (m,)
    F = schedule.force[:, j, :]  # (K,) + alpha.shape + (m,)
    return schedule.generalized[:, j] + np.einsum("...m,k...m->k...", beta, F)


# ------------------------------------------------------------------------ shifts (SPEC 4)
@dataclass(frozen=True)
class Intervals:
    """Per-interval integrals on the knots (SPEC 4).

    b_F: ``int 1/kappa_1`` per interval [kg m^2 rad], shape (n-1,).
    Gamma: ``int beta/kappa_1`` per interval and thruster [kg m^3 rad], shape (n-1, m).
    """

    knots: np.ndarray
    fractions: np.ndarray
    b_F: np.ndarray
    Gamma: np.ndarray


def intervals(zd: ZeroDynamics, knots: np.ndarray) -> Intervals:
    """Exact (spectral, error below the zero-dynamics tolerance) b_F and Gamma_j (SPEC 4)."""
    kn = np.asarray(knots, float)
    b, G = zd.interval_integrals(kn)
    return Intervals(kn, zd.maps.s(kn), b, G)


def one_step_change(zd: ZeroDynamics, schedule: Schedule) -> np.ndarray:
    """The paper's value ``sum_j b_F T_j + sum_j Gamma_j . F_j`` [kg^2 m^4/s^2], shape (K,):
    the change of zeta^- in ONE step for a fixed zeta^+ (SPEC 4 erratum), not the shift."""
    b, G = zd.interval_integrals(schedule.knots)
    return schedule.generalized @ b + np.einsum("kjm,jm->k", schedule.force, G)


def true_shift(zd: ZeroDynamics, schedule: Schedule) -> np.ndarray:
    """``Delta zeta* = (sum_j b_F T_j + sum_j Gamma_j . F_j) / (1 - delta_zero^2)``
    [kg^2 m^4/s^2] (SPEC 4): the shift of the Poincare fixed point."""
    return zd.fixed_point_of(one_step_change(zd, schedule))


def nominal_zeta_star(zd: ZeroDynamics) -> float:
    """``zeta_0* = V_0(alpha_f) / (1 - delta_zero^2)`` [kg^2 m^4/s^2] (SPEC 3):
    :meth:`ZeroDynamics.fixed_point` of zero thrust."""
    return zd.fixed_point()


def _coefficients(zd: ZeroDynamics, knots: np.ndarray, mode: str, thruster: int | None
                  ) -> np.ndarray:
    """Row ``a`` with ``(1 - delta_zero^2) zeta* = V_0(alpha_f) + a . x`` for interval values x."""
    b, G = zd.interval_integrals(knots)
    return b if mode == "generalized" else G[:, thruster]


# ------------------------------------------------------------------ solver (a): targets
@dataclass(frozen=True)
class TargetSolution:
    """Minimum-norm interval values reaching a target fixed point or speed (SPEC 4).

    ``values``: T_j [N m] or F_j [N]; ``zeta_star`` [kg^2 m^4/s^2]; ``speed`` [m/s];
    ``residual``: achieved minus target (zeta* or speed). ``None`` fields when ``success`` is
    false; ``reason`` says why.
    """

    success: bool
    reason: str
    kind: str  # "zeta" or "speed"
    target: float
    values: np.ndarray | None = None
    zeta_star: float | None = None
    speed: float | None = None
    residual: float | None = None
    evaluations: int = 0


def min_norm_values(zd: ZeroDynamics, knots: np.ndarray, zeta_target: float, mode: str,
                    thruster: int | None = None) -> np.ndarray:
    """Least-norm x with ``zeta*(x) = zeta_target`` (SPEC 4): the fixed point is affine,
    ``(1 - delta_zero^2) zeta* = V_0(alpha_f) + a . x`` (a = b_F or Gamma_j), so
    ``x = a c / |a|^2`` with ``c = (1 - delta_zero^2) zeta_target - V_0(alpha_f)``."""
    a = _coefficients(zd, knots, mode, thruster)
    c = (1.0 - zd.delta_zero_sq) * zeta_target - float(zd.V0(np.array(zd.alpha_f)))
    return a * (c / float(a @ a))


def _target_precheck(zd: ZeroDynamics, knots, mode, thruster) -> str:
    d2 = zd.delta_zero_sq
    if not zd.valid:
        return zd.invalid_reason
    if not 0.0 < d2 < 1.0:
        return f"delta_zero^2 = {d2:.6g} is not in (0, 1): no stable fixed point to move"
    a = _coefficients(zd, knots, mode, thruster)
    if not np.any(a):
        return "the thrust has no effect on the fixed point (all b_F or Gamma_j are zero)"
    return ""


def solve_target_zeta(zd: ZeroDynamics, knots: np.ndarray, zeta_target: float, mode: str,
                      thruster: int | None = None) -> TargetSolution:
    """Solver (a): minimum-norm values reaching ``zeta* = zeta_target`` [kg^2 m^4/s^2]."""
    why = _target_precheck(zd, knots, mode, thruster)
    if why:
        return TargetSolution(False, why, "zeta", zeta_target)
    x = min_norm_values(zd, knots, zeta_target, mode, thruster)
    m = zd.model.n_thrusters
    lc = limit_cycles(zd, Schedule.piecewise(knots, x[None, :], mode, m, thruster))[0]
    if not lc.exists:
        return TargetSolution(False, f"the minimum-norm thrust reaches zeta* = {zeta_target:.6g} "
                              f"but there is {lc.missing}", "zeta",
                              zeta_target, values=x, evaluations=1)
    return TargetSolution(True, "target fixed point reached with minimum-norm thrust", "zeta",
                          zeta_target, x, lc.zeta_star, lc.speed, lc.zeta_star - zeta_target, 1)


def solve_target_speed(zd: ZeroDynamics, knots: np.ndarray, speed: float, mode: str,
                       thruster: int | None = None, xtol: float = 1e-12,
                       max_doublings: int = 40) -> TargetSolution:
    """Solver (a) for a target average speed [m/s] (step length / step time, SPEC 3).

    Along the family ``x(zeta*) = min_norm_values(zeta*)`` the speed depends nonlinearly on
    zeta*: it is bracketed by doubling / halving zeta* from the nominal fixed point, then
    solved with Brent's method (``xtol`` relative to zeta*). Fails with a reason when no
    periodic orbit of the family has that speed (the walker would stop, or the speed is out of
    reach within ``max_doublings`` doublings).
    """
    why = _target_precheck(zd, knots, mode, thruster)
    if why:
        return TargetSolution(False, why, "speed", speed)
    count = 0

    def cycle(z: float) -> LimitCycle:
        nonlocal count
        count += 1
        x = min_norm_values(zd, knots, z, mode, thruster)
        sched = Schedule.piecewise(knots, x[None, :], mode, zd.model.n_thrusters, thruster)
        return limit_cycles(zd, sched)[0]

    z0 = nominal_zeta_star(zd)
    if not z0 > 0:
        z0 = zd.integral_scale
    lc0 = cycle(z0)
    if not lc0.exists:  # move up until an orbit exists
        for _ in range(max_doublings):
            z0 *= 2.0
            lc0 = cycle(z0)
            if lc0.exists:
                break
        else:
            return TargetSolution(False, f"no periodic orbit found up to zeta* = {z0:.6g}",
                                  "speed", speed, evaluations=count)
    lo, lc_lo, hi, lc_hi = z0, lc0, z0, lc0
    while lc_hi.speed < speed:
        if count > 2 * max_doublings:
            return TargetSolution(False, f"target speed {speed:g} m/s not reached: "
                                  f"{lc_hi.speed:.6g} m/s at zeta* = {hi:.6g}", "speed", speed,
                                  evaluations=count)
        lo, lc_lo = hi, lc_hi
        hi *= 2.0
        lc_hi = cycle(hi)
        if not lc_hi.exists:
            return TargetSolution(False, f"target speed {speed:g} m/s not reached: no orbit at "
                                  f"zeta* = {hi:.6g} ({lc_hi.reason})", "speed", speed,
                                  evaluations=count)
    while lc_lo.speed > speed:
        if count > 2 * max_doublings:
            return TargetSolution(False, f"target speed {speed:g} m/s not reached: "
                                  f"{lc_lo.speed:.6g} m/s at zeta* = {lo:.6g}", "speed", speed,
                                  evaluations=count)
        cand = lo / 2.0
        lc_c = cycle(cand)
        if not lc_c.exists:  # locate the slowest orbit of the family by bisection
            bad, good, lc_good = cand, lo, lc_lo
            for _ in range(50):
                mid = 0.5 * (bad + good)
                lc_m = cycle(mid)
                if lc_m.exists:
                    good, lc_good = mid, lc_m
                    if lc_m.speed <= speed:
                        break
                else:
                    bad = mid
                if good - bad <= 1e-9 * good:
                    break
            if not lc_good.speed <= speed:
                return TargetSolution(
                    False, f"target speed {speed:g} m/s is below the slowest periodic orbit of "
                    f"this thrust family (about {lc_good.speed:.6g} m/s at zeta* = {good:.6g}; "
                    f"slower, {lc_c.reason})", "speed", speed, evaluations=count)
            cand, lc_c = good, lc_good
        hi, lc_hi = lo, lc_lo
        lo, lc_lo = cand, lc_c

    def speed_of(z: float) -> float:
        lc = cycle(z)
        if not lc.exists:
            raise _NoOrbit(lc.reason)
        return lc.speed

    if lc_lo.speed == speed:
        z = lo
    else:
        try:
            z = zd.zeta_for_speed(speed, speed_of, lo, hi, xtol=xtol * hi,
                                  rtol=4 * np.finfo(float).eps, maxiter=200)
        except _NoOrbit as e:
            return TargetSolution(False, f"the orbit vanished inside the bracket [{lo:.6g}, "
                                  f"{hi:.6g}]: {e}", "speed", speed, evaluations=count)
    x = min_norm_values(zd, knots, z, mode, thruster)
    lc = cycle(z)
    return TargetSolution(True, "target speed reached with minimum-norm thrust (Brent's method "
                          "on zeta*)", "speed", speed, x, lc.zeta_star, lc.speed,
                          lc.speed - speed, count)


class _NoOrbit(Exception):
    pass


# ------------------------------------------------------------- solver (b): shape-only knots
@dataclass(frozen=True)
class KnotSolution:
    """Free knots making a pattern shape-only: ``sum_j P_kj w_j = 0`` for every row k (SPEC 4),
    with ``w_j`` = b_F (generalized) or Gamma_j of the driven thruster (force mode).

    ``fractions`` (of the step) and ``alpha`` [rad] of all knots; ``coordinate``: the cumulative
    ``W(alpha_j)/W(alpha_f)`` (W = int 1/kappa_1 or int beta/kappa_1), in which the condition is
    linear; ``conditions``: number of independent conditions; ``residual``:
    ``max_k |sum_j P_kj w_j| / max_k sum_j |P_kj w_j|``. ``None`` fields when ``success`` is
    false; ``reason`` says why.
    """

    success: bool
    reason: str
    free: tuple[int, ...]
    conditions: int
    method: str = ""
    fractions: np.ndarray | None = None
    alpha: np.ndarray | None = None
    coordinate: np.ndarray | None = None
    residual: float | None = None


def _cumulative(zd: ZeroDynamics, mode: str, thruster: int | None) -> Callable:
    if mode == "generalized":
        return lambda a: zd.B(np.asarray(a, float))
    return lambda a: zd.Gamma(np.asarray(a, float))[..., thruster]


def _monotone(zd: ZeroDynamics, mode: str, thruster: int | None) -> str:
    """'' if the cumulative coordinate is strictly monotone over the step, else a reason."""
    if not zd.valid:
        return zd.invalid_reason
    if mode == "generalized":
        return ""
    a = np.linspace(zd.alpha_i, zd.alpha_f, 801)
    t = zd.terms(a)
    g = t["beta"][:, thruster] * t["eDPhi"]
    sg = np.sign(g)
    if np.all(sg == sg[0]) and sg[0] != 0:
        return ""
    j = int(np.argmax(sg != sg[0])) if sg[0] != 0 else 0
    name = zd.model.robot.thruster_names[thruster]
    return (f"beta of thruster {name} changes sign near alpha = {a[j]:.6g} rad, so Gamma is not "
            "monotone along the step and the knots are not unique: give all knots")


def solve_knots(zd: ZeroDynamics, fractions: Sequence[float | None], P: np.ndarray, mode: str,
                thruster: int | None = None, min_gap: float = 1e-6) -> KnotSolution:
    """Solver (b): the free knots (``None`` in ``fractions``) for which the pattern values
    ``P`` (K, n-1) leave the fixed point unchanged for every row (SPEC 4 shape-only shaping).

    In the coordinate ``u = W(alpha)/W(alpha_f)`` (monotone) the conditions
    ``sum_j P_kj (u_{j+1} - u_j) = 0`` are linear. Among the solutions with increasing knots we
    take the one closest (least squares) to equal spacing in u between the given knots; if that
    one is not increasing, the one maximising the smallest interval (a linear program). If the
    conditions are inconsistent, or no increasing solution exists, ``success`` is false and
    ``reason`` says so. The paper's example (n = 4, T = (-k, 0, k)) gives
    ``b_F(alpha_2, alpha_1) = b_F(alpha_4, alpha_3) = b_F(alpha_3, alpha_2)``.
    """
    s = list(fractions)
    n = len(s)
    free = tuple(i for i, v in enumerate(s) if v is None)
    P = np.atleast_2d(np.asarray(P, float))
    why = _monotone(zd, mode, thruster)
    if why:
        return KnotSolution(False, why, free, 0)
    W = _cumulative(zd, mode, thruster)
    Wf = float(W(zd.alpha_f))
    # condition row per k over all knot values u_1..u_n: c_i = P_{i-1} - P_i (P_0 = P_n = 0)
    Pp = np.hstack([np.zeros((P.shape[0], 1)), P, np.zeros((P.shape[0], 1))])
    Cfull = Pp[:, :-1] - Pp[:, 1:]  # (K, n)
    scale = np.abs(P).max(axis=1, keepdims=True)
    keep = scale[:, 0] > 0
    Cfull = Cfull[keep] / scale[keep]
    fixed = [i for i in range(n) if i not in free]
    u_fixed = np.array([float(W(_alpha_at(zd, s[i]))) / Wf for i in fixed])
    u_fixed[0], u_fixed[-1] = 0.0, 1.0
    A = Cfull[:, list(free)]
    rhs = -Cfull[:, fixed] @ u_fixed
    nf = len(free)
    rank = int(np.linalg.matrix_rank(A, tol=1e-10)) if A.size else 0
    # reference: equal spacing in u between given neighbours
    u_ref = np.empty(n)
    u_ref[fixed] = u_fixed
    for i in free:
        lo = max(f for f in fixed if f < i)
        hi = min(f for f in fixed if f > i)
        u_ref[i] = u_ref[lo] + (u_ref[hi] - u_ref[lo]) * (i - lo) / (hi - lo)
    x0 = u_ref[list(free)]
    cond = "sum_j T_j b_F,j = 0" if mode == "generalized" else "sum_j F_j Gamma_j = 0"
    if A.shape[0] == 0:
        x, method = x0, "no condition (zero pattern): equal spacing in u"
    else:
        x = x0 + (np.linalg.lstsq(A, rhs - A @ x0, rcond=None)[0] if nf else 0.0)
        if np.abs(A @ x - rhs).max() > 1e-9:
            need = int(np.linalg.matrix_rank(np.hstack([A, rhs[:, None]]), tol=1e-10))
            return KnotSolution(False, (
                f"no shape-only knots exist: {cond} must hold for every k, which gives {need} "
                f"independent condition(s) on the knots, and {nf} free knot(s) cannot meet "
                f"them"), free, rank)
        method = "least squares closest to equal spacing in u"
    u = u_ref.copy()
    u[list(free)] = x
    if nf and np.min(np.diff(u)) < min_gap:
        u_lp, gap = _max_min_gap(A, rhs, u_fixed, fixed, free, n)
        if u_lp is None or gap < min_gap:
            g = "none" if u_lp is None else f"{gap + 0.0:.3g}"
            return KnotSolution(False, (
                f"no shape-only knots exist: every solution of {cond} puts two knots "
                f"together or out of order (largest possible smallest interval in u: {g})"),
                free, rank)
        u, method = u_lp, "maximum smallest interval in u (linear program)"
    # invert u(alpha) knot by knot
    sol_s = np.array([0.0 if v is None else v for v in s], float)
    for i in free:
        sol_s[i] = brentq(lambda t, ui=u[i]: float(W(_alpha_at(zd, t))) / Wf - ui, 0.0, 1.0,
                          xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
    alpha = knots_alpha(zd, sol_s)
    w = np.diff(W(alpha))
    terms = P * w[None, :]
    denom = float(np.abs(terms).sum(axis=1).max()) or 1.0
    resid = float(np.abs(terms.sum(axis=1)).max()) / denom
    if not np.all(np.diff(sol_s) > 0):
        return KnotSolution(False, "the solved knots are not increasing (numerical failure)",
                            free, rank, method)
    return KnotSolution(True, f"{nf} free knot(s) solved: fixed point unchanged", free, rank,
                        method, sol_s, alpha, u, resid)


def _max_min_gap(A, rhs, u_fixed, fixed, free, n) -> tuple[np.ndarray | None, float]:
    """LP: maximise t subject to A x = rhs and u_{i+1} - u_i >= t (u = fixed or free values)."""
    nf = len(free)
    pos = {i: c for c, i in enumerate(free)}
    val = dict(zip(fixed, u_fixed))
    A_ub, b_ub = [], []
    for i in range(n - 1):  # u_i - u_{i+1} + t <= 0
        row = np.zeros(nf + 1)
        const = 0.0
        for idx, sign in ((i, 1.0), (i + 1, -1.0)):
            if idx in pos:
                row[pos[idx]] += sign
            else:
                const += sign * val[idx]
        row[-1] = 1.0
        A_ub.append(row)
        b_ub.append(-const)
    A_eq = np.hstack([A, np.zeros((A.shape[0], 1))])
    c = np.zeros(nf + 1)
    c[-1] = -1.0
    res = linprog(c, A_ub=np.array(A_ub), b_ub=np.array(b_ub), A_eq=A_eq, b_eq=rhs,
                  bounds=[(0.0, 1.0)] * nf + [(None, 1.0)], method="highs")
    if res.status != 0:
        return None, -np.inf
    u = np.empty(n)
    u[fixed] = u_fixed
    u[list(free)] = res.x[:nf]
    return u, float(res.x[-1])


# ------------------------------------------------------------------------ vector field
@dataclass(frozen=True)
class VectorField:
    """Zero-dynamics vector field on a grid (SPEC 3) for one schedule.

    plane ``"alpha_dot"``: (alpha, alpha'), d_y = alpha'' [rad/s^2] with
        alpha'' = (dkappa_1/dalpha / kappa_1) alpha'^2 + kappa_1 (kappa_2 + u(alpha));
    plane ``"sigma"``: (alpha, sigma_N), d_y = sigma_N' = kappa_2 + u(alpha) [N m];
    d_alpha = alpha' [rad/s]. Arrays have shape (len(y), len(alpha)).
    """

    plane: str
    alpha: np.ndarray
    y: np.ndarray
    d_alpha: np.ndarray
    d_y: np.ndarray


def dkappa1_dalpha(zd: ZeroDynamics, alpha: np.ndarray) -> np.ndarray:
    """``dkappa_1/dalpha = -kappa_1^2 d(1/kappa_1)/dalpha`` [1/(kg m^2 rad)], with
    ``d(1/kappa_1)/dalpha`` the second derivative of the spectral series ``int 1/kappa_1``."""
    B = zd.B
    d2 = ChebSeries(B.a, B.b, C.chebder(B.coef, m=2, scl=2.0 / (B.b - B.a), axis=0))
    k1 = zd.terms(alpha)["kappa1"]
    return -(k1**2) * d2(alpha)


def vector_field(zd: ZeroDynamics, schedule: Schedule, plane: str, y_range: tuple[float, float],
                 n_alpha: int = 41, n_y: int = 31) -> VectorField:
    """The field of the 2-D zero dynamics for the single schedule ``schedule`` (SPEC 3)."""
    a = np.linspace(zd.alpha_i, zd.alpha_f, n_alpha)
    if a[0] > a[-1]:
        a = a[::-1]
    y = np.linspace(y_range[0], y_range[1], n_y)
    t = zd.terms(a)
    k1, k2 = t["kappa1"], t["kappa2"]
    u = generalized_input(zd, schedule, a)[0]
    Y = y[:, None]
    if plane == "sigma":
        return VectorField(plane, a, y, k1 * Y + 0 * a, np.broadcast_to(k2 + u, (n_y, n_alpha)))
    if plane == "alpha_dot":
        dk1 = dkappa1_dalpha(zd, a)
        return VectorField(plane, a, y, np.broadcast_to(Y, (n_y, n_alpha)) + 0 * a,
                           dk1 / k1 * Y**2 + k1 * (k2 + u))
    raise ValueError(f"plane must be 'alpha_dot' or 'sigma', got {plane!r}")
