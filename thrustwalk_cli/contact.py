"""Ground-contact feasibility along the periodic orbit (SPEC section 5).

Stance phase (stance foot fixed, ``q_u' = [q'; 0]``, ``q_u'' = [q''; 0]``). On Z, with
``zeta = sigma_N^2 / 2`` [kg^2 m^4/s^2]:

    q'     = Phi alpha',   q'' = Phi alpha'' + dPhi alpha'^2,   alpha'^2 = 2 kappa_1^2 zeta
    alpha'' from the unactuated row of the pinned dynamics:
           e_N^T D (Phi alpha'' + dPhi alpha'^2) + e_N^T h(q, Phi alpha') = b_N F_T (+ T)
    u      = rows 1..N-1 of (D q'' + h - B_F F_T)                                [N m]
    F_1    = rows N+1..N+2 of (D_u [q''; 0] + h_u(q, [q'; 0]) - B_Fu F_T)        [N]

Because ``h`` is quadratic in the velocity, everything is exactly affine in ``(zeta, F_T)``:

    F_1(alpha) = Lambda_2(alpha) F_T + Lambda_1(alpha) zeta(alpha) + Lambda_0(alpha)

The Lambdas are computed term by term (no differencing). Generalised-mode schedules (a
generalised force ``T`` on q_N, SPEC 4) are realised as a pure couple on the link whose absolute
angle is q_N (no net force): it enters ``alpha''`` and ``u`` but adds no column to the force rows.

Conditions (SPEC 5): ``F_1^v >= eps`` and the exact planar friction cone
``|F_1^h| <= mu F_1^v`` (an inscribed pyramid ``mu / sqrt(2)`` would be about 29 % too strict).
Impact: impulse ``F_2 = M_F q'^-`` proportional to ``sigma_N^-`` with ``F_2^v > 0``,
``|F_2^h| <= mu F_2^v``, and the trailing (old stance) foot lifts off: its vertical velocity
just after impact is > 0.

Worst points are found on a grid (knots included from both sides) and then polished by a
vectorised golden-section search inside their knot interval, so margins are not grid-limited.

The ``thrustwalk feasibility`` study (feasible region, records, figure data) is in
:mod:`thrustwalk_cli.contact_study`; its names are re-exported here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import chebyshev as C

from .errors import InputError
from .model import CompiledModel
from .quadrature import ChebSeries
from .zero_dynamics import LimitCycle, Schedule, ZeroDynamics, limit_cycles

GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
SCUFF_TOL = 1e-6  # [m] swing-foot penetration tolerated as numerical zero
SWING_WINDOW = (0.05, 0.95)  # s-range where the swing-foot clearance is measured

# ----------------------------------------------------------------------- exact stance terms
@dataclass(frozen=True)
class StanceTerms:
    """Exact affine stance terms on Z at ``alpha`` (shape ``(g,)``), SPEC 5.

    ``F_1 = L2 F_T + L1 zeta + L0 + LT T`` [N]; ``u = U2 F_T + U1 zeta + U0 + UT T`` [N m];
    ``alpha'' = A2 F_T + A1 zeta + A0 + AT T`` [rad/s^2]. Components of F_1: (horizontal,
    vertical). ``swing_height``: swing-foot height above the stance foot [m].
    """

    alpha: np.ndarray
    L0: np.ndarray  # (g, 2)
    L1: np.ndarray  # (g, 2)
    L2: np.ndarray  # (g, 2, m)
    LT: np.ndarray  # (g, 2)
    U0: np.ndarray  # (g, N-1)
    U1: np.ndarray
    U2: np.ndarray  # (g, N-1, m)
    UT: np.ndarray
    A0: np.ndarray  # (g,)
    A1: np.ndarray
    A2: np.ndarray  # (g, m)
    AT: np.ndarray
    swing_height: np.ndarray  # (g,)


def stance_terms(model: CompiledModel, maps, alpha: np.ndarray) -> StanceTerms:
    """Lambda_0..2 (and torque / alpha'' counterparts) at ``alpha`` (SPEC 5), exactly.

    Per unit zeta: ``alpha'^2 = 2 kappa_1^2``; the velocity part of ``h`` is
    ``alpha'^2 (h(q, Phi) - G)`` since ``h`` is quadratic in ``q'``. With ``E = e_N^T D Phi``:
    ``A0 = -G_N / E``, ``A1 = -2 kappa_1^2 (e_N^T (h(q,Phi) - G) + e_N^T D dPhi) / E``,
    ``A2 = b_N / E``, ``AT = 1 / E``.
    """
    alpha = np.atleast_1d(np.asarray(alpha, float))
    N = model.n
    q = maps.q_Z(alpha)
    phi = maps.Phi(alpha)
    dphi = maps.dPhi(alpha)
    D = model.D(q)
    G = model.G(q)
    BF = model.B_F(q)
    Du = model.D_u(q)
    BFu = model.B_Fu(q)
    z2 = np.zeros(alpha.shape + (2,))
    Gu = model.h_u(q, np.zeros(alpha.shape + (N + 2,)))
    hu_v = model.h_u(q, np.concatenate([phi, z2], axis=-1)) - Gu  # per unit alpha'^2
    h_v = model.h(q, phi) - G
    eD = D[..., N - 1, :]
    E = np.einsum("gj,gj->g", eD, phi)
    a2 = 2.0 / E**2  # alpha'^2 per unit zeta = 2 kappa_1^2
    A0 = -G[..., N - 1] / E
    A1 = -a2 * (h_v[..., N - 1] + np.einsum("gj,gj->g", eD, dphi)) / E
    A2 = BF[..., N - 1, :] / E[:, None]
    AT = 1.0 / E
    Q0 = phi * A0[:, None]
    Q1 = phi * A1[:, None] + dphi * a2[:, None]
    Q2 = phi[:, :, None] * A2[:, None, :]
    QT = phi * AT[:, None]

    def mv(M, v):
        return np.einsum("gij,gj->gi", M, v)

    Dc = Du[:, N:, :N]  # force rows, joint columns
    L0 = mv(Dc, Q0) + Gu[:, N:]
    L1 = mv(Dc, Q1) + a2[:, None] * hu_v[:, N:]
    L2 = np.einsum("gij,gjm->gim", Dc, Q2) - BFu[:, N:, :]
    LT = mv(Dc, QT)
    b = slice(0, N - 1)
    U0 = (mv(D, Q0) + G)[:, b]
    U1 = (mv(D, Q1) + a2[:, None] * h_v)[:, b]
    U2 = (np.einsum("gij,gjm->gim", D, Q2) - BF)[:, b, :]
    UT = mv(D, QT)[:, b]
    return StanceTerms(alpha, L0, L1, L2, LT, U0, U1, U2, UT, A0, A1, A2, AT,
                       model.p_swing(q)[..., 1])


# ------------------------------------------------------------------------- polynomial fits
@dataclass(frozen=True)
class TermFit:
    """Chebyshev fit of one Lambda_k over the step: ``L(alpha) = sum_k c_k T_k(x)``,
    ``x = 2 (alpha - alpha_i)/(alpha_f - alpha_i) - 1``. ``coef``: (degree+1, ...) in the
    Lambda's units; ``max_error`` absolute (on a check grid that is not the fit grid),
    ``relative_error`` = max_error / max |Lambda|."""

    name: str
    degree: int
    coef: np.ndarray
    max_error: float
    relative_error: float
    reached: bool

    def __call__(self, x: np.ndarray) -> np.ndarray:
        out = C.chebval(np.asarray(x, float), self.coef, tensor=True)
        return np.moveaxis(np.asarray(out), -1, 0)


@dataclass(frozen=True)
class Fits:
    """Polynomial approximations L_0, L_1, L_2, L_T of the Lambdas (SPEC 5)."""

    alpha_i: float
    alpha_f: float
    fits: dict[str, TermFit]
    tol: float | None

    def x(self, alpha: np.ndarray) -> np.ndarray:
        return 2.0 * (np.asarray(alpha, float) - self.alpha_i) / (self.alpha_f - self.alpha_i) - 1

    def force_terms(self, alpha: np.ndarray) -> tuple[np.ndarray, ...]:
        x = self.x(np.atleast_1d(alpha))
        return tuple(self.fits[k](x) for k in ("L0", "L1", "L2", "LT"))


def fit_terms(model: CompiledModel, zd: ZeroDynamics, degree: int | None = None,
              tol: float = 1e-3, max_degree: int = 30, fit_points: int = 257,
              check_points: int = 1001) -> Fits:
    """Least-squares Chebyshev fits of Lambda_0..2, L_T over the step.

    ``degree`` fixed, or the smallest degree whose relative max error (check grid) is <= ``tol``
    (at most ``max_degree``; ``reached`` says whether the target was met).
    """
    a, b = zd.alpha_i, zd.alpha_f
    af = a + (b - a) * 0.5 * (1 - np.cos(np.pi * np.arange(fit_points) / (fit_points - 1)))
    ac = np.linspace(a, b, check_points)
    tf, tc = stance_terms(model, zd.maps, af), stance_terms(model, zd.maps, ac)
    xf = 2 * (af - a) / (b - a) - 1
    xc = 2 * (ac - a) / (b - a) - 1
    out = {}
    for name in ("L0", "L1", "L2", "LT"):
        yf, yc = getattr(tf, name), getattr(tc, name)
        scale = float(np.abs(yc).max()) or 1.0
        degrees = [degree] if degree is not None else range(1, max_degree + 1)
        for d in degrees:
            coef = C.chebfit(xf, yf.reshape(len(xf), -1), d)
            approx = C.chebval(xc, coef, tensor=True).T.reshape(yc.shape)
            err = float(np.abs(approx - yc).max())
            if degree is not None or err <= tol * scale:
                break
        out[name] = TermFit(name, int(d), coef.reshape((d + 1,) + yf.shape[1:]), err,
                            err / scale, degree is not None or err <= tol * scale)
    return Fits(a, b, out, None if degree is not None else tol)


# ----------------------------------------------------------------------------- impact data
@dataclass(frozen=True)
class ImpactData:
    """Impact on Z per unit pre-impact momentum, in the walking direction (SPEC 5).

    ``impulse_per_sigma``: ``F_2 / |sigma_N^-|`` [N s per kg m^2/s] (direction independent of
    speed); ``liftoff_per_sigma``: vertical velocity of the trailing foot just after impact per
    ``|sigma_N^-|`` [m/s per kg m^2/s]; ``friction_ratio = |F_2^h| / F_2^v``.
    """

    impulse_per_sigma: np.ndarray
    trailing_foot_velocity_per_sigma: np.ndarray
    friction_ratio: float | None
    admissible_vertical: bool
    liftoff: bool

    @property
    def liftoff_per_sigma(self) -> float:
        return float(self.trailing_foot_velocity_per_sigma[1])

    def admissible(self, mu: float) -> bool:
        return (self.admissible_vertical and self.liftoff and self.friction_ratio is not None
                and self.friction_ratio <= mu)

    def reasons(self, mu: float) -> list[str]:
        out = []
        if not self.admissible_vertical:
            out.append("impact impulse pulls the swing foot down (F_2^v <= 0)")
        elif self.friction_ratio is not None and self.friction_ratio > mu:
            out.append(f"impact impulse outside the friction cone "
                       f"(|F_2^h|/F_2^v = {self.friction_ratio:.4g} > mu = {mu:g})")
        if not self.liftoff:
            out.append("the trailing foot does not lift off after impact "
                       f"(vertical velocity {self.liftoff_per_sigma:.4g} m/s per unit "
                       "|sigma_N^-| <= 0)")
        return out


def impact_data(model: CompiledModel, zd: ZeroDynamics) -> ImpactData:
    """``F_2 = M_F Phi(alpha_f) kappa_1(alpha_f) sigma_N^-``; the trailing foot's velocity is the
    last two components of ``q_u'^+ = M_u q'^-`` (SPEC 5). Thrust does not enter (not impulsive)."""
    Mu, MF, _ = model.impact_maps(zd.maps.q_minus)
    t = zd.terms(np.array([zd.alpha_f]))
    dq = t["Phi"][0] * t["kappa1"][0] * zd.sigma_sign  # q'^- per unit |sigma_N^-|
    F2 = MF @ dq
    v = (Mu @ dq)[model.n:]
    ratio = float(abs(F2[0]) / F2[1]) if F2[1] > 0 else None
    return ImpactData(F2, v, ratio, bool(F2[1] > 0), bool(v[1] > 0))


def swing_clearance(model: CompiledModel, zd: ZeroDynamics, points: int = 801) -> dict:
    """Swing-foot height along the step [m]: minimum for s in ``SWING_WINDOW`` (away from
    lift-off and touch-down, where it is 0 by construction) and the deepest penetration
    anywhere strictly inside the step."""
    a = np.linspace(zd.alpha_i, zd.alpha_f, points)
    h = model.p_swing(zd.maps.q_Z(a))[..., 1]
    s = np.linspace(0.0, 1.0, points)
    win = (s >= SWING_WINDOW[0]) & (s <= SWING_WINDOW[1])
    j = int(np.argmin(np.where(win, h, np.inf)))
    inner = h[1:-1]
    k = int(np.argmin(inner)) + 1
    return {"min_height": float(h[j]), "alpha_at_min_height": float(a[j]),
            "max_height": float(h.max()), "deepest": float(min(h[k], 0.0)),
            "alpha_at_deepest": float(a[k]), "scuffs": bool(h[k] < -SCUFF_TOL),
            "alpha": a, "height": h}


# ------------------------------------------------------------------------- case evaluation
def step_grid(knots: np.ndarray, points: int = 401) -> tuple[np.ndarray, np.ndarray]:
    """Grid over the step with every knot interval sampled end to end (knots appear twice, with
    the thrust of each side). Returns ``(alpha, interval index)``."""
    kn = np.asarray(knots, float)
    n_int = len(kn) - 1
    per = max(41, points // n_int)
    al = [np.linspace(kn[j], kn[j + 1], per) for j in range(n_int)]
    return np.concatenate(al), np.repeat(np.arange(n_int), per)


class _ZetaAt:
    """``zeta_i(alpha_i) = zeta^+_i + V_Z(alpha_i; schedule i)`` for one alpha per schedule, with
    V_0, Gamma and b_F stacked into one Chebyshev series (one evaluation per call)."""

    def __init__(self, zd: ZeroDynamics, sched: Schedule):
        self.sched = sched
        self.m = zd.Gamma.coef.shape[1]
        coef = np.column_stack([zd.V0.coef, zd.Gamma.coef, zd.B.coef])
        self.series = ChebSeries(zd.V0.a, zd.V0.b, coef)
        kn = sched.knots
        self.lo, self.hi = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
        self.at_knots = self.series(kn)  # (n+1, 2+m)

    def __call__(self, zeta_plus: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        pts = np.vstack([alpha[None, :],
                         np.clip(alpha[None, :], self.lo[:, None], self.hi[:, None])])
        v = self.series(pts)  # (1+n, k, 2+m)
        m = self.m
        dG = v[1:, :, 1:1 + m] - self.at_knots[:-1, None, 1:1 + m]  # (n, k, m)
        dB = v[1:, :, -1] - self.at_knots[:-1, None, -1]  # (n, k)
        return (zeta_plus + v[0, :, 0] + np.einsum("jkm,kjm->k", dG, self.sched.force)
                + np.einsum("jk,kj->k", dB, self.sched.generalized))


Provider = Callable[[np.ndarray], tuple[np.ndarray, ...]]


def _exact_provider(model: CompiledModel, zd: ZeroDynamics) -> Provider:
    def f(alpha):
        t = stance_terms(model, zd.maps, alpha)
        return t.L0, t.L1, t.L2, t.LT
    return f


def _force(terms, zeta, F, T):
    """F_1 from the affine form; zeta (...,), F (..., m), T (...,) broadcast with terms."""
    L0, L1, L2, LT = terms
    return (np.einsum("...im,...m->...i", L2, F) + L1 * zeta[..., None] + L0
            + LT * T[..., None])


def friction_ratio(F1: np.ndarray) -> np.ndarray:
    """``|F^h| / F^v`` of forces ``F1`` (..., 2) [-]; inf where ``F^v <= 0``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(F1[..., 1] > 0, np.abs(F1[..., 0]) / F1[..., 1], np.inf)


def _golden(f: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray,
            iters: int = 45) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised golden-section minimisation of ``f`` on ``[lo_i, hi_i]`` (one bracket per
    entry); returns (argmin, min) of the last bracket's interior points."""
    a, b = lo.astype(float).copy(), hi.astype(float).copy()
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        left = fc <= fd
        na, nb = np.where(left, a, c), np.where(left, d, b)
        kx, kf = np.where(left, c, d), np.where(left, fc, fd)
        x = np.where(left, nb - GOLDEN * (nb - na), na + GOLDEN * (nb - na))
        fx = f(x)
        c, fc = np.where(left, x, kx), np.where(left, fx, kf)
        d, fd = np.where(left, kx, x), np.where(left, kf, fx)
        a, b = na, nb
    best = fc <= fd
    return np.where(best, c, d), np.where(best, fc, fd)


@dataclass(frozen=True)
class StanceExtremes:
    """Worst points of the stance conditions for a batch of cases (SI units)."""

    min_vertical: np.ndarray
    alpha_min_vertical: np.ndarray
    max_ratio: np.ndarray  # inf where F^v <= 0 somewhere
    alpha_max_ratio: np.ndarray


def _extremes(provider: Provider, zd: ZeroDynamics, sched: Schedule, zeta_plus: np.ndarray,
              alpha: np.ndarray, idx: np.ndarray, F1: np.ndarray, polish: bool
              ) -> StanceExtremes:
    """Grid extremes of F^v (min) and |F^h|/F^v (max), polished inside their knot interval."""
    k = F1.shape[0]
    rows = np.arange(k)
    Fv, R = F1[..., 1], friction_ratio(F1)
    jv, jr = np.argmin(Fv, axis=1), np.argmax(R, axis=1)
    out = [Fv[rows, jv], alpha[jv], R[rows, jr], alpha[jr]]
    if not polish:
        return StanceExtremes(*out)

    def bracket(j):
        same = idx[np.clip(j - 1, 0, len(idx) - 1)] == idx[j]
        lo = np.where(same & (j > 0), alpha[np.clip(j - 1, 0, None)], alpha[j])
        same = idx[np.clip(j + 1, 0, len(idx) - 1)] == idx[j]
        hi = np.where(same & (j < len(idx) - 1), alpha[np.clip(j + 1, None, len(idx) - 1)],
                      alpha[j])
        return np.minimum(lo, hi), np.maximum(lo, hi)

    zeta_at = _ZetaAt(zd, sched)

    def f1_at(a, interval):
        z = zeta_at(zeta_plus, a)
        F = sched.force[rows, interval, :]
        T = sched.generalized[rows, interval]
        return _force(provider(a), z, F, T)

    # minimise F^v; maximise |F^h|/F^v (= minimise its negative) where it is finite
    for slot, j, col, sign in ((0, jv, 1, 1.0), (2, jr, None, -1.0)):
        lo, hi = bracket(j)

        def obj(a, interval=idx[j], col=col, sign=sign):
            F1a = f1_at(a, interval)
            val = F1a[:, col] if col is not None else friction_ratio(F1a)
            return np.where(np.isfinite(val), sign * val, 1e300)

        xa, fa = _golden(obj, lo, hi)
        better = np.isfinite(out[slot]) & (fa < sign * out[slot])
        out[slot] = np.where(better, sign * fa, out[slot])
        out[slot + 1] = np.where(better, xa, out[slot + 1])
    return StanceExtremes(*out)


@dataclass(frozen=True)
class CaseResult:
    """Contact feasibility of one thrust case on its periodic orbit (SPEC 5), SI units.

    ``feasible``: a periodic orbit exists, ``F_1^v >= eps`` and ``|F_1^h| <= mu F_1^v`` along the
    step, the impact is admissible and the trailing foot lifts off. ``reason`` names every
    failed condition. Stance fields are ``None`` when no orbit exists.
    """

    label: str
    thrust: float | list | None
    feasible: bool
    reason: str
    cycle: LimitCycle
    min_vertical_force: float | None = None
    alpha_at_min_vertical_force: float | None = None
    max_friction_ratio: float | None = None
    alpha_at_max_friction_ratio: float | None = None
    impact_impulse: list | None = None
    impact_friction_ratio: float | None = None
    liftoff_velocity: float | None = None
    max_abs_torque: list | None = None
    poly: dict | None = None
    margins: dict | None = None
    profile: dict | None = field(default=None, repr=False)


@dataclass(frozen=True)
class ContactReport:
    """Everything the ``feasibility`` command writes (SPEC 5)."""

    mu: float
    eps: float
    impact: ImpactData
    swing: dict
    fits: Fits
    cases: list[CaseResult]
    knots: np.ndarray


def evaluate(model: CompiledModel, zd: ZeroDynamics, sched: Schedule, *, mu: float,
             eps: float = 0.0, fits: Fits | None = None, labels: list[str] | None = None,
             thrust: list | None = None, points: int = 401, polish: bool = True,
             profiles: bool = True) -> ContactReport:
    """Contact feasibility of every schedule in ``sched`` on its own periodic orbit (SPEC 5)."""
    if fits is None:
        fits = fit_terms(model, zd)
    k = sched.size
    labels = labels or [f"case {i}" for i in range(k)]
    thrust = thrust if thrust is not None else [None] * k
    cycles = limit_cycles(zd, sched)
    imp = impact_data(model, zd)
    swing = swing_clearance(model, zd)
    alpha, idx = step_grid(sched.knots, points)
    exact = stance_terms(model, zd.maps, alpha)
    ex_terms = (exact.L0, exact.L1, exact.L2, exact.LT)
    po_terms = fits.force_terms(alpha)
    zstar = np.array([c.zeta_star if c.exists else 0.0 for c in cycles])
    zplus = zd.delta_zero_sq * zstar
    zeta = zplus[:, None] + zd.V_Z(alpha, sched)  # (k, g)
    F = sched.force[:, idx, :]  # (k, g, m)
    T = sched.generalized[:, idx]
    F1 = _force(ex_terms, zeta, F, T)
    F1p = _force(po_terms, zeta, F, T)
    U = (np.einsum("gim,kgm->kgi", exact.U2, F) + exact.U1 * zeta[..., None] + exact.U0
         + exact.UT * T[..., None])
    ext = _extremes(_exact_provider(model, zd), zd, sched, zplus, alpha, idx, F1, polish)
    ext_p = _extremes(fits.force_terms, zd, sched, zplus, alpha, idx, F1p, polish)
    fit_err = np.abs(F1p - F1).max(axis=(1, 2))
    imp_ok = imp.admissible(mu)
    cases = []
    for i, lc in enumerate(cycles):
        if not lc.exists:
            why = lc.reason if lc.reason.startswith("no periodic orbit") else \
                f"no periodic orbit: {lc.reason}"
            cases.append(CaseResult(labels[i], thrust[i], False, f"infeasible: {why}", lc,
                                    impact_friction_ratio=imp.friction_ratio))
            continue
        why = []
        v_ok = ext.min_vertical[i] >= eps
        r_ok = np.isfinite(ext.max_ratio[i]) and ext.max_ratio[i] <= mu
        if not v_ok:
            why.append(f"vertical ground force {ext.min_vertical[i]:.4g} N < eps = {eps:g} N at "
                       f"alpha = {ext.alpha_min_vertical[i]:.4g} rad")
        if not r_ok and v_ok:
            why.append(f"friction ratio |F^h|/F^v = {ext.max_ratio[i]:.4g} > mu = {mu:g} at "
                       f"alpha = {ext.alpha_max_ratio[i]:.4g} rad")
        why += imp.reasons(mu)
        sig = abs(lc.sigma_minus)
        ratio = float(ext.max_ratio[i]) if np.isfinite(ext.max_ratio[i]) else None
        pv = bool(ext_p.min_vertical[i] >= eps and np.isfinite(ext_p.max_ratio[i])
                  and ext_p.max_ratio[i] <= mu and imp_ok)
        pr = float(ext_p.max_ratio[i]) if np.isfinite(ext_p.max_ratio[i]) else None
        feasible = bool(v_ok and r_ok and imp_ok)
        margins = {
            "vertical_force": float(ext.min_vertical[i] - eps),
            "friction": None if ratio is None else mu - ratio,
            "impact_friction": None if imp.friction_ratio is None else mu - imp.friction_ratio,
            "impact_vertical_impulse": float(imp.impulse_per_sigma[1] * sig),
            "liftoff_velocity": float(imp.liftoff_per_sigma * sig),
        }
        prof = None
        if profiles:
            prof = {"alpha": alpha, "F1": F1[i], "ratio": friction_ratio(F1[i]), "torque": U[i],
                    "zeta": zeta[i], "thrust": F[i], "generalized": T[i]}
        cases.append(CaseResult(
            labels[i], thrust[i], feasible,
            "feasible" if feasible else "infeasible: " + "; ".join(why), lc,
            min_vertical_force=float(ext.min_vertical[i]),
            alpha_at_min_vertical_force=float(ext.alpha_min_vertical[i]),
            max_friction_ratio=ratio,
            alpha_at_max_friction_ratio=float(ext.alpha_max_ratio[i]) if ratio is not None
            else None,
            impact_impulse=(imp.impulse_per_sigma * sig).tolist(),
            impact_friction_ratio=imp.friction_ratio,
            liftoff_velocity=float(imp.liftoff_per_sigma * sig),
            max_abs_torque=np.abs(U[i]).max(axis=0).tolist(),
            poly={"feasible": pv, "agrees": pv == feasible,
                  "min_vertical_force": float(ext_p.min_vertical[i]),
                  "alpha_at_min_vertical_force": float(ext_p.alpha_min_vertical[i]),
                  "max_friction_ratio": pr,
                  "max_force_error": float(fit_err[i])},
            margins=margins, profile=prof))
    return ContactReport(mu, eps, imp, swing, fits, cases, sched.knots)


def check_contact_options(mu: float, eps: float) -> None:
    """Bad ``--mu`` [-] / ``--eps`` [N] (shared by feasibility and optimize) -> InputError."""
    if not (np.isfinite(mu) and mu > 0):
        raise InputError(f"option --mu: the friction coefficient must be > 0 (got {mu:g})")
    if not (np.isfinite(eps) and eps >= 0):
        raise InputError(f"option --eps: the minimum vertical force must be >= 0 N "
                         f"(got {eps:g})")


# The feasibility study lives in :mod:`contact_study` (which imports this module); its public
# names stay reachable here, resolved on first use.
_STUDY_NAMES = ("Region", "feasible_region", "fits_record", "impact_record", "case_record",
                "FRICTION_NOTE", "UNITS", "schedule_from_spec", "check_options",
                "feasibility_study")


def __getattr__(name: str):
    if name in _STUDY_NAMES:
        from . import contact_study
        return getattr(contact_study, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
