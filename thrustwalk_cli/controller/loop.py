"""The step-to-step controller in closed loop with the full-order compiled simulation (SPEC 7,
11, 12).

At every impact the controller measures ``x_k`` (zeta^- of the plant, with a seeded uniform
relative error ``e_k in [-noise, noise]``: ``x_meas = x_k (1 + e_k)``), solves the SPEC 11 QP
(:class:`~thrustwalk_cli.controller.planner.Planner`) and sets the thrust values of the next step
on the plant (:class:`thrustwalk_cli.simulation.stepper.Stepper`, ``set_thrust`` between
steps). The plant may differ from the controller's model (its own robot parameters, the same
virtual constraints) and may be pushed (impulse at a phase of a step, SPEC 12).

Certificate (per step). *Certified*: the plan's polished worst points (the planner's
continuous conditions, :class:`~thrustwalk_cli.controller.planner.Planner`) are inside the
cone to the planner's tolerance over the measurement band, the QP was feasible and the impact
admissible. *Flagged*: the model's ground force ``F_1(alpha)`` for the chosen thrust, over the
band of true ``x_k`` the measurement allows and widened by the fit error bound and a numerical
tolerance (``REL_TOL``), against the realised ``F_1`` of the full-order step sampled along it
(at the realised alpha); a step whose realised force or ``x_{k+1}`` leaves that band did not
behave as predicted (a push, a plant that differs, a lagging thruster the controller ignored,
outputs off the manifold). *Realised* extremes of the step: ``F_1`` on ``REALISED_SAMPLES``
times of the step's dense output (every integration piece sampled end to end, so the jumps of
the thrust at the knots are not bridged), each local extremum that could reach the limit
polished by golden section between its neighbouring samples, and the simulation kernel's own
statistics; ``in_cone`` holds them to the cone within ``CONE_TOL`` (the simulation's accuracy:
an active friction row is realised at mu to about 1e-9). Units SI.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..contact.evaluate import friction_ratio
from ..hzd.extrema import golden_min, grid_miss, neighbours, peaks
from ..hzd.zero_dynamics import ZeroDynamics
from ..simulation import kernel as K
from ..simulation.batch import push_row
from ..simulation.closed_loop import ClosedLoop, SimConfig, ThrustModel
from ..simulation.full_order import Start, initial_state
from ..simulation.records import behind_level, missed_footing
from ..simulation.stepper import Stepper, failure_text, step_record
from ..thrust.dynamics import ThrusterDynamics
from ..thrust.schedule import Schedule
from .planner import Plan, Planner, predicted_margins
from .step_model import interval_of

SAMPLES = 81  # samples per step for the certificate and the figures
REL_TOL = 1e-6  # numerical tolerance of the comparison, relative to the weight and to |F_1|
REALISED_SAMPLES = 201  # samples per step of the realised extremes (then polished)
REALISED_POLISH = 20  # golden-section steps of the realised extremes (bracket shrinks 7e-5)
CONE_TOL = 1e-7  # realised cone: friction ratio [1], and F^v relative to the weight


@dataclass(frozen=True)
class Push:
    """An impulse ``(P_x, P_y)`` [N s] at the end of the stance link (the hip of a
    one-link stance leg, a kneed walker's stance knee) at phase ``s``
    of step ``step`` (SPEC 12)."""

    step: int
    s: float
    impulse: tuple[float, float]


@dataclass
class StepLog:
    """One step of a run (SI units). ``plan`` is None for the uncontrolled walker."""

    step: int
    t_start: float
    t_impact: float
    x_true: float
    x_meas: float
    x_ref: float | None
    u: np.ndarray
    plan: Plan | None
    x_next: float
    step_time: float
    speed: float
    min_vertical_force: float
    max_friction_ratio: float | None
    impact_friction_ratio: float
    pushed: bool
    thrust_at_impact: np.ndarray
    predicted: dict | None = None
    realised: dict | None = None
    certificate: dict | None = None
    samples: dict = field(default_factory=dict, repr=False)
    #: what the step's energies are computed from (``energetics.run.run_energy``): the
    #: step's closed loop with its own thrust and ``(step, pieces, q^-, q'^-)``
    energy_input: tuple | None = field(default=None, repr=False)
    terrain_height: float = 0.0  # [m] the ground the step landed on (SPEC 14; 0: level)


@dataclass
class Run:
    """A closed-loop (or uncontrolled) run: ``success`` false when it stopped early
    (``failure``, ``reason`` as the simulation words them)."""

    label: str
    success: bool
    failure: str
    reason: str
    steps: list[StepLog]


def segment_intervals(cl: ClosedLoop, knots: np.ndarray, zd: ZeroDynamics) -> np.ndarray:
    """Knot interval of each simulation segment (breakpoints at the knots and the guard)."""
    edges = [-np.inf] + list(cl.breaks) + [np.inf]
    mids = [0.5 * (max(lo, 0.0) + min(hi, 1.0)) for lo, hi in zip(edges[:-1], edges[1:])]
    alpha = zd.alpha_i + np.array(mids) * zd.maps.span
    return interval_of(knots, alpha)


def run_loop(plant: ZeroDynamics, planner: Planner | None, *, label: str, steps: int,
             x0: float, refs: np.ndarray | None, knots: np.ndarray, driven: list[int],
             dynamics: ThrusterDynamics | None, f0: float = 0.0, pushes: tuple[Push, ...] = (),
             noise: float = 0.0, seed: int = 0, config: SimConfig = SimConfig(),
             t_max: float = 10.0, mu: float = 0.7, eps: float = 0.0,
             progress=None, heights=None) -> Run:
    """Run ``steps`` steps of the plant from the post-impact state of ``zeta^- = x0`` on Z;
    ``planner`` None: the uncontrolled walker (all thrust setpoints 0). ``refs[k-1]``: the
    reference for ``x_{k+1}`` [kg^2 m^4/s^2]; ``dynamics``: the plant's thruster dynamics (None:
    ideal thrust on ``knots``). ``heights``: the terrain (SPEC 14), step ``k``'s swing foot
    landing ``heights[k - 1]`` [m] above its stance foot (the guard; past ``config.max_s``
    without touching the ground: ``missed_footing``), None: level ground; the planner's step
    model stays that of level (or sloped) ground and sees each step through its measured
    zeta^-."""
    model = plant.model
    m = model.n_thrusters
    md = len(driven)
    knots = np.asarray(knots, float)
    n_int = len(knots) - 1
    if dynamics is None:
        sched = Schedule.zero(knots, m)
        th = ThrustModel("piecewise", np.zeros(m), schedule=sched)
    else:
        th = ThrustModel(dynamics.kind, np.zeros(m), initial=np.full(m, f0), dynamics=dynamics)
    cfg = SimConfig(steps=1, rtol=config.rtol, atol=config.atol, scuff_tol=config.scuff_tol,
                    min_impact_s=config.min_impact_s, torque_limit=config.torque_limit,
                    max_s=config.max_s)
    cl = ClosedLoop(plant, th, cfg)
    stepper = Stepper(cl, t_max, dense=True)
    seg_int = segment_intervals(cl, knots, plant) if dynamics is None else None
    x = initial_state(plant, th, Start(zeta_minus=x0))
    N, nz = model.n, th.n_states
    rng = np.random.default_rng(seed)
    nu = planner.nu if planner is not None else (n_int * md if dynamics is None else md)
    u_prev = np.zeros(nu)
    t = 0.0
    x_true = float(x0)
    logs: list[StepLog] = []
    weight = model.robot.total_mass * model.robot.gravity
    for k in range(1, steps + 1):
        e = rng.uniform(-noise, noise) if noise > 0 else 0.0
        x_meas = x_true * (1.0 + e)
        z = x[2 * N:2 * N + nz]
        plan = None
        if planner is not None:
            plan = planner.plan(x_meas, float(refs[k - 1]), u_prev, z)
            u = plan.u
        else:
            u = np.zeros(nu)
        # the plant's thrust: per segment (ideal) or the setpoints (dynamic)
        if dynamics is None:
            per = u.reshape(-1, md)  # intervals x driven (one interval for a dynamic model)
            if per.shape[0] != n_int:  # a planner with one interval on a multi-knot plant
                per = np.repeat(per[:1], n_int, axis=0)
            seg_force = np.zeros((len(seg_int), m))
            seg_force[:, driven] = per[seg_int]
            stepper.set_thrust(seg_force=seg_force)
        else:
            target = np.zeros(m)
            target[driven] = u.reshape(-1, md)[0]
            stepper.set_thrust(target=target)
        push = next((p for p in pushes if p.step == k), None)
        row = None if push is None else push_row(model, k, push.s, push.impulse)
        h = 0.0 if heights is None else float(heights[k - 1])
        res = stepper.step(k, t, x, push=row, ground=h, behind=behind_level(heights, k))
        if res.status != 0:
            kind, text = failure_text(res.outcome, cfg, t_max)
            if (heights is not None and int(res.outcome[K.O_STATUS]) == K.FAIL_EVENT
                    and int(res.outcome[K.O_EVENT]) == K.EV_OVERSHOOT):
                kind, text = missed_footing(cfg.max_s, h, res.outcome[K.O_T])
            return Run(label, False, kind, f"step {k}: {text}", logs)
        rec = step_record(res.record, N, nz, m)
        length = float(model.p_swing(np.asarray(rec.q_minus))[0])
        log = StepLog(
            step=k, t_start=rec.t_start, t_impact=rec.t_impact, x_true=x_true, x_meas=x_meas,
            x_ref=None if refs is None else float(refs[k - 1]), u=np.asarray(u, float),
            plan=plan, x_next=rec.zeta_minus, step_time=rec.step_time,
            speed=length / rec.step_time, min_vertical_force=rec.min_vertical_force,
            max_friction_ratio=rec.max_friction_ratio,
            impact_friction_ratio=rec.impulse_friction_ratio, pushed=push is not None,
            thrust_at_impact=np.asarray(rec.thrust_at_impact, float), terrain_height=h)
        step_cl = _sample(log, res.pieces, plant, th, u, knots, driven, dynamics, cfg,
                          None if plan is None else (eps, mu))
        log.energy_input = (step_cl, (k, res.pieces, rec.q_minus, rec.dq_minus))
        if plan is not None:
            _certify(log, planner, plan, weight, mu, eps)
        logs.append(log)
        x_true = rec.zeta_minus
        x = res.x_next
        t = rec.t_impact
        u_prev = np.asarray(u, float)
        if progress is not None:
            progress(1)
    return Run(label, True, "", f"completed {steps} steps", logs)


def _sample(log: StepLog, pieces: list, plant: ZeroDynamics, th: ThrustModel, u: np.ndarray,
            knots: np.ndarray, driven: list[int], dynamics, cfg: SimConfig,
            extremes: tuple[float, float] | None = None) -> ClosedLoop:
    """Realised time histories of the step at ``SAMPLES`` times: alpha, thrust, F_1; with
    ``extremes = (eps, mu)`` also the polished realised extremes
    (:func:`realised_extremes`). Returns the step's closed loop (its own thrust)."""
    m = plant.model.n_thrusters
    if dynamics is None:  # the simulation's own schedule for this step
        md = len(driven)
        per = np.asarray(u, float).reshape(-1, md)
        force = np.zeros((1, len(knots) - 1, m))
        force[0][:, driven] = per if per.shape[0] == len(knots) - 1 else per[:1]
        th = ThrustModel("piecewise", np.zeros(m),
                         schedule=Schedule(knots, force, np.zeros((1, len(knots) - 1))))
    cl = ClosedLoop(plant, th, cfg)
    ts = np.linspace(log.t_start, log.t_impact, SAMPLES)
    X = np.zeros((SAMPLES, pieces[0][3](pieces[0][0]).size))
    seg = np.zeros(SAMPLES, int)
    for j, (ta, tb, sg, sol) in enumerate(pieces):
        last = j == len(pieces) - 1
        sel = (ts >= ta) & ((ts <= tb) if last else (ts < tb))
        if j == 0:
            sel |= ts < ta
        if last:
            sel |= ts > tb
        if sel.any():
            X[sel] = sol(ts[sel]).T
            seg[sel] = sg
    d = cl.details(X, seg)
    log.samples = {"t": ts, "alpha": d["alpha"], "F": d["F"], "F1": d["F1"]}
    if extremes is not None:
        log.samples["extremes"] = realised_extremes(cl, pieces, log.t_start, log.t_impact,
                                                    *extremes)
    return cl


def realised_extremes(cl: ClosedLoop, pieces: list, t0: float, t1: float, eps: float,
                      mu: float) -> dict:
    """The step's least ``F_1^v`` [N] and largest ``|F_1^h|/F_1^v`` [1] on its dense output:
    ``REALISED_SAMPLES`` times, each integration piece sampled end to end (a piece holds one
    thrust segment), every local extremum that the sampling could hide beyond the limit
    polished by golden section between its neighbouring samples (:mod:`~thrustwalk_cli.hzd.
    extrema`), with the times and alphas where they occur."""
    span = max(t1 - t0, 1e-300)
    t_all, piece, X = [], [], []
    for p, (ta, tb, _, sol) in enumerate(pieces):
        if not tb > ta:
            continue
        n = max(5, int(np.ceil(REALISED_SAMPLES * (tb - ta) / span)) + 1)
        t = np.linspace(ta, tb, n)
        t_all.append(t)
        piece.append(np.full(n, p))
        X.append(sol(t).T)
    t_all, piece, X = np.concatenate(t_all), np.concatenate(piece), np.vstack(X)
    segs = np.array([pieces[p][2] for p in range(len(pieces))], int)
    d = cl.details(X, segs[piece])
    F1 = d["F1"]
    bad = {"v": -F1[:, 1], "r": friction_ratio(F1)}
    limit = {"v": -eps, "r": mu}
    ent_q, ent_j = [], []
    for q, b in bad.items():
        top = float(np.max(np.where(np.isfinite(b), b, -np.inf), initial=-np.inf))
        j = peaks(b, piece, min(limit[q], top) - grid_miss(b, piece), 8)
        ent_q += [q] * j.size
        ent_j.append(j)
    ent_j = np.concatenate(ent_j)
    ent_q = np.array(ent_q)
    ent_p = piece[ent_j]

    def state(t: np.ndarray) -> np.ndarray:
        out = np.empty((t.size, X.shape[1]))
        for p in np.unique(ent_p):
            sel = ent_p == p
            out[sel] = pieces[p][3](t[sel]).T
        return out

    def objective(t: np.ndarray) -> np.ndarray:
        F = cl.details(state(t), segs[ent_p])["F1"]
        val = np.where(ent_q == "v", -F[:, 1], friction_ratio(F))
        return np.where(np.isfinite(val), -val, 1e300)

    lo, hi = neighbours(t_all, ent_j, piece)
    t_pol, f_pol = golden_min(objective, lo, hi, REALISED_POLISH)
    grid_bad = np.array([bad[q][j] for q, j in zip(ent_q, ent_j)])
    better = -f_pol > grid_bad
    worst = np.where(better, -f_pol, grid_bad)
    t_worst = np.where(better, t_pol, t_all[ent_j])
    out = {"samples": int(t_all.size)}
    ks = [int(sel[np.argmax(worst[sel])]) for sel in (np.flatnonzero(ent_q == q)
                                                       for q in ("v", "r"))]
    X_w = np.vstack([pieces[ent_p[k]][3](np.array([t_worst[k]])).T for k in ks])
    a_w = cl.details(X_w, segs[ent_p[ks]])["alpha"]
    for k, a, (q, name) in zip(ks, a_w, (("v", "min_vertical_force"),
                                         ("r", "max_friction_ratio"))):
        out[name] = float(worst[k]) if q == "r" else -float(worst[k])
        out[f"t_at_{name}"] = float(t_worst[k])
        out[f"alpha_at_{name}"] = float(a)
    return out


def _certify(log: StepLog, planner: Planner, plan: Plan, weight: float, mu: float,
             eps: float) -> None:
    """Predicted vs realised margins, and whether reality stayed inside the prediction's
    error bound (see the module docstring)."""
    zd = planner.zd
    lo_a, hi_a = min(zd.alpha_i, zd.alpha_f), max(zd.alpha_i, zd.alpha_f)
    alpha = np.clip(log.samples["alpha"], lo_a, hi_a)
    rw = planner.rows_at(alpha)
    Fm = rw.force(plan.x_meas, plan.u)
    Fa, Fb = rw.force(plan.x_band[0], plan.u), rw.force(plan.x_band[1], plan.u)
    F1 = log.samples["F1"]
    E = planner.error_bound(rw, plan.x_band[1])
    tol = REL_TOL * (weight + np.abs(Fm).max()) + E[:, None]
    lo, hi = np.minimum(Fa, Fb) - tol, np.maximum(Fa, Fb) + tol
    outside = np.maximum(lo - F1, F1 - hi).max(initial=0.0)
    xlo, xhi = plan.x_next_band
    xtol = REL_TOL * max(abs(plan.x_next), 1.0)
    x_out = max(xlo - xtol - log.x_next, log.x_next - xhi - xtol, 0.0)
    log.samples["F1_predicted"] = Fm
    if plan.margins is not None:
        pred = dict(plan.margins)
    else:
        grid = planner.grid_rows()
        pred = predicted_margins(plan, grid, mu, planner.error_bound(grid, plan.x_band[1]),
                                 eps)
    ext = log.samples["extremes"]
    real_v = min(ext["min_vertical_force"], log.min_vertical_force)
    kr = log.max_friction_ratio if log.max_friction_ratio is not None else np.inf
    real_r = max(ext["max_friction_ratio"], kr)
    cone_v = CONE_TOL * weight
    log.predicted = {**pred, "x_next": plan.x_next, "x_next_band": list(plan.x_next_band)}
    log.realised = {"min_vertical_force": real_v,
                    "max_friction_ratio": float(real_r) if np.isfinite(real_r) else None,
                    "alpha_at_min_vertical_force": ext["alpha_at_min_vertical_force"],
                    "alpha_at_max_friction_ratio": ext["alpha_at_max_friction_ratio"],
                    "x_next": log.x_next,
                    "in_cone": bool(real_v >= eps - cone_v and np.isfinite(real_r)
                                    and real_r <= mu + CONE_TOL
                                    and log.impact_friction_ratio <= mu)}
    certified = bool(pred["feasible"] and plan.status != "infeasible" and planner.impact_ok)
    log.certificate = {
        "certified": certified,
        "flagged": bool(outside > 0 or x_out > 0),
        "max_force_outside_bound": float(outside),
        "x_next_outside_bound": float(x_out),
        "force_tolerance": float(tol.max()),
        "cutting_planes": [float(a) for a in plan.cut_alpha],
    }
