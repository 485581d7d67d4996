"""Gait design: stable, walkable Bezier gaits found by constrained optimisation (SPEC 2, 3, 5).

The problem (decision variables, Chebyshev-Lobatto nodes, objectives, constraint families
and the solver's safety margins) is assembled in :mod:`thrustwalk_cli.design.problem`; the
independent re-check in :mod:`thrustwalk_cli.design.verify`; what to design in
:mod:`thrustwalk_cli.design.spec`. The report record and the gait file are rendered by
:mod:`thrustwalk_cli.studies.design_gait`.

Solver: SciPy SLSQP with one shared forward-difference Jacobian per point, several seeded
starts (start 0 is the deterministic default start). The chosen gait is re-checked by the
independent code paths (adaptive zero dynamics, :func:`limit_cycles`, the contact evaluation,
dense grids); ``feasible`` is the verdict of that re-check.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from ..description.gait import Gait
from ..model.compiled import CompiledModel
from .problem import FAMILIES, Evaluation, Problem
from .spec import ELASTIC, FEAS_TOL, DesignSpec
from .verify import verify


# ------------------------------------------------------------------------------- solver
class _Cache:
    """Objective, constraints and a forward-difference Jacobian shared by every callback."""

    def __init__(self, prob: Problem):
        self.p = prob
        self.x = None
        self.ev: Evaluation | None = None
        self.jx = None
        self.jac = None

    def at(self, x) -> Evaluation:
        x = np.asarray(x, float)
        if self.x is None or not np.array_equal(x, self.x):
            self.x, self.ev = x.copy(), self.p.evaluate(x)
        return self.ev

    @staticmethod
    def flat(ev: Evaluation) -> tuple[float, np.ndarray, np.ndarray]:
        eq = np.concatenate(list(ev.eq.values())) if ev.eq else np.zeros(0)
        iq = np.concatenate(list(ev.ineq.values())) if ev.ineq else np.zeros(0)
        return ev.scaled, eq, iq

    def jacobian(self, x):
        x = np.asarray(x, float)
        if self.jx is not None and np.array_equal(x, self.jx):
            return self.jac
        f0, e0, i0 = self.flat(self.at(x))
        n = x.size
        gf, ge, gi = np.zeros(n), np.zeros((e0.size, n)), np.zeros((i0.size, n))
        for j in range(n):
            h = 1e-7 * max(1.0, abs(x[j]))
            xp = x.copy()
            xp[j] += h
            f1, e1, i1 = self.flat(self.p.evaluate(xp))
            gf[j], ge[:, j], gi[:, j] = (f1 - f0) / h, (e1 - e0) / h, (i1 - i0) / h
        self.jx, self.jac = x.copy(), (gf, ge, gi)
        return self.jac


@dataclass(frozen=True)
class StartResult:
    """One solver run: its start index, SciPy status, objective [SI], worst normalised
    violation, iterations, evaluations and wall time [s]."""

    index: int
    x: np.ndarray = field(repr=False)
    status: str
    objective: float
    max_violation: float
    iterations: int
    evaluations: int
    seconds: float


def _selection(blocks: dict[str, np.ndarray], slack: dict[str, int]) -> np.ndarray:
    """0/1 matrix adding family ``k``'s slack to each of its constraint rows."""
    n = sum(v.size for v in blocks.values())
    S = np.zeros((n, len(slack)))
    r = 0
    for k, v in blocks.items():
        if k in slack:
            S[r:r + v.size, slack[k]] = 1.0
        r += v.size
    return S


def solve_start(prob: Problem, x0: np.ndarray, index: int = 0) -> StartResult:
    """SLSQP from ``x0`` in elastic mode (``prob.start`` must have set up this start).

    One slack ``s_k >= 0`` per constraint family relaxes it (``g + s_k >= 0``,
    ``|h| <= s_k``) and costs ``ELASTIC s_k``: the linearised subproblems stay consistent from
    any start, the exact penalty drives the slacks to 0 when the family can be satisfied, and a
    slack left at the end measures that family's violation.
    """
    t0 = time.perf_counter()
    e0 = prob.evaluations
    ev0 = prob.evaluate(x0)
    if not ev0.ok:
        return StartResult(index, x0, "the start point cannot be evaluated", float("inf"),
                           float("inf"), 0, prob.evaluations - e0, time.perf_counter() - t0)
    prob.fix_shapes(ev0)
    cache = _Cache(prob)
    fams = [k for k in FAMILIES if k in ev0.eq or k in ev0.ineq]
    slack = {k: i for i, k in enumerate(fams)}
    Si, Se = _selection(ev0.ineq, slack), _selection(ev0.eq, slack)
    n = x0.size
    viol = ev0.violations()
    z0 = np.concatenate([x0, [viol[k] * 1.01 + 1e-9 for k in fams]])

    def fun(z):
        return cache.flat(cache.at(z[:n]))[0] + ELASTIC * z[n:].sum()

    def grad(z):
        return np.concatenate([cache.jacobian(z[:n])[0], np.full(len(fams), ELASTIC)])

    def cons(z):
        _, e, g = cache.flat(cache.at(z[:n]))
        sl = z[n:]
        return np.concatenate([g + Si @ sl, e + Se @ sl, Se @ sl - e])

    def cons_jac(z):
        _, je, jg = cache.jacobian(z[:n])
        return np.vstack([np.hstack([jg, Si]), np.hstack([je, Se]), np.hstack([-je, Se])])

    bounds = prob.bounds() + [(0.0, None)] * len(fams)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(fun, z0, jac=grad, method="SLSQP", bounds=bounds,
                       constraints=[{"type": "ineq", "fun": cons, "jac": cons_jac}],
                       options={"maxiter": prob.spec.max_iter, "ftol": 1e-10})
    x = res.x[:n]
    ev = prob.evaluate(x)
    return StartResult(index, x, str(res.message), ev.objective, ev.max_violation,
                       int(res.nit), prob.evaluations - e0, time.perf_counter() - t0)


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class DesignResult:
    """Outcome of :func:`solve_design` (SI units).

    feasible: the chosen gait passed the independent re-check (:func:`verify`); reason says
    why not otherwise, and ``blocking`` names the constraint family with the largest
    normalised violation at the best point. objective: value on the re-checked periodic orbit
    (``effort`` [N^2 m s] or ``peak`` [N m]). check: the re-check record (every margin).
    """

    feasible: bool
    reason: str
    blocking: str | None
    spec: DesignSpec
    gait: Gait
    thrust: tuple[float, ...]
    objective: float | None
    solver_objective: float
    violations: dict[str, float]
    check: dict
    starts: tuple[StartResult, ...]
    evaluations: int
    seconds: float
    c: tuple[float, ...]
    eps: float


def solve_design(model: CompiledModel, spec: DesignSpec,
                progress: Callable[[int, int, str], None] | None = None) -> DesignResult:
    """Design a gait for ``spec`` (module docstring): ``spec.starts`` seeded SLSQP runs, the
    best feasible one re-checked by :func:`verify`. ``progress(done, total, message)`` is
    called after every start. Deterministic for a given spec (seed included)."""
    t0 = time.perf_counter()
    prob = Problem(model, spec)
    rng = np.random.default_rng(spec.seed)
    runs: list[StartResult] = []
    for k in range(spec.starts):
        x0 = prob.start(None if k == 0 else rng)
        r = solve_start(prob, x0, k)
        runs.append(r)
        if progress is not None:
            ok = "feasible" if r.max_violation <= FEAS_TOL else f"violation {r.max_violation:.2g}"
            progress(k + 1, spec.starts, f"start {k}: objective {r.objective:.5g}, {ok}")
    order = sorted(runs, key=lambda r: (r.max_violation > FEAS_TOL, r.objective
                                        if r.max_violation <= FEAS_TOL else r.max_violation))
    chosen, check = None, None
    for r in order:
        if r.max_violation > FEAS_TOL:
            break
        g = prob.gait(r.x)
        F = prob.unpack(r.x)[2]
        chk = verify(model, g, spec, F, prob.eps)
        if chk["feasible"]:
            chosen, check = r, chk
            break
        if check is None:
            chosen, check = r, chk
    if chosen is None:
        chosen = order[0]
        check = verify(model, prob.gait(chosen.x), spec, prob.unpack(chosen.x)[2], prob.eps)
    ev = prob.evaluate(chosen.x)
    viol = ev.violations()
    feasible = bool(check["feasible"]) and chosen.max_violation <= FEAS_TOL
    blocking = None
    if not feasible:
        solver_bad = {k: v for k, v in viol.items() if v > FEAS_TOL}
        if solver_bad:
            blocking = max(solver_bad, key=solver_bad.get)
        else:
            blocking = check["failed"][0] if check["failed"] else "orbit"
        reason = (f"no feasible gait found in {spec.starts} start(s): blocked by {blocking} "
                  f"({describe(blocking, ev, prob)}; normalised violation "
                  f"{viol.get(blocking, 0.0):.3g} at the best point)")
        others = [k for k, v in sorted(viol.items(), key=lambda kv: -kv[1])
                  if v > FEAS_TOL and k != blocking]
        if others:
            reason += "; also violated: " + ", ".join(others)
        if check["failed"]:
            reason += "; re-check failed: " + ", ".join(check["failed"])
    else:
        reason = "feasible: every constraint re-checked on the periodic orbit"
    F = prob.unpack(chosen.x)[2]
    return DesignResult(feasible, reason, blocking, spec, prob.gait(chosen.x),
                        tuple(map(float, F)) if prob.m else (), check.get("objective"),
                        chosen.objective, viol, check, tuple(runs), prob.evaluations,
                        time.perf_counter() - t0, tuple(prob.c.tolist()), prob.eps)


def describe(family: str, ev: Evaluation, prob: Problem) -> str:
    """What family ``family`` asks for and what the point ``ev`` achieves (one phrase)."""
    s, i = prob.spec, ev.info
    if not ev.ok or not i:
        return "the point cannot be evaluated"
    mu = s.mu
    text = {
        "orbit": f"a periodic orbit with zeta > {s.min_zeta_ratio:g} zeta^- along the step: "
                 f"min zeta = {i['min_zeta']:.4g}, zeta^- = {i['zeta_minus']:.4g} kg^2 m^4/s^2",
        "stability": f"delta_zero^2 <= {s.max_delta_sq:g}: got {i['delta_zero_sq']:.4g}",
        "speed": f"speed {s.speed} m/s: reached {i['speed']:.4g} m/s",
        "step_length": f"step length {s.step_length} m: got {i['step_length']:.4g} m",
        "foot_placement": f"swing foot on the ground ahead of the stance foot at impact: "
                          f"step length {i['step_length']:.4g} m",
        "clearance": f"swing foot >= {s.clearance:g} m at mid-step: {i['mid_height']:.4g} m",
        "scuffing": f"swing foot above the ground over the step: lowest "
                    f"{i['min_height']:.4g} m",
        "vertical_force": f"F_1^v >= {prob.eps:.4g} N: min {i['min_vertical_force']:.4g} N",
        "friction": f"|F_1^h| <= mu F_1^v with mu = {mu:g}: max ratio "
                    f"{i['max_friction_ratio']:.4g}",
        "impact": f"impulse in the cone (mu = {mu:g}) and lift-off >= {s.min_liftoff:g} m/s: "
                  f"ratio {i['impact_friction_ratio']:.4g}, lift-off "
                  f"{i['liftoff_velocity']:.4g} m/s",
        "joint_range": "joint angles inside the robot file's ranges",
        "torque_limit": "joint torques inside the robot file's limits: max |u| = "
                        + ", ".join(f"{v:.4g}" for v in i["max_abs_torque"]) + " N m",
    }
    return text.get(family, family)
