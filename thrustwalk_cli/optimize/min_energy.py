"""Energy-optimal thrust schedules (SPEC 15 "Energy-optimal thrust", issue 28).

Decision variables as in :mod:`.min_effort` (force mode only: one thruster ``k``, ``x_j`` [N] on
knot interval ``j``); the constraints are exactly the SPEC 6 ones of the effort objective (the
same :class:`~.min_effort.LinearProblem`, the same exchange method for the contact rows, the
same root search for a target speed). The objective is the thruster's input energy per step
[J] (or, for a ``fuel`` model without a heating value, its fuel mass per step [kg]):

    E(x) = sum_j int_{interval j} P_k(x_j, V(alpha)) dt,    dt = d|alpha| / |alpha'|

with ``|alpha'| = |kappa_1| sqrt(2 zeta(alpha))`` and ``V = sign(x_j) d_k . p_k'`` the axial air
speed through the disk (:mod:`..energetics.power`; for the momentum model, per unit
``alpha'``: ``P dt = K |x| (sign(x) b/2 + sqrt(b^2/4 + |x| r^2 / (2 rho A))) d|alpha|`` with
``b = s (B_F^T Phi)_k``, ``r = 1 / |alpha'|`` and ``K = 1 / (FM eta)``; hover, ``b = 0``:
``dt_j |x_j|^{3/2} / sqrt(2 rho A) / (FM eta)``). ``linear``: ``w |x| dt_j``; ``fuel``:
``tsfc |x| dt_j`` (times the heating value [J/kg] when given); ``table``: the table's
interpolant times ``dt_j`` (convex only if its slopes do not decrease: checked, a non-convex
table is refused).

**The orbit depends on the schedule.** ``zeta(alpha) = delta_zero^2 zeta* + V_0(alpha) + c(alpha)
x`` is affine in ``x`` (zeta* fixed), so ``r(alpha)`` and ``V(alpha)`` change with ``x``. For a
frozen orbit (``r``, ``b`` fixed) each interval's energy is a convex function of ``x_j`` alone
(momentum: ``t sqrt(a + u t)`` is convex for ``t >= 0``, and the one-sided slopes at ``x_j = 0``,
``min(V, 0)`` and ``max(V, 0)`` per node, are ordered): a separable convex objective under
linear constraints. Sequential convex programming: freeze the orbit of the current schedule,
solve the convex problem exactly, recompute the orbit (the time weights ``dt``, ``r(alpha)``,
``V(alpha)``) on the new schedule, repeat until the schedule changes by less than ``TOL_SCP``
relative (at most ``MAX_SCP`` iterations). Each convex problem also carries the linear term
``g_orbit . x``, the part of the energy's gradient that comes through the orbit
(``dE/dzeta(alpha) dzeta/dx``, evaluated at the current schedule): with it a fixed point of the
iteration satisfies the KKT conditions of the full problem (the orbit's dependence included),
not only of the problem with frozen time weights. The full problem is not convex in general:
the fixed point is a KKT point (globally optimal for the convex problem with the converged orbit
frozen); a run that does not converge is reported as such, never as optimal.

Each convex problem is solved exactly: ``momentum`` by a primal-dual interior-point method
(Mehrotra predictor-corrector) on ``x = p - q``, ``p, q >= 0`` (the kink of ``|x|^{3/2}`` at 0
split off), finished by identifying the active set (signs of ``x_j``, active rows) and solving
its KKT equations by Newton's method, then verified (every row feasible, multipliers >= 0,
subgradient condition at ``x_j = 0``); ``linear``, ``fuel`` and ``table`` (piecewise linear, an
epigraph variable per interval) are linear programmes solved by the HiGHS simplex (a vertex:
exact). The KKT residuals are those of the full problem: stationarity with the subgradient
interval at ``x_j = 0`` (bounded least squares for the multipliers on the active rows),
complementarity, primal feasibility.

One idea in one file (above 600 lines): the energy objective of one thruster, its convex
subproblem, the solver finished on its active set and the KKT check of the full problem read
the same frozen-orbit data and are verified against each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog, lsq_linear

from ..contact.terms import stance_terms
from ..errors import ComputationError, InputError
from ..hzd.quadrature import _cc_weights, lobatto
from ..hzd.zero_dynamics import ZeroDynamics
from ..model.compiled import CompiledModel
from .min_effort import (
    KKT_TOL,
    LinearProblem,
    OptimalSchedule,
    OrbitAtRest,
    _cum_at,
    _solve_fixed,
    optimize,
)
from .qp import normalise_rows

TOL_SCP = 1e-10
MAX_SCP = 30
NODES = (33, 65, 129, 257, 513)
QUAD_RTOL = 1e-13


def objective_quantity(power) -> tuple[str, str]:
    """(quantity, unit) minimised for a thruster power model: input energy [J] per step, or
    fuel mass [kg] per step for a ``fuel`` model without a heating value."""
    if power.kind == "fuel" and power.heating_value is None:
        return "fuel mass", "kg"
    return "input energy", "J"


def table_convexity(power) -> str | None:
    """None when a ``table`` model is convex in the thrust (slopes nondecreasing), else where
    it is not (words). Other kinds: None (convex)."""
    if power.kind != "table":
        return None
    T, P = np.asarray(power.thrust, float), np.asarray(power.power, float)
    s = np.diff(P) / np.diff(T)
    bad = np.flatnonzero(np.diff(s) < -1e-12 * np.maximum(1.0, np.abs(s[:-1])))
    if not bad.size:
        return None
    i = int(bad[0]) + 1
    return (f"its slope falls from {s[i - 1]:.6g} to {s[i]:.6g} W/N at {T[i]:g} N (a convex "
            "table has nondecreasing slopes)")


@dataclass(frozen=True)
class FrozenOrbit:
    """The orbit of one schedule, sampled per knot interval on Lobatto nodes (SPEC 15):
    ``alpha`` [rad], quadrature weights ``w`` over ``|d alpha|``, ``r = 1/|alpha'|`` [s/rad],
    ``b = s (B_F^T Phi)_k`` [m/rad] (so ``d_k . p_k' = b |alpha'|``), ``zeta`` and ``C`` (g, n):
    ``d zeta / d x`` at the nodes. ``dt`` [s]: time in each interval."""

    alpha: tuple[np.ndarray, ...]
    w: tuple[np.ndarray, ...]
    r: tuple[np.ndarray, ...]
    b: tuple[np.ndarray, ...]
    zeta: tuple[np.ndarray, ...]
    C: tuple[np.ndarray, ...]

    @property
    def dt(self) -> np.ndarray:
        return np.array([float(w @ r) for w, r in zip(self.w, self.r)])


def freeze_orbit(prob: LinearProblem, zs: float, x: np.ndarray) -> FrozenOrbit:
    """The orbit of schedule ``x`` at fixed point ``zs`` (``zeta(alpha) = delta_zero^2 zs +
    V_0 + c(alpha) x``, the affine form of the constraint rows), nodes doubled per interval
    until the time and ``int |b|`` agree with the nested coarse rule to ``QUAD_RTOL``."""
    zd = prob.spec.zd
    kn, n, k = prob.knots, prob.n, prob.thruster
    d2 = zd.delta_zero_sq
    cum_k = _cum_at(zd, prob.mode, k, kn)
    lo_k, hi_k = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])

    def zeta_at(a: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
        C = np.zeros((len(a), n))
        for ll in range(n):
            C[:, ll] = _cum_at(zd, prob.mode, k, np.clip(a, lo_k[ll], hi_k[ll])) - cum_k[ll]
        return d2 * zs + zd.V0(a) + C @ x, C

    return sample_orbits(prob.spec.model, zd, kn, [k], zeta_at)[0]


def sample_orbits(model: CompiledModel, zd: ZeroDynamics, knots: np.ndarray,
                  thrusters: list[int], zeta_at) -> list[FrozenOrbit]:
    """One step's orbit sampled per knot interval on Lobatto nodes, as seen by each of
    ``thrusters`` (one :class:`FrozenOrbit` each: the same nodes, weights, ``r`` and ``zeta``;
    each thruster's own ``b``). ``zeta_at(alpha, j)`` -> ``(zeta, C)``: zeta [kg^2 m^4/s^2] at
    the nodes of interval ``j`` and its derivative ``C`` (g, n_var) in the decision variables.
    Nodes are doubled per interval until the time and every ``int |b|`` agree with the nested
    coarse rule to ``QUAD_RTOL`` (:class:`OrbitAtRest` when zeta <= 0 at a node)."""
    maps = zd.maps
    kn = np.asarray(knots, float)
    s = zd.direction
    lo_k, hi_k = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
    names = ("alpha", "w", "r", "b", "zeta", "C")
    out = [{name: [] for name in names} for _ in thrusters]
    for j in range(len(kn) - 1):
        lo, hi = lo_k[j], hi_k[j]
        half = 0.5 * (hi - lo)
        for m in NODES:
            a = lobatto(lo, hi, m)
            zeta, C = zeta_at(a, j)
            if np.any(zeta <= 0.0):
                raise OrbitAtRest(f"the orbit of the schedule comes to rest (zeta <= 0 at "
                                       f"alpha = {a[np.argmin(zeta)]:.6g} rad)")
            st = stance_terms(model, maps, a)
            r = 1.0 / (np.abs(st.AT) * np.sqrt(2.0 * zeta))
            BtP = s * np.einsum("gnm,gn->gm", model.B_F(maps.q_Z(a)), maps.Phi(a))
            bs = [BtP[:, k] for k in thrusters]
            w = _cc_weights(m) * half
            wc = _cc_weights((m - 1) // 2 + 1) * half
            err = abs(w @ r - wc @ r[::2]) / max(abs(w @ r), 1e-300)
            for b in bs:
                err = max(err, abs(w @ np.abs(b) - wc @ np.abs(b[::2]))
                          / max(w @ np.abs(b), 1e-300))
            if err <= QUAD_RTOL or m == NODES[-1]:
                break
        for o, b in zip(out, bs):
            for name, v in (("alpha", a), ("w", w), ("r", r), ("b", b), ("zeta", zeta),
                            ("C", C)):
                o[name].append(v)
    return [FrozenOrbit(**{name: tuple(v) for name, v in o.items()}) for o in out]


class EnergyObjective:
    """The energy (or fuel mass) per step of thruster ``k``'s schedule with the orbit frozen
    (module docstring): a separable convex function of ``x``, and the orbit's part of the
    full gradient.

    ``branch(j, t, sigma)``: value and first two derivatives in ``t = |x_j| >= 0`` of interval
    ``j`` on the branch ``sign(x_j) = sigma``; ``value(x)``; ``subgradient(x)``: the interval
    ``[lo, hi]`` of d/dx_j (``lo = hi`` away from the kink at 0 and a table's breakpoints);
    ``orbit_gradient(x)``: ``d E / d zeta(alpha) . d zeta / d x`` at ``x`` (0 when the orbit
    is the frozen one's own schedule's, added to the frozen gradient it gives the full one).
    """

    def __init__(self, power, orbit: FrozenOrbit):
        self.power = power
        self.orbit = orbit
        self.kind = power.kind
        p = power
        if self.kind == "momentum":
            self.K = 1.0 / (p.figure_of_merit * p.efficiency)
            self.kA = 1.0 / (2.0 * p.rho * p.area)
        elif self.kind == "linear":
            self.c = float(p.watts_per_newton)
        elif self.kind == "fuel":
            self.c = float(p.tsfc) * (1.0 if p.heating_value is None else float(p.heating_value))
        elif self.kind == "table":
            self.T = np.asarray(p.thrust, float)
            self.P = np.asarray(p.power, float)
            self.slope = np.diff(self.P) / np.diff(self.T)
        else:
            raise ValueError(f"unknown power model kind {self.kind!r}")
        self.dt = orbit.dt

    @property
    def n(self) -> int:
        return len(self.dt)

    def branch(self, j: int, t: float, sigma: float) -> tuple[float, float, float]:
        o = self.orbit
        w, r, b = o.w[j], o.r[j], o.b[j]
        if self.kind == "momentum":
            sq = np.sqrt(0.25 * b * b + self.kA * t * r * r)
            u = self.kA * r * r
            f = self.K * float(w @ (t * (0.5 * sigma * b + sq)))
            d1 = self.K * float(w @ (0.5 * sigma * b + sq + 0.5 * u * t / np.where(sq > 0, sq,
                                                                                   np.inf)))
            with np.errstate(divide="ignore", invalid="ignore"):
                h = np.where(sq > 0, u * (b * b + 3.0 * u * t) / (4.0 * sq**3), np.inf)
            d2 = self.K * float(w @ h)
            if t == 0.0:  # one-sided slope at 0: max(sigma b, 0) per node
                d1 = self.K * float(w @ np.maximum(sigma * b, 0.0))
            return f, d1, d2
        if self.kind in ("linear", "fuel"):
            return self.c * t * self.dt[j], self.c * self.dt[j], 0.0
        x = sigma * t
        return float(np.interp(x, self.T, self.P)) * self.dt[j], np.nan, 0.0

    def interval_values(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        if self.kind == "table":
            return np.interp(x, self.T, self.P) * self.dt
        return np.array([self.branch(j, abs(v), np.sign(v) or 1.0)[0]
                         for j, v in enumerate(x)])

    def value(self, x: np.ndarray) -> float:
        return float(np.sum(self.interval_values(x)))

    def subgradient(self, x: np.ndarray, tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``[lo, hi]`` of the frozen objective's subdifferential per coordinate (``|x_j| <=
        tol`` counts as the kink at 0)."""
        x = np.asarray(x, float)
        lo, hi = np.zeros(self.n), np.zeros(self.n)
        for j, v in enumerate(x):
            if self.kind == "table":
                i = np.searchsorted(self.T, v)
                if i < len(self.T) and abs(self.T[i] - v) <= tol:  # a breakpoint
                    lo[j] = self.slope[i - 1] if i > 0 else -np.inf
                    hi[j] = self.slope[i] if i < len(self.slope) else np.inf
                else:
                    s = self.slope[min(max(i - 1, 0), len(self.slope) - 1)]
                    lo[j] = hi[j] = s
                lo[j] *= self.dt[j]
                hi[j] *= self.dt[j]
            elif abs(v) <= tol:
                lo[j] = -self.branch(j, 0.0, -1.0)[1]
                hi[j] = self.branch(j, 0.0, 1.0)[1]
            else:
                sg = float(np.sign(v))
                lo[j] = hi[j] = sg * self.branch(j, abs(v), sg)[1]
        return lo, hi

    def orbit_gradient(self, x: np.ndarray) -> np.ndarray:
        """``sum_j int (d/dr)(P dt) (dr/dzeta) C(alpha) d|alpha|`` at ``x`` [J/N]: the energy's
        change through the orbit (``r = 1/|alpha'|``, ``dr/dzeta = -r / (2 zeta)``)."""
        o = self.orbit
        g = np.zeros(o.C[0].shape[1])  # every decision variable (the orbit depends on all)
        for j, v in enumerate(np.asarray(x, float)):
            w, r, b, z, C = o.w[j], o.r[j], o.b[j], o.zeta[j], o.C[j]
            t = abs(v)
            if self.kind == "momentum":
                if t == 0.0:
                    continue
                sq = np.sqrt(0.25 * b * b + self.kA * t * r * r)
                dPdr = self.K * t * self.kA * t * r / sq  # d(P r)/dr
            elif self.kind in ("linear", "fuel"):
                dPdr = np.full(len(r), self.c * t)
            else:
                dPdr = np.full(len(r), float(np.interp(v, self.T, self.P)))
            g += (w * dPdr * (-r / (2.0 * z))) @ C
        return g


def energy_of(prob: LinearProblem, zs: float, x: np.ndarray, power) -> float:
    """The energy (fuel mass) per step of schedule ``x`` on its own orbit (module docstring)."""
    return EnergyObjective(power, freeze_orbit(prob, zs, x)).value(x)


# ------------------------------------------------------------------------- the convex solves
@dataclass(frozen=True)
class Rows:
    """``prob.at(zs)`` with unit-norm rows and the constant rows (``A ~ 0``) left out:
    ``A x <= b``, ``ae x = be``; ``index``: the rows' positions in the problem, ``norms``
    their original norms (multipliers in the problem's scaling: ``lambda / norm``)."""

    A: np.ndarray
    b: np.ndarray
    ae: np.ndarray
    be: float
    index: np.ndarray
    norms: np.ndarray

    def __iter__(self):
        return iter((self.A, self.b, self.ae, self.be))


def constraint_rows(prob: LinearProblem, zs: float) -> Rows | None:
    """The rows of ``prob`` at fixed point ``zs`` (:class:`Rows`); None when a constant row is
    violated (infeasible)."""
    A, b, ae, be = prob.at(zs)
    An, bn, norms, const = normalise_rows(A, b)
    if np.any(bn[const] < -1e-9 * (1 + np.abs(b[const]))):
        return None
    s = np.linalg.norm(ae) or 1.0
    keep = np.flatnonzero(~const)
    return Rows(An[keep], bn[keep], ae / s, be / s, keep, norms[keep])


def _solve_lp(obj: EnergyObjective, g: np.ndarray, rows, prob: LinearProblem) -> np.ndarray:
    """``linear``, ``fuel``: ``min sum c dt_j (p_j + q_j) + g (p - q)``; ``table``: ``min sum
    dt_j t_j + g x`` with ``t_j >=`` each segment's line (epigraph). HiGHS dual simplex."""
    A, b, ae, be = rows
    n = obj.n
    if obj.kind == "table":
        T, P, sl = obj.T, obj.P, obj.slope
        cost = np.concatenate([g, obj.dt])
        seg = []
        for j in range(n):
            for i in range(len(sl)):  # P_i + s_i (x_j - T_i) - t_j <= 0
                row = np.zeros(2 * n)
                row[j], row[n + j] = sl[i], -1.0
                seg.append((row, sl[i] * T[i] - P[i]))
        G = np.vstack([np.column_stack([A, np.zeros((len(A), n))])] + [r for r, _ in seg])
        h = np.concatenate([b, [v for _, v in seg]])
        E = np.concatenate([ae, np.zeros(n)])[None, :]
        bounds = [(max(prob.lo[j], T[0]), min(prob.hi[j], T[-1])) for j in range(n)] \
            + [(None, None)] * n
    else:
        cost = np.concatenate([obj.c * obj.dt + g, obj.c * obj.dt - g])
        G = np.column_stack([A, -A])
        h = b
        E = np.concatenate([ae, -ae])[None, :]
        bounds = [(0, None)] * (2 * n)
    res = linprog(cost, A_ub=G, b_ub=h, A_eq=E, b_eq=[be], bounds=bounds, method="highs-ds")
    if res.status != 0:
        raise ComputationError(f"energy LP (HiGHS) failed: {res.message}")
    y = res.x
    x = y[:n] if obj.kind == "table" else y[:n] - y[n:]
    return x + 0.0  # no -0.0


def _ipm(obj: EnergyObjective, g: np.ndarray, rows, x0: np.ndarray,
         max_iter: int = 200) -> np.ndarray:
    """Primal-dual interior point (Mehrotra) for ``min sum_j f+_j(p_j) + f-_j(q_j) + g (p - q)``
    s.t. ``A (p - q) <= b``, ``a_eq (p - q) = b_eq``, ``p, q >= 0`` (infeasible start on the
    rows; ``p, q`` kept > 0)."""
    A, b, ae, be = rows
    n = obj.n
    G = np.column_stack([A, -A])
    E = np.concatenate([ae, -ae])
    c = np.concatenate([g, -g])
    y = np.concatenate([np.maximum(x0, 0.0), np.maximum(-x0, 0.0)]) + 0.1 * (1 + np.abs(x0).max())
    s = np.maximum(b - G @ y, 1.0)
    z = np.ones(len(b))
    v = np.ones(2 * n)  # duals of y >= 0
    nu = 0.0

    def grad_hess(y):
        gr, H = np.zeros(2 * n), np.zeros(2 * n)
        for j in range(n):
            for half, sg in ((0, 1.0), (1, -1.0)):
                _, d1, d2 = obj.branch(j, y[half * n + j], sg)
                gr[half * n + j], H[half * n + j] = d1, d2
        return gr + c, H

    with np.errstate(all="ignore"):  # a breakdown is caught by the merit (best iterate kept)
        return _ipm_loop(obj, grad_hess, G, E, b, be, c, y, s, z, v, nu, max_iter)


def _newton_direction(K, G, rd, rp, rs, y, s, z, v, rc_s, rc_y):
    """The reduced Newton system of :func:`_ipm` (complementarity residuals ``rc_s = s z -
    target``, ``rc_y = y v - target``): (dy, ds, dz, dnu, dv)."""
    rhs = np.concatenate([-rd + G.T @ ((rc_s - z * rs) / s) - rc_y / y, [-rp]])
    try:
        sol = np.linalg.solve(K, rhs)
    except np.linalg.LinAlgError:
        sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
    dy, dnu = sol[:-1], sol[-1]
    ds = -rs - G @ dy
    dz = -(rc_s + z * ds) / s
    dv = -(rc_y + v * dy) / y
    return dy, ds, dz, dnu, dv


def _step(x: np.ndarray, dx: np.ndarray) -> float:
    """The longest step <= 1 keeping ``x + t dx >= 0``."""
    neg = dx < 0
    return min(1.0, float(np.min(-x[neg] / dx[neg]))) if neg.any() else 1.0


def _ipm_loop(obj, grad_hess, G, E, b, be, c, y, s, z, v, nu, max_iter):
    n = obj.n
    m = len(b) + 2 * n
    bscale = 1.0 + max(np.abs(b).max(initial=0.0), abs(be))
    best = (np.inf, y.copy())
    for _ in range(max_iter):
        gr, H = grad_hess(y)
        rd = gr + G.T @ z + E * nu - v
        rp = float(E @ y - be)
        rs = G @ y + s - b
        mu = (s @ z + y @ v) / m
        scale = 1.0 + np.abs(gr).max()
        merit = max(mu / scale, np.abs(rd).max() / scale, abs(rp) / bscale,
                    np.abs(rs).max(initial=0.0) / bscale)
        if not np.isfinite(merit):
            break
        if merit < best[0]:
            best = (merit, y.copy())
        if merit <= 1e-14:
            break
        D = z / s
        M = np.diag(H + v / y) + (G.T * D) @ G
        K = np.block([[M, E[:, None]], [E[None, :], np.zeros((1, 1))]])
        args = (K, G, rd, rp, rs, y, s, z, v)
        dy, ds, dz, dnu, dv = _newton_direction(*args, s * z, y * v)  # affine
        ap = min(_step(y, dy), _step(s, ds))
        ad = min(_step(z, dz), _step(v, dv))
        mu_aff = ((s + ap * ds) @ (z + ad * dz) + (y + ap * dy) @ (v + ad * dv)) / m
        sigma = (mu_aff / mu) ** 3
        dy, ds, dz, dnu, dv = _newton_direction(*args, s * z + ds * dz - sigma * mu,
                                                y * v + dy * dv - sigma * mu)
        ap = 0.995 * min(_step(y, dy), _step(s, ds))
        ad = 0.995 * min(_step(z, dz), _step(v, dv))
        y, s = y + ap * dy, s + ap * ds
        z, v, nu = z + ad * dz, v + ad * dv, nu + ad * dnu
    y = best[1]
    return y[:n] - y[n:]


def _finish(obj: EnergyObjective, g: np.ndarray, rows, x: np.ndarray) -> np.ndarray | None:
    """Active-set finish of an interior-point solution: fix the signs of ``x`` (zeros at 0) and
    the active rows, solve their KKT equations by Newton's method, and return the point if it
    is verified (every row feasible, multipliers >= 0, the subgradient condition at the zeros,
    signs kept); None otherwise."""
    A, b, ae, be = rows
    n = obj.n
    xs = np.abs(x).max(initial=0.0)
    ztol = 1e-7 * max(xs, 1e-3)
    sign = np.where(np.abs(x) <= ztol, 0.0, np.sign(x))
    act = np.flatnonzero(b - A @ x <= 1e-7 * (1 + np.abs(b)))
    free = np.flatnonzero(sign != 0)
    xx = np.where(sign == 0, 0.0, x)
    Aeq = np.vstack([ae[None, :], A[act]])
    beq = np.concatenate([[be], b[act]])
    for _ in range(50):
        gr = np.zeros(n)
        H = np.zeros(n)
        for j in free:
            _, d1, d2 = obj.branch(j, abs(xx[j]), sign[j])
            gr[j], H[j] = sign[j] * d1, d2
        gr += g
        Af = Aeq[:, free]
        k = Af.shape[0]
        KKT = np.block([[np.diag(H[free]), Af.T], [Af, np.zeros((k, k))]])
        rhs = np.concatenate([-gr[free], beq - Aeq @ xx])
        sol = np.linalg.lstsq(KKT, rhs, rcond=None)[0]
        # Newton on x_F: the multipliers of the linearised system are the total ones
        dx = sol[:len(free)]
        xx[free] += dx
        if np.abs(dx).max(initial=0.0) <= 1e-15 * max(xs, 1e-300):
            break
    if np.any(np.sign(xx[free]) != sign[free]):
        return None
    if np.any(A @ xx - b > 1e-12 * (1 + np.abs(b))) or abs(ae @ xx - be) > 1e-12 * (1 + abs(be)):
        return None
    k = energy_kkt(obj, g, rows, xx, act_tol=1e-9)
    if k["stationarity_relative"] > 1e-9:
        return None
    return xx


def energy_kkt(obj: EnergyObjective, g: np.ndarray, rows, x: np.ndarray,
               act_tol: float = 1e-7) -> dict:
    """KKT residuals of ``x`` for ``min obj(x) + g x`` s.t. the (normalised) rows: multipliers
    ``lambda >= 0`` on the active rows, ``nu`` on the equality and a subgradient ``d in [lo,
    hi]`` by bounded least squares of ``d + g + A_act^T lambda + nu a_eq = 0``."""
    A, b, ae, be = rows
    slack = b - A @ x
    active = np.flatnonzero(slack <= act_tol * (1 + np.abs(b)))
    ztol = 1e-9 * max(np.abs(x).max(initial=0.0), 1e-3)
    lo, hi = obj.subgradient(x, tol=ztol)
    lo, hi = lo + g, hi + g
    n = len(x)
    M = np.column_stack([A[active].T, ae, np.eye(n)])
    lb = np.concatenate([np.zeros(len(active)), [-np.inf], lo])
    ub = np.concatenate([np.full(len(active), np.inf), [np.inf], hi])
    fixed = lb == ub
    rhs = -M[:, fixed] @ lb[fixed]
    sol = np.zeros(M.shape[1])
    sol[fixed] = lb[fixed]
    if np.any(~fixed):
        r = lsq_linear(M[:, ~fixed], rhs, bounds=(lb[~fixed], ub[~fixed]), method="bvls",
                       tol=1e-14, lsq_solver="exact")
        sol[~fixed] = r.x
    res = np.linalg.norm(M @ sol)
    d = sol[len(active) + 1:]
    scale = max(np.linalg.norm(d), 1e-300)
    lam = sol[:len(active)]
    if isinstance(rows, Rows):  # in the problem's rows and scaling
        lam_out, act_out = lam / rows.norms[active], rows.index[active]
    else:
        lam_out, act_out = lam, active
    return {
        "stationarity_relative": float(res / scale) if np.linalg.norm(d) > 1e-12 else float(res),
        "primal_infeasibility": float(max(0.0, -slack.min(initial=0.0))),
        "equality_residual": float(abs(ae @ x - be)),
        "complementarity": float(np.max(lam * np.abs(slack[active]), initial=0.0)),
        "min_multiplier": float(lam.min(initial=0.0)),
        "active": act_out, "multipliers": lam_out, "nu": float(sol[len(active)]),
        "gradient": d.tolist(),
    }


def convex_solve(obj: EnergyObjective, g: np.ndarray, rows, prob: LinearProblem,
                 x0: np.ndarray) -> tuple[np.ndarray, str]:
    """The exact optimum of ``min obj(x) + g x`` under the rows (module docstring)."""
    if obj.kind != "momentum":
        return _solve_lp(obj, g, rows, prob), "linear programme (HiGHS dual simplex)"
    x = _ipm(obj, g, rows, x0)
    xf = _finish(obj, g, rows, x)
    if xf is not None:
        return xf, "interior point (Mehrotra) + active-set Newton finish, verified"
    return x, "interior point (Mehrotra); active-set finish not verified"


@dataclass(frozen=True)
class EnergySolve:
    """One sequential convex programme at fixed zeta*: the schedule ``x`` [N], its energy on
    its own orbit ``energy`` [J or kg], the time in each interval ``dt`` [s], the iterations,
    the last relative change of the schedule, ``converged``, the KKT residuals of the full
    problem (``kkt``, on ``prob.at(zs)``'s rows normalised), ``history`` (energy per
    iteration)."""

    x: np.ndarray
    energy: float
    dt: np.ndarray
    iterations: int
    change: float
    converged: bool
    kkt: dict
    solver: str
    history: tuple[float, ...]
    objective: EnergyObjective

    @property
    def kkt_ok(self) -> bool:
        k = self.kkt
        return (k["stationarity_relative"] <= 1e-6 and k["primal_infeasibility"] <= KKT_TOL
                and k["equality_residual"] <= KKT_TOL)

    def verdict(self, contact: str, contact_ok: bool) -> tuple[str, str]:
        """(status, reason) of the final solve; ``contact``: the exchange method's words."""
        fp = (f"sequential convex programming: {self.iterations} iteration(s), last relative "
              f"change of the schedule {self.change:.2g}")
        if not self.converged:
            return "not converged", (
                f"not converged: the time-weight fixed point did not converge ({fp}, tolerance "
                f"{TOL_SCP:g}, at most {MAX_SCP}); the schedule is feasible but not shown to be "
                f"optimal; {contact}")
        if not self.kkt_ok:
            k = self.kkt
            return "not verified", (
                f"not verified: the fixed point converged ({fp}) but the KKT check fails "
                f"(stationarity {k['stationarity_relative']:.2e}, infeasibility "
                f"{k['primal_infeasibility']:.2e}); {contact}")
        head = ("optimal: energy-optimal schedule found" if contact_ok else
                "optimal on the alpha grid")
        return "optimal", (
            f"{head} (a KKT point of the energy problem, the orbit's dependence on the schedule "
            f"included; {fp}; KKT conditions verified; {contact})")


def solve_energy(prob: LinearProblem, zs: float, power, x0: np.ndarray) -> EnergySolve | None:
    """Sequential convex programming at fixed zeta* ``zs`` from the feasible schedule ``x0``
    (module docstring); None when the rows are infeasible."""
    rows = constraint_rows(prob, zs)
    if rows is None:
        return None
    return sequential_convex(lambda x: EnergyObjective(power, freeze_orbit(prob, zs, x)), rows,
                             prob, x0)


def sequential_convex(objective_at, rows, bounds, x0: np.ndarray) -> EnergySolve:
    """The module docstring's iteration from the feasible ``x0`` under the normalised
    ``rows``: ``objective_at(x)`` freezes the orbit of ``x`` (an :class:`EnergyObjective` or
    any separable objective with its methods), :func:`convex_solve` solves the convex problem
    with the orbit's gradient term, until the relative change is below ``TOL_SCP`` (at most
    ``MAX_SCP``); the KKT residuals of the full problem at the end. ``bounds``: ``lo``/``hi``
    per variable [N] (a table's epigraph LP)."""
    x = np.asarray(x0, float).copy()
    change, history, solver = np.inf, [], ""
    it = 0
    for it in range(1, MAX_SCP + 1):  # noqa: B007 (reported)
        obj = objective_at(x)
        history.append(obj.value(x))
        g = obj.orbit_gradient(x)
        xn, solver = convex_solve(obj, g, rows, bounds, x)
        size = max(np.abs(xn).max(initial=0.0), np.abs(x).max(initial=0.0))
        diff = np.abs(xn - x).max(initial=0.0)
        change = 0.0 if diff == 0.0 else diff / max(size, 1e-300)
        x = xn
        if change < TOL_SCP:
            break
    obj = objective_at(x)
    k = energy_kkt(obj, obj.orbit_gradient(x), rows, x)
    return EnergySolve(x, obj.value(x), obj.dt, it, float(change), bool(change < TOL_SCP), k,
                       solver, tuple(history), obj)


def check_power(model: CompiledModel, thruster: int):
    """The thruster's power model, or :class:`InputError` (parameter ``objective``): none given,
    or a non-convex table."""
    t = model.robot.thrusters[thruster]
    if t.power is None:
        raise InputError.param("objective", f"energy needs a `power:` for thruster {t.name} in "
                                            f"the robot file ({model.robot.source_file})")
    why = table_convexity(t.power)
    if why is not None:
        raise InputError.param("objective", f"energy: the power table of thruster {t.name} is "
                                            f"not convex ({why}): the energy problem would not "
                                            "be convex")
    return t.power


def optimize_energy(model: CompiledModel, zd: ZeroDynamics, fractions: np.ndarray, *,
                    thruster: int = 0, **kw) -> OptimalSchedule:
    """The energy-optimal schedule of thruster ``thruster`` (force mode) reaching the target of
    :func:`.min_effort.optimize` under the same constraints (``kw``: its options): the
    module docstring's sequential convex programme at each fixed zeta*, started from the
    minimum-effort schedule. A table's thrust range bounds the schedule."""
    power = check_power(model, thruster)

    def solve(prob: LinearProblem, zs: float):
        x0, _, _ = _solve_fixed(prob, zs)
        if x0 is None:
            return None, None, "", None
        es = solve_energy(prob, zs, power, x0)
        if es is None:
            return None, None, "", None
        return es.x, es.kkt, es.solver, es

    rng = None
    if power.kind == "table":
        rng = (float(power.thrust[0]), float(power.thrust[-1]))
    return optimize(model, zd, fractions, mode="force", thruster=thruster, solve=solve,
                    objective_name="energy", thrust_range=rng, **kw)
