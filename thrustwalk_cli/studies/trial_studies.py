"""The sweep studies of the robustness and rough-ground commands (SPEC 12, 14): ``push-trial``
(one full-order push or basin trial per point, several per engine task: :func:`trial_chunk`),
``rough-trial`` (one full-order run on seeded rough ground until failure or the cap,
:mod:`thrustwalk_cli.resilience.rough`) and ``reduced-walk`` (one Monte-Carlo sample of the
robot's parameters on the reduced model), as entries of :data:`TRIAL_STUDIES`, which
:data:`.sweep_studies.STUDIES` includes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from ..description.terrain import S_MAX
from ..energetics.run import run_energy
from ..errors import InputError
from ..sweep.runner import chunk_size
from ..sweep.tasks import canonical
from ..walker import Walker
from .documents import UNITS
from .sweep_points import PointResult, SweepStudy, fresh, on_slope

# ------------------------------------------------------------------- a trial's energy (SPEC 15)
#: the energy fields of a push or basin trial [J] (:func:`trial_energy`; None: a model missing)
ENERGY_FIELDS = ("energy_legs_mechanical", "energy_legs_electrical",
                 "energy_thrust_mechanical", "energy_thrust_input", "energy_mechanical",
                 "energy_total", "push_energy")


def trial_energy(result) -> dict:
    """The energy a trial (``resilience.trials.TrialResult``) spent over its completed steps
    [J] (SPEC 15, :func:`~thrustwalk_cli.energetics.run.run_energy` on the dense output, each
    step with the thrust it walked): the joints' positive mechanical work
    ``sum_j int max(0, u_j q_j') dt`` (``energy_legs_mechanical``), their electrical energy
    (``energy_legs_electrical``), the thrusters' positive work on the walker
    (``energy_thrust_mechanical``) and input energy (``energy_thrust_input``),
    ``energy_mechanical`` = legs + thrust positive work, ``energy_total`` = legs electrical +
    thrust input, each summed over the steps (None when a step's is: a model missing, said in
    ``energy_reason``), the push's own energy apart (``push_energy``: the jump of ``K + V`` at
    the push) and ``energy_steps`` the steps counted (0: every value None)."""
    return trial_energies([result])[0]


def trial_energies(results: list) -> list[dict]:
    """:func:`trial_energy` of several trials at once (e.g. an engine task's chunk), the same
    values: the steps of every trial walked on one closed loop go to one ``run_energy`` call
    (a controlled step's thrust as data, ``seg_force``), so that its cost per call is paid
    once per closed loop, not per trial and step; each step's energies are its own, summed
    per trial in step order."""
    groups: dict[tuple, list[tuple[int, int, tuple, object]]] = {}
    loops: dict[tuple, object] = {}
    per_trial: list[list] = []
    for i, res in enumerate(results):
        walked = list(res.energy_input)
        per_trial.append([None] * len(walked))
        for j, (cl, force, step) in enumerate(walked):
            key = (id(cl), force is None)
            loops[key] = cl
            groups.setdefault(key, []).append((i, j, step, force))
    for key, items in groups.items():
        forces = None if key[1] else [f for _, _, _, f in items]
        for (i, j, _, _), e in zip(items, run_energy(loops[key], [it[2] for it in items],
                                                     seg_force=forces)):
            per_trial[i][j] = e
    return [_trial_sums(e) for e in per_trial]


def _trial_sums(energies: list) -> dict:
    """The fields of :func:`trial_energy` from a trial's step energies (in step order)."""
    out: dict = {"energy_steps": len(energies)}
    if not energies:
        out.update({k: None for k in ENERGY_FIELDS})
        out["energy_reason"] = "no completed step: no energy"
        return out

    def total(name):
        vals = [getattr(e, name) for e in energies]
        return None if any(v is None for v in vals) else float(sum(vals))

    lm, le = total("legs_mechanical"), total("legs_electrical")
    tm, ti = total("thrust_mechanical"), total("thrust_input")
    missing: list[str] = []
    for e in energies:
        missing += [line for line in e.missing if line not in missing]
    out.update({"energy_legs_mechanical": lm, "energy_legs_electrical": le,
                "energy_thrust_mechanical": tm, "energy_thrust_input": ti,
                "energy_mechanical": None if lm is None or tm is None else lm + tm,
                "energy_total": None if le is None or ti is None else le + ti,
                "push_energy": float(sum(e.push_energy for e in energies)),
                "energy_reason": "; ".join(missing) or None})
    return out


# ------------------------------------------------------------------- robustness (SPEC 12)
_STRATEGY_KEYS = ("strategy", "strategy_label", "thruster", "thrust", "schedule", "knots",
                  "max_thrust", "mu", "min_vertical_force")
_RUNNER_KEYS = _STRATEGY_KEYS + ("push_direction", "push_link", "push_at", "push_duration",
                                 "transverse", "steps", "recovery_tol", "output_tol", "rtol",
                                 "atol", "terrain")


def _nominal(walker: Walker, p: Mapping) -> Walker:
    """The walker a controller was made for: the base robot with the point's gait (the point's
    robot is the plant)."""
    make = p.get("_nominal")
    return walker if make is None else on_slope(make(), p)


def realized_strategy(walker: Walker, p: Mapping, points: int = 401):
    """The point's strategy made concrete for its walker (kept per process: the trials of a
    strategy share it)."""
    from ..resilience.strategy import from_parameters, realize

    walker = on_slope(walker, p)
    model = _nominal(walker, p)
    mu = walker.gait.mu if p.get("mu") is None else float(p["mu"])
    key = ("realized", id(walker), id(model), canonical({k: p.get(k) for k in _STRATEGY_KEYS}),
           points)
    r = fresh(key, lambda v: v[0] is walker and v[1] is model, lambda: (
        walker, model, realize(walker.zd, from_parameters(p), mu=mu,
                               eps=float(p["min_vertical_force"]), points=points,
                               model_zd=None if model is walker else model.zd)))
    return r[2], mu


def trial_setup(walker: Walker, p: Mapping):
    """The push point and the index of the transverse output of a push-trial point."""
    from ..resilience.push import push_point

    robot = walker.robot
    act = [c.name for c in robot.coordinates if c.actuated]
    name = p.get("transverse") or act[0]
    if name not in act:
        raise InputError.param("transverse", f"unknown actuated coordinate {name!r} (robot "
                                             f"{robot.name} has: {', '.join(act)})")
    point = push_point(walker.model, p.get("push_link"), float(p["push_at"]),
                       tuple(p["push_direction"]))
    return point, act.index(name)


def _terrain_of(p: Mapping) -> dict:
    """The ``heights`` and ``s_max`` of the point's ``terrain`` (SPEC 14; none: level)."""
    t = p.get("terrain")
    return {} if t is None else {"heights": [float(h) for h in t["heights"]],
                                 "s_max": float(t.get("s_max", S_MAX))}


def _trial_runner(walker: Walker, p: Mapping):
    """The trial runner of the point's strategy and settings (kept per process)."""
    from ..resilience.trials import TrialRunner

    walker = on_slope(walker, p)
    real, mu = realized_strategy(walker, p)
    key = ("runner", id(walker), canonical({k: p.get(k) for k in _RUNNER_KEYS}))

    def make():
        point, transverse = trial_setup(walker, p)
        run = TrialRunner(walker.zd, real, point, steps=int(p["steps"]), mu=mu,
                          eps=float(p["min_vertical_force"]),
                          recovery_tol=float(p["recovery_tol"]),
                          output_tol=float(p["output_tol"]), rtol=float(p["rtol"]),
                          atol=float(p["atol"]), transverse=transverse,
                          duration=float(p["push_duration"]),
                          **_terrain_of(p))
        return walker, run

    return fresh(key, lambda v: v[0] is walker, make)[1]


_PT_FIELDS = {
    "outcome": ("", "recovered, unsettled, fell, slipped, lifted, scuffed, stopped or error"),
    "recovered": ("1", "back within recovery_tol of the orbit after the steps"),
    "converging": ("1", "recovered, or still walking and converging (inside the reduced "
                        "basin, closer each step)"),
    "failed_step": ("1", "the step of a failure (empty when every step was walked)"),
    "steps_completed": ("1", "steps completed"),
    "final_zeta_minus": (UNITS["zeta"], "zeta^- of the last step"),
    "relative_error": ("1", "|zeta^- - zeta_ref| / zeta_ref of the last step"),
    "zeta_ref": (UNITS["zeta"], "the orbit a recovery is measured against"),
    "speed": (UNITS["speed"], "average speed of the last step"),
    "max_friction_ratio": (UNITS["friction_ratio"], "largest |F_1^h|/F_1^v over the steps"),
    "min_vertical_force": (UNITS["force"], "least vertical ground force over the steps"),
    "push_friction_ratio": (UNITS["friction_ratio"], "|F^h|/F^v of the push's impulsive "
                                                     "ground reaction"),
    "push_vertical_impulse": (UNITS["impulse"], "vertical part of the push's impulsive ground "
                                                "reaction"),
    "energy_steps": ("1", "completed steps the energies are summed over (SPEC 15)"),
    "energy_legs_mechanical": ("J", "joints' positive mechanical work over the steps"),
    "energy_legs_electrical": ("J", "joints' electrical energy over the steps (empty: a motor "
                                    "model missing, energy_reason)"),
    "energy_thrust_mechanical": ("J", "thrusters' positive work on the walker over the steps"),
    "energy_thrust_input": ("J", "thrusters' input energy over the steps (empty: a power model "
                                 "missing, energy_reason)"),
    "energy_mechanical": ("J", "energy_legs_mechanical + energy_thrust_mechanical"),
    "energy_total": ("J", "energy_legs_electrical + energy_thrust_input (empty: a model "
                          "missing)"),
    "push_energy": ("J", "the mechanical energy the push itself added (apart from the above)"),
    "energy_reason": ("", "the models missing, when an energy is empty"),
    "failed_height": ("m", "the terrain height of the failed step (empty: no failure, or no "
                           "terrain)"),
}


#: the outcomes of a push trial that are not failures (every step walked)
_WALKED = ("recovered", "unsettled")


def failed_height(res, p: Mapping) -> dict:
    """The ground height [m] of the step a push or basin trial failed on (SPEC 14), as
    ``rough-trial``'s ``failed_height``: ``terrain.heights[failed_step - 1]`` of the point's
    terrain (0 past the list: level ground); None with ``failed_height_reason`` when every
    step was walked or the point has no terrain (level ground)."""
    t = p.get("terrain")
    if t is None:
        return {"failed_height": None, "failed_height_reason": "no terrain: level ground"}
    if res.outcome in _WALKED or res.step is None:
        return {"failed_height": None,
                "failed_height_reason": f"no failure: every step walked ({res.outcome})"}
    heights = [float(h) for h in t["heights"]]
    k = int(res.step)
    return {"failed_height": heights[k - 1] if k <= len(heights) else 0.0,
            "failed_height_reason": None}


def _push_trial_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from ..resilience.trials import Trial

    walker = on_slope(walker, p)
    impulse, sigma, rate = (float(p["push_impulse"]), float(p["start_sigma"]),
                            float(p["start_rate"]))
    if impulse != 0.0 and (sigma != 0.0 or rate != 0.0):
        raise InputError.param(("push_impulse", "start_sigma"), "a push trial starts on the "
                                                                "orbit: give a push or a start "
                                                                "off the orbit, not both")
    runner = _trial_runner(walker, p)
    trial = Trial(impulse, float(p["push_phase"]), sigma, rate)
    res = runner.run(trial)
    height = failed_height(res, p)
    doc = {"strategy": runner.r.strategy.label,
           "trial": {"push_impulse": impulse, "push_phase": trial.phase,
                     "push_vector": runner.point.impulse(impulse).tolist(),
                     "start_sigma": sigma, "start_rate": rate},
           **res.document(), **height}
    return PointResult(doc, {**res.fields(), "failed_height": height["failed_height"]},
                       pending=res)  # the energy: _finish_push_trials


def _finish_push_trials(results: list[PointResult]) -> list[PointResult]:
    """The push trials' energies (:func:`trial_energies`, the chunk's trials together) added
    to their documents (``energy``) and fields."""
    energies = trial_energies([r.pending for r in results])
    return [replace(r, document={**r.document, "energy": e}, fields={**r.fields, **e},
                    pending=None) for r, e in zip(results, energies)]


def _check_push_trial(walker: Walker, p: dict) -> list[tuple[str, str]]:
    try:
        walker = on_slope(walker, p)
    except InputError as exc:
        return [("slope", exc.problems[0].message)]
    out = check_strategy(walker, p)
    try:
        walker.robot.check_push("push_impulse", float(p["push_impulse"]))
    except InputError as exc:
        out.append(("push_impulse", exc.problems[0].message))
    try:
        trial_setup(walker, p)
    except InputError as exc:
        out += [(pr.params[0], pr.message) for pr in exc.problems]
    if float(p["push_impulse"]) != 0.0 and (float(p["start_sigma"]) != 0.0
                                            or float(p["start_rate"]) != 0.0):
        out.append(("push_impulse", "a push trial starts on the orbit: give a push or a start "
                                    "off the orbit, not both"))
    return out


def check_strategy(walker: Walker, p: dict) -> list[tuple[str, str]]:
    """The strategy's own problems (thruster, thrust limits, schedule, knots), found before
    any point runs."""
    try:
        walker = on_slope(walker, p)
        if p.get("strategy") == "control" and p.get("max_thrust") is not None:
            robot = walker.robot
            if robot.thrusters:
                robot.check_thrust_bound("max_thrust", float(p["max_thrust"]),
                                         [robot.thruster_index(p.get("thruster"))])
        realized_strategy(walker, p)
    except InputError as exc:
        return [(pr.params[0] if pr.params else "strategy", pr.message) for pr in exc.problems]
    return []


_ROUGH_KEYS = _STRATEGY_KEYS + ("s_max", "rtol", "atol")


def rough_runner(walker: Walker, p: Mapping):
    """The rough-ground runner of the point's strategy and settings on the point's slope
    (SPEC 14: the step heights on top of it; kept per process)."""
    from ..resilience.rough import RoughRunner

    walker = on_slope(walker, p)
    real, mu = realized_strategy(walker, p)
    key = ("rough", id(walker), canonical({k: p.get(k) for k in _ROUGH_KEYS}))

    def make():
        return walker, RoughRunner(walker.zd, real, s_max=float(p["s_max"]), mu=mu,
                                   eps=float(p["min_vertical_force"]), rtol=float(p["rtol"]),
                                   atol=float(p["atol"]))

    return fresh(key, lambda v: v[0] is walker, make)[1]


_RT_FIELDS = {
    "outcome": ("", "censored (the cap reached), fell, stopped, scuffed, lifted, slipped, "
                    "missed_footing or error"),
    "failed": ("1", "the run failed before the cap (error: no)"),
    "steps_completed": ("1", "steps completed"),
    "attempted": ("1", "steps attempted: the completed ones and the failed one"),
    "failed_step": ("1", "the step that failed (empty when none did)"),
    "failed_height": ("m", "the ground height of the failed step"),
    "terrain_seed": ("1", "the seed of the trial's terrain (a terrain file's rough: seed "
                          "replays it)"),
}


def _rough_trial_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from ..resilience.rough import trial_terrain

    walker = on_slope(walker, p)
    runner = rough_runner(walker, p)
    sigma, cap = float(p["sigma"]), int(p["cap"])
    terrain = trial_terrain(p["distribution"], sigma, int(p["seed"]), int(p["trial"]),
                            float(p["s_max"]))
    walk = runner.walk(terrain.heights(cap), cap)
    doc = {"strategy": runner.r.strategy.label, "sigma": sigma,
           "distribution": p["distribution"], "trial": int(p["trial"]),
           "terrain": terrain.record(), **walk.document()}
    fields = {"failed": walk.failed, "terrain_seed": terrain.seed, **walk.document()}
    return PointResult(doc, fields)


_RW_FIELDS = {
    "walks": ("1", "the point's robot walks under the strategy (stable orbit in its reduced "
                   "basin, swing foot clear; control: the base robot's controller settles)"),
    "zeta_star": (UNITS["zeta"], "the converged zeta^-"),
    "speed": (UNITS["speed"], "the converged average speed"),
    "step_time": (UNITS["step_time"], "the converged step time"),
    "controlled_steps": ("1", "control: steps until the controlled map settled"),
    "basin_exists": ("1", "fixed strategies: the reduced basin contains the orbit"),
    "basin_lower": (UNITS["zeta"], "fixed strategies: lower end of the reduced basin in zeta^-"),
    "basin_upper": (UNITS["zeta"], "fixed strategies: upper end of the reduced basin in zeta^-"),
}


def _reduced_walk_point(walker: Walker, p: dict, start: dict | None) -> PointResult:
    from ..resilience.strategy import from_parameters
    from ..resilience.uncertainty import controlled_sample, fixed_sample

    walker = on_slope(walker, p)
    s = from_parameters(p)
    mu = walker.gait.mu if p.get("mu") is None else float(p["mu"])
    eps = float(p["min_vertical_force"])
    if s.kind == "control":
        model = _nominal(walker, p)
        real, _ = realized_strategy(model, {**p, "_nominal": None}, int(p["points"]))
        res = controlled_sample(walker.zd, real.planner, real.zeta_ref, s.knots, real.driven,
                                mu=mu, eps=eps)
    else:
        res = fixed_sample(walker.zd, s, mu=mu, eps=eps, points=int(p["points"]))
    doc = {"strategy": s.label, "walks": res.success, "reason": res.reason,
           "robot_parameters": dict(walker.robot.parameters),
           "basin": None if res.basin is None else res.basin.document(), **res.fields()}
    return PointResult(doc, res.fields())


def _prepare_trials(walker: Walker, settings: dict) -> None:
    """Compile the simulation kernel once here, not in every worker at the same time."""
    from .compile import compile_kernel

    compile_kernel()


TRIAL_STUDIES: dict[str, SweepStudy] = {
    "push-trial": SweepStudy("push-trial", _PT_FIELDS, _push_trial_point,
                             check=_check_push_trial, prepare=_prepare_trials,
                             finish=_finish_push_trials),
    "rough-trial": SweepStudy("rough-trial", _RT_FIELDS, _rough_trial_point,
                              check=check_strategy, prepare=_prepare_trials),
    "reduced-walk": SweepStudy("reduced-walk", _RW_FIELDS, _reduced_walk_point,
                               check=check_strategy, verdict="walks"),
}


STEPS_PER_CHUNK = 320  # trial_chunk: simulated steps per task at most (32 ten-step trials)


def trial_chunk(todo: int, workers: int, steps: int) -> int:
    """Trials per engine task for ``todo`` trials of ``steps`` steps on ``workers`` workers:
    :func:`~thrustwalk_cli.sweep.runner.chunk_size`, i.e. ``ceil(todo / (8 workers))`` (at
    least 8 tasks per worker when there are that many trials: balance and progress), at most
    ``STEPS_PER_CHUNK // steps`` trials (320 simulated steps: 32 trials of 10 steps, tens of
    milliseconds of work against the engine's 1-2 ms per task) and at least 1."""
    return chunk_size(todo, workers, most=max(1, STEPS_PER_CHUNK // max(1, int(steps))))
