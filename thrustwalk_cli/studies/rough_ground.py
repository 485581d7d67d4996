"""The ``rough-ground`` study (SPEC 14): the mean first passage time (MFPT, steps attempted up to
and including the failing one) against the roughness sigma, per thrust strategy, two ways.

* **Monte-Carlo**: ``trials`` full-order runs per (strategy, sigma) from the strategy's fixed
  point on i.i.d. seeded step heights until failure or ``cap`` steps
  (:mod:`thrustwalk_cli.resilience.rough`), every run a point of the sweep engine (study
  ``rough-trial``: keyed by content, local processes or Dask, recorded one by one, so a stopped
  run resumes). Estimate: the geometric MLE with censored runs counted, and its Clopper-Pearson
  95 % interval (:mod:`thrustwalk_cli.resilience.mfpt`).
* **Mesh Markov chain**: the one-step full-order map from ``mesh + 1`` level-equivalent
  ``zeta^-`` values around the fixed point (over the labels the terrain can reach) on
  ``terrain_samples + 1`` heights over ``+-6 sigma_max`` (uniform: the support), failure edges
  located by bisection; per sigma the transition matrix integrates the height's density exactly
  cell by cell; ``MFPT = 1/(1 - lambda_2)`` and the expected steps from the fixed point
  ``(I - Q)^-1 1``. Uncertainty: the larger change of ``1/(1 - lambda_2)`` with half the mesh
  points or half the terrain samples. The residual of the reduction (the outputs' error after
  an impact on a step, dropped by the chain) is measured and reported.

Agreement per (strategy, sigma): the mesh's expected steps from the fixed point inside the
Monte-Carlo 95 % interval. The headline: the sigma at which each strategy's mesh MFPT crosses
``target`` steps (log-linear interpolation in sigma), against ``none``. Units SI (sigma in m).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import (
    InputError,
    check_callable,
    check_choice,
    check_count,
    check_instance,
    check_number,
    check_numbers,
    check_text,
)
from ..files.sweep_file import STUDY_PARAMETERS
from ..resilience.mfpt import chain_mfpt, mc_estimate
from ..resilience.rough import (
    DISTRIBUTIONS,
    FAILURES,
    build_step_map,
    half_width,
    success_interval,
    transition_matrix,
    visited_range,
)
from ..resilience.strategy import Strategy, labels_unique
from ..sweep.runner import RunCounts, chunk_size, run_tasks
from ..sweep.tasks import PointTask, identity, task_key
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, Table, col, gait_record, result_repr, robot_record, units
from .robustness import parse_strategy, walker_texts
from .sweep_studies import STUDIES, run_point
from .trial_studies import check_strategy, realized_strategy, rough_runner

MAX_SIGMAS = 200
MAX_TRIALS = 100_000
MAX_CAP = 1_000_000
TARGET = 1000.0  # [steps] the headline's MFPT
HEIGHT_RANGE = 6.0  # the mesh's heights span +- this many sigma_max (normal)
VISIT_STEPS = 400  # the walk whose visited zeta^- the mesh covers
TRIALS_PER_CHUNK = 8  # Monte-Carlo trials per engine task at most
MESH_THREADS = 2  # threads of the mesh's one-step simulations (the kernel releases the GIL;
#                   control: 1, its planner is not shared between threads)
UNITS = units("zeta", sigma="m", mfpt="steps", height="m", output_y="rad")
DEFINITIONS = {
    "mfpt": "mean first passage time: expected steps attempted up to and including the one "
            "that fails (completed steps + 1); 1/p for a per-step failure probability p",
    "outcomes": {
        "censored": "the run reached the cap without failing (counted with its steps, not "
                    "dropped)",
        "fell": "the stance leg passed the horizontal, or no impact came",
        "stopped": "alpha reversed: the walker stopped and fell back",
        "scuffed": "an early strike before the guard was armed (a step up too high), or the "
                   "trailing foot did not lift off at impact",
        "lifted": "the vertical ground force dropped to min_vertical_force, or the impact "
                  "impulse did not press on the ground",
        "slipped": "the stance force or the impact impulse left the friction cone",
        "missed_footing": "no touchdown by s_max (a step down too deep)",
        "error": "the run could not be computed: no verdict (counted as censored at its last "
                 "completed step)",
    },
    "monte_carlo": "geometric MLE T/F (F failures, T steps attempted by every run, censored "
                   "ones included) with the Clopper-Pearson 95 % interval of p = F/T inverted",
    "mesh": "Markov chain on the pre-impact state reduced to (zeta^-, h): zeta^- at an impact "
            "and the height of its ground (the state on Z there; output_error_at_impact: the "
            "largest max |y| left at an impact, what the reduction drops), its transitions "
            "from one-step full-order simulations integrated over the next height's density; "
            "mfpt = 1/(1 - lambda_2), lambda_2 the largest eigenvalue of the transition matrix "
            "among the non-failed states; from_fixed_point = (I - Q)^-1 1 from the level "
            "impact at the fixed point",
    "uncertainty": "the larger |change| of the mesh mfpt with half the mesh points or half the "
                   "terrain samples",
    "agreement": "agree: the mesh's from_fixed_point lies inside the Monte-Carlo 95 % interval "
                 "(with no failure in the Monte-Carlo, above its lower end); disagree "
                 "otherwise; not compared: a side is missing",
}


def _defaults() -> dict:
    return {f.key: f.default for f in STUDY_PARAMETERS["rough-trial"].fields}


@dataclass(frozen=True)
class RoughGroundPlan:
    """Everything a rough-ground run computes, checked and keyed before any trial: the
    strategies (made concrete), the sigmas [m], one task per trial (``where``: (strategy,
    sigma, trial) of each) and the mesh settings."""

    walker: Walker = field(repr=False)
    strategies: tuple[Strategy, ...]
    realized: tuple = field(repr=False)
    params: tuple[dict, ...] = field(repr=False)
    sigmas: tuple[float, ...]
    settings: dict
    tasks: tuple[PointTask, ...] = field(repr=False)
    where: tuple[tuple[int, int, int], ...] = field(repr=False)
    identity: str
    warnings: tuple[str, ...] = ()


def plan_rough_ground(walker: Walker, *, sigma: Sequence[float],
                      strategy: Sequence[str | Strategy] | None = None, trials: int = 50,
                      cap: int = 1000, seed: int = 0, distribution: str = "normal",
                      mesh: int = 20, terrain_samples: int = 24, s_max: float = 1.3,
                      mu: float | None = None, min_vertical_force: float = 0.0,
                      thruster: str | None = None, knots: Sequence[float] = (0.0, 0.5, 1.0),
                      max_thrust: float | None = None, target: float = TARGET,
                      rtol: float = 1e-9, atol: float = 1e-9) -> RoughGroundPlan:
    """Check every option and key every Monte-Carlo trial (module docstring; SI units):
    ``sigma`` [m] standard deviations of the step heights (>= 0), ``strategy`` (default none
    and control; none alone for a robot without thrusters), ``trials`` per (strategy, sigma),
    ``cap`` steps per trial, ``seed`` of the terrains, ``distribution`` normal or uniform,
    ``mesh`` and ``terrain_samples`` (even: their halves are the refinement), ``s_max`` [1]
    the missed-footing limit, the cone (``mu``, ``min_vertical_force`` [N]), the controller
    (``thruster``, ``knots``, ``max_thrust`` [N]), ``target`` [steps] the headline's MFPT and
    the integrator tolerances."""
    check_walker(walker)
    sigmas = check_numbers("sigma", sigma, max_len=MAX_SIGMAS, ge=0, le=1, unit="m")
    if strategy is not None and (isinstance(strategy, (str, bytes)) or
                                 not hasattr(strategy, "__iter__")):
        raise InputError.param("strategy", f"must be a list of strategies (e.g. [\"none\", "
                                           f"\"constant:-20\"]), got {type(strategy).__name__}")
    trials = check_count("trials", trials, le=MAX_TRIALS)
    cap = check_count("cap", cap, le=MAX_CAP)
    seed = check_count("seed", seed, ge=0, le=2 ** 63 - 1)
    distribution = check_choice("distribution", distribution, DISTRIBUTIONS)
    mesh = check_count("mesh", mesh, ge=4, le=400)
    terrain_samples = check_count("terrain_samples", terrain_samples, ge=4, le=400)
    s_max = check_number("s_max", s_max, gt=1, le=3)
    mu = check_number("mu", mu, gt=0, optional=True)
    min_vertical_force = check_number("min_vertical_force", min_vertical_force, ge=0,
                                      unit="N")
    check_text("thruster", thruster, optional=True)
    knots = check_numbers("knots", knots)
    max_thrust = check_number("max_thrust", max_thrust, gt=0, optional=True, unit="N")
    target = check_number("target", target, gt=1, le=1e12)
    rtol = check_number("rtol", rtol, gt=0, lt=0.1)
    atol = check_number("atol", atol, gt=0, lt=0.1)
    if mesh % 2 or terrain_samples % 2:
        raise InputError.param("mesh" if mesh % 2 else "terrain_samples",
                               "must be even (its half is the refinement check)")
    if len(set(sigmas)) != len(sigmas):
        raise InputError.param("sigma", "a value is given twice")
    if len(sigmas) * trials > MAX_TRIALS:
        raise InputError.param("trials", f"{len(sigmas) * trials} trials per strategy: the "
                                         f"limit is {MAX_TRIALS}")
    zd, robot = walker.zd, walker.robot
    if max_thrust is not None and robot.thrusters:
        robot.check_thrust_bound("max_thrust", max_thrust, [robot.thruster_index(thruster)])
    if not zd.valid:
        raise InputError.param("gait", f"the gait has no walking orbit: {zd.invalid_reason}")
    if strategy is None:
        strategy = ["none", "control"] if robot.thrusters else ["none"]
    strategies = [parse_strategy(s, walker, thruster, knots, max_thrust) for s in strategy]
    if not strategies:
        raise InputError.param("strategy", "no strategy")
    labels_unique(strategies)
    robot_text, gait_text = walker_texts(walker)
    common = {"cap": int(cap), "seed": int(seed), "distribution": distribution,
              "s_max": float(s_max), "mu": mu, "min_vertical_force": float(min_vertical_force),
              "rtol": float(rtol), "atol": float(atol)}
    realized, params, warnings = [], [], []
    for s in strategies:
        p = {**_defaults(), **common, **s.parameters()}
        for _name, msg in check_strategy(walker, p):
            raise InputError.param("strategy", f"{s.label}: {msg}")
        real, _ = realized_strategy(walker, p)
        realized.append(real)
        params.append(p)
        warnings += [f"{s.label}: {n}" for n in real.notes]
        if real.zeta_ref is None:
            warnings.append(f"{s.label}: no orbit to start on ({real.cycle.reason}); its "
                            "trials are errors and it has no mesh chain")
    tasks, where = [], []
    for k in range(len(strategies)):
        st = {**params[k]}
        for i, sg in enumerate(sigmas):
            for t in range(trials):
                values = {"sigma": float(sg), "trial": float(t)}
                key = task_key("rough-trial", robot_text, gait_text, st, values)
                tasks.append(PointTask(len(tasks), key, "rough-trial", tuple(values.items()),
                                       tuple(st.items()), robot.source_file, robot_text,
                                       walker.gait.source_file, gait_text,
                                       label=f"rough-ground trial {len(tasks)}"))
                where.append((k, i, t))
    settings = {**common, "mu": zd.gait.mu if mu is None else float(mu),
                "sigmas": [float(v) for v in sigmas], "trials": int(trials),
                "strategies": [s.parameters() for s in strategies],
                "terrain": {"distribution": distribution,
                            "sigma": "standard deviation of the step heights" + (
                                "; uniform on [-sqrt(3) sigma, sqrt(3) sigma]"
                                if distribution == "uniform" else ""),
                            "draws": "trial t: numpy.random.default_rng(SeedSequence([seed, "
                                     "t]) state) standard draws scaled by sigma, the same for "
                                     "every sigma and strategy"},
                "mesh": {"points": int(mesh) + 1, "terrain_samples": int(terrain_samples) + 1,
                         "height_range": HEIGHT_RANGE},
                "target_mfpt": float(target), "knots": list(map(float, knots)),
                "max_thrust": max_thrust, "thruster": thruster,
                "integrator": {"method": "compiled DOP853", "rtol": rtol, "atol": atol}}
    return RoughGroundPlan(walker, tuple(strategies), tuple(realized), tuple(params),
                           tuple(float(v) for v in sigmas), settings, tuple(tasks),
                           tuple(where), identity([t.key for t in tasks]), tuple(warnings))


# ------------------------------------------------------------------------------ the mesh
def mesh_chain(plan: RoughGroundPlan, k: int,
               progress: Callable[[int], None] | None = None) -> dict:
    """The mesh chain of strategy ``k`` for every sigma of the plan (module docstring): the
    heights span +-6 sigma_max (uniform: the support) cut to the heights a step from the fixed
    point completes on, widened by a quarter on each side; the states' impact heights are the
    grid heights inside that success interval and its two ends (where an impact exists);
    the zeta^- mesh covers the range a walk of ``VISIT_STEPS`` steps on heights of
    sigma_max (cut to the success interval) visits, widened by 25 % of it and 2 % of zeta*
    on each side (the probability of leaving it is reported)."""
    t0 = time.perf_counter()
    p, real = plan.params[k], plan.realized[k]
    st = plan.settings
    if real.zeta_ref is None:
        return {"computed": False, "reason": f"no orbit: {real.cycle.reason}", "sigmas": []}
    runner = rough_runner(plan.walker, p)
    dist, smax = st["distribution"], max(plan.sigmas)
    M, n = st["mesh"]["terrain_samples"] - 1, st["mesh"]["points"] - 1
    H = (HEIGHT_RANGE * smax if dist == "normal" else half_width(dist, smax)) or 1e-6
    zs = float(real.zeta_ref)
    ok = success_interval(runner, zs, np.linspace(-H, H, 25))
    if ok is None:
        return {"computed": False, "reason": "no step from the fixed point completes on any "
                                             f"height in +-{H:.3g} m", "sigmas": []}
    lo_h, hi_h = max(-H, ok[0] - 0.25 * (ok[1] - ok[0])), min(H, ok[1] + 0.25 * (ok[1] - ok[0]))
    if hi_h - lo_h < 1e-9:
        lo_h, hi_h = -H, H
    grid_h = np.linspace(lo_h, hi_h, M + 1)
    if not lo_h < 0.0 < hi_h:
        grid_h = np.unique(np.append(grid_h, 0.0))
    hp = np.unique(np.concatenate([grid_h[(grid_h > ok[0]) & (grid_h < ok[1])], ok]))
    hp = np.array([v for v in hp if runner.alpha_at(float(v)) is not None])
    from ..resilience.rough import trial_terrain

    walk = np.clip(trial_terrain(dist, smax, st["seed"], -1 % (2 ** 31), st["s_max"]
                                 ).heights(VISIT_STEPS), ok[0], ok[1])
    z_lo, z_hi = visited_range(runner, zs, walk)
    pad = 0.25 * (z_hi - z_lo) + 0.02 * zs
    z = np.linspace(max(z_lo - pad, 1e-3 * zs), z_hi + pad, n + 1)
    from ..resilience.rough import RoughRunner

    extra = [RoughRunner(plan.walker.zd, real, s_max=st["s_max"], mu=st["mu"],
                         eps=st["min_vertical_force"], rtol=st["integrator"]["rtol"],
                         atol=st["integrator"]["atol"])
             for _ in range(MESH_THREADS - 1 if real.planner is None else 0)]  # one QP
    smap = build_step_map([runner, *extra], z, hp, grid_h, progress)
    rows = []
    for sg in plan.sigmas:
        out = {}
        for name, ze, he in (("full", 1, 1), ("half_mesh", 2, 1), ("half_samples", 1, 2)):
            ch = transition_matrix(smap, dist, sg, ze, he)
            out[name] = (chain_mfpt(ch.Q, ch.weights(zs, 0.0)), ch)
        c, ch = out["full"]
        diffs = [abs(out[nm][0].mfpt - c.mfpt) for nm in ("half_mesh", "half_samples")
                 if c.mfpt is not None and out[nm][0].mfpt is not None]
        unc = max(diffs) if len(diffs) == 2 else None
        qs = ch.quasi_stationary()
        rows.append({
            "sigma": float(sg), "mfpt": c.mfpt, "from_fixed_point": c.from_start,
            "lambda2": c.lambda2, "one_minus_lambda2": 1.0 - c.lambda2,
            "uncertainty": unc,
            "half_mesh_mfpt": out["half_mesh"][0].mfpt,
            "half_samples_mfpt": out["half_samples"][0].mfpt,
            "failure_probability_at_fixed_point": float(ch.weights(zs, 0.0) @ ch.fail),
            "clipped_mass": float(qs @ ch.clipped),
            "reason": c.reason or ("" if unc is not None else
                                   "no uncertainty: a refined chain reaches no failure")})
    return {"computed": True, "reason": "", "zeta_range": [float(z[0]), float(z[-1])],
            "visited": [z_lo, z_hi], "zeta_points": int(z.size),
            "impact_heights": [float(v) for v in hp], "heights": [float(lo_h), float(hi_h)],
            "success_interval_at_fixed_point": [float(ok[0]), float(ok[1])],
            "terrain_samples": int(grid_h.size), "states": int(z.size * hp.size),
            "simulations": smap.simulations,
            "failure_kinds_on_grid": dict(sorted(smap.kinds.items())),
            "output_error_at_impact": smap.output_error,
            "seconds": time.perf_counter() - t0, "sigmas": rows}


# ------------------------------------------------------------------------------ running
def run_rough_ground(plan: RoughGroundPlan, *, workers: int | None = None,
                     scheduler: str | None = None, executor=None,
                     finished: Mapping[str, dict] | None = None,
                     on_record: Callable[[dict], None] | None = None,
                     chunk: int | None = None,
                     mesh_progress: Callable[[int], None] | None = None,
                     meshes: Sequence[dict] | None = None) -> RoughGroundResult:
    """Run every trial of ``plan`` without a record in ``finished`` (key -> record) on
    ``executor`` (default: ``workers`` local processes or the Dask cluster of ``scheduler``),
    ``on_record(record)`` as each finishes, then the mesh chains in this process
    (:func:`mesh_chain`, ``mesh_progress(1)`` per mesh label simulated) unless ``meshes``
    gives them. ``chunk``: trials per engine task (default
    :func:`~thrustwalk_cli.sweep.runner.chunk_size` with at most ``TRIALS_PER_CHUNK``: a
    trial walks until it fails, often a few tens of milliseconds, about the engine's cost per
    task); the records do not depend on it."""
    from .sweep import check_executor, task_executor

    check_instance("plan", plan, RoughGroundPlan, "a RoughGroundPlan (plan_rough_ground)")
    check_executor(workers, scheduler)
    chunk = check_count("chunk", chunk, optional=True)
    check_callable("on_record", on_record)
    check_callable("mesh_progress", mesh_progress)
    t0 = time.perf_counter()
    keys = {t.key for t in plan.tasks}
    done = {k: v for k, v in (finished or {}).items() if k in keys}
    todo = sum(t.key not in done for t in plan.tasks)
    own = executor is None and todo > 0
    if own:
        executor = task_executor(plan.tasks, STUDIES["rough-trial"], {}, workers, scheduler,
                                 todo)
    if chunk is None:
        chunk = chunk_size(todo, getattr(executor, "workers", 1), most=TRIALS_PER_CHUNK)
    try:
        counts = (run_tasks(plan.tasks, run_point, executor, done,
                            on_record or (lambda r: None), chunk={"rough-trial": int(chunk)})
                  if todo else RunCounts(skipped=len(plan.tasks)))
    finally:
        if own:
            executor.close()
    desc = executor.describe() if executor is not None else {"kind": "none", "workers": 0}
    t_mc = time.perf_counter() - t0
    if meshes is None:
        meshes = tuple(mesh_chain(plan, k, mesh_progress) for k in range(len(plan.strategies)))
    elif len(meshes) != len(plan.strategies):
        raise InputError.param("meshes", f"one mesh chain per strategy ({len(plan.strategies)}"
                                         f"), got {len(meshes)}")
    return RoughGroundResult(plan, tuple(done.get(t.key) for t in plan.tasks), counts, desc,
                             tuple(meshes), t_mc, sum(m.get("seconds", 0.0) for m in meshes))


def rough_ground(walker: Walker, *, sigma: Sequence[float], workers: int | None = None,
                 scheduler: str | None = None, progress: Callable[[int], None] | None = None,
                 **options) -> RoughGroundResult:
    """MFPT against roughness per strategy, by Monte-Carlo and by the mesh chain (SPEC 14;
    module docstring); ``options`` as :func:`plan_rough_ground`. ``progress(1)`` per trial
    recorded."""
    import inspect

    from .sweep import check_executor

    check_executor(workers, scheduler)
    check_callable("progress", progress)
    known = inspect.signature(plan_rough_ground).parameters
    for name in options:
        if name not in known or name == "walker":
            raise InputError.param(name, "not an option of rough_ground (they are: "
                                         f"{', '.join(k for k in known if k != 'walker')})")
    plan = plan_rough_ground(walker, sigma=sigma, **options)
    return run_rough_ground(plan, workers=workers, scheduler=scheduler,
                            on_record=None if progress is None else (lambda r: progress(1)))


# ------------------------------------------------------------------------------ the result
def crossing(sigmas: Sequence[float], mfpt: Sequence[float | None], target: float
             ) -> tuple[float | None, str]:
    """The sigma [m] where an MFPT curve (None: infinite) first falls through ``target``
    [steps], interpolated linearly in sigma on log(MFPT); None with the reason when it does
    not cross in the range."""
    pts = [(s, np.inf if v is None else float(v)) for s, v in zip(sigmas, mfpt)]
    pts.sort()
    for (s0, v0), (s1, v1) in zip(pts[:-1], pts[1:]):
        if v0 >= target > v1:
            if not np.isfinite(v0):
                return s1, "at the first sigma below the target (the one before has none)"
            a, b = np.log(v0), np.log(v1)
            return float(s0 + (np.log(target) - a) / (b - a) * (s1 - s0)), ""
    if pts and all(v >= target for _, v in pts):
        return None, f"not reached (the MFPT stays above {target:g} steps up to sigma = " \
                     f"{1e3 * pts[-1][0]:g} mm)"
    if pts and pts[0][1] < target:
        return None, f"not reached (the MFPT is already below {target:g} steps at sigma = " \
                     f"{1e3 * pts[0][0]:g} mm)"
    return None, "not reached"


@dataclass(frozen=True)
class RoughGroundResult:
    """The trials of a :class:`RoughGroundPlan` with their records (None: not run), the mesh
    chains per strategy, what this run did and where; renders ``rough_ground.json``,
    ``mfpt.csv``, ``trials.csv`` and the figure ``mfpt``."""

    __repr__ = result_repr

    plan: RoughGroundPlan
    records: tuple[dict | None, ...] = field(repr=False)
    counts: RunCounts
    executor: dict
    meshes: tuple[dict, ...] = field(repr=False)
    mc_time: float = 0.0
    mesh_time: float = 0.0

    name = "rough_ground"

    @property
    def missing(self) -> int:
        return sum(r is None for r in self.records)

    def _outcome(self, rec: dict | None) -> str | None:
        if rec is None:
            return None
        return rec["fields"]["outcome"] if rec["status"] == "ok" else "error"

    def monte_carlo(self, k: int, i: int) -> dict:
        """The Monte-Carlo estimate of strategy ``k`` at sigma ``i`` (module docstring)."""
        kinds = dict.fromkeys(FAILURES, 0)
        F = T = censored = errors = run = 0
        first_error = ""
        for (kk, ii, _), rec in zip(self.plan.where, self.records):
            if kk != k or ii != i or rec is None:
                continue
            run += 1
            o = self._outcome(rec)
            f = rec["fields"] if rec["status"] == "ok" else {}
            if o in kinds:
                kinds[o] += 1
                F += 1
                T += int(f["attempted"])
            else:
                T += int(f.get("steps_completed") or 0)
                if o == "censored":
                    censored += 1
                else:
                    errors += 1
                    first_error = first_error or (rec["document"] or {}).get("reason") \
                        or rec["reason"]
        est = mc_estimate(F, T) if run else None
        doc = est.document() if est is not None else {"mfpt": None, "ci_lower": None,
                                                      "ci_upper": None, "failures": 0,
                                                      "exposure": 0}
        return {**doc, "trials": run, "censored": censored, "errors": errors,
                "failures_by_kind": kinds, "not_run": self.plan.settings["trials"] - run,
                "first_error": first_error or None}

    @staticmethod
    def agreement(mc: dict, mesh: dict | None) -> str:
        if mesh is None or mc["trials"] == 0:
            return "not compared"
        v, lo, hi = mesh.get("from_fixed_point"), mc["ci_lower"], mc["ci_upper"]
        if mc["failures"] == 0:
            return "agree" if v is None or (lo is not None and v >= lo) else "disagree"
        if v is None:
            return "disagree"
        return "agree" if lo <= v <= (np.inf if hi is None else hi) else "disagree"

    def strategy_summary(self, k: int) -> dict:
        p = self.plan
        s, real, mesh = p.strategies[k], p.realized[k], self.meshes[k]
        rows = []
        for i, sg in enumerate(p.sigmas):
            mc = self.monte_carlo(k, i)
            m = mesh["sigmas"][i] if mesh["computed"] else None
            rows.append({"sigma": sg, "monte_carlo": mc, "mesh": m,
                         "agreement": self.agreement(mc, m)})
        return {"label": s.label, "strategy": s.parameters(), "zeta_ref": real.zeta_ref,
                "mesh": {kk: v for kk, v in mesh.items() if kk not in ("sigmas", "seconds")},
                "sigmas": rows}

    def headline(self) -> dict:
        p = self.plan
        target = p.settings["target_mfpt"]
        per = []
        for k, s in enumerate(p.strategies):
            mesh = self.meshes[k]
            if not mesh["computed"]:
                per.append({"label": s.label, "sigma": None, "reason": mesh["reason"]})
                continue
            sig, why = crossing(p.sigmas, [r["mfpt"] for r in mesh["sigmas"]], target)
            per.append({"label": s.label, "sigma": sig, "reason": why})
        base = next((h for h in per if h["label"] == "none"), None)
        lines = []
        head = f"at MFPT = {target:,.0f} steps"
        for h in per:
            if base is None or h is base:
                continue
            if h["sigma"] is not None and base["sigma"] is not None:
                lines.append(f"{head}, {h['label']} tolerates sigma = {1e3 * h['sigma']:.3g} mm "
                             f"vs {1e3 * base['sigma']:.3g} mm without thrust")
            else:
                lines.append(f"{head}: {h['label']} " + (
                    f"tolerates sigma = {1e3 * h['sigma']:.3g} mm" if h["sigma"] is not None
                    else h["reason"]) + "; without thrust " + (
                    f"sigma = {1e3 * base['sigma']:.3g} mm" if base["sigma"] is not None
                    else base["reason"]))
        if not lines:
            lines += [f"{head}: {h['label']} " + (
                f"tolerates sigma = {1e3 * h['sigma']:.3g} mm" if h["sigma"] is not None
                else h["reason"]) for h in per]
        return {"target_mfpt": target, "curve": "mesh chain 1/(1 - lambda_2), log-linear in "
                                                  "sigma between grid values",
                "strategies": per, "text": lines}

    def warnings(self) -> list[str]:
        out = list(self.plan.warnings)
        for k, s in enumerate(self.plan.strategies):
            summ = self.strategy_summary(k)
            errs = sum(r["monte_carlo"]["errors"] for r in summ["sigmas"])
            if errs:
                first = next(r["monte_carlo"]["first_error"] for r in summ["sigmas"]
                             if r["monte_carlo"]["errors"])
                out.append(f"{s.label}: {errs} trial(s) could not be computed (counted as "
                           f"censored at their last step); first: {first}")
            for r in summ["sigmas"]:
                if r["agreement"] == "disagree":
                    out.append(f"{s.label}, sigma = {r['sigma']:g} m: the mesh chain "
                               f"({_g(r['mesh']['from_fixed_point'])} steps) is outside the "
                               f"Monte-Carlo 95 % interval [{_g(r['monte_carlo']['ci_lower'])},"
                               f" {_g(r['monte_carlo']['ci_upper'])}]")
                m = r["mesh"]
                if m is not None and m["clipped_mass"] > 1e-3:
                    out.append(f"{s.label}, sigma = {r['sigma']:g} m: a walker that has not "
                               f"failed leaves the mesh with probability "
                               f"{m['clipped_mass']:.2g} per step (put on its end)")
        if self.missing:
            out.append(f"{self.missing} trial(s) not run: run again to resume")
        return out

    @property
    def success(self) -> bool:
        return not self.missing and all(
            r["agreement"] != "disagree" for k in range(len(self.plan.strategies))
            for r in self.strategy_summary(k)["sigmas"]) and all(
            m["computed"] for m in self.meshes)

    @property
    def reason(self) -> str:
        if self.missing:
            return f"{self.missing} of {len(self.records)} trials not run (run again to resume)"
        bad = [f"{self.plan.strategies[k].label} at sigma = {r['sigma']:g} m"
               for k in range(len(self.plan.strategies))
               for r in self.strategy_summary(k)["sigmas"] if r["agreement"] == "disagree"]
        if bad:
            return f"the mesh chain and the Monte-Carlo disagree: {', '.join(bad)}"
        nomesh = [m["reason"] for m in self.meshes if not m["computed"]]
        if nomesh:
            return f"no mesh chain: {nomesh[0]}"
        return "every trial run; the mesh chain lies inside the Monte-Carlo interval wherever " \
               "both are computed"

    def document(self) -> dict:
        p, w = self.plan, self.plan.walker
        return {
            "schema_version": SCHEMA_VERSION, "units": UNITS, "success": self.success,
            "reason": self.reason, "warnings": self.warnings(),
            "robot": robot_record(w.zd), "gait": gait_record(w.zd), "settings": p.settings,
            "definitions": DEFINITIONS, "headline": self.headline(),
            "strategies": [self.strategy_summary(k) for k in range(len(p.strategies))],
            "counts": {"trials": len(p.tasks), "recorded": len(p.tasks) - self.missing,
                       "not_run": self.missing, "skipped": self.counts.skipped,
                       "computed": self.counts.ok + self.counts.failed,
                       "resubmitted": self.counts.resubmitted},
            "identity": p.identity, "executor": self.executor,
            "wall_time": {"monte_carlo": self.mc_time, "mesh": self.mesh_time},
            "trials_folder": "trials",
        }

    def tables(self) -> dict[str, Table]:
        p = self.plan
        header = ["strategy", col("sigma", "m"), col("mc_mfpt", "steps"),
                  col("mc_ci_lower", "steps"), col("mc_ci_upper", "steps"), "failures",
                  col("exposure", "steps"), "trials", "censored", "errors",
                  *[f"failed_{kd}" for kd in FAILURES], col("mesh_mfpt", "steps"),
                  col("mesh_from_fixed_point", "steps"), "lambda2",
                  col("mesh_uncertainty", "steps"), "agreement"]
        rows = []
        for k in range(len(p.strategies)):
            summ = self.strategy_summary(k)
            for r in summ["sigmas"]:
                mc, m = r["monte_carlo"], r["mesh"] or {}
                rows.append([summ["label"], r["sigma"], mc["mfpt"], mc["ci_lower"],
                             mc["ci_upper"], mc["failures"], mc["exposure"], mc["trials"],
                             mc["censored"], mc["errors"],
                             *[mc["failures_by_kind"][kd] for kd in FAILURES], m.get("mfpt"),
                             m.get("from_fixed_point"), m.get("lambda2"),
                             m.get("uncertainty"), r["agreement"]])
        th = ["trial", "key", "strategy", col("sigma", "m"), "outcome", "steps_completed",
              "attempted", "failed_step", col("failed_height", "m"), "terrain_seed", "reason"]
        trows = []
        for t, (k, _i, tr), rec in zip(p.tasks, p.where, self.records):
            if rec is None:
                continue
            f = rec["fields"] if rec["status"] == "ok" else {}
            doc = rec["document"] or {}
            trows.append([tr, t.key[:20], p.strategies[k].label, dict(t.values)["sigma"],
                          self._outcome(rec), f.get("steps_completed"), f.get("attempted"),
                          f.get("failed_step"), f.get("failed_height"), f.get("terrain_seed"),
                          doc.get("reason") or rec["reason"]])
        return {"mfpt": Table(header, rows, [
                    "one row per (strategy, sigma): Monte-Carlo MFPT with its 95 % interval "
                    "and the mesh chain's (SPEC 14); empty: not computed (no failure, or "
                    "infinite)"]),
                "trials": Table(th, trows, ["one row per Monte-Carlo run; its record is "
                                            "trials/KEY.json"])}

    def figure_data(self) -> dict:
        p = self.plan
        out = []
        for k in range(len(p.strategies)):
            summ = self.strategy_summary(k)
            out.append({"label": summ["label"],
                        "mc": [(r["sigma"], r["monte_carlo"]["mfpt"], r["monte_carlo"]["ci_lower"],
                                r["monte_carlo"]["ci_upper"]) for r in summ["sigmas"]
                               if r["monte_carlo"]["trials"]],
                        "mesh": [(r["sigma"], None if r["mesh"] is None else r["mesh"]["mfpt"])
                                 for r in summ["sigmas"]]})
        return {"strategies": out, "target": p.settings["target_mfpt"],
                "cap": p.settings["cap"]}

    def figures(self, titles: bool = False) -> dict:
        from ..plots import rough_ground as plots

        w = self.plan.walker
        title = f"{w.robot.name} / {w.gait.name}: MFPT on rough ground" if titles else ""
        return {"mfpt": plots.mfpt(self.figure_data(), title)}


def _g(v) -> str:
    return "none" if v is None else f"{v:.4g}"
