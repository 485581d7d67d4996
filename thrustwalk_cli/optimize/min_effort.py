"""Minimum-effort thrust schedules as an exact convex QP (SPEC section 6).

Decision variables: one thrust value per knot interval, ``x_j`` = physical thrust ``F_j`` [N] of
one thruster (force mode) or the generalised force ``T_j`` on q_N [N m] (generalised mode).

    minimise   sum_j w_j x_j^2       (w_j: alpha-length [rad] or nominal time [s] of interval j)
    subject to (1 - delta_zero^2) zeta* = V_0(alpha_f) + sum_j g_j x_j          (fixed point)
               zeta(alpha) = delta_zero^2 zeta* + V_0(alpha) + sum_j c_j(alpha) x_j >= zeta_min
               F_1^v(alpha) >= eps,  |F_1^h(alpha)| <= mu F_1^v(alpha)          (alpha grid)
               lo_j <= x_j <= hi_j

with ``g_j = Gamma_j`` (``b_F`` in generalised mode) and ``c_j(alpha)`` the part of interval j
integrated up to alpha (SPEC 4); ``F_1 = Lambda_2 F + Lambda_1 zeta + Lambda_0`` (SPEC 5). Every
constraint is affine in ``(x, zeta*)``. Impact admissibility does not depend on the schedule
(thrust is not impulsive) and is checked first.

Solution, exactly: feasibility is decided by a linear programme (HiGHS). The QP is then a
least-distance problem (``y = sqrt(w) x``; the equality is eliminated on its null space) solved
by Lawson-Hanson NNLS, a finite active-set method; the KKT conditions are verified with
multipliers from NNLS on the active set. A primal active-set method (``active_set_qp``) solves the
same problem independently (used as a fallback and in the tests). An infeasible problem is
reported with the constraint families whose removal makes it feasible.

The contact conditions are imposed on an alpha grid (knots from both sides); the solution is
then re-checked between grid points (golden-section polish of the worst points, SPEC 5) and any
violated point is added as a new row (an exchange method for the semi-infinite constraints),
until the re-check passes. Contact rows carry a relative margin of 1e-9 so that an active
constraint does not end up on the wrong side by rounding.

A target speed is not linear in the thrust: it is met by a 1-D root search over zeta* along the
minimum-effort schedules (each one an exact QP), inside the reachable zeta* range from two LPs.

The LP / QP solvers and the KKT check are in :mod:`thrustwalk_cli.optimize.qp`; the command's
study (parameter checks, records, gait file) in :mod:`thrustwalk_cli.studies.optimize`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from itertools import combinations

import numpy as np
from scipy.optimize import linprog

from ..contact.evaluate import CaseResult, evaluate, step_grid
from ..contact.terms import fit_terms, impact_data, stance_terms
from ..errors import ComputationError, InputError
from ..hzd.quadrature import integrate, lobatto
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics, limit_cycles
from ..model.compiled import CompiledModel
from ..thrust.schedule import Schedule
from .qp import active_set_qp, kkt, ldp_qp, lp_feasible, normalise_rows

FAMILIES = {
    "fixed_point": "fixed-point equation (1 - delta_zero^2) zeta* = V_Z(alpha_f) (the target)",
    "vertical_force": "vertical ground force F_1^v >= eps along the step",
    "friction": "friction cone |F_1^h| <= mu F_1^v along the step",
    "zeta_min": "zeta(alpha) >= zeta_min along the step (the walker keeps moving)",
    "thrust_bounds": "thrust bounds",
    "impact": "impact admissibility (independent of the schedule: thrust is not impulsive)",
    "orbit": "a stable periodic orbit (0 < delta_zero^2 < 1, kappa_1 of one sign)",
}


KKT_TOL = 1e-7


MAX_EXCHANGE = 8


@dataclass(frozen=True)
class LinearProblem:
    """SPEC 6 constraints, affine in ``(x, zeta*)``.

    Inequalities ``A x + z zeta* <= b`` (rows labelled by ``family``, ``alpha`` [rad] (NaN-free:
    bounds use the interval's start) and ``detail``); equality ``a_eq x + z_eq zeta* = b_eq``.
    ``weights`` [rad or s]; ``lo``, ``hi`` thrust bounds [N or N m].
    """

    knots: np.ndarray
    mode: str
    thruster: int
    weights: np.ndarray
    A: np.ndarray
    z: np.ndarray
    b: np.ndarray
    family: np.ndarray
    alpha: np.ndarray
    detail: tuple[str, ...]
    a_eq: np.ndarray
    z_eq: float
    b_eq: float
    lo: np.ndarray
    hi: np.ndarray
    impact_ok: bool
    impact_reasons: tuple[str, ...]
    spec: _RowSpec | None = field(default=None, repr=False)

    @property
    def n(self) -> int:
        """The number of unknowns ``x`` (columns of ``A``; SPEC 6)."""
        return self.A.shape[1]

    def at(self, zeta_star: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Inequalities and equality with zeta* fixed: ``A x <= b``, ``a_eq x = b_eq``."""
        return self.A, self.b - self.z * zeta_star, self.a_eq, self.b_eq - self.z_eq * zeta_star

    def schedule(self, x: np.ndarray, m: int) -> Schedule:
        """The thrust schedule for values ``x`` (one schedule in the batch)."""
        n = len(x)
        force = np.zeros((1, n, m))
        gen = np.zeros((1, n))
        if self.mode == "force":
            force[0, :, self.thruster] = x
        else:
            gen[0] = x
        return Schedule(self.knots, force, gen)


MARGIN = 1e-9  # relative safety margin so that an active constraint's rounding stays inside


@dataclass(frozen=True)
class _RowSpec:
    """What the contact/zeta rows need (kept on the problem to add rows at new points)."""

    model: CompiledModel
    zd: ZeroDynamics
    mu: float
    eps: float
    zeta_min: float
    zeta_min_rel: float


def _contact_rows(spec: _RowSpec, kn: np.ndarray, mode: str, thruster: int,
                  alpha: np.ndarray, idx: np.ndarray, with_zeta: bool = True) -> tuple:
    """Rows ``A x + z zeta* <= b`` of the contact (and zeta) conditions at points ``alpha``
    belonging to knot intervals ``idx``: F_1 = P + Zc zeta* + X x (SPEC 5, 6)."""
    zd = spec.zd
    n = len(kn) - 1
    t = stance_terms(spec.model, zd.maps, alpha)
    d2 = zd.delta_zero_sq
    cum_k = _cum_at(zd, mode, thruster, kn)
    per = t.L2[:, :, thruster] if mode == "force" else t.LT  # (g, 2) per unit x
    lo_k, hi_k = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
    c = np.zeros((len(alpha), n))
    for j in range(n):
        c[:, j] = _cum_at(zd, mode, thruster, np.clip(alpha, lo_k[j], hi_k[j])) - cum_k[j]
    V0 = zd.V0(alpha)
    onehot = np.zeros((len(alpha), n))
    onehot[np.arange(len(alpha)), idx] = 1.0
    X = t.L1[:, :, None] * c[:, None, :] + per[:, :, None] * onehot[:, None, :]  # (g, 2, n)
    P = t.L0 + t.L1 * V0[:, None]  # (g, 2)
    Zc = t.L1 * d2  # (g, 2)
    h, v = 0, 1
    mu = spec.mu * (1.0 - MARGIN)
    eps = spec.eps + MARGIN * spec.model.robot.total_mass * spec.model.robot.gravity
    g = len(alpha)
    A = [-X[:, v, :], X[:, h, :] - mu * X[:, v, :], -X[:, h, :] - mu * X[:, v, :]]
    z = [-Zc[:, v], Zc[:, h] - mu * Zc[:, v], -Zc[:, h] - mu * Zc[:, v]]
    b = [P[:, v] - eps, -(P[:, h] - mu * P[:, v]), P[:, h] + mu * P[:, v]]
    fam = ["vertical_force"] * g + ["friction"] * (2 * g)
    det = ["F_1^v >= eps"] * g + ["F_1^h <= mu F_1^v"] * g + ["-F_1^h <= mu F_1^v"] * g
    al = [alpha] * 3
    if with_zeta:
        A.append(-c)
        z.append(-np.full(g, d2 - spec.zeta_min_rel))
        b.append(V0 - spec.zeta_min)
        fam += ["zeta_min"] * g
        det += ["zeta >= zeta_min"] * g
        al.append(alpha)
    return np.vstack(A), np.concatenate(z), np.concatenate(b), fam, np.concatenate(al), det


def build_problem(model: CompiledModel, zd: ZeroDynamics, fractions: np.ndarray, *,
                  mode: str = "force", thruster: int = 0, mu: float, eps: float = 0.0,
                  zeta_min: float = 0.0, zeta_min_rel: float = 0.0,
                  bounds: tuple[np.ndarray, np.ndarray], weights: str = "alpha",
                  points: int = 201) -> LinearProblem:
    """Assemble the SPEC 6 constraints on an alpha grid (knots included from both sides).

    ``zeta(alpha) >= zeta_min + zeta_min_rel zeta*`` [kg^2 m^4/s^2]; ``bounds`` per interval.
    The contact rows carry a relative margin ``MARGIN`` (mu (1 - MARGIN), eps + MARGIN m g).
    """
    fr = np.asarray(fractions, float)
    kn = zd.alpha_i + fr * (zd.alpha_f - zd.alpha_i)
    n = len(kn) - 1
    alpha, idx = step_grid(kn, points)
    spec = _RowSpec(model, zd, mu, eps, zeta_min, zeta_min_rel)
    A, z, b, fam, al, det = _contact_rows(spec, kn, mode, thruster, alpha, idx)
    lo, hi = bounds
    A = np.vstack([A, np.eye(n), -np.eye(n)])
    z = np.concatenate([z, np.zeros(2 * n)])
    b = np.concatenate([b, np.asarray(hi, float), -np.asarray(lo, float)])
    fam = fam + ["thrust_bounds"] * (2 * n)
    al = np.concatenate([al, kn[:-1], kn[:-1]])
    det = (det + [f"x_{j + 1} <= upper bound" for j in range(n)]
           + [f"x_{j + 1} >= lower bound" for j in range(n)])
    g = np.diff(_cum_at(zd, mode, thruster, kn))
    imp = impact_data(model, zd)
    if weights == "alpha":
        w = np.abs(np.diff(kn))
    elif weights == "time":
        w = _interval_times(zd, kn)
    else:
        raise InputError.param("weights", f"expected 'alpha' or 'time', got {weights!r}")
    return LinearProblem(
        knots=kn, mode=mode, thruster=thruster, weights=w, A=A, z=z, b=b,
        family=np.array(fam), alpha=al, detail=tuple(det), a_eq=g, z_eq=-(1.0 - zd.delta_zero_sq),
        b_eq=-float(zd.V0(np.array(zd.alpha_f))), lo=np.asarray(lo, float),
        hi=np.asarray(hi, float), impact_ok=imp.admissible(mu),
        impact_reasons=tuple(imp.reasons(mu)), spec=spec)


def add_points(prob: LinearProblem, alpha: np.ndarray) -> LinearProblem:
    """The problem with contact and zeta rows added at ``alpha`` (each point in every knot
    interval that contains it): the exchange step that enforces the conditions between grid
    points."""
    kn = prob.knots
    lo_k, hi_k = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
    pts, ids = [], []
    for a in np.atleast_1d(alpha):
        for j in np.flatnonzero((lo_k <= a) & (a <= hi_k)):
            pts.append(a)
            ids.append(j)
    if not pts:
        return prob
    A, z, b, fam, al, det = _contact_rows(prob.spec, kn, prob.mode, prob.thruster,
                                          np.array(pts), np.array(ids))
    return replace(prob, A=np.vstack([prob.A, A]), z=np.concatenate([prob.z, z]),
                   b=np.concatenate([prob.b, b]),
                   family=np.concatenate([prob.family, np.array(fam)]),
                   alpha=np.concatenate([prob.alpha, al]), detail=prob.detail + tuple(det))


def _cum_at(zd: ZeroDynamics, mode: str, thruster: int, alpha: np.ndarray) -> np.ndarray:
    return zd.Gamma(alpha)[:, thruster] if mode == "force" else zd.B(alpha)


def _interval_times(zd: ZeroDynamics, kn: np.ndarray) -> np.ndarray:
    """Time spent in each knot interval on the zero-thrust orbit [s] (fixed QP weights)."""
    lc = zd.nominal_cycle()
    if not lc.exists:
        raise InputError.param("weights", "time: the zero-thrust periodic orbit does not exist "
                               f"({lc.reason}); use `weights` alpha")
    out = []
    for j in range(len(kn) - 1):
        a = lobatto(kn[j], kn[j + 1], 33)
        zeta = lc.zeta_plus + zd.V0(a)
        k1 = zd.terms(a)["kappa1"]
        val, _ = integrate(kn[j], kn[j + 1], 1.0 / np.abs(k1 * np.sqrt(2.0 * zeta)))
        out.append(abs(float(val)))
    return np.array(out)


# --------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class OptimalSchedule:
    """Result of :func:`optimize` (SPEC 6). Thrust values [N] (force) or [N m] (generalised);
    objective ``sum w_j x_j^2`` [N^2 rad or N^2 s]; zeta [kg^2 m^4/s^2]; speed [m/s].

    ``feasible`` false -> ``violated`` names the constraint families whose removal makes the
    problem feasible and ``reason`` says it in words (an infeasible problem is a valid answer).
    """

    feasible: bool
    status: str
    reason: str
    problem: LinearProblem
    target: dict
    fractions: np.ndarray
    violated: tuple[str, ...] = ()
    values: np.ndarray | None = None
    objective: float | None = None
    zeta_star_target: float | None = None
    cycle: LimitCycle | None = None
    active: list[dict] = field(default_factory=list)
    kkt: dict | None = None
    contact: CaseResult | None = None
    solver: str = ""
    zeta_range: tuple[float, float] | None = None
    objective_name: str = "effort"
    energy: object | None = None  # min_energy.EnergySolve of an energy objective

    @property
    def optimal(self) -> bool:
        """A feasible schedule that is verified optimal (energy: the fixed point converged and
        the KKT conditions hold); ``status`` says otherwise."""
        return self.feasible and self.status == "optimal"


def _solve_fixed(prob: LinearProblem, zs: float) -> tuple[np.ndarray | None, dict | None, str]:
    """QP at fixed zeta*: (x, kkt, solver) or (None, None, '') when infeasible."""
    A, b, ae, be = prob.at(zs)
    ok, x0 = lp_feasible(A, b, ae, be)
    if not ok:
        return None, None, ""
    x = ldp_qp(A, b, ae, be, prob.weights)
    k = kkt(A, b, ae, be, prob.weights, x)
    solver = "least-distance QP (Lawson-Hanson NNLS)"
    if not _kkt_ok(k):
        x = active_set_qp(A, b, ae, be, prob.weights, x0)
        k = kkt(A, b, ae, be, prob.weights, x)
        solver = "primal active-set QP (fallback)"
        if not _kkt_ok(k):
            raise ComputationError(
                f"QP solution fails the KKT check (stationarity {k['stationarity_relative']:.2e}, "
                f"infeasibility {k['primal_infeasibility']:.2e})")
    return x, k, solver


def _kkt_ok(k: dict) -> bool:
    return (k["stationarity_relative"] <= 1e-6 and k["primal_infeasibility"] <= KKT_TOL
            and k["equality_residual"] <= KKT_TOL)


def diagnose(prob: LinearProblem, zs: float | None) -> tuple[str, ...]:
    """Constraint families whose removal makes the problem feasible (singly, else in pairs).

    ``zs`` None: zeta* is a free variable (target speed)."""
    fams = [f for f in ("vertical_force", "friction", "zeta_min", "thrust_bounds")
            if np.any(prob.family == f)] + ["fixed_point"]

    def feasible_without(drop: set[str]) -> bool:
        keep = ~np.isin(prob.family, list(drop))
        if zs is None:
            A = np.column_stack([prob.A[keep], prob.z[keep]])
            ae = np.append(prob.a_eq, prob.z_eq)
            return lp_feasible(A, prob.b[keep], None if "fixed_point" in drop else ae,
                               prob.b_eq)[0]
        A, b, ae, be = prob.at(zs)
        if "fixed_point" in drop:
            return lp_feasible(A[keep], b[keep], None, None)[0]
        return lp_feasible(A[keep], b[keep], ae, be)[0]

    single = tuple(f for f in fams if feasible_without({f}))
    if single:
        return single
    return tuple(f"{a}+{b}" for a, b in combinations(fams, 2) if feasible_without({a, b}))


def describe(v: str) -> str:
    """Words for a family name or a ``"a+b"`` pair of :data:`FAMILIES`."""
    return " and ".join(FAMILIES[p] for p in v.split("+"))


def _infeasible(prob, target, fractions, violated, headline="", *, removal=True, zs=None,
                zrange=None):
    """An infeasible result. ``removal``: ``violated`` are the families whose removal makes the
    problem feasible; otherwise they are the families that limit the reachable range."""
    parts = [headline] if headline else []
    if removal and violated:
        parts.append("no schedule satisfies every constraint; dropping any one of these makes "
                     "it feasible: " + " | ".join(describe(v) for v in violated))
    elif removal:
        parts.append("no single constraint family or pair of families explains it")
    reason = "infeasible: " + "; ".join(parts)
    return OptimalSchedule(False, "infeasible", reason, prob, target, fractions,
                           violated=tuple(violated), zeta_star_target=zs, zeta_range=zrange)


def _active_rows(prob: LinearProblem, k: dict) -> list[dict]:
    return [{"family": str(prob.family[i]), "alpha": float(prob.alpha[i]),
             "constraint": prob.detail[i], "multiplier": float(lam)}
            for i, lam in zip(k["active"], k["multipliers"])]


def zeta_range(prob: LinearProblem) -> tuple[float, float, dict]:
    """Reachable zeta* range under all constraints (two LPs in ``(x, zeta*)``) and, per end, the
    families with non-zero LP multipliers (the ones that limit it)."""
    A = np.column_stack([prob.A, prob.z])
    An, bn, _, const = normalise_rows(A, prob.b)
    ae = np.append(prob.a_eq, prob.z_eq)
    s = np.linalg.norm(ae)
    ends, limits = [], {}
    for sign, name in ((1.0, "min"), (-1.0, "max")):
        cost = np.zeros(A.shape[1])
        cost[-1] = sign
        res = linprog(cost, A_ub=An[~const], b_ub=bn[~const], A_eq=(ae / s)[None, :],
                      b_eq=[prob.b_eq / s], bounds=[(None, None)] * A.shape[1],
                      method="highs")
        if res.status == 2:
            raise _Infeasible()
        if res.status != 0:
            raise ComputationError(f"zeta* range LP (HiGHS) failed: {res.message}")
        ends.append(float(res.x[-1]))
        marg = np.abs(res.ineqlin.marginals)
        fam = prob.family[~const][marg > 1e-9 * max(marg.max(initial=0.0), 1e-300)]
        limits[name] = sorted(set(map(str, fam)))
    return ends[0], ends[1], limits


class _Infeasible(Exception):
    pass


class OrbitAtRest(ComputationError):
    """A schedule's orbit comes to rest (zeta <= 0 somewhere): an objective that integrates
    in time (energy) is not defined there."""


def _effort_solve(prob: LinearProblem, zs: float):
    """The effort objective's solve at fixed zeta*: (x, kkt, solver, None)."""
    x, k, solver = _solve_fixed(prob, zs)
    return x, k, solver, None


def optimize(model: CompiledModel, zd: ZeroDynamics, fractions: np.ndarray, *,
             target_zeta: float | None = None, target_speed: float | None = None,
             mode: str = "force", thruster: int = 0, mu: float, eps: float = 0.0,
             zeta_min: float | None = None, max_thrust: float | None = None,
             weights: str = "alpha", points: int = 201, solve=None,
             objective_name: str = "effort",
             thrust_range: tuple[float, float] | None = None) -> OptimalSchedule:
    """Minimum-effort schedule reaching ``target_zeta`` [kg^2 m^4/s^2] or ``target_speed`` [m/s]
    under the SPEC 6 constraints. ``zeta_min`` default: 1 % of zeta*. ``max_thrust``: ``|x_j| <=``
    this [N or N m], intersected with the thruster's limits in force mode (and with
    ``thrust_range`` [N] when given).

    ``solve(prob, zs) -> (x, kkt, solver, extra)`` replaces the effort QP at fixed zeta* (the
    energy objective, :func:`.min_energy.optimize_energy`; ``extra`` its record, None: the
    problem is infeasible when ``x`` is None); the constraints, the exchange method and the
    root search for a target speed are the same for every objective."""
    solve = _effort_solve if solve is None else solve
    fr = np.asarray(fractions, float)
    n = len(fr) - 1
    if mode == "force":
        lim = model.robot.thrusters[thruster].limits
        lo = np.full(n, lim[0] if max_thrust is None else max(lim[0], -max_thrust))
        hi = np.full(n, lim[1] if max_thrust is None else min(lim[1], max_thrust))
        if thrust_range is not None:
            lo, hi = np.maximum(lo, thrust_range[0]), np.minimum(hi, thrust_range[1])
    else:
        lo, hi = np.full(n, -max_thrust), np.full(n, max_thrust)
    prob = build_problem(model, zd, fr, mode=mode, thruster=thruster, mu=mu, eps=eps,
                         zeta_min=0.0 if zeta_min is None else zeta_min,
                         zeta_min_rel=0.01 if zeta_min is None else 0.0,
                         bounds=(lo, hi), weights=weights, points=points)
    target = ({"zeta_star": target_zeta} if target_zeta is not None
              else {"speed": target_speed})
    d2 = zd.delta_zero_sq
    if not zd.valid or not 0.0 < d2 < 1.0:
        why = zd.invalid_reason or f"delta_zero^2 = {d2:.6g} is not in (0, 1)"
        return _infeasible(prob, target, fr, ("orbit",), f"no stable periodic orbit: {why}",
                           removal=False)
    if not prob.impact_ok:
        return _infeasible(prob, target, fr, ("impact",), "; ".join(prob.impact_reasons),
                           removal=False)
    fits = fit_terms(model, zd)
    for rounds in range(1, MAX_EXCHANGE + 1):  # noqa: B007 (reported after the loop)
        zrange = None
        if target_zeta is not None:
            zs = float(target_zeta)
        else:
            found = _zeta_for_speed(model, zd, prob, target, fr, target_speed, solve)
            if isinstance(found, OptimalSchedule):
                return found
            zs, zrange = found
        x, k, solver, extra = solve(prob, zs)
        if x is None:
            return _infeasible(prob, target, fr, diagnose(prob, zs), zs=zs, zrange=zrange)
        sched = prob.schedule(x, model.n_thrusters)
        check = evaluate(model, zd, sched, mu=mu, eps=eps, fits=fits,
                         labels=["optimal"]).cases[0]
        worst = _zeta_dip(zd, prob, sched, zs)
        if check.min_vertical_force < eps:
            worst.append(check.alpha_at_min_vertical_force)
        if check.max_friction_ratio is not None and check.max_friction_ratio > mu:
            worst.append(check.alpha_at_max_friction_ratio)
        if check.cycle.exists and (check.feasible or not worst):
            break
        if not worst:
            raise ComputationError(f"the optimal schedule has no periodic orbit: "
                                   f"{check.cycle.reason}")
        prob = add_points(prob, np.array(worst))
    if not check.cycle.exists:
        raise ComputationError(f"the optimal schedule has no periodic orbit after "
                               f"{MAX_EXCHANGE} exchange rounds: {check.cycle.reason}")
    contact = (f"contact conditions hold between grid points, {rounds} exchange round(s)"
               if check.feasible else
               f"the continuous re-check fails after {MAX_EXCHANGE} exchange rounds: "
               f"{check.reason}")
    status = "optimal"
    if extra is None:
        reason = ("optimal: minimum-effort schedule found (KKT conditions verified; "
                  f"{contact})" if check.feasible else f"optimal on the alpha grid, but {contact}")
        value = float(prob.weights @ x**2)
    else:
        status, reason = extra.verdict(contact, check.feasible)
        value = float(extra.energy)
    return OptimalSchedule(
        True, status, reason, prob, target, fr, values=x,
        objective=value, zeta_star_target=zs, cycle=check.cycle,
        active=_active_rows(prob, k), kkt=k, contact=check, solver=solver, zeta_range=zrange,
        objective_name=objective_name, energy=extra)


def _zeta_for_speed(model, zd, prob, target, fr, target_speed, solve=_effort_solve):
    """zeta* whose minimum-effort schedule walks at ``target_speed`` (1-D root search inside
    the reachable zeta* range), or an infeasible result naming the limiting families."""
    try:
        zlo, zhi, limits = zeta_range(prob)
    except _Infeasible:
        return _infeasible(prob, target, fr, diagnose(prob, None))
    zrange = (zlo, zhi)
    pad = 1e-9 * max(abs(zhi), 1.0)
    a, b = zlo + pad, zhi - pad
    vb = _speed_at(model, zd, prob, b, solve=solve)
    va = _speed_at(model, zd, prob, a, strict=False, solve=solve)
    frac = 1e-6
    while va is None and frac < 1.0:  # no orbit at the very bottom: move up geometrically
        a = zlo + frac * (b - zlo)
        va = _speed_at(model, zd, prob, a, strict=False, solve=solve)
        frac *= 4.0
    if va is None:
        raise ComputationError("no periodic orbit anywhere in the reachable zeta* range")
    if not va <= target_speed <= vb:
        end = "max" if target_speed > vb else "min"
        lim = "; ".join(describe(f) for f in limits[end]) or "none"
        bound = vb if end == "max" else va
        word = "fastest" if end == "max" else "slowest"
        return _infeasible(
            prob, target, fr, tuple(limits[end]),
            f"target speed {target_speed:g} m/s is outside the reachable range "
            f"[{va:.4g}, {vb:.4g}] m/s of {_OPTIMA[solve is _effort_solve]} schedules (the "
            f"{word} has "
            f"zeta* = {(b if end == 'max' else a):.6g}, {bound:.4g} m/s), limited by: {lim}",
            removal=False, zrange=zrange)
    zs = zd.zeta_for_speed(target_speed, lambda z: _speed_at(model, zd, prob, z, solve=solve),
                           a, b, xtol=1e-12 * max(abs(b), 1.0), rtol=1e-12)
    return zs, zrange


_OPTIMA = {True: "minimum-effort", False: "energy-optimal"}


def _speed_at(model, zd, prob, zs: float, strict: bool = True,
              solve=_effort_solve) -> float | None:
    """Speed [m/s] of the optimal schedule at ``zs`` (``solve``: the objective's solve at fixed
    zeta*); None (strict: error) without an orbit."""
    try:
        x = solve(prob, zs)[0]
    except OrbitAtRest:
        if strict:
            raise
        return None
    if x is None:
        raise ComputationError(f"QP infeasible at zeta* = {zs:.6g} inside the reachable range")
    lc = limit_cycles(zd, prob.schedule(x, model.n_thrusters))[0]
    if not lc.exists:
        if not strict:
            return None
        raise ComputationError(f"no periodic orbit at zeta* = {zs:.6g}: {lc.reason}")
    return float(lc.speed)


def _zeta_dip(zd: ZeroDynamics, prob: LinearProblem, sched: Schedule, zs: float,
              points: int = 2001) -> list[float]:
    """Where ``zeta(alpha)`` falls below its bound between grid points (dense check)."""
    a = np.linspace(zd.alpha_i, zd.alpha_f, points)
    zeta = zd.delta_zero_sq * zs + zd.V_Z(a, sched)[0]
    need = prob.spec.zeta_min + prob.spec.zeta_min_rel * zs
    j = int(np.argmin(zeta - need))
    return [float(a[j])] if zeta[j] < need * (1 - 1e-9) else []
