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
from ..files.sweep_file import STUDY_PARAMETERS, keyed
from ..model.slope import check_slope
from ..resilience.mfpt import chain_mfpt
from ..resilience.rough import (
    DISTRIBUTIONS,
    build_step_map,
    half_width,
    success_interval,
    transition_matrix,
    visited_range,
)
from ..resilience.strategy import Strategy
from ..sweep.runner import RunCounts, chunk_size, run_tasks
from ..sweep.tasks import PointTask, identity, task_key
from ..walker import Walker, check_walker
from .documents import show_options
from .robustness import walker_strategies, walker_texts
from .rough_ground_result import (  # noqa: F401 - DEFINITIONS, UNITS: named here too
    DEFINITIONS,
    TARGET,
    UNITS,
    RoughGroundPlan,
    RoughGroundResult,
)
from .sweep_studies import STUDIES, run_point
from .trial_studies import check_strategy, realized_strategy, rough_runner

MAX_SIGMAS = 200
MAX_TRIALS = 100_000
MAX_CAP = 1_000_000
HEIGHT_RANGE = 6.0  # the mesh's heights span +- this many sigma_max (normal)
VISIT_STEPS = 400  # the walk whose visited zeta^- the mesh covers
TRIALS_PER_CHUNK = 8  # Monte-Carlo trials per engine task at most
MESH_THREADS = 2  # threads of the mesh's one-step simulations (the kernel releases the GIL;
#                   control: 1, its planner is not shared between threads)
def _defaults() -> dict:
    return {f.key: f.default for f in STUDY_PARAMETERS["rough-trial"].fields}


def plan_rough_ground(walker: Walker, *, sigma: Sequence[float],
                      strategy: Sequence[str | Strategy] | None = None, trials: int = 50,
                      cap: int = 1000, seed: int = 0, distribution: str = "normal",
                      mesh: int = 20, terrain_samples: int = 24, s_max: float = 1.3,
                      mu: float | None = None, min_vertical_force: float = 0.0,
                      thruster: str | None = None, knots: Sequence[float] = (0.0, 0.5, 1.0),
                      max_thrust: float | None = None, target: float = TARGET,
                      rtol: float = 1e-9, atol: float = 1e-9,
                      slope: float = 0.0) -> RoughGroundPlan:
    """Check every option and key every Monte-Carlo trial (module docstring; SI units):
    ``sigma`` [m] standard deviations of the step heights (>= 0), ``strategy`` (default none
    and control; none alone for a robot without thrusters), ``trials`` per (strategy, sigma),
    ``cap`` steps per trial, ``seed`` of the terrains, ``distribution`` normal or uniform,
    ``mesh`` and ``terrain_samples`` (even: their halves are the refinement), ``s_max`` [1]
    the missed-footing limit, the cone (``mu``, ``min_vertical_force`` [N]), the controller
    (``thruster``, ``knots``, ``max_thrust`` [N]), ``target`` [steps] the headline's MFPT and
    the integrator tolerances. ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground
    angle (SPEC 14, as ``simulate --slope`` and a terrain file's ``slope``,
    :meth:`Walker.on_slope`): every trial and the mesh chain's one-step map walk the slope
    frame, the step heights ``h_k`` on top of it (normal to the slope); the document gains the
    ``slope`` block. 0: level ground, bit for bit (keys and identity as without it)."""
    check_walker(walker)
    walker = walker.on_slope(check_slope(slope))
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
    strategies = walker_strategies(walker, strategy, thruster, knots, max_thrust)
    robot_text, gait_text = walker_texts(walker)
    common = {"cap": int(cap), "seed": int(seed), "distribution": distribution,
              "s_max": float(s_max), "mu": mu, "min_vertical_force": float(min_vertical_force),
              "rtol": float(rtol), "atol": float(atol),
              **({"slope": walker.slope} if walker.slope != 0.0 else {})}
    realized, params, warnings = [], [], []
    for s in strategies:
        p = keyed({**_defaults(), **common, **s.parameters()})
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


show_options(rough_ground, plan_rough_ground)
