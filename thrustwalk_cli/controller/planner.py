"""The per-step QP of SPEC section 11: at each impact, choose the next step's thrust values.

Given the measured ``x_k`` (zeta^- of the impact that starts step k) and the previous values
``u_{k-1}``:

    min_u  w ((x_{k+1} - x_ref)/zeta_s)^2 + sum_j e w_j (u_j/F_s)^2 + r |u - u_{k-1}|^2/F_s^2
    s.t.   F_1^v(alpha) >= eps + E(alpha),
           |F_1^h(alpha)| <= mu F_1^v(alpha) - (E + mu E)(alpha)          on an alpha grid
           zeta_k(alpha) >= zeta_min
           u_min <= u <= u_max,   |u - u_{k-1}| <= rate

with ``x_{k+1}``, ``zeta_k`` and ``F_1`` affine in ``(x_k, u)`` (:mod:`.step_model`); ``w_j`` the
alpha-length fraction of interval j, ``F_s`` the largest thrust limit [N], ``zeta_s`` the
nominal zeta* [kg^2 m^4/s^2]. ``E`` is the error bound of the fitted polynomials L_k (0 with the
exact Lambda terms). A measurement ``x_k`` known to within a relative ``noise`` is handled
exactly: every constraint is affine in ``x_k``, so it holds for every true value in
``[x/(1+noise), x/(1-noise)]`` when it holds at both ends (each row takes the worse end).

Tracking weight ``w = None`` (default) puts tracking first (the limit of large ``w``): the QP
is solved with ``x_{k+1} = x_ref`` as an equality — unconstrained and reachable this is
deadbeat; when the equality cannot be met, the attainable ``x_{k+1}`` closest to ``x_ref`` is
found by a linear programme (HiGHS) and met instead: the step is *saturated*. A finite ``w``
is the SPEC 11 objective as written. When even the inequalities are incompatible (the
contact conditions cannot hold for this ``x_k`` with any thrust), the step is *infeasible*:
the thrust that minimises the largest normalised violation (an LP) is applied and the step is
not certified. Impact admissibility does not depend on the thrust (SPEC 11): checked once.

Every QP is solved exactly by :class:`thrustwalk_cli.optimize.qp.ConvexQP` (NNLS
least-distance with generated rows). Units SI.

One idea in one file (above 600 lines): the per-step QP with its rows, its exact
polishing between grid points and its cutting planes, which together make one certified
plan.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from ..contact.terms import impact_data
from ..errors import InputError
from ..hzd.extrema import golden_min, grid_miss, neighbours, peaks
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics
from ..optimize.qp import ConvexQP, normalise_rows
from .energy_plan import FEASIBLE_TOL, Bounds, energy_plan, energy_powers, predicted_energy
from .step_model import (
    IdealThrust,
    ResponseThrust,
    Rows,
    RowSeries,
    StepStops,
    Terms,
    rows,
    series_nodes,
    step_grid,
)

FAMILIES = ("vertical_force", "friction", "zeta_min", "thrust_bounds", "rate_limit")
MAX_RESPONSE_ITER = 12  # fixed-point iterations of the slow-thruster time map
MAX_CUT_ROUNDS = 8  # cutting-plane rounds of one plan (one or two on the test robots)
RATIO_TOL = 1e-9  # certificate tolerance of the friction ratio [1]
FORCE_TOL = 1e-9  # ... of the vertical force, relative to the robot's weight
ZETA_TOL = 1e-9  # ... of zeta >= zeta_min, relative to the nominal zeta*
POLISH_ITERATIONS = 20  # golden-section steps: the bracket (two grid spacings) shrinks 7e-5
PEAKS = 16  # local extrema polished per quantity and end of the measurement band
SERIES_NODES = (33, 65, 129, 257)  # Chebyshev nodes per knot interval, fewest first
SERIES_TOL = 1e-12  # accepted deviation of the polishing series, relative to weight / zeta*


@dataclass(frozen=True)
class Settings:
    """The QP's data (SPEC 11). ``mu`` [1], ``eps`` [N], ``zeta_min`` [kg^2 m^4/s^2], ``lo``/
    ``hi`` thrust bounds per driven thruster [N], ``rate`` [N per step] or None, weights
    dimensionless (``tracking`` None: tracking first), ``noise`` relative bound of the
    measurement error of zeta^- [1], ``points`` alpha grid size. ``continuous``: enforce and
    certify the contact conditions between the grid points too (polished worst points and
    cutting planes, see :class:`Planner`); off, the plan holds them on the grid only.
    ``objective``: ``effort`` (the QP above) or ``energy`` (tracking first, the driven
    thrusters' input energy over the predicted step minimised under the same rows:
    :mod:`.energy_plan`)."""

    mu: float
    eps: float
    zeta_min: float
    lo: np.ndarray
    hi: np.ndarray
    rate: float | None
    tracking: float | None
    effort: float
    smooth: float
    noise: float
    points: int
    zeta_scale: float
    force_scale: float
    continuous: bool = False
    objective: str = "effort"


@dataclass
class Plan:
    """One step's decision: thrust values ``u`` [N] (interval-major, per driven thruster),
    ``status`` (``tracking``: the reference is met; ``saturated``: met as closely as the
    constraints allow; ``infeasible``: the constraints cannot hold, least violation applied),
    predicted ``x_next`` [kg^2 m^4/s^2] with its band over the measurement interval, the
    active constraint families, the time of its QP solves [s] and the model rows on the grid.
    With continuous constraints: ``margins`` (the polished predicted extremes, see
    :meth:`Planner.plan`), the cutting planes' ``cut_alpha`` [rad], the rounds it took and
    ``polish_time`` [s] (polishing and the cutting planes' rows). With the energy objective,
    ``energy``: the predicted input energy of the plan [J] and how it was found
    (:meth:`Planner.plan`)."""

    u: np.ndarray
    status: str
    x_meas: float
    x_ref: float
    x_target: float
    x_next: float
    x_next_band: tuple[float, float]
    x_band: tuple[float, float]
    active: list[str]
    qp_time: float
    rows: Rows = field(repr=False)
    step_time: float | None = None
    iterations: int = 1
    violation: float = 0.0
    margins: dict | None = None
    cut_alpha: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cut_rounds: int = 0
    polish_time: float = 0.0
    energy: dict | None = None


class Planner:
    """Builds and solves the SPEC 11 QP step after step (the controller's model side).

    **Continuous contact conditions** (``settings.continuous``). The QP imposes the rows on an
    alpha grid; between grid points the friction ratio of the plan may exceed mu (by 1e-5 on
    a 200-point-per-interval grid in a friction-limited step). After each solve the planner
    polishes the plan's worst points as the feasibility check does: the local extrema of
    ``F_1^v - E``, ``(|F_1^h| + E)/(F_1^v - E)`` and zeta on the grid, at both ends of the
    measurement band, each refined by golden section between its neighbouring grid points
    (:func:`~thrustwalk_cli.hzd.extrema.golden_min`, :func:`~thrustwalk_cli.hzd.extrema.
    neighbours`; every local extremum that the grid could hide beyond the limit, by
    :func:`~thrustwalk_cli.hzd.extrema.grid_miss`). Where a polished point violates its
    condition by more than the tolerance (friction ratio ``RATIO_TOL``, vertical force
    ``FORCE_TOL`` of the weight, zeta ``ZETA_TOL`` of zeta*), the exact rows at that alpha are
    added to the QP (a cutting plane; an exchange method for the semi-infinite programme) and
    it is solved again, until no polished point violates (``MAX_CUT_ROUNDS``). The plan then
    satisfies the continuous conditions to the tolerance; :attr:`Plan.margins` holds the
    polished extremes and ``feasible`` (the certificate's contact part) is decided on them with
    the tolerance, so round-off of an active row cannot flip it. Between grid points the rows
    come from a Chebyshev series of the exact rows on each knot interval
    (:class:`~.step_model.RowSeries`, 33-257 nodes; its deviation from the exact rows on the
    grid, about 1e-13 of the forces, is added to the margins); the cutting planes' rows are
    exact. Cost (measured on a busy 2-core machine): the series once per planner (per plan for
    slow thrusters); a polish is 20 series evaluations of a small batch, about 7 ms against
    0.1-0.3 ms for the QP; a cutting-plane round is one exact row evaluation, one more QP solve
    and one more polish (the friction-limited 3-link: two rounds, 16.5 ms per plan). Off
    (the default, e.g. for ``robustness``), the plan holds the rows on the grid only.
    """

    def __init__(self, zd: ZeroDynamics, terms: Terms, thrust: IdealThrust | ResponseThrust,
                 settings: Settings):
        self.zd, self.terms, self.thrust, self.st = zd, terms, thrust, settings
        self.d2 = zd.delta_zero_sq
        kn = thrust.knots
        self.alpha, self.idx = step_grid(kn, settings.points)
        nu = thrust.nu
        md = len(thrust.driven)
        frac = np.abs(np.diff(kn)) / abs(kn[-1] - kn[0])
        wj = np.repeat(frac, md)
        Fs, st = settings.force_scale, settings
        self.W = np.diag(st.effort * wj / Fs**2 + st.smooth / Fs**2)
        self.R = st.smooth / Fs**2
        # steady state (u_prev = u): the smoothing term vanishes, the effort alone is weighed
        self.W_steady = np.diag((st.effort if st.effort > 0 else 1.0) * wj / Fs**2)
        imp = impact_data(zd.model, zd)
        self.impact_ok = imp.admissible(st.mu)
        self.impact_reasons = imp.reasons(st.mu)
        self.lo = np.tile(st.lo, len(kn) - 1)
        self.hi = np.tile(st.hi, len(kn) - 1)
        self.umax = np.maximum(np.abs(self.lo), np.abs(self.hi))
        robot = zd.model.robot
        self.weight = float(robot.total_mass * robot.gravity)
        self.tolerance = {"friction_ratio": RATIO_TOL, "vertical_force": FORCE_TOL * self.weight,
                          "zeta": ZETA_TOL * st.zeta_scale}
        self._static = None if thrust.dynamic else rows(zd, terms, thrust, self.alpha,
                                                        self.idx)
        self._qp_cache: dict = {}
        self._rows_cache: dict = {}
        self._nodes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._series_n: int | None = None
        self._static_series: tuple | None = None
        self.nu = nu
        self.powers = None if settings.objective != "energy" else energy_powers(
            zd, thrust.driven, dynamic=thrust.dynamic, tracking_weight=settings.tracking,
            rate_weight=settings.smooth)
        self._energy_info: dict | None = None

    # ------------------------------------------------------------------ constraint rows
    def error_bound(self, rw: Rows, x_hi: float, fb: float | None = None) -> np.ndarray:
        """Bound on the error of ``F_1`` from the fitted terms at the rows' alpha [N] (0 with the
        exact terms): ``e_0 + e_1 max|zeta| + e_2 sum_t max|F_t|`` with ``e_k`` the fits' maximum
        errors and the maxima over every allowed thrust and ``x_k <= x_hi`` (``fb``: the thrust
        sum, default from these rows)."""
        if self.terms.fits is None:
            return np.zeros(rw.alpha.size)
        zb = np.abs(rw.z0) + np.abs(rw.Zu) @ self.umax + self.d2 * x_hi
        if fb is None:
            fb = self._thrust_sum(rw)
        e0, e1, e2 = self.terms.errors
        return e0 + e1 * zb + e2 * fb

    def _thrust_sum(self, rw: Rows) -> float:
        return float(np.sum(np.abs(rw.f0).max(axis=0) + np.abs(rw.S).max(axis=0) @ self.umax))

    def contact_rows(self, rw: Rows, x_hi: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The contact and zeta rows ``A u <= b0 + bx x_k`` with the family of each row
        (SPEC 5, 11); with fitted terms each is tightened by the fit error bound ``E``."""
        st = self.st
        mu = st.mu
        E = self.error_bound(rw, x_hi)
        h, v = 0, 1
        Pu, P0, Px = rw.Pu, rw.P0, rw.Px
        g = len(P0)
        A = np.vstack([-Pu[:, v], Pu[:, h] - mu * Pu[:, v], -Pu[:, h] - mu * Pu[:, v], -rw.Zu])
        b0 = np.concatenate([P0[:, v] - st.eps - E, -(P0[:, h] - mu * P0[:, v]) - (1 + mu) * E,
                             P0[:, h] + mu * P0[:, v] - (1 + mu) * E, rw.z0 - st.zeta_min])
        bx = np.concatenate([Px[:, v], -(Px[:, h] - mu * Px[:, v]), Px[:, h] + mu * Px[:, v],
                             np.full(g, self.d2)])
        fam = np.array(["vertical_force"] * g + ["friction"] * (2 * g) + ["zeta_min"] * g)
        return A, b0, bx, fam

    def constraints(self, rw: Rows, x_lo: float, x_hi: float, u_prev: np.ndarray | None,
                    rate: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``A u <= b`` holding for every ``x_k`` in ``[x_lo, x_hi]`` (each row at the worse
        end: it is affine in ``x_k``), with thrust bounds and (``rate``) rate limits; and the
        family of each row."""
        rate = rate and self.st.rate is not None
        key = (rate, x_hi if self.terms.fits is not None else None)
        cached = self._rows_cache.get(key) if rw is self._static else None
        if cached is not None:
            A, b0, bx, fam = cached
        else:
            A, b0, bx, fam = self.contact_rows(rw, x_hi)
            eye = np.eye(self.nu)
            A = np.vstack([A, eye, -eye] + ([eye, -eye] if rate else []))
            fam = np.concatenate([fam, ["thrust_bounds"] * (2 * self.nu)]
                                 + ([["rate_limit"] * (2 * self.nu)] if rate else []))
            if rw is self._static:
                if len(self._rows_cache) > 4:
                    self._rows_cache.clear()
                self._rows_cache[key] = (A, b0, bx, fam)
        b = b0 + np.minimum(bx * x_lo, bx * x_hi)
        parts = [b, self.hi, -self.lo]
        if rate:
            parts += [u_prev + self.st.rate, -(u_prev - self.st.rate)]
        return A, np.concatenate(parts), fam

    def grid_rows(self) -> Rows:
        """The model on the QP's alpha grid for the current thrust map."""
        if self._static is not None:
            return self._static
        return rows(self.zd, self.terms, self.thrust, self.alpha, self.idx)

    def rows_at(self, alpha: np.ndarray) -> Rows:
        """The model at any alpha (for comparison with the realised step)."""
        return rows(self.zd, self.terms, self.thrust, alpha)

    # ------------------------------------------------------------------ the QP
    def _qp(self, key: str, H: np.ndarray, A: np.ndarray, a_eq: np.ndarray | None,
            cache: bool = True) -> ConvexQP:
        """Cached factorisations (the matrices are fixed for ideal thrusters on the grid)."""
        cache = cache and self._static is not None
        qp = self._qp_cache.get(key) if cache else None
        if qp is None:
            qp = ConvexQP(H, A, a_eq)
            if cache:
                self._qp_cache[key] = qp
        return qp

    def _solve(self, rw: Rows, x_meas: float, x_ref: float, u_prev: np.ndarray | None,
               steady: bool = False
               ) -> tuple[np.ndarray | None, str, float, list[str], float]:
        """One QP on the rows ``rw`` (the grid, or cutting planes then the grid: the last row
        is at alpha_f). ``steady``: the steady state ``x_{k+1} = x_k = x_ref`` with the least
        effort, no rate limit and no smoothing (u None, status ``unreachable`` without one)."""
        st = self.st
        self._energy_info = None
        x_lo, x_hi = self.x_band(x_meas)
        A, b, fam = self.constraints(rw, x_lo, x_hi, u_prev, rate=not steady)
        cache = rw is self._static
        g = rw.Zu[-1]  # x_{k+1} = d2 x + z0(alpha_f) + g u
        base = self.d2 * x_meas + rw.z0[-1]
        if steady:
            qp = self._qp(f"steady{A.shape[0]}", 2.0 * self.W_steady, A, g, cache)
            u, active = qp.solve(np.zeros(self.nu), b, x_ref - base)
            if u is None:
                return None, "unreachable", float(x_ref), [], 0.0
            return u, "tracking", float(x_ref), sorted({str(f) for f in fam[active]}), 0.0
        H = 2.0 * self.W  # W holds the effort and the smoothing weights
        c = -2.0 * self.R * u_prev
        active: np.ndarray
        if st.tracking is None:
            qp = self._qp(f"eq{A.shape[0]}", H, A, g, cache)
            u, active = qp.solve(c, b, x_ref - base)
            status, target = "tracking", x_ref
            if u is None:
                free = self._qp(f"free{A.shape[0]}", H, A, None, cache)
                u0, _ = free.solve(c, b)
                if u0 is None:
                    u, viol = self._least_violation(A, b, fam)
                    return u, "infeasible", float(base + g @ u), ["infeasible"], viol
                sign = 1.0 if x_ref > base + g @ u0 else -1.0
                ext = self._extreme(A, b, sign * g)
                target = base + sign * ext
                target -= sign * 1e-9 * max(abs(target), st.zeta_scale)  # stay inside
                if sign * (target - (base + g @ u0)) < 0:
                    target = float(base + g @ u0)
                u, active = qp.solve(c, b, target - base)
                if u is None:
                    u, active = u0, np.zeros(0, int)
                    target = float(base + g @ u0)
                status = "saturated"
            if self.powers is not None:
                u, active = self._energy(A, b, g, float(target - base), u, active, x_meas)
        else:
            w = st.tracking / st.zeta_scale**2
            Ht = H + 2.0 * w * np.outer(g, g)
            ct = c - 2.0 * w * g * (x_ref - base)
            qp = self._qp(f"soft{A.shape[0]}", Ht, A, None, cache)
            u, active = qp.solve(ct, b)
            if u is None:
                u, viol = self._least_violation(A, b, fam)
                return u, "infeasible", float(base + g @ u), ["infeasible"], viol
            target = float(base + g @ u)
            status = ("saturated" if active.size and abs(target - x_ref) > 1e-9 * max(
                abs(x_ref), 1.0) else "tracking")
        act = sorted({str(f) for f in fam[active]})
        return u, status, float(target), act, 0.0

    def _energy(self, A: np.ndarray, b: np.ndarray, g: np.ndarray, rhs: float,
                u_eff: np.ndarray, active: np.ndarray, x_meas: float
                ) -> tuple[np.ndarray, np.ndarray]:
        """The energy plan (:func:`.energy_plan.energy_plan`) under the effort plan's rows
        ``A u <= b`` and its ``x_{k+1}`` target ``g u = rhs``, from the effort plan ``u_eff``;
        the effort plan is kept (and said so in :attr:`_energy_info`) when no verified energy
        plan is found or it would not use less energy. Returns ``(u, active rows)``."""
        e_eff = predicted_energy(self.zd, self.thrust, self.powers, x_meas, u_eff)
        if e_eff is not None and e_eff <= self._zero_energy():
            # input powers are >= 0, so E >= 0: a feasible plan that spends (to rounding) no
            # energy is optimal; the solver's KKT check is degenerate at zero thrust
            self._energy_info = {"effort_plan_energy": e_eff, "solver": "none needed",
                                 "iterations": 0, "kkt_stationarity": None,
                                 "status": "optimal", "reason": (
                                     "the effort plan spends no input energy (to rounding) and "
                                     "every thruster's input power is >= 0: it is optimal")}
            return u_eff, active
        u, es, words = energy_plan(self.zd, self.thrust, self.powers, x_meas, A, b, g, rhs,
                                   u_eff, Bounds(self.lo, self.hi))
        info = {"effort_plan_energy": e_eff, "solver": None if es is None else es.solver,
                "iterations": None if es is None else es.iterations,
                "kkt_stationarity": None if es is None else es.kkt["stationarity_relative"]}
        if u is not None and e_eff is not None and es.energy > e_eff:
            u, words = None, (f"the energy plan's KKT point ({es.energy:.6g}) uses more than the "
                              f"effort plan ({e_eff:.6g}): the effort plan is applied")
        if u is None:
            self._energy_info = {**info, "status": "effort plan applied", "reason": words}
            return u_eff, active
        act = np.flatnonzero(b - A @ u <= FEASIBLE_TOL * (1.0 + np.abs(b)))
        self._energy_info = {**info, "status": "optimal", "reason": (
            "a KKT point of the predicted step's input energy (the orbit's dependence on the "
            "thrust included), KKT conditions verified")}
        return u, act

    def _zero_energy(self) -> float:
        """What counts as no input energy over a step [J]: ``1e-12 m g l`` (``l`` the
        nominal step length), or 0 when a thruster's power table has a negative entry (then
        ``E >= 0`` is not known)."""
        for p in self.powers:
            if getattr(p, "kind", None) == "table" and np.min(p.power) < 0:
                return 0.0
        return 1e-12 * self.weight * abs(float(self.zd.step_length))

    def _extreme(self, A: np.ndarray, b: np.ndarray, cost_dir: np.ndarray) -> float:
        """``max cost_dir . u`` s.t. ``A u <= b`` (HiGHS)."""
        An, bn, _, const = normalise_rows(A, b)
        res = linprog(-cost_dir, A_ub=An[~const], b_ub=bn[~const],
                      bounds=[(None, None)] * A.shape[1], method="highs")
        if res.status != 0:
            return float(cost_dir @ np.clip(np.zeros(A.shape[1]), self.lo, self.hi))
        return float(-res.fun)

    def _least_violation(self, A: np.ndarray, b: np.ndarray, fam: np.ndarray
                         ) -> tuple[np.ndarray, float]:
        """``min t`` s.t. ``A_n u <= b_n + t`` on the normalised contact rows, the thrust
        bounds, rate limits and zeta >= zeta_min kept (the walker keeps moving; an LP, HiGHS);
        without such a point, every row but the bounds and rates relaxed. Returns (u, t)."""
        An, bn, _, const = normalise_rows(A, b)
        n = A.shape[1]
        for hard_fams in (("thrust_bounds", "rate_limit", "zeta_min"),
                          ("thrust_bounds", "rate_limit")):
            hard = np.isin(fam, hard_fams)
            soft = ~hard & ~const
            Aub = np.vstack([np.column_stack([An[soft], -np.ones(soft.sum())]),
                             np.column_stack([An[hard], np.zeros(hard.sum())])])
            bub = np.concatenate([bn[soft], bn[hard]])
            cost = np.zeros(n + 1)
            cost[-1] = 1.0
            res = linprog(cost, A_ub=Aub, b_ub=bub, bounds=[(None, None)] * n + [(0, None)],
                          method="highs")
            if res.status == 0:
                return res.x[:n], float(res.x[-1])
        return np.clip(np.zeros(n), self.lo, self.hi), float("inf")

    def x_band(self, x_meas: float) -> tuple[float, float]:
        """True zeta^- consistent with the measurement: ``[x/(1+noise), x/(1-noise)]``."""
        r = self.st.noise
        return x_meas / (1.0 + r), x_meas / (1.0 - r)

    # ------------------------------------------------------------------ polishing
    def _node_grid(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        if n not in self._nodes:
            self._nodes[n] = series_nodes(self.thrust.knots, n)
        return self._nodes[n]

    def _series(self, rw: Rows) -> tuple[RowSeries, dict]:
        """The rows between grid points (:class:`RowSeries`) for the current thrust map and
        its deviation from the exact grid rows ``rw``: built once for ideal thrust (with the
        fewest nodes of ``SERIES_NODES`` whose deviation is within ``SERIES_TOL``), per plan
        for slow thrusters (with that number of nodes)."""
        if self._static is not None and self._static_series is not None:
            return self._static_series
        sizes = SERIES_NODES if self._series_n is None else (self._series_n,)
        scale_x = 2.0 * self.st.zeta_scale
        for n in sizes:
            a, i = self._node_grid(n)
            ser = RowSeries(rows(self.zd, self.terms, self.thrust, a, i), i, self.thrust.knots)
            dev = ser.deviation(rw, self.idx)
            eF = float(dev["P0"].max() + dev["Px"].max() * scale_x
                       + (dev["Pu"] @ self.umax).max())
            eZ = float(dev["z0"] + dev["Zu"] @ self.umax)
            if eF <= SERIES_TOL * self.weight and eZ <= SERIES_TOL * self.st.zeta_scale:
                break
        self._series_n = n
        out = (ser, dev)
        if self._static is not None:
            self._static_series = out
        return out

    def _polish(self, rw: Rows, u: np.ndarray, x_meas: float
                ) -> tuple[dict, np.ndarray, np.ndarray]:
        """The plan's polished extremes (see the class docstring) and the alphas (with their
        knot intervals) where a condition is violated beyond its tolerance at an end of the
        measurement band: ``(margins, alpha, interval)``."""
        st, tol = self.st, self.tolerance
        ser, dev = self._series(rw)
        x_lo, x_hi = self.x_band(x_meas)
        fb = self._thrust_sum(rw)
        eF = float(dev["P0"].max() + dev["Px"].max() * x_hi + (dev["Pu"] @ self.umax).max())
        eZ = float(dev["z0"] + dev["Zu"] @ self.umax)
        E_grid = self.error_bound(rw, x_hi, fb)
        single = x_lo == x_hi and self.terms.fits is None
        views = ([("at_measured", x_meas, True)] if single else
                 [("at_measured", x_meas, False), ("lo", x_lo, True), ("hi", x_hi, True)])
        # q: 0 vertical force (min), 1 friction ratio (max), 2 zeta (min, lowest x only);
        # "badness" is maximised: -F_v, ratio, -zeta; limits in the same sign
        limit = np.array([-st.eps, st.mu, -st.zeta_min])
        tols = np.array([tol["vertical_force"], tol["friction_ratio"], tol["zeta"]])

        def badness(R: Rows, x: np.ndarray, bound: np.ndarray, q: np.ndarray,
                    E: np.ndarray, exact: bool) -> np.ndarray:
            F = R.P0 + R.Px * x[:, None] + np.einsum("gcv,v->gc", R.Pu, u)
            e = np.where(bound, E + (0.0 if exact else eF), 0.0)
            Fv = F[:, 1] - e
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(Fv > 0, (np.abs(F[:, 0]) + e) / Fv, np.inf)
            zeta = self.d2 * x + R.z0 + R.Zu @ u - np.where(bound & (not exact), eZ, 0.0)
            return np.choose(q, [-Fv, ratio, -zeta])

        g = rw.alpha.size
        ent_view, ent_q, ent_j, ent_bad = [], [], [], []
        for v, (_, x, bound) in enumerate(views):
            for q in (0, 1, 2):
                if q == 2 and x != min(vw[1] for vw in views):
                    continue
                bad = badness(rw, np.full(g, x), np.full(g, bound), np.full(g, q),
                              E_grid, True)
                top = float(np.max(np.where(np.isfinite(bad), bad, -np.inf), initial=-np.inf))
                floor = min(limit[q], top) - grid_miss(bad, self.idx)
                j = peaks(bad, self.idx, floor, PEAKS)
                ent_view += [v] * j.size
                ent_q += [q] * j.size
                ent_j.append(j)
                ent_bad.append(bad[j])
        ent_view, ent_q = np.array(ent_view, int), np.array(ent_q, int)
        ent_j, grid_bad = np.concatenate(ent_j), np.concatenate(ent_bad)
        xs = np.array([views[v][1] for v in ent_view])
        bnd = np.array([views[v][2] for v in ent_view], bool)
        interval = self.idx[ent_j]
        # the series of the quantities needed, for this u: columns F^h(x=0), dF^h/dx,
        # F^v(x=0), dF^v/dx, zeta(x=0), z0, Zu (fitted terms' error bound)
        lay = ser.layout
        K = sum(sl.stop - sl.start for sl, _ in lay.values())
        M = np.zeros((K, 5 + 1 + self.nu))
        P0, Px, Pu = lay["P0"][0], lay["Px"][0], lay["Pu"][0]
        for c in (0, 1):
            M[P0.start + c, 2 * c] = 1.0
            M[Px.start + c, 2 * c + 1] = 1.0
            M[Pu.start + c * self.nu:Pu.start + (c + 1) * self.nu, 2 * c] = u
        z0s, Zus = lay["z0"][0], lay["Zu"][0]
        M[z0s.start, 4] = M[z0s.start, 5] = 1.0
        M[Zus, 4] = u
        M[Zus, 6:] = np.eye(self.nu)
        at = ser.at(interval, M)
        fitted = self.terms.fits is not None
        e_fix = np.where(bnd, eF, 0.0)
        z_fix = self.d2 * xs - np.where(bnd, eZ, 0.0)
        e0, e1, e2 = self.terms.errors
        q0, q1 = ent_q == 0, ent_q == 1

        def objective(a: np.ndarray) -> np.ndarray:
            V = at(a)
            Fh = V[:, 0] + xs * V[:, 1]
            e = e_fix
            if fitted:
                zb = np.abs(V[:, 5]) + np.abs(V[:, 6:]) @ self.umax + self.d2 * x_hi
                e = e_fix + np.where(bnd, e0 + e1 * zb + e2 * fb, 0.0)
            Fv = V[:, 2] + xs * V[:, 3] - e
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(Fv > 0, (np.abs(Fh) + e) / Fv, np.inf)
            val = np.where(q0, -Fv, np.where(q1, ratio, -(V[:, 4] + z_fix)))
            return np.where(np.isfinite(val), -val, 1e300)

        lo, hi = neighbours(rw.alpha, ent_j, self.idx)
        a_pol, f_pol = golden_min(objective, lo, hi, POLISH_ITERATIONS)
        better = -f_pol > grid_bad
        worst = np.where(better, -f_pol, grid_bad)
        where = np.where(better, a_pol, rw.alpha[ent_j])

        def extreme(names: tuple[str, ...], q: int) -> tuple[float, float | None]:
            sel = np.isin(ent_view, [i for i, vw in enumerate(views) if vw[0] in names]) & (
                ent_q == q)
            if not sel.any():
                return -np.inf, None
            k = np.flatnonzero(sel)[np.argmax(worst[sel])]
            return float(worst[k]), float(where[k])

        bound_names = ("at_measured",) if single else ("lo", "hi")
        v_meas, _ = extreme(("at_measured",), 0)
        r_meas, _ = extreme(("at_measured",), 1)
        v_b, a_v = extreme(bound_names, 0)
        r_b, a_r = extreme(bound_names, 1)
        z_b, a_z = extreme(bound_names, 2)
        margins = {
            "min_vertical_force": -v_meas, "max_friction_ratio": r_meas,
            "min_vertical_force_bound": -v_b, "max_friction_ratio_bound": r_b,
            "alpha_at_min_vertical_force": a_v, "alpha_at_max_friction_ratio": a_r,
            "min_zeta_bound": -z_b, "alpha_at_min_zeta": a_z,
            "fit_error_bound": float(np.max(E_grid, initial=0.0)),
            "interpolation_error": eF,
            "feasible": bool(-v_b >= st.eps - tol["vertical_force"]
                             and r_b <= st.mu + tol["friction_ratio"]),
            "polished": True,
        }
        viol = bnd & (worst > limit[ent_q] + tols[ent_q])
        if not single:
            viol &= ent_view > 0
        a_cut, i_cut = where[viol], interval[viol]
        if a_cut.size:
            key = np.round(a_cut / (abs(self.alpha[-1] - self.alpha[0]) * 1e-12))
            _, first = np.unique(np.stack([key, i_cut]), axis=1, return_index=True)
            a_cut, i_cut = a_cut[first], i_cut[first]
        return margins, a_cut, i_cut

    # ------------------------------------------------------------------ planning
    def _run(self, x_meas: float, x_ref: float, u_prev: np.ndarray | None, steady: bool):
        """Solve (slow thrusters: with the time map iterated to a fixed point), then, with
        continuous conditions, polish and add cutting planes until no polished point
        violates."""
        dyn = self.thrust.dynamic
        th = self.thrust
        u = np.clip(u_prev, self.lo, self.hi) if dyn else None
        cut_a, cut_i = np.zeros(0), np.zeros(0, int)
        cut_rows = None
        margins = None
        iterations = rounds = 0
        step_time = None
        t_qp = t_pol = 0.0
        status, target, act, viol = "tracking", x_ref, [], 0.0
        stops = None
        if dyn:  # the first guess: zeta of the unthrusted step, at least zeta_min
            z0 = self.d2 * x_meas + th.V0n
            th.update(np.maximum(z0, max(self.st.zeta_min, 1e-2 * float(np.max(z0)))))
        for _ in range(MAX_RESPONSE_ITER + MAX_CUT_ROUNDS):
            iterations += 1
            if dyn:
                try:
                    step_time = th.update(th.zeta_nodes(x_meas, u))
                except StepStops as exc:
                    if iterations > 1:  # the plan's own step stops: no step to predict
                        stops = str(exc)
                        break
                    # the previous setpoint's step stops: plan on the guess's time map
                cut_rows = None
            rw = self.grid_rows()
            t0 = time.perf_counter()
            if cut_a.size and cut_rows is None:
                cut_rows = rows(self.zd, self.terms, self.thrust, cut_a, cut_i)
            t1 = time.perf_counter()
            aug = rw if cut_rows is None else cut_rows.concat(rw)
            u_new, status, target, act, viol = self._solve(aug, x_meas, x_ref, u_prev, steady)
            t2 = time.perf_counter()
            t_pol += t1 - t0
            t_qp += t2 - t1
            if u_new is None:  # steady state out of reach
                return None, status, target, act, viol, rw, None, cut_a, iterations, rounds, \
                    step_time, t_qp, t_pol
            settled = not dyn or np.max(np.abs(u_new - u), initial=0.0) <= (
                1e-9 * self.st.force_scale)
            u = u_new
            margins = None
            if not settled:
                continue
            if not self.st.continuous or status == "infeasible":
                break
            margins, new_a, new_i = self._polish(rw, u, x_meas)
            t_pol += time.perf_counter() - t2
            if new_a.size == 0 or rounds == MAX_CUT_ROUNDS:
                break
            cut_a, cut_i = np.concatenate([cut_a, new_a]), np.concatenate([cut_i, new_i])
            cut_rows = None
            rounds += 1
        if dyn and stops is None:
            try:
                step_time = th.update(th.zeta_nodes(x_meas, u))
            except StepStops as exc:
                stops = str(exc)
            rw = self.grid_rows()
            margins = None
        if stops is not None:  # planned on the last time map that exists; not certified
            status, act, margins = "infeasible", [f"no time map: {stops}"], None
        if self.st.continuous and margins is None:
            t0 = time.perf_counter()
            margins = self._polish(rw, u, x_meas)[0]
            t_pol += time.perf_counter() - t0
        return (u, status, target, act, viol, rw, margins, cut_a, iterations, rounds,
                step_time, t_qp, t_pol)

    def steady(self, x: float) -> tuple[np.ndarray | None, dict | None]:
        """The controller's own steady state at zeta^- = ``x`` [kg^2 m^4/s^2] (ideal thrust):
        the thrust it settles on when ``x_k = x_{k+1} = x_ref = x`` — the least-effort values
        under every contact row (continuous with ``settings.continuous``, with the cutting
        planes), the thrust bounds and zeta_min, the measurement band of ``x`` included (the
        smoothing term vanishes and the rate limit is slack at a fixed point; without an
        effort weight every fixed point is a steady state, and the least-effort one is taken).
        Returns ``(u, margins)``, u None when no thrust holds ``x``."""
        if self.thrust.dynamic:
            raise ValueError("the steady state is defined for ideal thrust")
        out = self._run(x, x, None, steady=True)
        return out[0], out[6]

    def steady_range(self) -> tuple[float, float] | None:
        """The zeta^- that some thrust holds in the steady state ``x_{k+1} = x_k = x`` under the
        grid rows [kg^2 m^4/s^2] (an interval: the rows are jointly affine in ``(x, u)``; two
        LPs, HiGHS); None when there is none. The continuous conditions (cutting planes)
        shrink it by at most the grid's miss."""
        rw = self._static if self._static is not None else self.grid_rows()
        A, b0, bx, _ = self.contact_rows(rw, 0.0)
        r = self.st.noise
        g, z0f = rw.Zu[-1], float(rw.z0[-1])
        # A u <= b0 + min(bx x/(1+r), bx x/(1-r)) for x > 0: two rows per row
        Ax = np.vstack([np.column_stack([A, -bx / (1.0 + r)]),
                        np.column_stack([A, -bx / (1.0 - r)])])
        bb = np.concatenate([b0, b0])
        n = self.nu
        eye = np.eye(n)
        Ab = np.vstack([Ax, np.column_stack([eye, np.zeros(n)]),
                        np.column_stack([-eye, np.zeros(n)])])
        bb = np.concatenate([bb, self.hi, -self.lo])
        An, bn, _, const = normalise_rows(Ab, bb)
        if np.any(bn[const] < 0):
            return None
        a_eq = np.r_[g, self.d2 - 1.0][None, :]
        cap = 1e3 * self.st.zeta_scale
        out = []
        for sign in (1.0, -1.0):
            cost = np.zeros(n + 1)
            cost[-1] = sign
            res = linprog(cost, A_ub=An[~const], b_ub=bn[~const], A_eq=a_eq, b_eq=[-z0f],
                          bounds=[(None, None)] * n + [(0.0, cap)], method="highs")
            if res.status != 0:
                return None
            out.append(float(res.x[-1]))
        return out[0], out[1]

    def plan(self, x_meas: float, x_ref: float, u_prev: np.ndarray,
             z: np.ndarray | None = None) -> Plan:
        """Step k's thrust from the measured ``x_meas`` [kg^2 m^4/s^2], the reference
        ``x_ref`` for ``x_{k+1}`` and ``u_prev``; ``z``: thruster states at the impact (slow
        thrusters)."""
        if self.thrust.dynamic:
            th = self.thrust
            th.start(z if z is not None else np.zeros(th.dyn.n_states))
        (u, status, target, act, viol, rw, margins, cut_a, iterations, rounds, step_time,
         t_qp, t_pol) = self._run(x_meas, x_ref, u_prev, steady=False)
        lo, hi = self.x_band(x_meas)
        g = rw.Zu[-1]
        energy = None
        if self.powers is not None:
            energy = self._energy_info or {
                "status": "not planned", "reason": f"a step {status}: the least violation of its "
                                                   "rows is applied, no energy plan",
                "effort_plan_energy": None, "solver": None, "iterations": None,
                "kkt_stationarity": None}
            e = predicted_energy(self.zd, self.thrust, self.powers, x_meas, u)
            energy = {"energy": e, **energy}
            if e is None:
                energy["reason"] += "; the predicted step comes to rest: no energy"
        xn = float(self.d2 * x_meas + rw.z0[-1] + g @ u)
        band = (float(self.d2 * lo + rw.z0[-1] + g @ u), float(self.d2 * hi + rw.z0[-1] + g @ u))
        return Plan(u=u, status=status, x_meas=float(x_meas), x_ref=float(x_ref),
                    x_target=float(target), x_next=xn, x_next_band=band, x_band=(lo, hi),
                    active=act, qp_time=t_qp, rows=rw, step_time=step_time,
                    iterations=iterations if self.thrust.dynamic else 1, violation=viol,
                    margins=margins, cut_alpha=cut_a, cut_rounds=rounds, polish_time=t_pol,
                    energy=energy)


def predicted_margins(plan: Plan, rw: Rows, mu: float, E: np.ndarray, eps: float = 0.0
                      ) -> dict:
    """Predicted worst vertical force [N] and friction ratio [1] on the rows' alpha (grid
    values, not polished), at the measured ``x`` and over the measurement band (the worse end),
    with the fit error bound ``E`` [N] (the friction ratio bound uses ``(|F^h| + E)/(F^v -
    E)``). For a planner without continuous conditions (:attr:`Plan.margins` is None)."""
    out = {}
    for name, x, e in (("at_measured", plan.x_meas, 0.0), ("lo", plan.x_band[0], E),
                       ("hi", plan.x_band[1], E)):
        F = rw.force(x, plan.u)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(F[:, 1] - e > 0, (np.abs(F[:, 0]) + e) / (F[:, 1] - e), np.inf)
        out[name] = (float((F[:, 1] - e).min()), float(ratio.max()))
    worst_v = min(out["lo"][0], out["hi"][0])
    worst_r = max(out["lo"][1], out["hi"][1])
    return {"min_vertical_force": out["at_measured"][0],
            "max_friction_ratio": out["at_measured"][1],
            "min_vertical_force_bound": worst_v, "max_friction_ratio_bound": worst_r,
            "fit_error_bound": float(np.max(E, initial=0.0)),
            "feasible": bool(worst_v >= eps and worst_r <= mu), "polished": False}


def regulator(zd: ZeroDynamics, knots: np.ndarray, driven: list[int], *, mu: float,
              eps: float = 0.0, zeta_min: float | None = None, max_thrust: float | None = None,
              rate_limit: float | None = None, tracking_weight: float | None = None,
              effort_weight: float = 1.0, rate_weight: float = 0.0, noise: float = 0.0,
              points: int = 401, terms: Terms | None = None,
              thrust: IdealThrust | ResponseThrust | None = None, continuous: bool = False,
              objective: str = "effort") -> tuple[Planner, LimitCycle]:
    """The SPEC 11 planner of ``thrustwalk control`` for thrust on ``knots`` [rad] (alpha
    values) of the ``driven`` thrusters, and the zero-thrust periodic orbit it is scaled by
    (and regulates to with the reference ``nominal``). Thrust bounds: the robot file's
    ``limits`` of each driven thruster, within ``max_thrust`` [N]; they must include 0 N.
    ``zeta_min`` default: 1 % of the nominal zeta*. ``thrust`` default: ideal thrust on the
    knots; ``terms`` default: the exact Lambda terms. ``continuous``: hold and certify the
    contact conditions between the grid points too (:class:`Planner`). ``objective``:
    ``effort`` or ``energy`` (:class:`Settings`)."""
    model, robot = zd.model, zd.model.robot
    if not zd.valid:
        raise InputError.param("gait", f"the gait has no walking orbit to control: "
                                       f"{zd.invalid_reason}")
    lc0 = zd.nominal_cycle()
    if not lc0.exists:
        raise InputError.param("gait", f"no zero-thrust periodic orbit to start from or "
                                       f"regulate to: {lc0.reason}")
    lo = np.array([robot.thrusters[t].limits[0] for t in driven], float)
    hi = np.array([robot.thrusters[t].limits[1] for t in driven], float)
    if max_thrust is not None:
        lo, hi = np.maximum(lo, -max_thrust), np.minimum(hi, max_thrust)
    if np.any(lo > 0) or np.any(hi < 0):
        raise InputError.param("thruster", "the thrust limits must include 0 N (the "
                                           "uncontrolled walker and the start)")
    force_scale = float(max(np.max(np.abs(lo)), np.max(np.abs(hi)), 1.0))
    zs0 = float(lc0.zeta_star)
    st = Settings(mu=float(mu), eps=float(eps),
                  zeta_min=0.01 * zs0 if zeta_min is None else float(zeta_min), lo=lo, hi=hi,
                  rate=rate_limit, tracking=tracking_weight, effort=float(effort_weight),
                  smooth=float(rate_weight), noise=float(noise), points=int(points),
                  zeta_scale=zs0, force_scale=force_scale, continuous=bool(continuous),
                  objective=objective)
    terms = Terms(model, zd) if terms is None else terms
    thrust = IdealThrust(zd, np.asarray(knots, float), driven) if thrust is None else thrust
    return Planner(zd, terms, thrust, st), lc0
