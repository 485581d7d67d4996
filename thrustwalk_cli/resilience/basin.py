"""The exact basin of attraction of the reduced step map (SPEC 12).

With a fixed thrust schedule (constant, piecewise, or none) the step that starts at the impact
with pre-impact value ``x = zeta^-`` [kg^2 m^4/s^2] has ``zeta^+ = delta_zero^2 x`` and

    zeta(alpha)  = delta_zero^2 x + V_Z(alpha)                                    (SPEC 3)
    F_1(alpha)   = Lambda_2 F_j + Lambda_1 zeta(alpha) + Lambda_0 + Lambda_T T_j   (SPEC 5)
    x_{k+1}      = delta_zero^2 x + V_Z(alpha_f)

so every condition of the step is affine in ``x``: ``g(alpha) + c(alpha) x >= 0`` with

    stop            g = V_Z,                       c = delta_zero^2         (zeta > 0)
    vertical force  g = F^v_0 - eps,               c = Lambda_1^v delta_zero^2
    friction        g = mu F^v_0 -+ F^h_0,         c = (mu Lambda_1^v -+ Lambda_1^h) delta_zero^2

(``F_0`` the ground force at ``x = 0``). A row with ``c > 0`` bounds ``x`` from below by
``-g/c``, one with ``c < 0`` from above: the step completes inside the cone iff

    x_lo = max_alpha { -g/c : c > 0 }  <  x  <=  x_hi = min_alpha { -g/c : c < 0 }

(the stop row gives ``x_lo >= -min V_Z / delta_zero^2``). The extrema over alpha are located on
a grid over each knot interval and polished by golden section between the neighbouring grid
points (:mod:`thrustwalk_cli.hzd.extrema`), so they are not grid-limited. The impact
conditions do not depend on ``x`` (SPEC 11: the impulse is proportional to sigma^-): checked
once. Since ``x -> delta_zero^2 x + V_Z(alpha_f)`` is monotone with slope in (0, 1), every
start in ``(x_lo, x_hi]`` converges to the fixed point without leaving the interval when the
fixed point lies in it: that interval is the exact basin of the reduced walker.

With step-to-step control (SPEC 11) the thrust of each step is chosen from ``x``; the
conditions are jointly affine in ``(x, u)`` and the controlled basin is the projection of that
polyhedron on ``x`` (two linear programmes on the controller's own alpha grid), checked by
iterating the controlled reduced map from starts across it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from ..contact.evaluate import step_grid
from ..contact.terms import impact_data, stance_terms
from ..controller.planner import Planner
from ..hzd.extrema import polish_min
from ..hzd.zero_dynamics import ZeroDynamics, limit_cycles
from ..optimize.qp import normalise_rows
from ..thrust.schedule import Schedule

FAMILIES = ("stop", "vertical_force", "friction")
VERIFY_STARTS = 41  # starts across a controlled basin, iterated by the controlled map
VERIFY_STEPS = 60


@dataclass(frozen=True)
class Bound:
    """One end of a basin: ``value`` [kg^2 m^4/s^2] (``None``: unbounded on that side), the
    condition ``family`` that sets it and the ``alpha`` [rad] where it binds."""

    value: float | None
    family: str
    alpha: float | None = None

    def document(self) -> dict:
        """The bound's JSON entry: ``zeta_minus`` [kg^2 m^4/s^2] (None: unbounded), ``family``,
        ``alpha`` [rad]."""
        return {"zeta_minus": self.value, "family": self.family, "alpha": self.alpha}


@dataclass(frozen=True)
class ReducedBasin:
    """The basin of the reduced walker for one strategy (module docstring), in zeta^- of the
    impact that starts a step [kg^2 m^4/s^2].

    ``exists``: a fixed point lies strictly inside ``(lower, upper]``, the impact is admissible
    and the map contracts; ``reason`` says what holds or fails. ``zeta_star`` the fixed point
    (the controller's reference for control), ``delta_zero_sq`` the map's slope, ``method``
    how the bounds were found, ``verified`` (control) the check by iterating the map."""

    exists: bool
    reason: str
    lower: Bound
    upper: Bound
    zeta_star: float | None
    delta_zero_sq: float
    method: str
    verified: dict | None = None
    rows: dict = field(default_factory=dict, repr=False)

    def contains(self, x: float) -> bool:
        """Whether a step started at ``x = zeta^-`` stays in the basin (``lower < x <=
        upper``)."""
        lo = -np.inf if self.lower.value is None else self.lower.value
        hi = np.inf if self.upper.value is None else self.upper.value
        return bool(self.exists and lo < x <= hi)

    def relative(self) -> tuple[float | None, float | None]:
        """The bounds as fractions of the fixed point [1]."""
        zs = self.zeta_star
        if not zs:
            return None, None
        return (None if self.lower.value is None else self.lower.value / zs,
                None if self.upper.value is None else self.upper.value / zs)

    def document(self) -> dict:
        """The basin's JSON entry (SPEC 12): exists, reason, method, both bounds, the bounds
        relative to zeta*, zeta* [kg^2 m^4/s^2], delta_zero^2 [1], verified."""
        lo, hi = self.relative()
        return {"exists": self.exists, "reason": self.reason, "method": self.method,
                "lower": self.lower.document(), "upper": self.upper.document(),
                "relative_to_zeta_star": {"lower": lo, "upper": hi},
                "zeta_star": self.zeta_star, "delta_zero_sq": self.delta_zero_sq,
                "verified": self.verified}


Rows = Callable[[np.ndarray, np.ndarray], dict[str, list[tuple[np.ndarray, np.ndarray]]]]


def affine_rows(zd: ZeroDynamics, sched: Schedule, mu: float, eps: float) -> Rows:
    """``rows(alpha, interval) -> {family: [(g, c), ...]}``: the step's conditions
    ``g + c x >= 0`` at ``alpha`` (module docstring) for the one-schedule batch ``sched``
    (thrust of knot interval ``interval`` at each alpha)."""
    model, d2 = zd.model, zd.delta_zero_sq

    def rows(alpha: np.ndarray, interval: np.ndarray) -> dict:
        alpha = np.atleast_1d(np.asarray(alpha, float))
        j = np.broadcast_to(np.asarray(interval, int), alpha.shape)
        Vz = zd.V_Z(alpha, sched)[0]
        t = stance_terms(model, zd.maps, alpha)
        F = sched.force[0, j, :]
        T = sched.generalized[0, j]
        F0 = (np.einsum("gim,gm->gi", t.L2, F) + t.L1 * Vz[:, None] + t.L0
              + t.LT * T[:, None])
        dF = t.L1 * d2
        h, v = 0, 1
        return {
            "stop": [(Vz, np.full(alpha.shape, d2))],
            "vertical_force": [(F0[:, v] - eps, dF[:, v])],
            "friction": [(mu * F0[:, v] - F0[:, h], mu * dF[:, v] - dF[:, h]),
                         (mu * F0[:, v] + F0[:, h], mu * dF[:, v] + dF[:, h])],
        }
    return rows


def _ratio(g: np.ndarray, c: np.ndarray, sign: float) -> np.ndarray:
    """``-g/c`` where ``sign * c > 0``, else -inf (sign +1: lower bounds) / +inf (-1)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        b = -g / c
    return np.where(sign * c > 0, b, -sign * np.inf)


def bounds(rows: Rows, alpha: np.ndarray, idx: np.ndarray
           ) -> tuple[Bound, Bound, list[str]]:
    """The lower and upper bounds on ``x`` over the step (module docstring) from the affine
    conditions ``rows`` on the grid ``alpha`` (knot interval ``idx`` of each point), each
    extremum polished between its neighbouring grid points; and the conditions that fail for
    every ``x`` (``c = 0`` with ``g < 0``).

    Every (condition, side) is one entry of a single batched polish: the lower bound of a row
    is the maximum of ``-g/c`` where ``c > 0``, the upper bound the minimum where ``c < 0``;
    both are minima of ``-sign * (-g/c)``, found together by :func:`polish_min` (one
    evaluation of ``rows`` per golden-section step for all of them)."""
    grid = rows(alpha, idx)
    lower, upper = Bound(None, "none"), Bound(None, "none")
    never: list[str] = []
    problems: list[tuple[str, int, float]] = []
    values = []
    for fam, pairs in grid.items():
        for r, (g, c) in enumerate(pairs):
            scale = np.max(np.abs(c)) if c.size else 1.0
            flat = np.abs(c) <= 1e-12 * max(scale, 1e-300)
            if np.any(flat & (g < 0)):
                never.append(f"{fam} at alpha = {alpha[np.argmax(flat & (g < 0))]:.6g} rad")
            for sign in (1.0, -1.0):
                vals = _ratio(g, c, sign)
                if not np.any(np.isfinite(vals)):
                    continue
                problems.append((fam, r, sign))
                values.append(-sign * vals)
    if not problems:
        return lower, upper, never
    a_star, m = polish_min(_at(rows, alpha, idx, problems), alpha, np.array(values), idx)
    for (fam, _, sign), a, v in zip(problems, a_star, m):
        v = float(-sign * v)
        if sign > 0:
            if lower.value is None or v > lower.value:
                lower = Bound(v, fam, float(a))
        elif upper.value is None or v < upper.value:
            upper = Bound(v, fam, float(a))
    return lower, upper, never


def _at(rows: Rows, alpha: np.ndarray, idx: np.ndarray,
        problems: list[tuple[str, int, float]]):
    """The objective of each batch entry as a function of alpha (one abscissa per entry):
    ``-sign * (-g/c)`` of the entry's row (family, index, sign), with the knot interval of
    the grid point nearest to the abscissa (the polishing brackets never cross a knot)."""
    def f(a: np.ndarray) -> np.ndarray:
        a = np.atleast_1d(np.asarray(a, float))
        j = idx[np.argmin(np.abs(alpha[None, :] - a[:, None]), axis=1)]
        at = rows(a, j)
        out = np.empty(a.shape)
        for e, (fam, r, sign) in enumerate(problems):
            g, c = at[fam][r]
            out[e] = -sign * _ratio(g[e:e + 1], c[e:e + 1], sign)[0]
        return out
    return f


def reduced_basin(zd: ZeroDynamics, sched: Schedule, *, mu: float, eps: float = 0.0,
                  points: int = 401) -> ReducedBasin:
    """The exact basin of the reduced walker under the fixed schedule ``sched`` (a one-schedule
    batch), SPEC 12: closed-form bounds (module docstring) with the friction coefficient
    ``mu`` [1] and the least vertical force ``eps`` [N]."""
    d2 = zd.delta_zero_sq
    alpha, idx = step_grid(sched.knots, points)
    rows = affine_rows(zd, sched, mu, eps)
    lower, upper, never = bounds(rows, alpha, idx)
    lc = limit_cycles(zd, sched)[0]
    zs = float(lc.zeta_star) if lc.zeta_star is not None else None
    method = ("closed form (SPEC 12): affine conditions polished over alpha on "
              f"{len(alpha)} grid points")
    imp = impact_data(zd.model, zd)
    reason = _verdict(zd, lower, upper, zs, never, imp.admissible(mu), imp.reasons(mu))
    return ReducedBasin(reason is None, reason or _inside(lower, upper, zs), lower, upper, zs,
                        d2, method)


def _inside(lower: Bound, upper: Bound, zs: float | None) -> str:
    lo = "-inf" if lower.value is None else f"{lower.value:.6g}"
    hi = "inf" if upper.value is None else f"{upper.value:.6g}"
    return (f"every zeta^- in ({lo}, {hi}] kg^2 m^4/s^2 converges to zeta* = {zs:.6g} without "
            f"stopping or leaving the cone (lower: {lower.family}, upper: {upper.family})")


def _verdict(zd: ZeroDynamics, lower: Bound, upper: Bound, zs: float | None, never: list[str],
             impact_ok: bool, impact_reasons: list[str]) -> str | None:
    """Why there is no basin (None: there is one)."""
    d2 = zd.delta_zero_sq
    if not zd.valid:
        return f"no walking orbit: {zd.invalid_reason}"
    if not 0.0 < d2 < 1.0:
        return f"the step map does not contract (delta_zero^2 = {d2:.6g})"
    if never:
        return "a condition fails for every zeta^-: " + "; ".join(never)
    if not impact_ok:
        return "the impact is inadmissible for every zeta^-: " + "; ".join(impact_reasons)
    if zs is None or not zs > 0:
        return "no fixed point zeta* > 0 for this thrust"
    lo = -np.inf if lower.value is None else lower.value
    hi = np.inf if upper.value is None else upper.value
    if not lo < hi:
        return (f"no zeta^- satisfies every condition (lower bound {lo:.6g} from "
                f"{lower.family} >= upper bound {hi:.6g} from {upper.family})")
    if not lo < zs <= hi:
        side = lower if zs <= lo else upper
        return (f"the orbit itself violates {side.family}: zeta* = {zs:.6g} outside "
                f"({lo:.6g}, {hi:.6g}]")
    return None


# ----------------------------------------------------------------------- with control
def controlled_basin(planner: Planner, x_ref: float) -> ReducedBasin:
    """The basin of the reduced walker under the step-to-step controller (module docstring):
    ``x`` for which the controller's constraints (``A u <= b0 + bx x``, thrust bounds) admit a
    thrust, by two linear programmes over ``(x, u)`` on the planner's grid; then the
    controlled map ``x_{k+1} = delta_zero^2 x + V_0(alpha_f) + Gamma(alpha_f) u(x)`` is iterated
    from starts across it (``verified``)."""
    zd = planner.zd
    d2 = zd.delta_zero_sq
    rw = planner.grid_rows()
    A, b0, bx, fam = planner.contact_rows(rw, 0.0)
    nu = planner.nu
    # rows over z = (x, u): -bx x + A u <= b0; thrust bounds on u
    Az = np.column_stack([-bx, A])
    An, bn, _, const = normalise_rows(Az, b0)
    keep = ~const
    bnds = [(None, None)] + list(zip(planner.lo, planner.hi))
    ends: list[Bound] = []
    for sign in (1.0, -1.0):
        cost = np.zeros(1 + nu)
        cost[0] = sign
        res = linprog(cost, A_ub=An[keep], b_ub=bn[keep], bounds=bnds, method="highs")
        if res.status == 3:
            ends.append(Bound(None, "none"))
            continue
        if res.status != 0:
            ends.append(Bound(np.nan, "infeasible"))
            continue
        z = res.x
        slack = bn[keep] - An[keep] @ z
        act = fam[keep][slack <= 1e-9]
        # the active family whose row moves with x (the one that stops the projection)
        moving = [f for f, bxr in zip(fam[keep][slack <= 1e-9],
                                      (-An[keep][:, 0])[slack <= 1e-9]) if abs(bxr) > 0]
        name = moving[0] if moving else (str(act[0]) if act.size else "thrust_bounds")
        ends.append(Bound(float(z[0]), "stop" if name == "zeta_min" else str(name)))
    lower, upper = ends
    method = ("projection of the controller's constraints (SPEC 11 QP rows on "
              f"{len(rw.alpha)} grid points, thrust bounds) on zeta^-: two linear programmes")
    imp = impact_data(zd.model, zd)
    if any(b.value is not None and not np.isfinite(b.value) for b in ends):
        return ReducedBasin(False, "the controller's constraints admit no thrust for any "
                                   "zeta^- (the linear programmes are infeasible)",
                            Bound(None, "infeasible"), Bound(None, "infeasible"), x_ref, d2,
                            method)
    reason = _verdict(zd, lower, upper, x_ref, [], imp.admissible(planner.st.mu),
                      imp.reasons(planner.st.mu))
    verified = None
    if reason is None:
        verified = _iterate(planner, x_ref, lower, upper)
        if verified["converged"] < verified["starts"]:
            bad = verified["starts"] - verified["converged"]
            reason = (f"the controlled map does not converge from {bad} of "
                      f"{verified['starts']} starts in the projected interval "
                      f"({verified['first_failure']})")
    text = reason or (_inside(lower, upper, x_ref) + "; the controlled map converges from "
                      f"all {verified['starts']} starts tried across it")
    return ReducedBasin(reason is None, text, lower, upper, x_ref, d2, method, verified)


def _iterate(planner: Planner, x_ref: float, lower: Bound, upper: Bound) -> dict:
    """Iterate the controlled reduced map from ``VERIFY_STARTS`` starts across the interval
    (its ends moved inside by 1e-6 of its width; an unbounded side capped at 10 zeta*), each
    for ``VERIFY_STEPS`` steps or until ``(x, u)`` maps to itself bit for bit (a step's plan is
    a function of ``x`` and the previous ``u`` alone, so every later step would repeat it)."""
    d2 = planner.zd.delta_zero_sq
    lo = lower.value if lower.value is not None else 0.0
    hi = upper.value if upper.value is not None else 10.0 * x_ref
    w = hi - lo
    starts = np.linspace(lo + 1e-6 * w, hi - 1e-6 * w, VERIFY_STARTS)
    rw = planner.grid_rows()
    g, z0f = rw.Zu[-1], rw.z0[-1]
    ok, first = 0, ""
    worst = 0.0
    for x0 in starts:
        x, u = float(x0), np.zeros(planner.nu)
        good = True
        for _ in range(VERIFY_STEPS):
            plan = planner.plan(x, x_ref, u)
            if plan.status == "infeasible":
                good, first = False, first or f"infeasible QP at zeta^- = {x:.6g}"
                break
            x_new = float(d2 * x + z0f + g @ plan.u)
            if x_new == x and np.array_equal(plan.u, u):
                break  # a fixed point of (x, u): every later step would repeat it
            u, x = plan.u, x_new
        err = abs(x - x_ref) / x_ref
        worst = max(worst, err)
        if good and err <= 1e-9:
            ok += 1
        elif good:
            first = first or f"zeta^- {x0:.6g} ends {err:.3g} from the reference"
    return {"starts": len(starts), "converged": ok, "steps": VERIFY_STEPS,
            "worst_relative_error": worst, "first_failure": first or None}
