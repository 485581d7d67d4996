"""Energy on the zero-dynamics orbit (SPEC 15): exact, by quadrature, no simulation.

On Z, ``q' = Phi(alpha) alpha'``, the joint torques are affine in ``zeta`` and the thrust
(``u = U0 + U1 zeta + U2 F_T + UT T``, SPEC 5, :func:`~..contact.terms.stance_terms`) and
``dt = d alpha / alpha'``. Every power ``P`` integrates over the step as an integral in alpha
over ``|d alpha|`` (``s = sign(alpha_f - alpha_i) = sign(alpha')``):

    joint j, mechanical     u_j q_j' dt       = s u_j Phi_j d|alpha|                  [J]
    thruster k, on walker   F_k d_k . p_k' dt = s F_k (B_F^T Phi)_k d|alpha|
    generalised mode        T q_N' dt         = s T Phi_N d|alpha|
    Joule, thruster input   P dt              = P / |alpha'| d|alpha|
                            |alpha'| = |kappa_1| sqrt(2 zeta)

The integrands are smooth inside each knot interval of the thrust schedule (the thrust jumps at
the knots), so each interval is integrated on its own Chebyshev-Lobatto nodes (nodes doubled
until the nested error estimate of the smooth integrals is below ``RTOL`` relative).
``max(0, .)`` and ``|.|`` (positive and absolute work, clipped electrical power) are integrated
piecewise between the kinks: the roots of the integrand's Chebyshev interpolant on the interval
split it, and the interpolant's antiderivative is evaluated at the roots. The roots are isolated
between the nodes with a proof (no root, or exactly one, from a bound of the interpolant's
second derivative; gaps without a proof are halved up to ``SPLITS`` times) and polished from
the root of a cubic Hermite interpolant by a Newton step (:func:`_abs_and_positive`). A
thrust's power ``F_k (B_F^T Phi)_k`` is the constant thrust times one function of alpha on a
knot interval: its kinks are those of that function, found once for the whole batch.

Joint electrical power with a motor: ``P_m / eta_g`` (or ``P_m eta_g`` when negative) plus
the Joule loss ``J = R (u / (G k_t))^2`` (:mod:`.power`); negative electrical power is not
recovered (clipped at 0 per joint) unless ``regenerate``. The gearbox's factor jumps where
``P_m`` changes sign (a kink a Chebyshev interpolant cannot follow), so the energy is written
with smooth integrands only: ``P_el >= 0`` where ``P_m >= 0``, hence

    int max(0, P_el) = (1/eta_g - eta_g) int max(0, P_m) + int max(0, eta_g P_m + J)
    int P_el         = (1/eta_g - eta_g) int max(0, P_m) + eta_g int P_m + int J.

Thrust input power from the thruster's model with the axial air speed ``V_k = sign(F_k) d_k .
p_k'`` through the disk (momentum model).

Cost of transport ``CoT = E / (m g d)`` (``d`` the step length along the ground):
mechanical = (joints' positive work + thrusters' positive work on the walker) / (m g d), total =
(joints' electrical energy + thrusters' input energy) / (m g d), each split into legs and
thrust. A part whose model is missing is None with a reason, never 0.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.polynomial import chebyshev as C

from ..contact.terms import stance_terms
from ..hzd.quadrature import _cc_weights, _dct_matrix, lobatto
from ..hzd.zero_dynamics import ZeroDynamics
from ..thrust.schedule import Schedule
from .power import input_power, joule_power, missing_models

RTOL = 1e-10
MAX_NODES = 1025
SPLITS = 12  # halvings of a gap of the nodes to isolate the roots in it
SMALL = 256  # at most this many points: Chebyshev series evaluated without a recurrence


@dataclass(frozen=True)
class OrbitEnergy:
    """Energies of one step of the periodic orbit [J] (SPEC 15); per joint / per thruster
    tuples in the robot's order. ``None`` with a line in ``missing`` where a model is not
    given; everything None (``exists`` false) without an orbit."""

    exists: bool
    reason: str
    joint_work: tuple[float, ...] = ()  # net  int u_j q_j' dt
    joint_positive_work: tuple[float, ...] = ()
    joint_absolute_work: tuple[float, ...] = ()
    joint_electrical: tuple[float | None, ...] = ()
    thrust_work: tuple[float, ...] = ()  # int F_k d_k . p_k' dt on the walker
    thrust_positive_work: tuple[float, ...] = ()
    generalized_work: float = 0.0  # int T q_N' dt (generalised-mode schedules)
    thruster_input: tuple[float | None, ...] = ()
    fuel_mass: tuple[float | None, ...] = ()  # [kg] per step
    kinetic_start: float | None = None  # K^+ (just after impact)
    kinetic_end: float | None = None  # K^- (just before impact)
    potential_start: float | None = None
    potential_end: float | None = None
    step_time: float | None = None  # [s] the step time integrated with the energies
    distance: float | None = None  # [m]
    weight: float | None = None  # [N] m g
    error_estimate: float | None = None  # [J] nested quadrature estimate, largest
    regenerate: bool = False
    missing: tuple[str, ...] = field(default=())

    @classmethod
    def _of(cls, fields: dict) -> OrbitEnergy:
        """The object with these ``fields`` (every one, by name), as the constructor makes
        it: the frozen dataclass's ``__init__`` sets each of its 21 fields through
        ``object.__setattr__`` (4 us an object); a batch of orbits fills ``__dict__`` at
        once (the class has no ``__post_init__`` and no slots)."""
        e = object.__new__(cls)
        e.__dict__.update(fields)
        return e

    # -- derived ------------------------------------------------------------------------
    @property
    def impact_loss(self) -> float | None:
        """Kinetic energy lost at impact ``K^- - K^+`` [J] (>= 0 for a rigid impact)."""
        if self.kinetic_end is None:
            return None
        return self.kinetic_end - self.kinetic_start

    @property
    def identity_residual(self) -> float | None:
        """``joints' work + thrust work - (K^- + V^- - K^+ - V^+)`` [J] over the continuous
        phase (the work-energy identity; 0 up to quadrature)."""
        if self.kinetic_end is None:
            return None
        work = sum(self.joint_work) + sum(self.thrust_work) + self.generalized_work
        return work - (self.kinetic_end + self.potential_end - self.kinetic_start
                       - self.potential_start)

    def _mgd(self, energy: float | None) -> float | None:
        if energy is None or not self.distance:
            return None
        return energy / (self.weight * self.distance)

    @property
    def legs_mechanical(self) -> float | None:
        return float(sum(self.joint_positive_work)) if self.exists else None

    @property
    def thrust_mechanical(self) -> float | None:
        return float(sum(self.thrust_positive_work)) if self.exists else None

    @property
    def legs_electrical(self) -> float | None:
        vals = self.joint_electrical
        return None if not self.exists or any(v is None for v in vals) else float(sum(vals))

    @property
    def thrust_input(self) -> float | None:
        vals = self.thruster_input
        return None if not self.exists or any(v is None for v in vals) else float(sum(vals))

    def cot(self) -> dict:
        """Costs of transport [1]: mechanical and total, split legs / thrust (None: missing)."""
        lm, tm = self.legs_mechanical, self.thrust_mechanical
        le, ti = self.legs_electrical, self.thrust_input
        return {
            "mechanical": self._mgd(None if lm is None else lm + tm),
            "mechanical_legs": self._mgd(lm),
            "mechanical_thrust": self._mgd(tm),
            "total": self._mgd(None if le is None or ti is None else le + ti),
            "total_legs": self._mgd(le),
            "total_thrust": self._mgd(ti),
        }

    def record(self) -> dict:
        """The JSON block of one case (SI units: J, W, kg, s, m; CoT dimensionless)."""
        if not self.exists:
            return {"exists": False, "reason": self.reason}
        T = self.step_time
        lm, tm, le, ti = (self.legs_mechanical, self.thrust_mechanical, self.legs_electrical,
                          self.thrust_input)

        def power(e):
            return None if e is None or T is None else e / T

        fl = [f for f in self.fuel_mass if f is not None]
        return {
            "exists": True,
            "reason": self.reason,
            "per_step": {
                "joint_work": list(self.joint_work),
                "joint_positive_work": list(self.joint_positive_work),
                "joint_absolute_work": list(self.joint_absolute_work),
                "joint_electrical": list(self.joint_electrical),
                "thrust_work": list(self.thrust_work),
                "thrust_positive_work": list(self.thrust_positive_work),
                "generalized_work": self.generalized_work,
                "thruster_input": list(self.thruster_input),
                "fuel_mass": list(self.fuel_mass),
                "legs_mechanical": lm, "thrust_mechanical": tm,
                "legs_electrical": le, "thrust_input": ti,
                "impact_loss": self.impact_loss,
            },
            "fuel_per_metre": (sum(fl) / self.distance if fl else None),
            "cot": self.cot(),
            "average_power": {"legs_mechanical": power(lm), "thrust_mechanical": power(tm),
                              "legs_electrical": power(le), "thrust_input": power(ti)},
            "work_energy_residual": self.identity_residual,
            "quadrature_error_estimate": self.error_estimate,
            "negative_joint_power": ("recovered (regenerate)" if self.regenerate else
                                     "not recovered: electrical power clipped at 0 per joint"),
            "missing": list(self.missing),
        }


@lru_cache(maxsize=16)
def _node_tables(n: int) -> tuple[np.ndarray, ...]:
    """For ``n`` ascending Lobatto nodes ``x_i`` of [-1, 1]: the nodes, the gaps ``h_i =
    x_{i+1} - x_i``, the least ``sin(theta)`` on each gap (``x = cos(theta)``), the columns
    ``(k^2, k, k^2 (k^2 - 1) / 3)`` of :func:`_second_derivative_bound` as rows (3, n), the
    matrix (3n+1, n) taking node values to the Chebyshev coefficients, the derivatives at
    the nodes and the antiderivative's coefficients (``F(-1) = 0``), the matrix (n, n-2)
    taking coefficients to those of the second derivative, the rows ``T_j(x_i)`` (n, n-2)
    and ``min(j^2, j / s_i)`` (n-1, n-2) of :func:`_node_bound`, ``int_{-1}^1 T_k`` (n,)
    and the factors (3, n-1) ``(h_i^2 / s_i^2, h_i^2 / s_i^3, h_i^2) / 8`` of the gaps'
    no-root test (with the bound's rounding, ``1 + 1e-12``)."""
    x = -np.cos(np.pi * np.arange(n) / (n - 1))
    k = np.arange(n, dtype=float)
    sn = np.sqrt(np.maximum(1.0 - x * x, 0.0))
    s = np.minimum(sn[:-1], sn[1:])
    K = np.stack([k * k, k, k * k * (k * k - 1.0) / 3.0], axis=1)
    dct = _dct_matrix(n)
    dT = C.chebval(x, C.chebder(np.eye(n))).T  # (nodes, k) T_k'(x_i)
    d2 = C.chebder(np.eye(n), 2).T  # (k, j): T_k'' = sum_j d2[k, j] T_j
    k2 = k[:n - 2, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        kd = np.where(s[None, :] > 0, np.minimum(k2 * k2, k2 / s[None, :]), k2 * k2)
    T2 = C.chebval(x, np.eye(n - 2))  # (j, nodes) T_j(x_i)
    F1 = C.chebint(np.eye(n), lbnd=-1.0).sum(axis=0)  # (k,) int_{-1}^{1} T_k
    h = np.diff(x)
    with np.errstate(divide="ignore"):
        e_abc = np.stack([h * h / (s * s), h * h / (s * s * s), h * h]) * (0.125 * (1.0 + 1e-12))
    anti = C.chebint(np.eye(n), lbnd=-1.0) @ dct  # values -> F's coefficients (n+1, n)
    tables = (x, h, s, K.T.copy(), np.concatenate([dct, dT @ dct, anti]), d2, T2.T.copy(),
              kd.T.copy(), F1, e_abc)
    for t in tables:
        t.setflags(write=False)
    return tables


@lru_cache(maxsize=16)
def _weights(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Clenshaw-Curtis weights of ``n`` Lobatto nodes and of the nested ``(n-1)/2 + 1``."""
    return _cc_weights(n), _cc_weights((n - 1) // 2 + 1)


def _second_derivative_bound(abs_coef_sums: np.ndarray, s: np.ndarray) -> np.ndarray:
    """A bound of ``|p''|`` on each gap of the nodes for ``p = sum_k c_k T_k``, from the rows
    ``(sum |c_k| k^2, sum |c_k| k, sum |c_k| k^2 (k^2 - 1) / 3)`` (..., 3) and each gap's
    least ``sin(theta) = s`` (...): with ``x = cos(theta)``, ``T_k'' = (k cos(theta)
    sin(k theta) - k^2 sin(theta) cos(k theta)) / sin(theta)^3``, so ``|T_k''| <= k^2 / s^2
    + k / s^3``, and everywhere ``|T_k''| <= T_k''(1) = k^2 (k^2 - 1) / 3``."""
    A, B, G = (abs_coef_sums[..., i] for i in range(3))
    with np.errstate(divide="ignore", invalid="ignore"):
        loc = A / (s * s) + B / (s * s * s)
    return np.where(s > 0, np.minimum(G, loc), G) * (1.0 + 1e-12)  # and its own rounding


def _node_bound(d: np.ndarray, gap: np.ndarray, h: np.ndarray, T2: np.ndarray,
                kd: np.ndarray) -> np.ndarray:
    """A second bound of ``|p''|`` on gaps ``[x_i, x_{i+1}]`` of the nodes (``i = gap``,
    (G,)), for the Chebyshev coefficients ``d`` (G, n-2) of each one's ``p'' = sum_j d_j
    T_j``, tight where the coefficients decay: with ``|T_j'| = |j sin(j theta) /
    sin(theta)| <= min(j^2, j / s_i)`` on the gap (``s_i`` its least ``sin(theta)``; the
    rows ``kd`` (n-1, n-2)),

        max |p''| <= max(|p''(x_i)|, |p''(x_{i+1})|) + (h_i / 2) sum_j |d_j| min(j^2, j / s_i)

    (every point of the gap is within ``h_i / 2`` of one end); ``p''(x_i) = sum_j d_j
    T_j(x_i)`` (the rows ``T2`` (n, n-2)) with ``|T_j| <= 1``, so its rounding is below
    ``1e-13 sum_j |d_j|``, added."""
    ad = np.abs(d)
    t = np.einsum("gj,gj->g", ad, kd[gap])
    va = np.abs(np.einsum("gj,gj->g", d, T2[gap]))
    vb = np.abs(np.einsum("gj,gj->g", d, T2[gap + 1]))
    return (np.maximum(va, vb) + 0.5 * h[gap] * t + 1e-13 * ad.sum(axis=1)) * (1.0 + 1e-12)


def _clenshaw(c: np.ndarray, x: np.ndarray, derivative: bool = False):
    """``sum_k c[k, r] T_k(x_r)`` for coefficient columns ``c`` (n, r, ...) at points ``x``
    (r, ...) by Clenshaw's recurrence; with ``derivative`` also its derivative in ``x``."""
    b1 = np.zeros(np.broadcast_shapes(c.shape[1:], x.shape))
    b2 = np.zeros_like(b1)
    d1 = np.zeros_like(b1)
    d2 = np.zeros_like(b1)
    x2 = 2.0 * x
    for ck in c[:0:-1]:
        if derivative:
            d1, d2 = 2.0 * b1 + x2 * d1 - d2, d1
        b1, b2 = ck + x2 * b1 - b2, b1
    val = c[0] + x * b1 - b2
    return (val, b1 + x * d1 - d2) if derivative else val


def _chebyshev_at(cT: np.ndarray, x: np.ndarray, derivative: bool = False):
    """``p(x_r) = sum_k cT[k, r] T_k(x_r)`` for coefficient columns ``cT`` (n, r) at points
    ``x`` (r,) in [-1, 1]; with ``derivative`` also ``p'(x_r)``. Many points: Clenshaw's
    recurrence (:func:`_clenshaw`, n vector steps); a few (at most ``SMALL``): with ``x =
    cos(theta)``, ``T_k(x) + i sin(k theta) = e^(i k theta)`` (the powers of ``e^(i theta)``,
    one cumulative product), ``T_k' = k sin(k theta) / sin(theta)``, and at ``x = +-1``
    (``sin(theta) = 0``) its limit ``T_k'(+-1) = (+-1)^(k+1) k^2``."""
    if x.size > SMALL:
        return _clenshaw(cT, x, derivative)
    n = cT.shape[0]
    theta = np.arccos(np.clip(x, -1.0, 1.0))
    Z = np.empty((n, x.size), complex)
    Z[0] = 1.0
    Z[1:] = np.exp(1j * theta)
    Z = np.cumprod(Z, axis=0)
    val = np.einsum("kr,kr->r", cT, Z.real)
    if not derivative:
        return val
    k = np.arange(n, dtype=float)[:, None]
    sn = np.sin(theta)
    end = sn == 0.0
    d = np.einsum("kr,kr->r", cT * k, Z.imag) / np.where(end, 1.0, sn)
    if np.any(end):  # T_k'(+-1) = (+-1)^(k+1) k^2
        sgn = np.where(x[end] > 0, 1.0, -1.0)
        d[end] = np.einsum("kr,kr->r", cT[:, end] * (k * k), sgn[None] ** (k + 1))
    return val, d


def _hermite_root(fa: np.ndarray, fb: np.ndarray, da: np.ndarray, db: np.ndarray
                  ) -> np.ndarray:
    """A root ``t`` in [0, 1] of each cubic Hermite interpolant ``H`` with end values ``fa``,
    ``fb`` of opposite signs (``fa >= 0`` and ``fb < 0`` or the reverse) and end slopes
    ``da``, ``db`` (d/dt): Newton's method kept inside a bracket of ``H``'s sign change,
    bisecting where a step would leave it, to ``1e-15``."""
    lo, hi = np.zeros_like(fa), np.ones_like(fa)
    up = fa < 0.0  # H(lo) < 0 <= H(hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.nan_to_num(fa / (fa - fb), nan=0.5), 0.0, 1.0)
    act = np.arange(fa.size)
    for _ in range(60):
        tt, a, b, ea, eb = t[act], fa[act], fb[act], da[act], db[act]
        t2 = tt * tt
        t3 = t2 * tt
        H = (2 * t3 - 3 * t2 + 1) * a + (t3 - 2 * t2 + tt) * ea + (3 * t2 - 2 * t3) * b \
            + (t3 - t2) * eb
        dH = (6 * t2 - 6 * tt) * (a - b) + (3 * t2 - 4 * tt + 1) * ea + (3 * t2 - 2 * tt) * eb
        below = (H < 0.0) == up[act]  # the root is above tt
        lo[act] = np.where(below, tt, lo[act])
        hi[act] = np.where(below, hi[act], tt)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = tt - H / dH
        mid = 0.5 * (lo[act] + hi[act])
        new = np.where(np.isfinite(new) & (new >= lo[act]) & (new <= hi[act]), new, mid)
        new = np.where(H == 0.0, tt, new)
        t[act] = new
        done = (np.abs(new - tt) <= 1e-15) | (hi[act] - lo[act] <= 1e-15) | (H == 0.0)
        act = act[~done]
        if not act.size:
            break
    return t


def _abs_and_positive(values: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """``int |f|`` and ``int max(0, f)`` over an interval of half-length ``half`` for rows of
    samples ``values`` (P, n) at ascending Lobatto nodes, piecewise between the roots of each
    row's Chebyshev interpolant ``p`` (module docstring): with ``F`` its antiderivative
    (``F(-1) = 0``), ``s_0`` its sign at the start and ``r_1 < ... < r_p`` its roots,
    ``int |f| = s_0 (sum_i 2 (-1)^(i-1) F(r_i) + (-1)^p F(1))``.

    Each gap ``[x_i, x_{i+1}]`` of the nodes is shown to hold no root (its end values keep
    their sign and ``min(|p(x_i)|, |p(x_{i+1})|) > h_i^2 max|p''| / 8``, the linear
    interpolant's error bound) or exactly one (they change sign and ``p'`` keeps its sign:
    ``p'(x_i) p'(x_{i+1}) > 0`` and ``|p'(x_i)| + |p'(x_{i+1})| > h_i max|p''|``), with
    ``max|p''|`` bounded from the coefficients (:func:`_second_derivative_bound`; on a gap
    that this leaves without a proof, the smaller of it and :func:`_node_bound`); a gap
    still without a proof is halved (``p`` and ``p'`` at its middle,
    :func:`_chebyshev_at`) and the test repeated on the halves with the gap's bound, up to
    ``SPLITS`` times (a piece where ``|p|`` stays below ``1e-15`` of the row's largest node
    value is negligible and left unsplit). Each root starts at the root of the cubic
    Hermite interpolant of its bracket's end values and slopes (:func:`_hermite_root`) and
    takes one Newton step on ``p``, kept in the bracket (the root's error enters the
    integrals squared). Only roots closer than the last halving's width (``2^-SPLITS`` of a
    gap) and double roots are not separated."""
    P, n = values.shape
    if P == 0:
        return np.zeros(0), np.zeros(0)
    xn, h, sg, K, to_cd, d2, T2, kd, F1_m, e_abc = _node_tables(n)
    cd = to_cd @ values.T  # (3n+1, P), rows contiguous: what the recurrences gather
    cT = cd[:n]  # Chebyshev coefficients (n, P)
    coef, dv = cT.T, cd[n:2 * n].T  # (P, n): the coefficients, p' at the nodes
    S = (K @ np.abs(cT)).T  # (P, 3): the sums of _second_derivative_bound
    pos = values >= 0.0
    change = pos[:, 1:] != pos[:, :-1]
    av = np.abs(values)
    amin = np.minimum(av[:, :-1], av[:, 1:])
    # every gap at once: h_i^2 max|p''| / 8 <= min(G h_i^2, A h_i^2 / s_i^2 + B h_i^2 / s_i^3)
    # / 8 (the factors e_abc, with the bound's own rounding); the few gaps where that
    # proves no root-free gap, one by one below with the bound itself
    with np.errstate(invalid="ignore"):
        e = np.fmin(S[:, 2:3] * e_abc[2], S[:, 0:1] * e_abc[0] + S[:, 1:2] * e_abc[1])
    r, gap = np.nonzero(change | ~(amin > e))
    ch = change[r, gap]
    m2 = _second_derivative_bound(S[r], sg[gap])
    ga, gb = dv[r, gap], dv[r, gap + 1]
    mono = ga * gb > 0.0
    sdv = np.abs(ga) + np.abs(gb)
    hg, am = h[gap], amin[r, gap]
    one = ch & mono & (sdv > hg * m2)
    open_ = ch & ~one | ~ch & ~((am > 0.125 * hg * hg * m2) | (m2 == 0.0))
    if np.any(open_):  # the node bound too, where it is smaller
        rows_o, inv = np.unique(r[open_], return_inverse=True)
        d = (np.take(cT, rows_o, axis=1).T @ d2)[inv]  # p'''s coefficients, per gap
        m2[open_] = np.minimum(m2[open_], _node_bound(d, gap[open_], h, T2, kd))
        one = ch & mono & (sdv > hg * m2)
        open_ = ch & ~one | ~ch & ~((am > 0.125 * hg * hg * m2) | (m2 == 0.0))
    ro, go = r[one], gap[one]
    brackets = [(ro, xn[go], h[go], values[ro, go], values[ro, go + 1], ga[one], gb[one])]
    # the other gaps: halved until each piece provably holds no root or one
    r, gap = r[open_], gap[open_]
    piece = (r, xn[gap], h[gap], values[r, gap], values[r, gap + 1], ga[open_], gb[open_],
             m2[open_])
    tiny = 1e-15 * np.max(av, axis=1)  # a piece below it is negligible in the integrals
    for level in range(SPLITS + 1):
        r = piece[0]
        if not r.size:
            break
        if level == SPLITS:  # unresolved (a double root or roots closer than the width)
            ch = (piece[3] >= 0.0) != (piece[4] >= 0.0)
            brackets.append(tuple(v[ch] for v in piece[:7]))
            break
        r, a, w, fa, fb, ga, gb, m2 = piece
        w = 0.5 * w
        pm, dm = _chebyshev_at(np.take(cT, r, axis=1), a + w, derivative=True)
        r, a, fa, fb, ga, gb, m2 = (np.concatenate(v) for v in (
            (r, r), (a, a + w), (fa, pm), (pm, fb), (ga, dm), (dm, gb), (m2, m2)))
        w = np.concatenate([w, w])
        ch = (fa >= 0.0) != (fb >= 0.0)
        e2 = 0.125 * w * w * m2
        afa, afb = np.abs(fa), np.abs(fb)
        small = np.maximum(afa, afb) + e2 <= tiny[r]
        none = ~ch & ((np.minimum(afa, afb) > e2) | small)
        one = ch & (((ga * gb > 0.0) & (np.abs(ga) + np.abs(gb) > w * m2)) | small)
        brackets.append((r[one], a[one], w[one], fa[one], fb[one], ga[one], gb[one]))
        keep = ~(none | one)
        piece = (r[keep], a[keep], w[keep], fa[keep], fb[keep], ga[keep], gb[keep], m2[keep])
    rows, xa, hb, fa, fb, da, db = (np.concatenate(v) for v in zip(*brackets))
    F1 = coef @ F1_m  # F(1): T_k(1) = 1
    s0 = np.where(pos[:, 0], 1.0, -1.0)
    total_abs = s0 * F1  # no root
    if rows.size:
        order = np.lexsort((xa, rows))
        rows, xa, hb, fa, fb, da, db = (v[order] for v in (rows, xa, hb, fa, fb, da, db))
        t = _hermite_root(fa, fb, da * hb, db * hb)
        x = xa + t * hb
        # one Newton step on p itself
        c = np.take(cT, rows, axis=1)  # (n, roots), contiguous rows
        f, df = _chebyshev_at(c, x, derivative=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.clip(x - np.nan_to_num(np.where(df != 0, f / df, 0.0)), xa, xa + hb)
        Fr = _chebyshev_at(np.take(cd[2 * n:], rows, axis=1), x)  # F's coefficients
        rank = np.arange(rows.size) - np.searchsorted(rows, rows, side="left")
        count = np.bincount(rows, minlength=P)
        inner = np.bincount(rows, 2.0 * np.where(rank % 2 == 0, 1.0, -1.0) * Fr, minlength=P)
        total_abs = s0 * (inner + np.where(count % 2 == 0, 1.0, -1.0) * F1)
    return total_abs * half, 0.5 * (total_abs + F1) * half


def _nodes(zd: ZeroDynamics, knots: np.ndarray, j: int, n: int) -> dict:
    """What the energy integrands of knot interval ``j`` need at its ``n`` ascending Lobatto
    nodes that does not depend on the thrust values (they depend on alpha only): the stance
    terms' torque rows (SPEC 5), ``s Phi_j`` of the joints, ``s (B_F^T Phi)_k`` of the
    thrusters, ``s Phi_N``, ``|kappa_1|`` and the pieces of ``V_Z`` (``V_0`` and per knot
    interval the increments of ``Gamma`` and ``b_F``, as :meth:`ZeroDynamics.V_Z`); computed
    on first use and kept on ``zd``."""
    cache = zd.__dict__.setdefault("_energy_nodes", {})
    key = (tuple(knots.tolist()), j, n)
    out = cache.get(key)
    if out is not None:
        return out
    if len(cache) > 64:
        cache.clear()
    model, maps = zd.model, zd.maps
    N, m = model.n, model.n_thrusters
    s = zd.direction
    lo, hi = sorted((knots[j], knots[j + 1]))
    alpha = lobatto(lo, hi, n)
    st = stance_terms(model, maps, alpha)
    phi = maps.Phi(alpha)  # (g, N)
    out = cache[key] = {
        "U0": st.U0.T[None], "U1": st.U1.T[None], "UT": st.UT.T[None],
        "U2": st.U2.transpose(2, 1, 0).reshape(m, -1),
        "pphi": (s * phi[:, :N - 1].T)[None],
        "bt": s * np.einsum("gnm,gn->mg", model.B_F(maps.q_Z(alpha)), phi),  # (m, g)
        "bg": s * phi[:, N - 1],
        "k1": np.abs(st.AT),  # AT = 1 / (e_N^T D Phi) = kappa_1
        "V_Z": _vz_pieces(zd, alpha, knots)}
    return out


def _vz_pieces(zd: ZeroDynamics, alpha: np.ndarray, knots: np.ndarray) -> tuple:
    """The thrust-independent pieces of ``V_Z(alpha)`` (SPEC 3, 4) for a schedule's
    ``knots``, as :meth:`ZeroDynamics.V_Z` computes them: ``V_0(alpha)`` and per knot
    interval the increments of ``Gamma`` and ``b_F`` from the knot to ``alpha`` clipped into
    the interval."""
    klo, khi = np.minimum(knots[:-1], knots[1:]), np.maximum(knots[:-1], knots[1:])
    dG, dB = [], []
    for jj in range(len(knots) - 1):
        a = np.clip(alpha, klo[jj], khi[jj])
        dG.append(zd.Gamma(a) - zd.Gamma(knots[jj]))
        dB.append(zd.B(a) - zd.B(knots[jj]))
    return zd.V0(alpha), dG, dB


def _vz(pieces: tuple, sched: Schedule) -> np.ndarray:
    """``V_Z`` (k, g) of every schedule of the batch from :func:`_vz_pieces`, with the
    operations of :meth:`ZeroDynamics.V_Z` in its order (the same numbers)."""
    V0, dG, dB = pieces
    out = np.broadcast_to(V0, (sched.size,) + V0.shape).copy()
    for jj in range(len(dG)):
        out += np.einsum("...m,km->k...", dG[jj], sched.force[:, jj, :])
        out += sched.generalized[:, jj].reshape((-1,) + (1,) * V0.ndim) * dB[jj]
    return out


def _integrands(zd: ZeroDynamics, sched: Schedule, zp: np.ndarray, j: int, n: int) -> dict:
    """The integrands of knot interval ``j`` at ``n`` Lobatto nodes for the batch (module
    docstring): ``zeta``, the torques ``u`` and the joint powers per ``|d alpha|`` (k, joint,
    g), ``|alpha'|`` and its inverse (k, g), the thrust's and the generalised mode's powers per
    unit thrust (m, g), (g,)."""
    nd = _nodes(zd, np.asarray(sched.knots, float), j, n)
    N, m = zd.model.n, zd.model.n_thrusters
    k = sched.size
    F = sched.force[:, j, :]  # (k, m)
    Tg = sched.generalized[:, j]  # (k,)
    zeta = zp[:, None] + _vz(nd["V_Z"], sched)  # (k, g)
    zeta = np.maximum(zeta, 0.0)
    u = nd["U0"] + nd["U1"] * zeta[:, None, :]
    if m:  # + U2 F
        u = u + (F @ nd["U2"]).reshape(k, N - 1, n)
    u = u + nd["UT"] * Tg[:, None, None]
    adot = nd["k1"][None] * np.sqrt(2.0 * zeta)  # |alpha'| (k, g)
    with np.errstate(divide="ignore"):
        inv = 1.0 / adot
    return {"u": u, "pj": u * nd["pphi"], "bt": nd["bt"], "bg": nd["bg"], "adot": adot,
            "inv": inv}


def orbit_energy(zd: ZeroDynamics, schedule: Schedule, cycles, *, regenerate: bool = False
                 ) -> list[OrbitEnergy]:
    """The step energies of each schedule's periodic orbit (``cycles[i]`` its
    :class:`LimitCycle`), exactly by quadrature on Z (module docstring, SPEC 15).

    What depends on alpha only is computed once per walker, knots and node count
    (:func:`_nodes`); the node count of a knot interval starts where the last call ended
    (kept on ``zd``), and the smaller nested counts are tried first on subsets of those
    nodes, so the result is the one the doubling from 33 nodes gives."""
    model, maps = zd.model, zd.maps
    robot = model.robot
    N, m = model.n, model.n_thrusters
    motors = [c.motor for c in robot.coordinates if c.actuated]
    powers = [t.power for t in robot.thrusters]
    missing = missing_models(robot)
    missing_t = tuple(missing)
    live = [i for i, lc in enumerate(cycles) if lc.exists]
    out: list[OrbitEnergy | None] = [
        None if lc.exists else OrbitEnergy(False, f"no periodic orbit: {lc.reason}")
        for lc in cycles]
    if not live:
        return out
    sched = schedule.take(np.array(live))
    k = len(live)
    zp = np.array([cycles[i].zeta_plus for i in live])
    kn = np.asarray(sched.knots, float)
    acc = {name: np.zeros((k,) + shape) for name, shape in (
        ("work", (N - 1,)), ("abs", (N - 1,)), ("pos", (N - 1,)), ("el", (N - 1,)),
        ("tw", (m,)), ("tpos", (m,)), ("gen", ()), ("tin", (m,)), ("fuel", (m,)),
        ("time", ()))}
    err = np.zeros(k)
    tin_ok = np.ones((k, m), bool)
    timed = True  # alpha' > 0 at every node: the time-based integrals exist
    el = [jj for jj, mo in enumerate(motors) if mo is not None]
    start = zd.__dict__.setdefault("_energy_node_count", {})
    for j in range(len(kn) - 1):
        lo, hi = sorted((kn[j], kn[j + 1]))
        if hi <= lo:
            continue
        half = 0.5 * (hi - lo)
        F = sched.force[:, j, :]  # (k, m)
        Tg = sched.generalized[:, j]  # (k,)
        aF = np.abs(F)
        skey = (tuple(kn.tolist()), j)
        n, have, full = 33, 0, None
        while True:
            if have < n:  # the integrands at max(n, where the last call ended) nodes
                have = max(n, start.get(skey, 33))
                full = _integrands(zd, sched, zp, j, have)
            step = (have - 1) // (n - 1)  # the n nodes are every step-th of them
            it = {key: v[..., ::step] for key, v in full.items()}
            w, wc = _weights(n)
            w, wc = w * half, wc * half

            def quad(v, w=w, wc=wc):
                fine = v @ w
                return fine, np.abs(fine - v[..., ::2] @ wc)
            work, e_work = quad(it["pj"])  # (k, N-1)
            bt_i, e_bt = quad(it["bt"])  # (m,)
            bg_i, e_bg = quad(it["bg"])
            e = np.maximum(e_work.max(axis=1), np.abs(Tg) * e_bg)
            if m:
                e = np.maximum(e, (aF * e_bt).max(axis=1))
            finite = np.all(np.isfinite(it["inv"]))
            if finite:
                time_i, e_time = quad(it["inv"])
                e = np.maximum(e, e_time)
            scale = max(float(np.max(np.abs(work))), 1e-300)
            if np.all(e <= RTOL * scale) or n >= MAX_NODES:
                break
            n = 2 * n - 1
        start[skey] = n
        u, pj, bt, adot, inv = (np.ascontiguousarray(it[key]) for key in (
            "u", "pj", "bt", "adot", "inv"))
        err += e
        acc["work"] += work
        acc["tw"] += F * bt_i
        acc["gen"] += Tg * bg_i
        # every int |.| and int max(0, .) of the interval in one batch: the joints' powers,
        # the thrusters' per unit thrust and the clipped electrical powers
        parts = [pj.reshape(-1, n), bt]
        if finite and el:  # SPEC 15 with the gearbox's kink at P_m = 0 taken out
            eta = np.array([motors[jj].efficiency for jj in el])[None, :]
            joule = np.stack([joule_power(u[:, jj], motors[jj]) for jj in el], axis=1)
            joule = joule * inv[:, None, :]  # per |d alpha|
            if not regenerate:
                parts.append((eta[..., None] * pj[:, el] + joule).reshape(-1, n))
        ab, po = _abs_and_positive(np.concatenate(parts), half)
        nj = k * (N - 1)
        po_j = po[:nj].reshape(k, N - 1)
        acc["abs"] += ab[:nj].reshape(k, N - 1)
        acc["pos"] += po_j
        if m:  # int max(0, F b) = F int max(0, b) (F > 0), |F| int max(0, -b) (F < 0)
            b_abs, b_pos = ab[nj:nj + m], po[nj:nj + m]
            acc["tpos"] += np.where(F > 0, F * b_pos, aF * (b_abs - b_pos))
        if not finite:
            tin_ok[:] = False
            timed = False
            continue
        acc["time"] += time_i
        if el:  # (module docstring)
            kink = (1.0 / eta - eta) * po_j[:, el]
            if regenerate:
                acc["el"][:, el] += kink + eta * work[:, el] + quad(joule)[0]
            else:
                acc["el"][:, el] += kink + po[nj + m:].reshape(k, len(el))
        for kk, p in enumerate(powers):
            if p is None:
                continue
            V = np.sign(F[:, kk])[:, None] * bt[kk][None] * adot  # s^2 = 1
            Fk = np.broadcast_to(F[:, kk][:, None], V.shape)
            if p.kind == "fuel":
                acc["fuel"][:, kk] += quad(p.tsfc * np.abs(Fk) * inv)[0]
            try:
                P = input_power(p, Fk, V)
            except ValueError:
                tin_ok[:, kk] &= ~np.any((Fk < p.thrust[0]) | (Fk > p.thrust[-1]), axis=1)
                P = input_power(p, np.clip(Fk, p.thrust[0], p.thrust[-1]), V)
            if P is not None:
                acc["tin"][:, kk] += quad(P * inv)[0]
    qm, qp = maps.q_minus, maps.q_plus
    Dm, Dp = model.D(qm), model.D(qp)
    phim, phip = maps.Phi(np.array(zd.alpha_f)), maps.Phi(np.array(zd.alpha_i))
    Vm, Vp = float(model.V(qm)[0]), float(model.V(qp)[0])
    Km_unit, Kp_unit = 0.5 * phim @ Dm @ phim, 0.5 * phip @ Dp @ phip
    weight, distance = robot.weight, zd.step_length
    ad = np.array([[cycles[i].alpha_dot_plus, cycles[i].alpha_dot_minus] for i in live])
    K = (ad**2 * np.array([Kp_unit, Km_unit])).tolist()
    lists = {name: a.tolist() for name, a in acc.items()}
    el_none = [mo is None for mo in motors]
    tin_none = [p is None or (p.kind == "fuel" and p.heating_value is None) for p in powers]
    is_fuel = [p is not None and p.kind == "fuel" for p in powers]
    ok = tin_ok.tolist()
    errs = err.tolist()
    reason = "energies of the periodic orbit's step (exact quadrature on Z)"
    fields = [f.name for f in dataclasses.fields(OrbitEnergy)]
    for r, i in enumerate(live):
        extra = [f"thruster {robot.thrusters[kk].name}: thrust outside its power table's "
                 "range: input energy not computed"
                 for kk in range(m) if timed and not tin_none[kk] and not ok[r][kk]]
        if not timed:
            extra.append("alpha' = 0 at a quadrature node (the walker comes to rest on the "
                         "orbit): step time, electrical, thruster input and fuel not computed")
        el = lists["el"][r]
        tin, fl = lists["tin"][r], lists["fuel"][r]
        out[i] = OrbitEnergy._of(dict(zip(fields, (
            True, reason, tuple(lists["work"][r]), tuple(lists["pos"][r]),
            tuple(lists["abs"][r]),
            tuple(None if el_none[jj] or not timed else el[jj] for jj in range(N - 1)),
            tuple(lists["tw"][r]), tuple(lists["tpos"][r]), lists["gen"][r],
            tuple(None if tin_none[kk] or not ok[r][kk] else tin[kk] for kk in range(m)),
            tuple(fl[kk] if is_fuel[kk] and timed else None for kk in range(m)),
            K[r][0], K[r][1], Vp, Vm, lists["time"][r] if timed else None,
            distance, weight, errs[r], regenerate,
            tuple(missing + extra) if extra else missing_t))))
    return out


def power_profile(zd: ZeroDynamics, schedule: Schedule, cycle, *, samples: int = 201,
                  regenerate: bool = False) -> dict | None:
    """The powers along one step of the periodic orbit ``cycle`` of the first schedule of
    ``schedule`` [W], at ``samples`` values of alpha from ``alpha_i`` to ``alpha_f`` (SPEC 15;
    the integrands of :func:`orbit_energy` in time, not in alpha): with ``alpha' = s |kappa_1|
    sqrt(2 zeta)``,

        joint j          u_j q_j' = u_j Phi_j alpha'                         (N-1 columns)
        thruster k       F_k d_k . p_k' = F_k (B_F^T Phi)_k alpha'           (m columns)
        generalised      T q_N' = T Phi_N alpha'
        joint electrical P_el(u_j, q_j') (motor), clipped at 0 unless ``regenerate``
        thruster input   P_in(F_k, V_k), V_k = sign(F_k) d_k . p_k'  (power model)

    and the time since the start of the step ``time`` [s] (trapezoid in alpha of ``1 /
    |alpha'|``: for plots; the step time itself is :func:`orbit_energy`'s). A column whose
    model is missing (or a table left) is None. None when the orbit does not exist or the
    walker comes to rest on it."""
    from .power import input_power, joint_electrical_power

    if not cycle.exists:
        return None
    model, maps = zd.model, zd.maps
    robot = model.robot
    N, m = model.n, model.n_thrusters
    sched = schedule.take(np.array([0]))
    kn = np.asarray(sched.knots, float)
    # what depends on alpha only, once per walker, knots and samples
    cache = zd.__dict__.setdefault("_profile_terms", {})
    key = (tuple(kn.tolist()), samples)
    if key not in cache:
        if len(cache) > 16:
            cache.clear()
        alpha = np.linspace(zd.alpha_i, zd.alpha_f, samples)
        frac = (alpha - kn[0]) / (kn[-1] - kn[0])
        pk = (kn - kn[0]) / (kn[-1] - kn[0])
        j = np.clip(np.searchsorted(pk, frac, side="right") - 1, 0, len(kn) - 2)
        cache[key] = (alpha, j, stance_terms(model, maps, alpha), _vz_pieces(zd, alpha, kn),
                      maps.Phi(alpha), model.B_F(maps.q_Z(alpha)))
    alpha, j, st, vz, phi, BF = cache[key]
    alpha = alpha.copy()
    F = sched.force[0, j, :]  # (g, m)
    Tg = sched.generalized[0, j]  # (g,)
    zeta = np.maximum(cycle.zeta_plus + _vz(vz, sched)[0], 0.0)
    adot = np.abs(st.AT) * np.sqrt(2.0 * zeta)  # |alpha'|
    if not np.all(adot > 0.0):
        return None
    s = zd.direction
    u = st.U0 + st.U1 * zeta[:, None] + st.UT * Tg[:, None]
    if m:
        u = u + np.einsum("gim,gm->gi", st.U2, F)
    qd = phi * (s * adot)[:, None]  # q' (g, N)
    joint = u * qd[:, :N - 1]
    bt = np.einsum("gnm,gn->gm", BF, qd)  # d_k . p_k' (g, m)
    thrust = F * bt
    inv = 1.0 / adot
    h = np.abs(np.diff(alpha))
    time = np.concatenate([[0.0], np.cumsum(0.5 * h * (inv[1:] + inv[:-1]))])
    acts = [c for c in robot.coordinates if c.actuated]
    el: list = []
    for jj, c in enumerate(acts):
        if c.motor is None:
            el.append(None)
            continue
        p = joint_electrical_power(u[:, jj], qd[:, jj], c.motor)
        el.append(p if regenerate else np.maximum(p, 0.0))
    tin: list = []
    for kk, t in enumerate(robot.thrusters):
        p = t.power
        if p is None:
            tin.append(None)
            continue
        try:
            P = input_power(p, F[:, kk], np.sign(F[:, kk]) * bt[:, kk])
        except ValueError:  # a table's range left
            P = None
        tin.append(P)
    return {"alpha": alpha, "time": time, "joint_mechanical": joint,
            "thrust_mechanical": thrust, "generalized": Tg * qd[:, N - 1],
            "joint_electrical": el, "thruster_input": tin,
            "joint_names": [c.name for c in acts], "thruster_names": list(robot.thruster_names)}
