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
``reduced-walk`` of :mod:`.sweep_studies`): keyed by content, run on local worker processes or
a Dask cluster, recorded one by one (``on_record``) so that a stopped run resumes with the
records it has (``finished``). A trial takes milliseconds, about as long as the engine's own
cost per task, so consecutive trials run in chunks, several per task (:func:`trial_chunk`);
each keeps its own record, identical to a run of one trial per task. A sample (a robot built
and reduced: about 0.1 s) is a task of its own. Units SI.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

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
from ..files.sweep_file import STUDY_PARAMETERS, read_source
from ..files.uncertainty_file import load_uncertainty
from ..resilience.maps import (
    mean_of,
    outcome_counts,
    single_outcome,
    spread,
    summary_impulse,
    survivable,
)
from ..resilience.strategy import KINDS, Realized, Strategy, labels_unique, schedule_of_file
from ..resilience.trials import OUTCOMES
from ..sweep.points import draw
from ..sweep.runner import RunCounts, run_tasks
from ..sweep.tasks import PointTask, identity, task_key
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, Table, col, gait_record, result_repr, robot_record, units
from .sweep_studies import STUDIES, realized_strategy, run_point, trial_chunk

UNITS = units("impulse", "zeta", "speed", "force", "friction_ratio", "sigma_N", "output_rate",
              "output_y", "step_time", "delta_zero_sq", "alpha", phase="1", duration="s")
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


def _defaults(study: str) -> dict:
    """Every parameter of a sweep study with its default (the tasks carry them all)."""
    return {f.key: f.default for f in STUDY_PARAMETERS[study].fields}


# ------------------------------------------------------------------------------ the plan
@dataclass(frozen=True)
class RobustnessPlan:
    """Everything a robustness run computes, checked and keyed before any trial runs: the
    strategies (made concrete for the walker, with their reduced basins), the grids, the
    drawn parameters and one task per trial or sample, in order (``kinds``: ``push``,
    ``basin`` or ``sample`` per task; ``where``: (strategy, i, j) of each)."""

    walker: Walker = field(repr=False)
    strategies: tuple[Strategy, ...]
    realized: tuple[Realized, ...] = field(repr=False)
    settings: dict
    impulses: tuple[float, ...]
    phases: tuple[float, ...]
    sigmas: tuple[float, ...]
    rates: tuple[float, ...]
    uncertainty: Uncertainty | None
    draws: dict[str, tuple[float, ...]]
    tasks: tuple[PointTask, ...] = field(repr=False)
    kinds: tuple[str, ...] = field(repr=False)
    where: tuple[tuple[int, int, int], ...] = field(repr=False)
    identity: str
    warnings: tuple[str, ...] = ()

    @property
    def labels(self) -> list[str]:
        return [s.label for s in self.strategies]


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
                    rtol: float = 1e-9, atol: float = 1e-9) -> RobustnessPlan:
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
    velocity)."""
    check_walker(walker)
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
    if not zd.valid:
        raise InputError.param("gait", f"the gait has no walking orbit: {zd.invalid_reason}")
    if strategy is None:
        strategy = ["none", "control"] if robot.thrusters else ["none"]
    strategies = [parse_strategy(s, walker, thruster, knots, max_thrust) for s in strategy]
    if not strategies:
        raise InputError.param("strategy", "no strategy")
    labels_unique(strategies)
    robot_text, gait_text = _texts(walker)
    mu_v = zd.gait.mu if mu is None else float(mu)
    common = {"steps": int(steps), "push_direction": [float(v) for v in push_direction],
              "push_link": push_link, "push_at": float(push_at),
              "push_duration": float(push_duration), "transverse": basin_joint,
              "recovery_tol": float(recovery_tol), "output_tol": float(output_tol),
              "mu": mu, "min_vertical_force": float(min_vertical_force),
              "rtol": float(rtol), "atol": float(atol)}
    # the strategies made concrete here: every problem before any trial (and the basins)
    realized, warnings = [], []
    from .sweep_studies import check_strategy, trial_setup

    try:
        trial_setup(walker, {**_defaults("push-trial"), **common})
    except InputError as exc:
        raise InputError([InputError.param(RENAMED.get(pr.params[0], pr.params[0]),
                                           pr.message).problems[0]
                          for pr in exc.problems]) from None
    for s in strategies:
        p = {**_defaults("push-trial"), **common, **s.parameters()}
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
        st = {**_defaults("push-trial"), **common, **s.parameters()}
        for i, ph in enumerate(phases):
            for j, P in enumerate(impulses):
                add("push-trial", st, {"push_impulse": P, "push_phase": ph}, "push", (k, i, j))
        for i, sg in enumerate(sigmas):
            for j, rt in enumerate(rates):
                add("push-trial", st, {"start_sigma": sg, "start_rate": rt}, "basin", (k, i, j))
    if unc is not None:
        for k, s in enumerate(strategies):
            st = {**_defaults("reduced-walk"), **{c: common[c] for c in ("mu",
                                                                         "min_vertical_force")},
                  **s.parameters()}
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
    return RobustnessPlan(walker, tuple(strategies), tuple(realized), settings, impulses,
                          phases, sigmas, rates, unc, draws, tuple(tasks), tuple(kinds),
                          tuple(where), identity([t.key for t in tasks]), tuple(warnings))


def _texts(walker: Walker) -> tuple[str, str]:
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


# ------------------------------------------------------------------------------ the result
DEFINITIONS = {
    "outcomes": {
        "recovered": "every step walked and the last zeta^- within recovery_tol of the "
                     "strategy's orbit, outputs settled (max |y| <= output_tol)",
        "unsettled": "every step walked, not yet within the tolerance (converging: inside the "
                     "reduced basin and closer each step)",
        "fell": "the stance leg passed the horizontal, or the swing foot missed the ground",
        "slipped": "the push's impulsive ground reaction, a stance force or an impact impulse "
                   "left the friction cone",
        "lifted": "the push's impulsive ground reaction, a stance force (<= min_vertical_force)"
                  " or an impact impulse was not pressing on the ground",
        "scuffed": "the swing foot struck the ground early, or the trailing foot did not lift "
                   "off at impact",
        "stopped": "alpha reversed: the walker stopped and fell back",
        "error": "the trial could not be computed (integrator or controller failure): no "
                 "verdict",
    },
    "survivable": "per phase and direction, the largest grid impulse |P| such that every grid "
                  "impulse of that direction with |p| <= |P| recovered (0 when the smallest did "
                  "not); a lower bound within one grid step; bound: failed / grid edge / error "
                  "/ not run",
    "summary": "mean over phases of (P_forward + P_backward) / 2 [N s], each phase averaging "
               "the directions the impulse grid has",
    "converging_fraction": "basin slice: trials that recovered or are converging, over the "
                           "trials computed (errors and trials not run excluded)",
    "success_rate": "uncertainty: samples that walk, over the samples whose draw is a valid "
                    "robot",
}


@dataclass(frozen=True)
class RobustnessResult:
    """Every trial and sample of a :class:`RobustnessPlan` with its record (None: not run),
    what this run did (``counts``) and where it ran (``executor``); renders
    ``robustness.json``, ``trials.csv`` (and ``uncertainty.csv``) and the figures."""

    __repr__ = result_repr

    plan: RobustnessPlan
    records: tuple[dict | None, ...] = field(repr=False)
    counts: RunCounts
    executor: dict
    wall_time: float

    name = "robustness"

    # -- records -----------------------------------------------------------------------
    def _by_kind(self, kind: str, k: int) -> list[tuple[tuple[int, int], dict | None]]:
        p = self.plan
        return [((w[1], w[2]), r) for kd, w, r in zip(p.kinds, p.where, self.records)
                if kd == kind and w[0] == k]

    @staticmethod
    def _outcome(rec: dict | None) -> str | None:
        if rec is None:
            return None
        if rec["status"] != "ok":
            return "error"
        return rec["fields"]["outcome"]

    def push_grid(self, k: int) -> list[list[str | None]]:
        """Outcome per (phase, impulse) of strategy ``k`` (None: not run)."""
        p = self.plan
        grid: list[list[str | None]] = [[None] * len(p.impulses) for _ in p.phases]
        for (i, j), r in self._by_kind("push", k):
            grid[i][j] = self._outcome(r)
        return grid

    def slice_grid(self, k: int) -> tuple[list[list[str | None]], list[list[bool | None]]]:
        """Outcome and converging flag per (sigma, rate) of strategy ``k``."""
        p = self.plan
        out = [[None] * len(p.rates) for _ in p.sigmas]
        conv: list[list[bool | None]] = [[None] * len(p.rates) for _ in p.sigmas]
        for (i, j), r in self._by_kind("basin", k):
            out[i][j] = self._outcome(r)
            if r is not None and r["status"] == "ok":
                conv[i][j] = bool(r["fields"]["converging"])
        return out, conv

    def samples(self, k: int) -> list[dict | None]:
        return [r for _, r in self._by_kind("sample", k)]

    def _trial_records(self) -> list[tuple[str, dict | None]]:
        return [(kd, r) for kd, r in zip(self.plan.kinds, self.records) if kd != "sample"]

    @property
    def errors(self) -> int:
        return sum(self._outcome(r) == "error" for _, r in self._trial_records())

    @property
    def missing(self) -> int:
        return sum(r is None for r in self.records)

    @property
    def success(self) -> bool:
        """Every trial and sample has its record and no trial failed to compute."""
        return self.missing == 0 and self.errors == 0

    # -- summaries ---------------------------------------------------------------------
    def strategy_summary(self, k: int) -> dict:
        p = self.plan
        s, real = p.strategies[k], p.realized[k]
        grid = self.push_grid(k)
        rows = []
        for i, ph in enumerate(p.phases):
            f, fb = survivable(p.impulses, grid[i], 1.0)
            b, bb = survivable(p.impulses, grid[i], -1.0)
            rows.append({"phase": ph, "forward": f, "forward_bound": fb, "backward": b,
                         "backward_bound": bb})
        fwd, bwd = [r["forward"] for r in rows], [r["backward"] for r in rows]
        flat = [o for row in grid for o in row]
        single = {name: single_outcome(list(p.impulses) * len(p.phases), flat, sign)[0]
                  for name, sign in (("forward", 1.0), ("backward", -1.0))}
        lc = real.cycle
        out = {
            "label": s.label, "kind": s.kind, "parameters": s.parameters(),
            "notes": list(real.notes),
            "orbit": {"exists": bool(lc.exists), "reason": lc.reason,
                      "zeta_star": real.zeta_ref,
                      "speed": float(lc.speed) if lc.exists else None,
                      "what": "the controller's reference (the zero-thrust orbit)"
                      if s.kind == "control" else "the strategy's own fixed point"},
            "reduced_basin": real.basin.document(),
            "push": {"outcome_counts": outcome_counts(flat, OUTCOMES),
                     "recovered_fraction": _fraction(flat, ("recovered",)),
                     "survivable": rows, "mean_forward": mean_of(fwd),
                     "mean_backward": mean_of(bwd), "summary": summary_impulse(fwd, bwd),
                     "single_outcome": single},
        }
        if p.sigmas:
            out["basin_slice"] = self._slice_summary(k)
        if p.uncertainty is not None:
            out["uncertainty"] = self._sample_summary(k)
        return out

    def _slice_summary(self, k: int) -> dict:
        p, real = self.plan, self.plan.realized[k]
        outs, conv = self.slice_grid(k)
        flags = [c for row in conv for c in row if c is not None]
        frac = sum(flags) / len(flags) if flags else None
        agree = None
        if 0.0 in p.rates and real.zeta_ref is not None:
            j0 = p.rates.index(0.0)
            rows = []
            for i, sg in enumerate(p.sigmas):
                x = real.zeta_ref * (1.0 + sg) ** 2
                c = conv[i][j0]
                if c is None:
                    continue
                red = real.basin.contains(x)
                rows.append({"start_sigma": sg, "zeta_minus": x, "reduced": red,
                             "full_order": c})
            agree = {"points": len(rows), "agree": sum(r["reduced"] == r["full_order"]
                                                        for r in rows),
                     "disagreements": [r for r in rows if r["reduced"] != r["full_order"]]}
        return {"converging_fraction": frac, "trials": len(flags),
                "outcome_counts": outcome_counts([o for row in outs for o in row], OUTCOMES),
                "along_sigma_at_zero_rate": agree}

    def _sample_summary(self, k: int) -> dict:
        recs = self.samples(k)
        valid = [r for r in recs if r is not None and r["status"] == "ok"]
        invalid = [r for r in recs if r is not None and r["status"] != "ok"]
        walks = [r for r in valid if r["fields"]["walks"]]
        reasons: dict[str, int] = {}
        for r in valid:
            if not r["fields"]["walks"]:
                why = r["document"]["reason"].split(":")[0]
                reasons[why] = reasons.get(why, 0) + 1
        return {"samples": len(recs), "valid": len(valid), "invalid_draws": len(invalid),
                "first_invalid": invalid[0]["reason"] if invalid else None,
                "not_run": sum(r is None for r in recs), "walking": len(walks),
                "success_rate": len(walks) / len(valid) if valid else None,
                "speed": spread([r["fields"]["speed"] for r in walks]),
                "zeta_star": spread([r["fields"]["zeta_star"] for r in walks]),
                "failures": reasons}

    @property
    def reason(self) -> str:
        p = self.plan
        n = sum(kd != "sample" for kd in p.kinds)
        parts = [f"{n} trials of {len(p.strategies)} strategies"]
        if p.uncertainty is not None:
            parts.append(f"{sum(kd == 'sample' for kd in p.kinds)} parameter samples")
        text = ", ".join(parts)
        if self.errors:
            text += f"; {self.errors} trial(s) could not be computed"
        if self.missing:
            text += f"; {self.missing} not run (run again to resume)"
        sums = []
        for k, s in enumerate(p.strategies):
            v = self.strategy_summary(k)["push"]["summary"]
            sums.append(f"{s.label} {v:.3g} N s" if v is not None else f"{s.label} -")
        text += "; survivable impulse (mean over phases): " + ", ".join(sums)
        for note in self._single_outcomes():
            text += f"; {note['short']}"
        return text

    def _single_outcomes(self) -> list[dict]:
        """Push directions in which one outcome covers every trial (of two or more sizes,
        every phase) of one or more strategies: there the survivable push is 0 N s (or the
        grid's edge, all recovered) at every phase whatever the strategy, so it does not
        tell them apart. One note per (direction, outcome): the strategies, a short text
        for the summary and the full one, with what to change, for the warnings."""
        p = self.plan
        notes = []
        trials = {(kd, w[0], w[1], w[2]): r for kd, w, r in zip(p.kinds, p.where, self.records)}
        for name, sign in (("forward", 1.0), ("backward", -1.0)):
            by: dict[str, list[int]] = {}
            for k in range(len(p.strategies)):
                o = self.strategy_summary(k)["push"]["single_outcome"][name]
                if o is not None and o != "error":
                    by.setdefault(o, []).append(k)
            for o, ks in by.items():
                labels = [p.strategies[k].label for k in ks]
                every = len(ks) == len(p.strategies)
                sizes = sorted({abs(v) for v in p.impulses if v * sign > 0})
                who = ("every strategy" if every and len(ks) > 1 else
                       f"{'strategy' if len(ks) == 1 else 'strategies'} {', '.join(labels)}")
                short = f"every {name} push of {who} is {o}"
                if o == "recovered":
                    value = f"the grid's largest ({sizes[-1]:g} N s)"
                    fix = (f"larger impulses (`push_impulse` beyond {sizes[-1]:g} N s) find "
                           f"where it ends")
                else:
                    value = "0 N s"
                    by_push = all(
                        self._outcome(r) != o or str((r.get("document") or {}).get("reason", "")
                                                     ).startswith("step 1: the push ")
                        for (kd, k, i, j), r in trials.items()
                        if kd == "push" and k in ks and r is not None
                        and p.impulses[j] * sign > 0)
                    why = ("the push's impulsive ground reaction itself (linear in the "
                           "impulse: whether it lifts or slips the stance foot depends on the "
                           "phase, direction and point, not on the size)" if by_push else
                           "the stance foot's reaction to it")
                    fix = (f"decided by {why}; a push spread over time (`push_duration` T "
                           f"> 0 s, e.g. 0.05: the stance force over T is added to the "
                           f"reaction, SPEC 12, so small pushes pass and large ones do not) "
                           f"or at another point or direction (`push_link`, `push_at`, "
                           f"`push_direction`) makes the map depend on the size")
                full = (f"every {name} push ({len(sizes)} sizes x {len(p.phases)} phases) of "
                        f"{who} is `{o}`: the {name} survivable push is {value} at every "
                        f"phase{' for all of them' if len(ks) > 1 else ''}, so it does not "
                        f"tell the strategies apart; {fix}")
                hint = ("; widen `push_impulse`" if o == "recovered" else
                        "; try `push_duration` > 0 or another push point (warnings)")
                notes.append({"direction": name, "outcome": o, "strategies": labels,
                              "short": f"{short}: the {name} survivable push is {value} "
                                       f"whatever the strategy{hint}", "warning": full})
        return notes

    def warnings(self) -> list[str]:
        out = list(self.plan.warnings)
        out += [n["warning"] for n in self._single_outcomes()]
        bad = [r for kd, r in self._trial_records() if self._outcome(r) == "error"]
        if bad:
            first = (bad[0]["document"] or {}).get("reason") or bad[0]["reason"]
            out.append(f"{len(bad)} trial(s) could not be computed (outcome error, no verdict); "
                       f"first: {first}")
        if self.missing:
            out.append(f"{self.missing} trial(s) or sample(s) not run: run again to resume")
        if self.plan.uncertainty is not None:
            for k, s in enumerate(self.plan.strategies):
                u = self._sample_summary(k)
                if u["invalid_draws"]:
                    out.append(f"{s.label}: {u['invalid_draws']} draw(s) are not a valid robot "
                               f"(excluded from the success rate); first: {u['first_invalid']}")
        return out

    def document(self) -> dict:
        p, w = self.plan, self.plan.walker
        n_trials = sum(kd != "sample" for kd in p.kinds)
        return {
            "schema_version": SCHEMA_VERSION, "units": UNITS,
            "success": self.success, "reason": self.reason, "warnings": self.warnings(),
            "robot": robot_record(w.zd), "gait": gait_record(w.zd),
            "settings": p.settings, "definitions": DEFINITIONS,
            "strategies": [self.strategy_summary(k) for k in range(len(p.strategies))],
            "counts": {"trials": n_trials, "samples": len(p.kinds) - n_trials,
                       "recorded": len(p.kinds) - self.missing, "errors": self.errors,
                       "not_run": self.missing, "skipped": self.counts.skipped,
                       "computed": self.counts.ok + self.counts.failed,
                       "resubmitted": self.counts.resubmitted},
            "identity": p.identity, "executor": self.executor, "wall_time": self.wall_time,
            "trials_folder": "trials",
        }

    def tables(self) -> dict[str, Table]:
        p = self.plan
        header = ["trial", "key", "kind", "strategy", "push_phase", col("push_impulse", "N s"),
                  col("push_x", "N s"), col("push_y", "N s"), "start_sigma",
                  col("start_rate", "rad/s"), "outcome", "step", "recovered", "converging",
                  "steps_completed", col("final_zeta_minus", UNITS["zeta"]), "relative_error",
                  col("zeta_ref", UNITS["zeta"]), col("speed", "m/s"), "max_friction_ratio",
                  col("min_vertical_force", "N"), "push_friction_ratio",
                  col("push_vertical_impulse", "N s"), "reason"]
        rows = []
        for t, kd, wh, r in zip(p.tasks, p.kinds, p.where, self.records):
            if kd == "sample" or r is None:
                continue
            v = dict(t.values)
            f = r["fields"] if r["status"] == "ok" else {}
            doc = r["document"] or {}
            vec = (doc.get("trial") or {}).get("push_vector") or [None, None]
            rows.append([t.index, t.key[:20], kd, p.strategies[wh[0]].label,
                         v.get("push_phase"), v.get("push_impulse"), vec[0], vec[1],
                         v.get("start_sigma"), v.get("start_rate"), self._outcome(r),
                         f.get("failed_step"), f.get("recovered"), f.get("converging"),
                         f.get("steps_completed"), f.get("final_zeta_minus"),
                         f.get("relative_error"), f.get("zeta_ref"), f.get("speed"),
                         f.get("max_friction_ratio"), f.get("min_vertical_force"),
                         f.get("push_friction_ratio"), f.get("push_vertical_impulse"),
                         doc.get("reason") or r["reason"]])
        out = {"trials": Table(header, rows, [
            "one row per trial: push trials (pushed in step 1 on the strategy's orbit) and "
            "basin trials (started off the orbit); the full record is trials/KEY.json"])}
        if p.uncertainty is not None:
            names = list(p.draws)
            units_of = {a.name: a.unit for a in p.uncertainty.axes}
            uh = ["sample", "strategy"] + [col(n.replace(".", "_"), units_of[n]) for n in names] \
                + ["walks", col("zeta_star", UNITS["zeta"]), col("speed", "m/s"),
                   col("step_time", "s"), "controlled_steps", "reason"]
            urows = []
            for t, kd, wh, r in zip(p.tasks, p.kinds, p.where, self.records):
                if kd != "sample" or r is None:
                    continue
                v = dict(t.values)
                f = r["fields"] if r["status"] == "ok" else {}
                doc = r["document"] or {}
                urows.append([wh[1], p.strategies[wh[0]].label] + [v[n] for n in names]
                             + [f.get("walks"), f.get("zeta_star"), f.get("speed"),
                                f.get("step_time"), f.get("controlled_steps"),
                                doc.get("reason") or r["reason"]])
            out["uncertainty"] = Table(uh, urows, ["one row per (sample, strategy)"])
        return out

    # -- figures -----------------------------------------------------------------------
    def figure_data(self) -> dict:
        p = self.plan
        sums = [self.strategy_summary(k) for k in range(len(p.strategies))]
        data = {
            "labels": p.labels, "phases": list(p.phases), "impulses": list(p.impulses),
            "outcomes": list(OUTCOMES), "push_maps": [self.push_grid(k)
                                                       for k in range(len(p.strategies))],
            "survivable": [s["push"]["survivable"] for s in sums],
            "summary": [s["push"]["summary"] for s in sums],
            "reduced": [{"label": s["label"], **s["reduced_basin"]} for s in sums],
            "sigmas": list(p.sigmas), "rates": list(p.rates),
            "joint": p.settings["basin_slice"]["joint"], "slices": [], "uncertainty": None,
        }
        for k, real in enumerate(p.realized):
            if not p.sigmas:
                break
            outs, conv = self.slice_grid(k)
            zs = real.zeta_ref
            b = real.basin
            rel = [None if (v is None or zs is None or v <= 0) else float(np.sqrt(v / zs) - 1)
                   for v in (b.lower.value, b.upper.value)]
            data["slices"].append({"label": p.strategies[k].label, "outcomes": outs,
                                   "converging": conv, "reduced_sigma": rel,
                                   "basin_exists": b.exists,
                                   "fraction": sums[k]["basin_slice"]["converging_fraction"]})
        if p.uncertainty is not None:
            data["uncertainty"] = [{"label": s["label"],
                                    "speeds": [r["fields"]["speed"] for r in self.samples(k)
                                               if r is not None and r["status"] == "ok"
                                               and r["fields"]["walks"]],
                                    "rate": s["uncertainty"]["success_rate"],
                                    "valid": s["uncertainty"]["valid"]}
                                   for k, s in enumerate(sums)]
            data["nominal_speed"] = [s["orbit"]["speed"] for s in sums]
        return data

    def figures(self, titles: bool = False) -> dict:
        from ..plots import robustness as plots

        d = self.figure_data()
        w = self.plan.walker
        head = f"{w.robot.name} / {w.gait.name}: " if titles else None

        def t(what: str) -> str:
            return head + what if head else ""

        out = {"push_map": plots.push_map(d, t("push outcomes")),
               "survivable_push": plots.survivable_push(d, t("largest survivable push"))}
        out["basin"] = plots.basin(d, t("basins of attraction"))
        if d["uncertainty"] is not None:
            out["uncertainty"] = plots.uncertainty(d, t("parameter uncertainty"))
        return out


def _fraction(outcomes: Sequence[str | None], good: tuple[str, ...]) -> float | None:
    done = [o for o in outcomes if o is not None and o != "error"]
    return sum(o in good for o in done) / len(done) if done else None


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
                            on_record or (lambda r: None), chunk={"push-trial": int(chunk)})
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

