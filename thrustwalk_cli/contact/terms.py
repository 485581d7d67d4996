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
``|F_2^h| <= mu F_2^v``, the trailing (old stance) foot lifts off: its vertical velocity
just after impact is > 0, and the swing foot strikes: its vertical velocity just before impact
is < 0 (a touchdown at vertical velocity 0 grazes the ground; the impact is not transversal).

Worst points are found on a grid (knots included from both sides) and then polished by a
vectorised golden-section search inside their knot interval, so margins are not grid-limited.

Case evaluation (grids, polished extremes, verdicts) is in
:mod:`thrustwalk_cli.contact.evaluate`; the feasible region in :mod:`thrustwalk_cli.contact.region`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import chebyshev as C

from ..hzd.extrema import polish_max, polish_min
from ..hzd.zero_dynamics import ZeroDynamics
from ..model.compiled import CompiledModel

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

    ``alpha``: shape ``(g,)``, or ``(..., g)`` with leading batch axes that ``maps`` broadcasts
    over (the gait design evaluates many gaits at once); every result gains those axes.

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
    E = np.einsum("...j,...j->...", eD, phi)
    a2 = 2.0 / E**2  # alpha'^2 per unit zeta = 2 kappa_1^2
    A0 = -G[..., N - 1] / E
    A1 = -a2 * (h_v[..., N - 1] + np.einsum("...j,...j->...", eD, dphi)) / E
    A2 = BF[..., N - 1, :] / E[..., None]
    AT = 1.0 / E
    Q0 = phi * A0[..., None]
    Q1 = phi * A1[..., None] + dphi * a2[..., None]
    Q2 = phi[..., :, None] * A2[..., None, :]
    QT = phi * AT[..., None]

    def mv(M, v):
        return np.einsum("...ij,...j->...i", M, v)

    Dc = Du[..., N:, :N]  # force rows, joint columns
    L0 = mv(Dc, Q0) + Gu[..., N:]
    L1 = mv(Dc, Q1) + a2[..., None] * hu_v[..., N:]
    L2 = np.einsum("...ij,...jm->...im", Dc, Q2) - BFu[..., N:, :]
    LT = mv(Dc, QT)
    b = slice(0, N - 1)
    U0 = (mv(D, Q0) + G)[..., b]
    U1 = (mv(D, Q1) + a2[..., None] * h_v)[..., b]
    U2 = (np.einsum("...ij,...jm->...im", D, Q2) - BF)[..., b, :]
    UT = mv(D, QT)[..., b]
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
        """The Chebyshev variable ``x = 2 (alpha - alpha_i)/(alpha_f - alpha_i) - 1`` in [-1, 1]
        of ``alpha`` [rad]."""
        return 2.0 * (np.asarray(alpha, float) - self.alpha_i) / (self.alpha_f - self.alpha_i) - 1

    def force_terms(self, alpha: np.ndarray) -> tuple[np.ndarray, ...]:
        """The fitted ``(Lambda_0, Lambda_1, Lambda_2, Lambda_T)`` at ``alpha`` [rad] (SPEC 5),
        the samples first: [N], [N s^2/(kg^2 m^4)], [1], [1/m]."""
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
        yf, yc = getattr(tf, name), getattr(tc, name)  # L2: (g, 2, 0) without thrusters
        scale = float(np.abs(yc).max(initial=0.0)) or 1.0
        degrees = [degree] if degree is not None else range(1, max_degree + 1)
        for d in degrees:
            coef = C.chebfit(xf, yf.reshape(len(xf), -1), d)
            approx = C.chebval(xc, coef, tensor=True).T.reshape(yc.shape)
            err = float(np.abs(approx - yc).max(initial=0.0))
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
    ``|sigma_N^-|`` [m/s per kg m^2/s]; ``friction_ratio = |F_2^h| / F_2^v``;
    ``touchdown_per_sigma``: vertical velocity of the swing foot just before impact per
    ``|sigma_N^-|``; ``strikes``: it is < 0, so the swing foot crosses the ground transversally
    (at 0 it only grazes the ground and the impact is not a strike).
    """

    impulse_per_sigma: np.ndarray
    trailing_foot_velocity_per_sigma: np.ndarray
    friction_ratio: float | None
    admissible_vertical: bool
    liftoff: bool
    touchdown_per_sigma: float = -1.0
    strikes: bool = True

    @property
    def liftoff_per_sigma(self) -> float:
        """Vertical velocity of the trailing foot just after impact per ``|sigma_N^-|`` [m/s per
        kg m^2/s] (SPEC 5; > 0: it lifts off)."""
        return float(self.trailing_foot_velocity_per_sigma[1])

    def admissible(self, mu: float) -> bool:
        """The impact is admissible at friction coefficient ``mu`` [1] (SPEC 5): ``F_2^v > 0``,
        ``|F_2^h|/F_2^v <= mu``, the trailing foot lifts off and the swing foot strikes."""
        return (self.admissible_vertical and self.liftoff and self.strikes
                and self.friction_ratio is not None and self.friction_ratio <= mu)

    def reasons(self, mu: float) -> list[str]:
        """Why the impact is not admissible at ``mu`` [1], one phrase per failed condition of
        :meth:`admissible` (empty: it is)."""
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
        if not self.strikes:
            out.append("the swing foot does not move down onto the ground at touchdown "
                       f"(vertical velocity {self.touchdown_per_sigma:.3g} m/s per unit "
                       "|sigma_N^-|, not < 0 beyond round-off): a grazing contact, not a "
                       "strike")
        return out


def impact_data(model: CompiledModel, zd: ZeroDynamics) -> ImpactData:
    """``F_2 = M_F Phi(alpha_f) kappa_1(alpha_f) sigma_N^-``; the trailing foot's velocity is the
    last two components of ``q_u'^+ = M_u q'^-``; the swing foot's touchdown velocity is
    ``E_2y(q^-) q'^-`` (SPEC 5). Thrust does not enter (not impulsive)."""
    Mu, MF, _ = model.impact_maps(zd.maps.q_minus)
    t = zd.terms(np.array([zd.alpha_f]))
    dq = t["Phi"][0] * t["kappa1"][0] * zd.sigma_sign  # q'^- per unit |sigma_N^-|
    F2 = MF @ dq
    v = (Mu @ dq)[model.n:]
    ratio = float(abs(F2[0]) / F2[1]) if F2[1] > 0 else None
    foot = model.E_swing(zd.maps.q_minus) @ dq  # swing-foot velocity per unit |sigma_N^-|
    down = float(foot[1])
    strikes = down < -1e-9 * float(np.linalg.norm(foot))  # not tangential up to round-off
    return ImpactData(F2, v, ratio, bool(F2[1] > 0), bool(v[1] > 0), down, bool(strikes))


def swing_clearance(model: CompiledModel, zd: ZeroDynamics, points: int = 801) -> dict:
    """Swing-foot height along the step [m]: minimum for s in ``SWING_WINDOW`` (away from
    lift-off and touch-down, where it is 0 by construction), the maximum, and the deepest
    penetration anywhere strictly inside the step; each located on ``points`` samples and
    polished by golden section between the neighbouring samples (exact, not grid-limited)."""
    a = np.linspace(zd.alpha_i, zd.alpha_f, points)

    def height(x):
        return model.p_swing(zd.maps.q_Z(x))[..., 1]

    h = height(a)
    s = np.linspace(0.0, 1.0, points)
    win = (s >= SWING_WINDOW[0]) & (s <= SWING_WINDOW[1])
    a_min, h_min = polish_min(height, a, np.where(win, h, np.inf)[None], win.astype(int))
    inner = np.zeros(points, int)
    inner[1:-1] = 1
    a_deep, h_deep = polish_min(height, a, np.where(inner == 1, h, np.inf)[None], inner)
    _, h_max = polish_max(height, a, h[None])
    deepest = float(min(h_deep[0], 0.0))
    return {"min_height": float(h_min[0]), "alpha_at_min_height": float(a_min[0]),
            "max_height": float(h_max[0]), "deepest": deepest,
            "alpha_at_deepest": float(a_deep[0]), "scuffs": bool(deepest < -SCUFF_TOL),
            "alpha": a, "height": h}


def scuff_reason(swing: dict) -> str:
    """The scuffing verdict of a swing-foot clearance record (:func:`swing_clearance`)."""
    return (f"the swing foot goes {1e3 * -swing['deepest']:.4g} mm below the ground near "
            f"alpha = {swing['alpha_at_deepest']:.4g} rad (scuffing; tolerance "
            f"{1e3 * SCUFF_TOL:g} mm)")
