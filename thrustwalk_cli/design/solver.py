"""Gait design: stable, walkable Bezier gaits found by constrained optimisation (SPEC 2, 3, 5).

The problem (decision variables, Chebyshev-Lobatto nodes, objectives, constraint families
and the solver's safety margins) is assembled in :mod:`thrustwalk_cli.design.problem`; the
independent re-check in :mod:`thrustwalk_cli.design.verify`; what to design in
:mod:`thrustwalk_cli.design.spec`. The report record and the gait file are rendered by
:mod:`thrustwalk_cli.studies.design_gait`.

Solver: SciPy SLSQP with one shared forward-difference Jacobian per point (its perturbed
points evaluated in one vectorised call, :meth:`Problem.evaluate_many`), several seeded starts
(start 0 is the deterministic default start), and a feasibility restoration (:func:`restore`:
the nearest point meeting every constraint) when a start ends a little infeasible. The chosen
gait is re-checked by the independent code paths (adaptive zero dynamics, :func:`limit_cycles`,
the contact evaluation, dense grids); ``feasible`` is the verdict of that re-check.
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
from .spec import (
    ELASTIC,
    FEAS_TOL,
    STABILITY_MARGIN,
    VELOCITY_MARGIN,
    DesignSpec,
    unbounded_warnings,
)
from .verify import show, verify


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
        """Forward-difference Jacobian of the objective and the constraints at ``x`` (steps
        ``1e-7 max(1, |x_j|)``): all perturbed points in one :meth:`Problem.evaluate_many`."""
        x = np.asarray(x, float)
        if self.jx is not None and np.array_equal(x, self.jx):
            return self.jac
        self.jx, self.jac = x.copy(), self.differences(x)
        return self.jac

    def differences(self, x: np.ndarray, batched: bool = True):
        """The forward differences of :meth:`jacobian` (not cached); ``batched=False``
        evaluates the perturbed points one at a time (the reference the tests compare with:
        the same numbers)."""
        f0, e0, i0 = self.flat(self.at(x))
        n = x.size
        h = 1e-7 * np.maximum(1.0, np.abs(x))
        xp = np.repeat(x[None, :], n, axis=0)
        xp[np.arange(n), np.arange(n)] += h
        evs = (self.p.evaluate_many(xp) if batched else [self.p.evaluate(xj) for xj in xp])
        rows = [self.flat(ev) for ev in evs]
        f1 = np.array([r[0] for r in rows])
        e1 = np.array([r[1] for r in rows]).reshape(n, e0.size)
        i1 = np.array([r[2] for r in rows]).reshape(n, i0.size)
        return ((f1 - f0) / h, ((e1 - e0) / h[:, None]).T, ((i1 - i0) / h[:, None]).T)


@dataclass(frozen=True)
class StartResult:
    """One solver run: its start index, SciPy's message (``status``), objective [SI], worst
    normalised violation, iterations, evaluations, wall time [s] and SciPy SLSQP's exit
    ``code`` (0: converged to a KKT point within ``ftol``; 8: positive directional derivative
    in the line search; 9: iteration limit; ...; None: the start could not be evaluated).
    ``restoration``: iterations of the feasibility restoration (:func:`restore`; 0: not run)
    and ``restored``: whether its point replaced SLSQP's (``x``, ``objective`` and
    ``max_violation`` are then the restored point's; ``code`` and ``status`` stay SLSQP's)."""

    index: int
    x: np.ndarray = field(repr=False)
    status: str
    objective: float
    max_violation: float
    iterations: int
    evaluations: int
    seconds: float
    code: int | None = None
    restoration: int = 0
    restored: bool = False


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
    slack left at the end measures that family's violation. When SLSQP's last point is a little
    infeasible (normalised violation in ``(FEAS_TOL, RESTORE_FROM]``), :func:`restore` projects
    it onto the constraints; the projection replaces it if it meets them to ``FEAS_TOL``.
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
    steps, restored = 0, False
    if FEAS_TOL < ev.max_violation <= RESTORE_FROM:
        xr, steps = restore(prob, x, cache)
        evr = prob.evaluate(xr)
        if evr.ok and evr.max_violation <= FEAS_TOL:
            x, ev, restored = xr, evr, True
    return StartResult(index, x, str(res.message), ev.objective, ev.max_violation,
                       int(res.nit), prob.evaluations - e0, time.perf_counter() - t0,
                       int(res.status), steps, restored)


RESTORE_FROM = 0.1  # largest normalised violation of SLSQP's point that restoration starts from
RESTORE_TOL = 1e-2 * FEAS_TOL  # normalised violation at which restoration stops
RESTORE_ITER = 30  # its iteration limit


def restore(prob: Problem, x_end: np.ndarray, cache: _Cache | None = None,
            max_iter: int = RESTORE_ITER) -> tuple[np.ndarray, int]:
    """Feasibility restoration: the point nearest to ``x_end`` (SLSQP's last point, a little
    infeasible) that meets every constraint, without slacks,

        min_x 1/2 |x - x_end|^2   s.t.   h(x) = 0,  g(x) >= 0,  bounds,

    in the scaled variables (all O(1), see :mod:`.problem`) and the normalised constraint
    families of :meth:`Problem.evaluate`; solved by SLSQP with the same forward-difference
    Jacobian (the objective and its gradient are exact), stopped as soon as the largest
    normalised violation is <= ``RESTORE_TOL`` (a hundredth of the solver's tolerance
    ``FEAS_TOL``) or after ``max_iter`` iterations. Its Hessian is the identity plus the
    constraints' curvature, so from a point near the feasible set it converges like
    Gauss-Newton in a few iterations, where SLSQP on the design objective keeps stepping along
    its quasi-Newton model of the objective and lands a little off the constraints (``design-
    gait`` on a footed walker ended 1e-5 to 1e-4 away for hundreds of iterations). Returns the
    last point and the iterations taken; the caller keeps it only if it is feasible. The
    objective is not minimised again: SLSQP's exit code (no certified optimum) still stands.
    """
    cache = cache or _Cache(prob)
    x_end = np.array(x_end, float)
    taken = [0]

    def enough(intermediate_result):
        taken[0] += 1
        if cache.at(intermediate_result.x).max_violation <= RESTORE_TOL:
            raise StopIteration

    if cache.at(x_end).max_violation <= RESTORE_TOL:
        return x_end, 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(
            lambda x: 0.5 * float(np.sum((x - x_end) ** 2)), x_end, jac=lambda x: x - x_end,
            method="SLSQP", bounds=prob.bounds(), callback=enough,
            constraints=[c for c in (
                {"type": "eq", "fun": lambda x: cache.flat(cache.at(x))[1],
                 "jac": lambda x: cache.jacobian(x)[1]},
                {"type": "ineq", "fun": lambda x: cache.flat(cache.at(x))[2],
                 "jac": lambda x: cache.jacobian(x)[2]}) if c["fun"](x_end).size],
            options={"maxiter": max_iter, "ftol": 1e-16})
    return np.asarray(res.x, float), max(taken[0], int(getattr(res, "nit", 0)))


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class DesignResult:
    """Outcome of :func:`solve_design` (SI units).

    feasible: the chosen gait passed the independent re-check (:func:`verify`); reason says
    why not otherwise, and ``blocking`` names the constraint family with the largest
    normalised violation at the best point. objective: value on the re-checked periodic orbit
    (``effort`` [N^2 m s] or ``peak`` [N m]). check: the re-check record (every margin).
    optimality: whether SLSQP certified the chosen start's point as a local optimum
    (:func:`optimality`). warnings: what the design does not guarantee (an uncertified
    optimum, joints without torque limits or ranges: :func:`~.spec.unbounded_warnings`).
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
    optimality: dict = field(default_factory=dict)
    warnings: tuple[str, ...] = ()


def solve_design(model: CompiledModel, spec: DesignSpec,
                progress: Callable[[int, int, str], None] | None = None,
                initial: WarmStart | None = None) -> DesignResult:
    """Design a gait for ``spec`` (module docstring): ``spec.starts`` seeded SLSQP runs, the
    best feasible one re-checked by :func:`verify`. ``progress(done, total, message)`` is
    called after every start. ``initial``: a finished neighbouring design (continuation)
    that replaces the default start 0 (when it fits this problem). Deterministic for a given
    spec (seed included) and start."""
    t0 = time.perf_counter()
    prob = Problem(model, spec)
    rng = np.random.default_rng(spec.seed)
    runs: list[StartResult] = []
    for k in range(spec.starts):
        x0 = None
        if k == 0 and initial is not None:
            x0 = prob.warm_start(initial.q_minus, initial.coefficients, initial.zeta_minus)
        if x0 is None:
            x0 = prob.start(None if k == 0 else rng)
        r = solve_start(prob, x0, k)
        runs.append(r)
        if progress is not None:
            ok = "feasible" if r.max_violation <= FEAS_TOL else f"violation {r.max_violation:.2g}"
            progress(k + 1, spec.starts, f"start {k}: objective {r.objective:.5g}, {ok}")
    order = sorted(runs, key=lambda r: (r.max_violation > FEAS_TOL, r.objective
                                        if r.max_violation <= FEAS_TOL else r.max_violation))
    chosen, check, x = None, None, None
    for r in order:
        if r.max_violation > FEAS_TOL:
            break
        xp = prob.polish(r.x)
        chk = verify(model, prob.gait(xp), spec, prob.unpack(xp)[2], prob.eps)
        if chk["feasible"]:
            chosen, check, x = r, chk, xp
            break
        if check is None:
            chosen, check, x = r, chk, xp
    if chosen is None:
        chosen = order[0]
        x = prob.polish(chosen.x)
        check = verify(model, prob.gait(x), spec, prob.unpack(x)[2], prob.eps)
    ev = prob.evaluate(x)
    viol = ev.violations()
    feasible = bool(check["feasible"]) and chosen.max_violation <= FEAS_TOL
    blocking = None
    if not feasible:
        solver_bad = {k: v for k, v in viol.items() if v > FEAS_TOL}
        if solver_bad:
            blocking = max(solver_bad, key=solver_bad.get)
            what = describe(blocking, ev, prob)
        else:
            blocking = check["failed"][0] if check["failed"] else "orbit"
            what = "re-check: " + check.get("failure_details", {}).get(blocking, blocking)
        reason = (f"no feasible gait found in {spec.starts} start(s): blocked by {blocking} "
                  f"({what}; normalised violation {viol.get(blocking, 0.0):.3g} at the best "
                  "point)")
        others = [k for k, v in sorted(viol.items(), key=lambda kv: -kv[1])
                  if v > FEAS_TOL and k != blocking]
        if others:
            reason += "; also violated: " + ", ".join(others)
        if check["failed"]:
            details = check.get("failure_details", {})
            reason += "; re-check failed: " + ", ".join(
                f"{f} ({details[f]})" if f in details else f for f in check["failed"])
        hint = suggestion(blocking, prob, runs)
        if hint:
            reason += f"; {hint}"
    else:
        reason = "feasible: every constraint re-checked on the periodic orbit"
    F = prob.unpack(x)[2]
    opt = optimality(chosen, spec)
    notes = list(unbounded_warnings(model.robot))
    if feasible and not opt["certified"]:
        notes.insert(0, opt["note"])
    return DesignResult(feasible, reason, blocking, spec, prob.gait(x),
                        tuple(map(float, F)) if prob.m or spec.thrust is not None else (),
                        check.get("objective"),
                        chosen.objective, viol, check, tuple(runs), prob.evaluations,
                        time.perf_counter() - t0, tuple(prob.c.tolist()), prob.eps,
                        opt, tuple(notes))


CONVERGED = 0  # SciPy SLSQP's exit code for a point meeting its KKT test within ftol
ITERATION_LIMIT_CODE = 9  # SciPy SLSQP's exit code when max_iter is reached


def optimality(chosen: StartResult, spec: DesignSpec) -> dict:
    """Whether SLSQP certified the chosen start's point as a (local) optimum: SciPy exit code
    0 only. Any other ending (8: positive directional derivative for the line search, 9:
    iteration limit, ...) may still leave a feasible point (the re-check decides), but its
    objective is not shown to be minimal: ``note`` says so, names the start and SLSQP's
    message, and what to try (parameters in backquotes, rendered as flags by the command
    line)."""
    certified = chosen.code == CONVERGED
    note = None
    if not certified:
        code = "no exit code" if chosen.code is None else f"exit code {chosen.code}"
        if chosen.code == ITERATION_LIMIT_CODE:
            hint = (f"a larger `max_iter` (it stopped at {spec.max_iter} iterations) or more "
                    "`starts`")
        else:
            hint = f"more `starts` (now {spec.starts}) or a larger `max_iter` (now {spec.max_iter})"
        note = (f"optimum not certified: the chosen start {chosen.index} ended with SLSQP "
                f"{code} ({chosen.status!r}), not a converged optimum; the gait meets every "
                f"constraint of the independent re-check, but a lower objective may exist: "
                f"try {hint}")
    return {"certified": certified, "start": chosen.index, "slsqp_code": chosen.code,
            "slsqp_message": chosen.status, "note": note}


@dataclass(frozen=True)
class WarmStart:
    """A finished design to start from (continuation): pre-impact posture ``q_minus``
    [rad], Bezier ``coefficients`` ((N-1) x (M+1) [rad], invariance applied) and
    ``zeta_minus`` [kg^2 m^4/s^2] of its periodic orbit."""

    q_minus: tuple[float, ...]
    coefficients: tuple[tuple[float, ...], ...]
    zeta_minus: float


ITERATION_LIMIT = "Iteration limit reached"  # SciPy SLSQP's message when max_iter is hit


def suggestion(family: str, prob: Problem, runs: list[StartResult]) -> str:
    """The option that usually helps when ``family`` blocks a design (parameters in
    backquotes, rendered as flags by the command line), and a larger ``max_iter`` when starts
    stopped at the iteration limit."""
    s, robot = prob.spec, prob.model.robot
    thrust = ("`thrust_design` (constant thrust can supply the energy each impact takes, e.g. "
              "for a compass walker on flat ground)"
              if robot.thrusters and not s.thrust_design else "")
    hints = {
        "orbit": thrust or "another `speed` or `step_length`, or a higher `order`",
        "stability": "a larger `max_delta_sq` or another `speed`",
        "speed": thrust or "another `step_length`, or a higher `order`",
        "step_length": "another `speed` or `step_length`",
        "clearance": "a smaller `clearance`",
        "scuffing": ("`clearance` 0 (the swing leg has no knee: its foot passes the stance "
                     "foot at best touching the ground, whatever the `order`)"
                     if s.clearance > 0 and _rigid_legs(robot)
                     else "a higher `order` or a larger `clearance`"),
        "vertical_force": "a smaller `min_vertical_force` or a lower `speed`",
        "friction": "a larger `mu` or a lower `speed`",
        "impact": "a larger `mu`",
        "touchdown": "a smaller `min_touchdown_velocity`",
        "joint_range": "another `speed` or `step_length`",
        "torque_limit": "a lower `speed`" + (" or `thrust_design`" if thrust else ""),
    }
    out = []
    if family in hints:
        out.append("try " + hints[family])
    stuck = sum(ITERATION_LIMIT in r.status for r in runs)
    if stuck:
        out.append(f"{stuck} of {len(runs)} start(s) stopped at the iteration limit "
                   f"(`max_iter` = {s.max_iter}): try a larger `max_iter`")
    return "; ".join(out)


def _rigid_legs(robot) -> bool:
    """Whether the swing foot is on a link jointed directly to the stance (root) link and
    at least as far from that joint as the joint is from the stance foot (a compass walker):
    then, with the stance foot pinned and the joint above the ground, the swing foot below
    the joint is at height <= 0 where it passes the stance foot (|x| <= a: height
    sqrt(a^2 - x^2) - sqrt(b^2 - x^2) <= 0 for b >= a), so no clearance > 0 is reachable."""
    links = {ln.name: ln for ln in robot.links}
    swing, stance = links.get(robot.swing_foot.link), links.get(robot.stance_foot.link)
    if swing is None or stance is None or swing.parent != stance.name:
        return False
    a = np.hypot(*(np.subtract(swing.joint, robot.stance_foot.point)))
    b = np.hypot(*robot.swing_foot.point)
    return bool(b >= a * (1 - 1e-9))


def describe(family: str, ev: Evaluation, prob: Problem) -> str:
    """The violated inequality of family ``family`` at the point ``ev``, with the numbers that
    show the violation (the solver's own bounds, safety margins included; enough digits to
    tell the value from the bound), e.g. ``zeta >= 0.02 zeta^- violated: min zeta = 0.5 <
    0.02 * 64.39 = 1.288 kg^2 m^4/s^2``."""
    s, i = prob.spec, ev.info
    if not ev.ok or not i:
        return "the point cannot be evaluated"
    if family == "orbit":
        return _describe_orbit(ev, prob)
    mu_d = s.mu - 0.005
    if family == "stability":
        a, b = show(i["delta_zero_sq"], s.max_delta_sq - STABILITY_MARGIN)
        return f"delta_zero^2 <= {b} violated: delta_zero^2 = {a} > {b}"
    if family == "speed":
        a, b = show(i["speed"], s.speed, "m/s")
        return f"speed = {b} violated: reached {a}"
    if family == "step_length":
        a, b = show(i["step_length"], s.step_length, "m")
        return f"step length = {b} violated: got {a}"
    if family == "foot_placement":
        return (f"swing foot on the ground at least {0.05 * prob.ell:.3g} m ahead of the stance "
                f"foot at impact violated: step length {i['step_length']:.4g} m")
    if family == "clearance":
        a, b = show(i["mid_height"], s.clearance, "m")
        return f"swing foot >= {b} at mid-step violated: {a} < {b}"
    if family == "scuffing":
        return (f"swing foot >= 0 over the step violated: lowest {i['min_height']:.3g} m < 0")
    if family == "vertical_force":
        target = prob.eps + 0.005 * prob.weight
        a, b = show(i["min_vertical_force"], target, "N")
        return (f"F_1^v >= {b} (eps {prob.eps:.4g} N + 0.5 % of the weight) violated: "
                f"min F_1^v = {a} < {b}")
    if family == "friction":
        a, b = show(i["max_friction_ratio"], mu_d)
        return (f"|F_1^h| <= {b} F_1^v (mu = {s.mu:g} less 0.005) violated: max |F_1^h|/F_1^v "
                f"= {a} > {b}")
    if family == "impact":
        lift = s.min_liftoff + VELOCITY_MARGIN
        if i["impact_friction_ratio"] > mu_d:
            a, b = show(i["impact_friction_ratio"], mu_d)
            return (f"impact impulse |F_2^h| <= {b} F_2^v violated: |F_2^h|/F_2^v = {a} > {b}")
        a, b = show(i["liftoff_velocity"], lift, "m/s")
        return f"trailing foot lift-off >= {b} violated: {a} < {b}"
    if family == "touchdown":
        a, b = show(i["touchdown_velocity"], -(s.min_touchdown_velocity + VELOCITY_MARGIN),
                    "m/s")
        return (f"swing foot moving down at touchdown, vertical velocity <= {b}, violated: "
                f"{a} > {b}")
    if family == "joint_range":
        names = prob.model.robot.coordinate_names
        k = int(np.argmin(i["joint_range_margin"]))
        return (f"joint angles inside the robot file's ranges less 0.01 rad violated: "
                f"{names[k]} outside by {-i['joint_range_margin'][k]:.3g} rad")
    if family == "torque_limit":
        act = [c.name for c in prob.model.robot.coordinates if c.actuated]
        ratio = i["max_abs_torque"] / prob.torque_limit
        k = int(np.argmax(ratio))
        a, b = show(i["max_abs_torque"][k], 0.99 * prob.torque_limit[k], "N m")
        return f"|u_{act[k]}| <= 99 % of its limit = {b} violated: max |u_{act[k]}| = {a} > {b}"
    return family


def _describe_orbit(ev: Evaluation, prob: Problem) -> str:
    """The worst part of the ``orbit`` family (see :meth:`Problem.evaluate`)."""
    s, i = prob.spec, ev.info
    p = i["orbit_parts"]
    worst = {"fixed_point": p["fixed_point"]}
    for k in ("zeta", "delta", "kappa1", "monotonic", "range"):
        v = np.atleast_1d(p[k])
        worst[k] = float(np.maximum(-v, 0.0).max(initial=0.0))
    part = max(worst, key=worst.get)
    zm, d2 = i["zeta_minus"], i["delta_zero_sq"]
    if part == "zeta":
        a, b = show(i["min_zeta"], s.min_zeta_ratio * zm)
        return (f"zeta >= {s.min_zeta_ratio:g} zeta^- violated: min zeta = {a} < "
                f"{s.min_zeta_ratio:g} * {zm:.4g} = {b} kg^2 m^4/s^2")
    if part == "fixed_point":
        a, b = show((1.0 - d2) * zm, i["V_f"])
        return (f"periodic orbit (1 - delta_zero^2) zeta^- = V_Z(alpha_f) violated: {a} != {b} "
                "kg^2 m^4/s^2")
    if part == "delta":
        return f"delta_zero^2 >= 0.001 violated: delta_zero^2 = {d2:.4g}"
    if part == "kappa1":
        return ("kappa_1 of one sign over the step (alpha monotonic) violated: e_N^T D Phi "
                "changes sign or nears 0")
    if part == "monotonic":
        return (f"|alpha_f - alpha_i| >= 0.05 rad in the walking direction violated: "
                f"alpha_f - alpha_i = {i['span']:.4g} rad")
    return ("a periodic orbit with zeta* > 0 and zeta >= "
            f"{s.min_zeta_ratio:g} zeta^- at the ends of the thrust range violated")
