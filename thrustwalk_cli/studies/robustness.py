"""The ``robustness`` study (SPEC 12): how much larger a push, how much wider a basin, how much
more model error does the walker survive with thrust than without?

For every strategy (:mod:`thrustwalk_cli.resilience.strategy`: none, constant, schedule,
control) it computes

* a **push map**: one full-order trial per (phase, impulse) (:mod:`~thrustwalk_cli.resilience.
  trials`: pushed in step 1 on the strategy's orbit, ``steps`` steps in all), its outcome;
* the **largest survivable push** forward and backward per phase: the largest grid impulse
  ``P`` such that every grid impulse in ``(0, P]`` (backward: ``[-P, 0)``) recovered (a lower
  bound of the true value, within one grid step; ``bound`` says when the scan ended at the
  grid's edge, at a trial that could not be computed, or at one not run), and the summary
  ``mean over phases of (P_fwd + P_bwd) / 2`` [N s] (over the directions the grid has);
* the **reduced basin** (closed form, SPEC 12; for control the projection of its constraints)
  and a **full-order basin slice**: trials started off the orbit on a grid of ``sigma_N^+``
  (relative change) x the rate of one output, with the fraction that converges;
* with ``uncertainty``, a **Monte-Carlo** over robot parameters (reduced model of each drawn
  robot, :mod:`~thrustwalk_cli.resilience.uncertainty`): the fraction that walks and the
  spread of the converged speed.

Every trial and sample is a point of the sweep engine (studies ``push-trial`` and
``reduced-walk`` of :mod:`.trial_studies`): keyed by content, run on local worker processes or
a Dask cluster, recorded one by one (``on_record``) so that a stopped run resumes with the
records it has (``finished``). A trial takes milliseconds, about as long as the engine's own
cost per task, so consecutive trials run in chunks, several per task (:func:`trial_chunk`);
each keeps its own record, identical to a run of one trial per task. A sample (a robot built
and reduced: about 0.1 s) is a task of its own. Units SI.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from ..description.terrain import Terrain
from ..description.uncertainty import Uncertainty
from ..errors import (
    InputError,
    Problem,
    check_callable,
    check_count,
    check_instance,
    check_number,
    check_numbers,
    check_path,
    check_text,
)
from ..files.gait_file import load_gait
from ..files.robot_file import load_robot_text
from ..files.sweep_file import STUDY_PARAMETERS, keyed, read_source
from ..files.uncertainty_file import load_uncertainty
from ..resilience.strategy import KINDS, Strategy, labels_unique, schedule_of_file
from ..sweep.points import draw
from ..sweep.runner import RunCounts, run_tasks
from ..sweep.tasks import PointTask, identity, task_key
from ..walker import Walker, check_ground, check_walker
from .documents import show_options
from .robustness_result import DEFINITIONS, UNITS, RobustnessPlan, RobustnessResult
from .sweep_studies import STUDIES, run_point, run_points
from .trial_studies import realized_strategy, trial_chunk

__all__ = ["DEFINITIONS", "UNITS", "RobustnessPlan", "RobustnessResult", "plan_robustness",
           "robustness", "run_robustness"]
MAX_TRIALS = 100_000
RENAMED = {"transverse": "basin_joint", "schedule": "strategy"}  # study -> this study
MAX_SAMPLES = 100_000


# ------------------------------------------------------------------------------ strategies
def parse_strategy(text: str | Strategy, walker: Walker, thruster: str | None = None,
                   knots: Sequence[float] = (0.0, 0.5, 1.0),
                   max_thrust: float | None = None) -> Strategy:
    """``none``, ``constant`` (the gait's thrust: section), ``constant:F`` [N], ``control`` or
    ``schedule:FILE`` (a gait-format file whose ``thrust:`` section is the schedule) as a
    :class:`Strategy` driving ``thruster``."""
    if isinstance(text, Strategy):
        return text
    kind, sep, arg = str(text).strip().partition(":")
    kind = kind.strip()
    if kind not in KINDS:
        raise InputError.param("strategy", f"unknown strategy {text!r} (none, constant, "
                                           "constant:F, control, schedule:FILE)")
    if kind in ("none", "control") and sep:
        raise InputError.param("strategy", f"{kind} takes no value (got {text!r})")
    if kind == "none":
        return Strategy("none")
    if kind == "constant":
        if not sep:
            return Strategy("constant", thruster)
        try:
            value = float(arg)
        except ValueError:
            raise InputError.param("strategy", f"constant:F needs a thrust in N (got "
                                               f"{text!r})") from None
        if not abs(value) <= 1e9:
            raise InputError.param("strategy", f"constant:F needs a finite thrust (got {text!r})")
        return Strategy("constant", thruster, value)
    if kind == "schedule":
        if not arg.strip():
            raise InputError.param("strategy", "schedule:FILE needs a file (a gait file with a "
                                               "thrust: section)")
        gait, _ = load_gait(arg.strip())
        if gait.thrust is None:
            raise InputError.param("strategy", f"{arg.strip()} has no thrust: section (the "
                                               "schedule)")
        fr, values, mode, name = schedule_of_file(gait.thrust, walker.zd)
        return Strategy("schedule", name or thruster, None, (fr, values, mode),
                        name=f"schedule:{Path(arg.strip()).stem}")
    return Strategy("control", thruster, knots=tuple(map(float, knots)),
                    max_thrust=max_thrust)


def walker_strategies(walker: Walker, strategy: Sequence[str | Strategy] | None,
                      thruster: str | None, knots: Sequence[float],
                      max_thrust: float | None) -> list[Strategy]:
    """The strategies of a robustness or rough-ground run made from their texts
    (:func:`parse_strategy`; default none and control, only none without thrusters), with
    distinct labels; :class:`InputError` for a gait without a walking orbit or no strategy."""
    zd, robot = walker.zd, walker.robot
    if not zd.valid:
        raise InputError.param("gait", f"the gait has no walking orbit: {zd.invalid_reason}")
    if strategy is None:
        strategy = ["none", "control"] if robot.thrusters else ["none"]
    strategies = [parse_strategy(s, walker, thruster, knots, max_thrust) for s in strategy]
    if not strategies:
        raise InputError.param("strategy", "no strategy")
    labels_unique(strategies)
    return strategies


def _defaults(study: str) -> dict:
    """Every parameter of a sweep study with its default (the tasks carry them all)."""
    return {f.key: f.default for f in STUDY_PARAMETERS[study].fields}


# ------------------------------------------------------------------------------ the plan
def plan_robustness(walker: Walker, *, push_impulse: Sequence[float] | None = None,
                    push_phase: Sequence[float] | None = None,
                    strategy: Sequence[str | Strategy] | None = None, steps: int = 10,
                    push_direction: Sequence[float] = (1.0, 0.0), push_link: str | None = None,
                    push_at: float = 1.0, push_duration: float = 0.0,
                    recovery_tol: float = 0.05, output_tol: float = 1e-3,
                    mu: float | None = None, min_vertical_force: float = 0.0,
                    thruster: str | None = None, knots: Sequence[float] = (0.0, 0.5, 1.0),
                    max_thrust: float | None = None, basin_grid: int = 11,
                    basin_sigma: tuple[float, float] = (-0.8, 1.6), basin_rate: float = 0.5,
                    basin_joint: str | None = None,
                    uncertainty: str | Path | Uncertainty | None = None, samples: int = 100,
                    rtol: float = 1e-9, atol: float = 1e-9, slope: float = 0.0,
                    terrain: str | Path | Terrain | None = None) -> RobustnessPlan:
    """Check every option and key every trial (module docstring; parameters as the command's
    options, SI units): ``push_impulse`` [N s] signed along ``push_direction`` (default -30 to
    30 by 2), ``push_phase`` [1] in [0, 1] (default 0 to 1 by 0.05), ``strategy`` (default
    none and control; none alone for a robot without thrusters), ``steps`` per trial, the
    push point (``push_link``, ``push_at``), ``push_duration`` [s] for the stance foot's
    check (0: impulsive), the recovery test (``recovery_tol`` [1], ``output_tol`` [rad]), the
    cone (``mu``, ``min_vertical_force`` [N]), the controller (``thruster``, ``knots``,
    ``max_thrust`` [N]), the basin slice (``basin_grid`` points per axis, 0: none;
    ``basin_sigma`` range of the relative change of sigma_N^+; ``basin_rate`` [rad/s] range
    +- of the rate of ``basin_joint``), ``uncertainty`` (a file or :class:`Uncertainty`) with
    ``samples`` draws, and the integrator tolerances. A push impulse is at most
    :meth:`~thrustwalk_cli.description.robot.Robot.push_bound` (10 m/s of the whole robot's
    velocity).

    ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground angle (SPEC 14,
    :meth:`Walker.on_slope`): every strategy's orbit, reduced basin and controller, every push
    and basin trial (the pushes stay in the world frame, turned into the slope frame as
    ``simulate --slope`` turns them) and every uncertainty sample are on that slope; the
    document gains the ``slope`` block and each orbit its climb rate. 0: level ground, bit for
    bit (the trials' keys included).

    ``terrain``: a terrain file (path) or :class:`~thrustwalk_cli.description.terrain.Terrain`
    (SPEC 14, as ``simulate --terrain``): its slope (unless ``slope`` is given: not both) and
    the step heights every push and basin trial walks (the same ground for every trial: step
    ``k`` lands ``h_k`` above its stance foot; past the terrain's ``s_max`` without a
    touchdown the trial ``fell``, missed footing). The strategies' orbits, basins and
    controllers stay those of the plane ground (the reference the recovery is measured
    against); the uncertainty samples (reduced model) do not walk the terrain."""
    check_walker(walker)
    slope, terrain = check_ground(slope, terrain)
    walker = walker.on_slope(slope)
    push_impulse = check_numbers("push_impulse", push_impulse, optional=True, min_len=0,
                                 max_len=MAX_TRIALS)
    push_phase = check_numbers("push_phase", push_phase, optional=True, min_len=0,
                               max_len=MAX_TRIALS)
    if strategy is not None and (isinstance(strategy, (str, bytes)) or
                                 not hasattr(strategy, "__iter__")):
        raise InputError.param("strategy", f"must be a list of strategies (e.g. [\"none\", "
                                           f"\"control\"]), got {type(strategy).__name__} "
                                           f"{strategy!r:.40}")
    if strategy is not None:
        strategy = list(strategy)
        for s in strategy:
            if not isinstance(s, (str, Strategy)):
                raise InputError.param("strategy", f"a strategy is a name such as "
                                                   f"\"constant:-20\" or a Strategy, got "
                                                   f"{type(s).__name__} {s!r:.40}")
    steps = check_count("steps", steps, le=1000)
    push_direction = check_numbers("push_direction", push_direction, min_len=2, max_len=2)
    check_text("push_link", push_link, optional=True)
    push_at = check_number("push_at", push_at)
    push_duration = check_number("push_duration", push_duration, unit="s")
    recovery_tol = check_number("recovery_tol", recovery_tol)
    output_tol = check_number("output_tol", output_tol, unit="rad")
    mu = check_number("mu", mu, optional=True)
    min_vertical_force = check_number("min_vertical_force", min_vertical_force, unit="N")
    check_text("thruster", thruster, optional=True)
    knots = check_numbers("knots", knots)
    max_thrust = check_number("max_thrust", max_thrust, gt=0, optional=True, unit="N")
    basin_grid = check_count("basin_grid", basin_grid, ge=0, le=201)
    basin_sigma = check_numbers("basin_sigma", basin_sigma, min_len=2, max_len=2)
    basin_rate = check_number("basin_rate", basin_rate, unit="rad/s")
    check_text("basin_joint", basin_joint, optional=True)
    if uncertainty is not None and not isinstance(uncertainty, Uncertainty):
        uncertainty = check_path("uncertainty", uncertainty)
    samples = check_count("samples", samples, le=MAX_SAMPLES)
    rtol = check_number("rtol", rtol)
    atol = check_number("atol", atol)
    robot, zd = walker.robot, walker.zd
    impulses = tuple(float(v) for v in (push_impulse if push_impulse is not None
                                        else np.arange(-30.0, 30.0 + 1e-9, 2.0)))
    phases = tuple(float(v) for v in (push_phase if push_phase is not None
                                      else np.round(np.arange(0.0, 1.0 + 1e-9, 0.05), 12)))
    if impulses:
        robot.check_push("push_impulse", max(impulses, key=abs))
    if max_thrust is not None and robot.thrusters:
        robot.check_thrust_bound("max_thrust", max_thrust, [robot.thruster_index(thruster)])
    problems: list[Problem] = []

    def bad(param, message):
        problems.append(InputError.param(param, message).problems[0])

    if not impulses:
        bad("push_impulse", "no impulse values")
    if not phases:
        bad("push_phase", "no phase values")
    if any(not 0.0 <= s <= 1.0 for s in phases):
        bad("push_phase", f"phases are fractions of the step in [0, 1] (got "
                          f"{min(phases):g} ... {max(phases):g})")
    if len(set(impulses)) != len(impulses) or len(set(phases)) != len(phases):
        bad(("push_impulse", "push_phase"), "a value is given twice")
    if not 1 <= steps <= 1000:
        bad("steps", f"must be 1..1000 steps per trial (got {steps})")
    if not 0 < recovery_tol < 1:
        bad("recovery_tol", f"must lie in (0, 1) (got {recovery_tol:g})")
    if not output_tol > 0:
        bad("output_tol", f"must be > 0 rad (got {output_tol:g})")
    if not 0 <= push_duration <= 1:
        bad("push_duration", f"must lie in [0, 1] s (got {push_duration:g})")
    if not (basin_grid == 0 or 2 <= basin_grid <= 201):
        bad("basin_grid", f"must be 0 (no slice) or 2..201 points per axis (got {basin_grid})")
    lo_s, hi_s = basin_sigma
    if not -1 < lo_s < hi_s <= 100:
        bad("basin_sigma", f"a range lo:hi with -1 < lo < hi (got {lo_s:g}:{hi_s:g})")
    if not 0 <= basin_rate <= 1000:
        bad("basin_rate", f"must lie in [0, 1000] rad/s (got {basin_rate:g})")
    if not 1 <= samples <= MAX_SAMPLES:
        bad("samples", f"must be 1..{MAX_SAMPLES} (got {samples})")
    if not (0 < rtol < 0.1 and 0 < atol < 0.1):
        bad(("rtol", "atol"), "tolerances must lie in (0, 0.1)")
    if mu is not None and not mu > 0:
        bad("mu", f"must be > 0 (got {mu:g})")
    if not min_vertical_force >= 0:
        bad("min_vertical_force", f"must be >= 0 N (got {min_vertical_force:g})")
    if problems:
        raise InputError(problems)
    strategies = walker_strategies(walker, strategy, thruster, knots, max_thrust)
    robot_text, gait_text = walker_texts(walker)
    mu_v = zd.gait.mu if mu is None else float(mu)
    common = {"steps": int(steps), "push_direction": [float(v) for v in push_direction],
              "push_link": push_link, "push_at": float(push_at),
              "push_duration": float(push_duration), "transverse": basin_joint,
              "recovery_tol": float(recovery_tol), "output_tol": float(output_tol),
              "mu": mu, "min_vertical_force": float(min_vertical_force),
              "rtol": float(rtol), "atol": float(atol),
              **({"slope": slope} if slope != 0.0 else {})}
    if terrain is not None:
        common["terrain"] = {"heights": [float(h) for h in terrain.heights(int(steps))],
                             "s_max": float(terrain.s_max)}
    # the strategies made concrete here: every problem before any trial (and the basins)
    realized, warnings = [], []
    from .trial_studies import check_strategy, trial_setup

    try:
        trial_setup(walker, keyed({**_defaults("push-trial"), **common}))
    except InputError as exc:
        raise InputError([InputError.param(RENAMED.get(pr.params[0], pr.params[0]),
                                           pr.message).problems[0]
                          for pr in exc.problems]) from None
    for s in strategies:
        p = keyed({**_defaults("push-trial"), **common, **s.parameters()})
        for name, msg in check_strategy(walker, p):
            raise InputError.param(RENAMED.get(name, name), f"{s.label}: {msg}")
        real, _ = realized_strategy(walker, p)
        realized.append(real)
        warnings += [f"{s.label}: {n}" for n in real.notes]
        if real.zeta_ref is None:
            warnings.append(f"{s.label}: no orbit to start the trials on ({real.cycle.reason}); "
                            "its trials are recorded as errors")
        elif not real.basin.exists:
            warnings.append(f"{s.label}: no reduced basin: {real.basin.reason}")
    sigmas = tuple(float(v) for v in np.linspace(lo_s, hi_s, basin_grid)) if basin_grid \
        else ()
    rates = tuple(float(v) for v in np.linspace(-basin_rate, basin_rate, basin_grid)) \
        if basin_grid and basin_rate > 0 else ((0.0,) if basin_grid else ())
    unc, draws = None, {}
    if uncertainty is not None:
        unc = _uncertainty(uncertainty, walker)
        rng = np.random.default_rng(unc.seed)
        draws = {a.name: draw(a, rng, samples) for a in unc.axes}
    n_trials = len(strategies) * (len(impulses) * len(phases) + len(sigmas) * len(rates))
    if n_trials > MAX_TRIALS:
        raise InputError.param(("push_impulse", "push_phase"), f"{n_trials} trials: the limit "
                                                               f"is {MAX_TRIALS}")
    tasks, kinds, where = [], [], []

    def add(study: str, settings: dict, values: dict, kind: str, at: tuple[int, int, int]):
        key = task_key(study, robot_text, gait_text, settings, values)
        tasks.append(PointTask(len(tasks), key, study, tuple(values.items()),
                               tuple(settings.items()), robot.source_file, robot_text,
                               walker.gait.source_file, gait_text,
                               label=f"robustness {kind} trial {len(tasks)}"))
        kinds.append(kind)
        where.append(at)

    for k, s in enumerate(strategies):
        st = keyed({**_defaults("push-trial"), **common, **s.parameters()})
        for i, ph in enumerate(phases):
            for j, P in enumerate(impulses):
                add("push-trial", st, {"push_impulse": P, "push_phase": ph}, "push", (k, i, j))
        for i, sg in enumerate(sigmas):
            for j, rt in enumerate(rates):
                add("push-trial", st, {"start_sigma": sg, "start_rate": rt}, "basin", (k, i, j))
    if unc is not None:
        for k, s in enumerate(strategies):
            st = keyed({**_defaults("reduced-walk"),
                        **{c: common[c] for c in ("mu", "min_vertical_force", "slope")
                           if c in common}, **s.parameters()})
            for i in range(samples):
                vals = {"sample": float(i), **{n: v[i] for n, v in draws.items()}}
                add("reduced-walk", st, vals, "sample", (k, i, 0))
    settings = {**common, "mu": mu_v, "impulses": list(impulses), "phases": list(phases),
                "strategies": [s.parameters() for s in strategies],
                "basin_slice": {"grid": basin_grid, "sigma": list(sigmas),
                                "rate": list(rates), "joint": basin_joint or next(
                                    c.name for c in robot.coordinates if c.actuated)},
                "knots": list(map(float, knots)), "max_thrust": max_thrust,
                "thruster": thruster,
                "uncertainty": None if unc is None else {
                    "file": unc.source_file, "sha256": unc.source_sha256, "seed": unc.seed,
                    "samples": samples, "description": unc.description,
                    "parameters": {a.parameter: {"distribution": a.distribution,
                                                 "parameters": list(a.parameters),
                                                 "unit": a.unit} for a in unc.axes}},
                "integrator": {"method": "compiled DOP853", "rtol": rtol, "atol": atol}}
    if terrain is not None:
        settings["terrain"] = {**terrain.record(), "heights": common["terrain"]["heights"]}
        if unc is not None:
            warnings.append("the uncertainty samples walk the reduced model on the plane "
                            "ground: the terrain's steps are not in them")
    return RobustnessPlan(walker, tuple(strategies), tuple(realized), settings, impulses,
                          phases, sigmas, rates, unc, draws, tuple(tasks), tuple(kinds),
                          tuple(where), identity([t.key for t in tasks]), tuple(warnings))


def walker_texts(walker: Walker) -> tuple[str, str]:
    """The robot and gait files' texts (the tasks carry them: workers need no shared folder),
    checked to be the walker's own."""
    robot, gait = walker.robot, walker.gait
    robot_text = read_source(robot.source_file)
    if load_robot_text(robot_text, robot.source_file).canonical() != robot.canonical():
        raise InputError.param("robot", f"the walker's robot is not its file {robot.source_file} "
                                        "as written (parameters replaced, or the file changed): "
                                        "the trials run from the files")
    gait_text = read_source(gait.source_file)
    return robot_text, gait_text


def _uncertainty(spec: str | Path | Uncertainty, walker: Walker) -> Uncertainty:
    """The uncertainty file (or description), its parameters checked against the robot."""
    if isinstance(spec, Uncertainty):
        unc, where = spec, None
    else:
        unc, source = load_uncertainty(spec)
        where = source.where
    known = dict(walker.robot.parameters)
    problems = []
    for a in unc.axes:
        if a.parameter not in known:
            msg = (f"no parameter '{a.parameter}' in robot {walker.robot.name} (its parameters: "
                   f"{', '.join(sorted(known)) or 'none'})")
            problems.append(where(("parameters", a.parameter), msg) if where else
                            InputError.param("uncertainty", msg).problems[0])
    if problems:
        raise InputError(problems)
    return unc


# ------------------------------------------------------------------------------ running
def run_robustness(plan: RobustnessPlan, *, workers: int | None = None,
                   scheduler: str | None = None, executor=None,
                   finished: Mapping[str, dict] | None = None,
                   on_record: Callable[[dict], None] | None = None,
                   chunk: int | None = None) -> RobustnessResult:
    """Run every task of ``plan`` without a record in ``finished`` (key -> record) on
    ``executor`` (default: ``workers`` local processes, or the Dask cluster of
    ``scheduler``); ``on_record(record)`` as each finishes (the trials of a chunk one after
    the other as the chunk returns). ``chunk``: push and basin trials per engine task
    (default :func:`trial_chunk` of the trials to run and the executor's workers; 1: one per
    task; samples always run one per task); the records do not depend on it."""
    from .sweep import check_executor, task_executor

    check_instance("plan", plan, RobustnessPlan, "a RobustnessPlan (plan_robustness)")
    check_executor(workers, scheduler)
    chunk = check_count("chunk", chunk, optional=True)
    check_callable("on_record", on_record)
    t0 = time.perf_counter()
    done = {k: v for k, v in (finished or {}).items() if k in {t.key for t in plan.tasks}}
    todo = sum(t.key not in done for t in plan.tasks)
    own = executor is None and todo > 0
    if own:
        executor = task_executor(plan.tasks, STUDIES["push-trial"], {}, workers, scheduler,
                                 todo)
    if chunk is None:
        trials = sum(t.key not in done for t, kd in zip(plan.tasks, plan.kinds)
                     if kd != "sample")
        chunk = trial_chunk(trials, getattr(executor, "workers", 1), plan.settings["steps"])
    try:
        counts = (run_tasks(plan.tasks, run_point, executor, done,
                            on_record or (lambda r: None), chunk={"push-trial": int(chunk)},
                            many=run_points)
                  if todo else RunCounts(skipped=len(plan.tasks)))
    finally:
        if own:
            executor.close()
    desc = executor.describe() if executor is not None else {"kind": "none", "workers": 0}
    return RobustnessResult(plan, tuple(done.get(t.key) for t in plan.tasks), counts, desc,
                            time.perf_counter() - t0)


def robustness(walker: Walker, *, workers: int | None = None, scheduler: str | None = None,
               progress: Callable[[int], None] | None = None, **options) -> RobustnessResult:
    """Push maps, survivable pushes, basins and parameter uncertainty per thrust strategy
    (SPEC 12; module docstring); ``options`` as :func:`plan_robustness`. Runs on ``workers``
    local processes (default: one per core) or the Dask cluster at ``scheduler``;
    ``progress(1)`` for every trial's record (those of a chunk together, as it returns)."""
    import inspect

    from .sweep import check_executor

    check_executor(workers, scheduler)
    check_callable("progress", progress)
    known = inspect.signature(plan_robustness).parameters
    for name in options:
        if name not in known or name == "walker":
            raise InputError.param(name, "not an option of robustness (they are: "
                                         f"{', '.join(k for k in known if k != 'walker')})")
    plan = plan_robustness(walker, **options)
    return run_robustness(plan, workers=workers, scheduler=scheduler,
                          on_record=None if progress is None else (lambda r: progress(1)))


show_options(robustness, plan_robustness)
