"""Contact feasibility of thrust cases on their periodic orbits (SPEC section 5).

For every schedule of a batch: the exact affine ground force
``F_1(alpha) = Lambda_2 F_T + Lambda_1 zeta(alpha) + Lambda_0``
(:mod:`thrustwalk_cli.contact.terms`) on a grid over the step (knots included from both
sides), its worst points polished by a vectorised golden-section search inside their knot
interval (margins are not grid-limited),
the same with the polynomial fits L_k, the impact conditions and the verdict:
``F_1^v >= eps``, ``|F_1^h| <= mu F_1^v``, admissible impact, trailing foot lifting off. SI units.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..hzd.extrema import golden_min_smooth, neighbours
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics, ZetaAt, limit_cycles
from ..model.compiled import CompiledModel
from ..thrust.schedule import Schedule
from .terms import (
    Fits,
    ImpactData,
    fit_terms,
    impact_data,
    scuff_reason,
    stance_terms,
    swing_clearance,
)


# ------------------------------------------------------------------------- case evaluation
def step_grid(knots: np.ndarray, points: int = 401) -> tuple[np.ndarray, np.ndarray]:
    """Grid over the step with every knot interval sampled end to end (knots appear twice, with
    the thrust of each side). Returns ``(alpha, interval index)``."""
    kn = np.asarray(knots, float)
    n_int = len(kn) - 1
    per = max(41, points // n_int)
    al = [np.linspace(kn[j], kn[j + 1], per) for j in range(n_int)]
    return np.concatenate(al), np.repeat(np.arange(n_int), per)


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


def _unique_terms(provider: Provider, X: np.ndarray) -> tuple[np.ndarray, ...]:
    """``provider`` at the abscissae ``X`` (k, n), evaluated once per distinct row (cases of a
    sweep share their brackets), as arrays of leading shape (k, n)."""
    rows, inverse = np.unique(X, axis=0, return_inverse=True)
    terms = provider(rows.ravel())
    n = X.shape[1]
    return tuple(t.reshape((rows.shape[0], n) + t.shape[1:])[inverse.ravel()] for t in terms)


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

    zeta_at = ZetaAt(zd, sched)

    # minimise F^v; maximise |F^h|/F^v (= minimise its negative) where it is finite; the
    # search runs on a local interpolant of F_1 (golden_min_smooth), the value at its result
    # is the exact one
    for slot, j, col, sign in ((0, jv, 1, 1.0), (2, jr, None, -1.0)):
        lo, hi = neighbours(alpha, j, idx)
        F, T = sched.force[rows, idx[j], :], sched.generalized[rows, idx[j]]

        def sample(X, F=F, T=T):
            return _force(_unique_terms(provider, X), zeta_at(zeta_plus, X), F[:, None, :],
                          T[:, None])

        def obj(F1a, col=col, sign=sign):
            val = F1a[:, col] if col is not None else friction_ratio(F1a)
            return np.where(np.isfinite(val), sign * val, 1e300)

        xa = golden_min_smooth(sample, obj, lo, hi)
        fa = obj(_force(provider(xa), zeta_at(zeta_plus, xa), F, T))
        better = np.isfinite(out[slot]) & (fa < sign * out[slot])
        out[slot] = np.where(better, sign * fa, out[slot])
        out[slot + 1] = np.where(better, xa, out[slot + 1])
    return StanceExtremes(*out)


def _max_abs_torque(model: CompiledModel, zd: ZeroDynamics, sched: Schedule,
                    zeta_plus: np.ndarray, alpha: np.ndarray, idx: np.ndarray, U: np.ndarray,
                    polish: bool) -> np.ndarray:
    """``max |u_p|`` over the step per case and joint, (k, N-1) [N m]: the grid maximum of each
    (case, joint) polished by golden section inside its knot interval (u jumps at knots where
    the thrust changes)."""
    k, g, nb = U.shape
    A = np.abs(U).transpose(0, 2, 1).reshape(k * nb, g)  # entry e = case * nb + joint
    if not polish or A.size == 0:
        return A.max(axis=1, initial=0.0).reshape(k, nb)
    rows, joint = np.repeat(np.arange(k), nb), np.tile(np.arange(nb), k)
    e = np.arange(rows.size)
    rep = sched.take(rows)
    zeta_at, zp = ZetaAt(zd, rep), zeta_plus[rows]
    j = np.argmax(A, axis=1)
    F, T = rep.force[e, idx[j], :], rep.generalized[e, idx[j]]

    def terms(a):
        t = stance_terms(model, zd.maps, a)
        return t.U0, t.U1, t.U2, t.UT

    def torque(U0, U1, U2, UT, zeta, F, T):
        return (np.einsum("...im,...m->...i", U2, F) + U1 * zeta[..., None] + U0
                + UT * T[..., None])

    def sample(X):  # u_joint(e) at X (E, n): (E, n)
        u = torque(*_unique_terms(terms, X), zeta_at(zp, X), F[:, None, :], T[:, None])
        return u[e, :, joint]

    lo, hi = neighbours(alpha, j, idx)
    xa = golden_min_smooth(sample, lambda u: -np.abs(u), lo, hi)
    exact = torque(*terms(xa), zeta_at(zp, xa), F, T)[e, joint]
    return np.maximum(A[e, j], np.abs(exact)).reshape(k, nb)


@dataclass(frozen=True)
class CaseResult:
    """Contact feasibility of one thrust case on its periodic orbit (SPEC 5), SI units.

    ``feasible``: a periodic orbit exists, ``F_1^v >= eps`` and ``|F_1^h| <= mu F_1^v`` along the
    step, the impact is admissible, the trailing foot lifts off and the swing foot stays above
    the ground (no scuffing). ``reason`` names every
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
    fits: Fits | None  # None when evaluated without the polynomial fits
    cases: list[CaseResult]
    knots: np.ndarray


def evaluate(model: CompiledModel, zd: ZeroDynamics, sched: Schedule, *, mu: float,
             eps: float = 0.0, fits: Fits | None = None, labels: list[str] | None = None,
             thrust: list | None = None, points: int = 401, polish: bool = True,
             profiles: bool = True, cycles: list[LimitCycle] | None = None,
             swing: dict | None = None, polynomial: bool = True, torque: bool = True
             ) -> ContactReport:
    """Contact feasibility of every schedule in ``sched`` on its own periodic orbit (SPEC 5).

    ``cycles``/``swing``: the schedules' limit cycles and the swing-foot clearance when the
    caller has them already. ``polynomial=False`` skips the polynomial fits L_k (``poly`` is
    then None) and ``torque=False`` the polished joint-torque maxima (``max_abs_torque`` None):
    the verdict is the same, it only needs the exact terms."""
    if fits is None and polynomial:
        fits = fit_terms(model, zd)
    k = sched.size
    labels = labels or [f"case {i}" for i in range(k)]
    thrust = thrust if thrust is not None else [None] * k
    cycles = limit_cycles(zd, sched) if cycles is None else cycles
    imp = impact_data(model, zd)
    swing = swing_clearance(model, zd) if swing is None else swing
    alpha, idx = step_grid(sched.knots, points)
    exact = stance_terms(model, zd.maps, alpha)
    ex_terms = (exact.L0, exact.L1, exact.L2, exact.LT)
    zstar = np.array([c.zeta_star if c.exists else 0.0 for c in cycles])
    zplus = zd.delta_zero_sq * zstar
    zeta = zplus[:, None] + zd.V_Z(alpha, sched)  # (k, g)
    F = sched.force[:, idx, :]  # (k, g, m)
    T = sched.generalized[:, idx]
    F1 = _force(ex_terms, zeta, F, T)
    U = (np.einsum("gim,kgm->kgi", exact.U2, F) + exact.U1 * zeta[..., None] + exact.U0
         + exact.UT * T[..., None])
    ext = _extremes(_exact_provider(model, zd), zd, sched, zplus, alpha, idx, F1, polish)
    ext_p = fit_err = None
    if polynomial:
        F1p = _force(fits.force_terms(alpha), zeta, F, T)
        ext_p = _extremes(fits.force_terms, zd, sched, zplus, alpha, idx, F1p, polish)
        fit_err = np.abs(F1p - F1).max(axis=(1, 2))
    umax = _max_abs_torque(model, zd, sched, zplus, alpha, idx, U, polish) if torque else None
    imp_ok = imp.admissible(mu)
    cases = []
    for i, lc in enumerate(cycles):
        if not lc.exists:
            why = lc.missing
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
        if swing["scuffs"]:
            why.append(scuff_reason(swing))
        sig = abs(lc.sigma_minus)
        ratio = float(ext.max_ratio[i]) if np.isfinite(ext.max_ratio[i]) else None
        feasible = bool(v_ok and r_ok and imp_ok and not swing["scuffs"])
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
            max_abs_torque=None if umax is None else umax[i].tolist(),
            poly=None if ext_p is None else _poly_record(ext_p, i, eps, mu, imp_ok and not
                                                         swing["scuffs"], feasible, fit_err[i]),
            margins=margins, profile=prof))
    return ContactReport(mu, eps, imp, swing, fits, cases, sched.knots)


def _poly_record(ext_p: StanceExtremes, i: int, eps: float, mu: float, rest_ok: bool,
                 feasible: bool, fit_err: float) -> dict:
    """The verdict of case ``i`` with the polynomial fits L_k in place of the exact terms."""
    ratio = ext_p.max_ratio[i]
    pv = bool(ext_p.min_vertical[i] >= eps and np.isfinite(ratio) and ratio <= mu and rest_ok)
    return {"feasible": pv, "agrees": pv == feasible,
            "min_vertical_force": float(ext_p.min_vertical[i]),
            "alpha_at_min_vertical_force": float(ext_p.alpha_min_vertical[i]),
            "max_friction_ratio": float(ratio) if np.isfinite(ratio) else None,
            "max_force_error": float(fit_err)}


def check_contact_options(mu: float, eps: float) -> None:
    """Bad ``mu`` [-] / minimum vertical force ``eps`` [N] (shared by feasibility and optimize)
    -> InputError on the parameters ``mu`` / ``min_vertical_force``."""
    if not (np.isfinite(mu) and mu > 0):
        raise InputError.param("mu", f"the friction coefficient must be > 0 (got {mu:g})")
    if not (np.isfinite(eps) and eps >= 0):
        raise InputError.param("min_vertical_force", "the minimum vertical force must be >= 0 N "
                         f"(got {eps:g})")
