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
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from ..contact.terms import impact_data
from ..errors import InputError
from ..hzd.zero_dynamics import LimitCycle, Schedule, ZeroDynamics, limit_cycles
from ..optimize.qp import ConvexQP, normalise_rows
from .step_model import IdealThrust, ResponseThrust, Rows, Terms, rows, step_grid

FAMILIES = ("vertical_force", "friction", "zeta_min", "thrust_bounds", "rate_limit")
MAX_RESPONSE_ITER = 12  # fixed-point iterations of the slow-thruster time map


@dataclass(frozen=True)
class Settings:
    """The QP's data (SPEC 11). ``mu`` [1], ``eps`` [N], ``zeta_min`` [kg^2 m^4/s^2], ``lo``/
    ``hi`` thrust bounds per driven thruster [N], ``rate`` [N per step] or None, weights
    dimensionless (``tracking`` None: tracking first), ``noise`` relative bound of the
    measurement error of zeta^- [1], ``points`` alpha grid size."""

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


@dataclass
class Plan:
    """One step's decision: thrust values ``u`` [N] (interval-major, per driven thruster),
    ``status`` (``tracking``: the reference is met; ``saturated``: met as closely as the
    constraints allow; ``infeasible``: the constraints cannot hold, least violation applied),
    predicted ``x_next`` [kg^2 m^4/s^2] with its band over the measurement interval, the
    active constraint families, the QP time [s] and the model rows on the grid."""

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


class Planner:
    """Builds and solves the SPEC 11 QP step after step (the controller's model side)."""

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
        imp = impact_data(zd.model, zd)
        self.impact_ok = imp.admissible(st.mu)
        self.impact_reasons = imp.reasons(st.mu)
        self.lo = np.tile(st.lo, len(kn) - 1)
        self.hi = np.tile(st.hi, len(kn) - 1)
        self._static = None if thrust.dynamic else rows(zd, terms, thrust, self.alpha,
                                                        self.idx)
        self._qp_cache: dict = {}
        self._rows_cache: tuple | None = None
        self.nu = nu

    # ------------------------------------------------------------------ constraint rows
    def error_bound(self, rw: Rows, x_hi: float) -> np.ndarray:
        """Bound on the error of ``F_1`` from the fitted terms at the rows' alpha [N] (0 with the
        exact terms): ``e_0 + e_1 max|zeta| + e_2 sum_t max|F_t|`` with ``e_k`` the fits' maximum
        errors and the maxima over every allowed thrust and ``x_k <= x_hi``."""
        if self.terms.fits is None:
            return np.zeros(rw.alpha.size)
        umax = np.maximum(np.abs(self.lo), np.abs(self.hi))
        zb = np.abs(rw.z0) + np.abs(rw.Zu) @ umax + self.d2 * x_hi
        fb = float(np.sum(np.abs(rw.f0).max(axis=0) + np.abs(rw.S).max(axis=0) @ umax))
        e0, e1, e2 = self.terms.errors
        return e0 + e1 * zb + e2 * fb

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

    def constraints(self, rw: Rows, x_lo: float, x_hi: float, u_prev: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``A u <= b`` holding for every ``x_k`` in ``[x_lo, x_hi]`` (each row at the worse
        end: it is affine in ``x_k``), with thrust bounds and rate limits; and the family of
        each row."""
        key = (id(rw), x_hi if self.terms.fits is not None else None)
        if self._rows_cache is not None and self._rows_cache[0] == key:
            A, b0, bx, fam = self._rows_cache[1]
        else:
            A, b0, bx, fam = self.contact_rows(rw, x_hi)
            eye = np.eye(self.nu)
            A = np.vstack([A, eye, -eye] + ([eye, -eye] if self.st.rate is not None else []))
            fam = np.concatenate([fam, ["thrust_bounds"] * (2 * self.nu)]
                                 + ([["rate_limit"] * (2 * self.nu)] if self.st.rate is not None
                                    else []))
            if self._static is not None:
                self._rows_cache = (key, (A, b0, bx, fam))
        b = b0 + np.minimum(bx * x_lo, bx * x_hi)
        parts = [b, self.hi, -self.lo]
        if self.st.rate is not None:
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
    def _qp(self, key: str, H: np.ndarray, A: np.ndarray, a_eq: np.ndarray | None
            ) -> ConvexQP:
        """Cached factorisations (the matrices are fixed for ideal thrusters)."""
        qp = self._qp_cache.get(key) if self._static is not None else None
        if qp is None:
            qp = ConvexQP(H, A, a_eq)
            if self._static is not None:
                self._qp_cache[key] = qp
        return qp

    def _solve(self, rw: Rows, x_meas: float, x_ref: float, u_prev: np.ndarray
               ) -> tuple[np.ndarray, str, float, list[str], float]:
        st = self.st
        x_lo, x_hi = self.x_band(x_meas)
        A, b, fam = self.constraints(rw, x_lo, x_hi, u_prev)
        g = rw.Zu[-1]  # x_{k+1} = d2 x + z0(alpha_f) + g u
        base = self.d2 * x_meas + rw.z0[-1]
        H = 2.0 * self.W  # W holds the effort and the smoothing weights
        c = -2.0 * self.R * u_prev
        active: np.ndarray
        if st.tracking is None:
            qp = self._qp(f"eq{A.shape[0]}", H, A, g)
            u, active = qp.solve(c, b, x_ref - base)
            status, target = "tracking", x_ref
            if u is None:
                free = self._qp(f"free{A.shape[0]}", H, A, None)
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
        else:
            w = st.tracking / st.zeta_scale**2
            Ht = H + 2.0 * w * np.outer(g, g)
            ct = c - 2.0 * w * g * (x_ref - base)
            qp = self._qp(f"soft{A.shape[0]}", Ht, A, None)
            u, active = qp.solve(ct, b)
            if u is None:
                u, viol = self._least_violation(A, b, fam)
                return u, "infeasible", float(base + g @ u), ["infeasible"], viol
            target = float(base + g @ u)
            status = ("saturated" if active.size and abs(target - x_ref) > 1e-9 * max(
                abs(x_ref), 1.0) else "tracking")
        act = sorted({str(f) for f in fam[active]})
        return u, status, float(target), act, 0.0

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

    def plan(self, x_meas: float, x_ref: float, u_prev: np.ndarray,
             z: np.ndarray | None = None) -> Plan:
        """Step k's thrust from the measured ``x_meas`` [kg^2 m^4/s^2], the reference
        ``x_ref`` for ``x_{k+1}`` and ``u_prev``; ``z``: thruster states at the impact (slow
        thrusters)."""
        t0 = time.perf_counter()
        iterations = 1
        step_time = None
        if self.thrust.dynamic:
            th = self.thrust
            th.start(z if z is not None else np.zeros(th.m * th.dyn.n_states))
            u = np.clip(u_prev, self.lo, self.hi)
            step_time = th.update(np.maximum(self.d2 * x_meas + th.V0n, 0.0) + 0.0)
            for iterations in range(1, MAX_RESPONSE_ITER + 1):  # noqa: B007
                step_time = th.update(th.zeta_nodes(x_meas, u))
                rw = self.grid_rows()
                u_new, status, target, act, viol = self._solve(rw, x_meas, x_ref, u_prev)
                done = np.max(np.abs(u_new - u), initial=0.0) <= 1e-9 * self.st.force_scale
                u = u_new
                if done:
                    break
            step_time = th.update(th.zeta_nodes(x_meas, u))
            rw = self.grid_rows()
        else:
            rw = self.grid_rows()
            u, status, target, act, viol = self._solve(rw, x_meas, x_ref, u_prev)
        qp_time = time.perf_counter() - t0
        lo, hi = self.x_band(x_meas)
        g = rw.Zu[-1]
        xn = float(self.d2 * x_meas + rw.z0[-1] + g @ u)
        band = (float(self.d2 * lo + rw.z0[-1] + g @ u), float(self.d2 * hi + rw.z0[-1] + g @ u))
        return Plan(u=u, status=status, x_meas=float(x_meas), x_ref=float(x_ref),
                    x_target=float(target), x_next=xn, x_next_band=band, x_band=(lo, hi),
                    active=act, qp_time=qp_time, rows=rw, step_time=step_time,
                    iterations=iterations, violation=viol)


def predicted_margins(plan: Plan, rw: Rows, mu: float, E: np.ndarray) -> dict:
    """Predicted worst vertical force [N] and friction ratio [1] over the rows' alpha, at the
    measured ``x`` and over the measurement band (the worse end), with the fit error bound
    ``E`` [N] (the friction ratio bound uses ``(|F^h| + E)/(F^v - E)``)."""
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
            "feasible": bool(worst_v >= 0 and worst_r <= mu)}


def regulator(zd: ZeroDynamics, knots: np.ndarray, driven: list[int], *, mu: float,
              eps: float = 0.0, zeta_min: float | None = None, max_thrust: float | None = None,
              rate_limit: float | None = None, tracking_weight: float | None = None,
              effort_weight: float = 1.0, rate_weight: float = 0.0, noise: float = 0.0,
              points: int = 401, terms: Terms | None = None,
              thrust: IdealThrust | ResponseThrust | None = None
              ) -> tuple[Planner, LimitCycle]:
    """The SPEC 11 planner of ``thrustwalk control`` for thrust on ``knots`` [rad] (alpha
    values) of the ``driven`` thrusters, and the zero-thrust periodic orbit it is scaled by
    (and regulates to with the reference ``nominal``). Thrust bounds: the robot file's
    ``limits`` of each driven thruster, within ``max_thrust`` [N]; they must include 0 N.
    ``zeta_min`` default: 1 % of the nominal zeta*. ``thrust`` default: ideal thrust on the
    knots; ``terms`` default: the exact Lambda terms."""
    model, robot = zd.model, zd.model.robot
    if not zd.valid:
        raise InputError.param("gait", f"the gait has no walking orbit to control: "
                                       f"{zd.invalid_reason}")
    lc0 = limit_cycles(zd, Schedule.constant(zd, np.zeros((1, model.n_thrusters))))[0]
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
                  zeta_scale=zs0, force_scale=force_scale)
    terms = Terms(model, zd) if terms is None else terms
    thrust = IdealThrust(zd, np.asarray(knots, float), driven) if thrust is None else thrust
    return Planner(zd, terms, thrust, st), lc0
