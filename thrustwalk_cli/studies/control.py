"""The ``control`` study: step-to-step thrust control with certified contact (SPEC 11), run in
closed loop on the full-order compiled simulation (SPEC 7) with pushes, a plant that differs
from the model and measurement noise, beside the uncontrolled walker.

References (``x_ref``: the zeta^- to reach at the end of each step) come from a profile over
steps, ``[(step, value), ...]`` with steps increasing, held from each point to the next or
ramped linearly between points: ``zeta`` values [kg^2 m^4/s^2] directly; ``nominal``: the
zero-thrust fixed point zeta*_0 on every step (regulation to the nominal orbit); ``speed``
values [m/s] are tracked as speeds: the zeta^- reference of a speed is the controller's own
steady state that walks at it (:mod:`thrustwalk_cli.controller.references`, SPEC 11).
``tracking_error`` is the error of the quantity asked for (speed for ``speed``, zeta^-
otherwise); both errors are reported by name.

Slow thrusters (``thrust_model`` first- or second-order): the controller uses the thruster's
linear response (:class:`~thrustwalk_cli.controller.step_model.ResponseThrust`); for comparison the
same plant is also run with a controller that ignores the lag (it plans as if the thrust were
the command) and the mismatch of each of its steps is reported. Units SI.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..contact.evaluate import check_contact_options
from ..contact.terms import fit_terms, impact_data
from ..controller.energy_plan import OBJECTIVES, energy_powers
from ..controller.loop import (
    CONE_TOL,
    REALISED_POLISH,
    REALISED_SAMPLES,
    REL_TOL,
    Push,
    run_loop,
)
from ..controller.planner import (
    MAX_CUT_ROUNDS,
    POLISH_ITERATIONS,
    RATIO_TOL,
    Planner,
    regulator,
)
from ..controller.references import SpeedReference, reference_values, speed_references
from ..controller.step_model import IdealThrust, ResponseThrust, Terms
from ..description.terrain import Terrain
from ..errors import (
    InputError,
    check_callable,
    check_choice,
    check_count,
    check_flag,
    check_instance,
    check_number,
    check_number_map,
    check_numbers,
    check_pushes,
    check_texts,
)
from ..files.robot_file import plant_robot
from ..hzd.zero_dynamics import ZeroDynamics
from ..simulation.closed_loop import MAX_STEPS, SimConfig, check_thruster_rate
from ..simulation.full_order import Start
from ..thrust.command import given_dynamics
from ..thrust.dynamics import ThrusterDynamics, canonical, check_model, make, model_names
from ..walker import Walker, check_ground, check_walker, plant_walker
from .control_result import ControlResult
from .documents import climb_rate, dynamics_record

REFERENCES = ("speed", "zeta", "nominal")
ENERGY_WORDS = (
    "each step's plan meets x_{k+1} = x_ref first (or the attainable x_{k+1} closest to it: "
    "saturated) and minimises E(u) = sum over driven thrusters t and knot intervals j of int "
    "P_t(u_jt, V_t) dt over the step predicted from the measured zeta^- (zeta_k(alpha) = "
    "delta_zero^2 x_k + V_0(alpha) + Gamma(alpha) u, dt = d|alpha|/|alpha'|, V_t = sign(u_jt) "
    "d_t . p_t', P_t the thruster's power: model) under the effort plan's constraints "
    "(contact rows with their cutting planes, zeta_min, thrust bounds, rate limit); solved by "
    "sequential convex programming (the orbit frozen at each iterate, the orbit's gradient "
    "term included; interior point with an active-set finish, or HiGHS for piecewise-linear "
    "models), the KKT conditions checked; where no verified energy plan using at most the "
    "effort plan's energy is found, the effort plan is applied and the step says so "
    "(qp.energy.status); the zeta^- of a speed reference is the least-effort steady state's")
TERMS = ("exact", "fitted")


# ----------------------------------------------------------------------------- references
def check_profile(profile, reference: str) -> None:
    """A profile has at least one point, steps >= 0 strictly increasing, values > 0."""
    if reference == "nominal":
        if profile:
            raise InputError.param("profile", "reference nominal takes no profile (it "
                                              "regulates to the zero-thrust orbit)")
        return
    if not profile:
        raise InputError.param("profile", f"reference {reference} needs a profile "
                                          "step:value,... (e.g. 0:0.8,10:1.4)")
    st = [p[0] for p in profile]
    if any(s < 0 or s != int(s) for s in st):
        raise InputError.param("profile", "steps must be whole numbers >= 0")
    if any(b <= a for a, b in zip(st[:-1], st[1:])):
        raise InputError.param("profile", f"steps must increase strictly (got "
                                          f"{', '.join(f'{s:g}' for s in st)})")
    if any(not (np.isfinite(p[1]) and p[1] > 0) for p in profile):
        unit = "m/s" if reference == "speed" else "kg^2 m^4/s^2"
        raise InputError.param("profile", f"values must be > 0 {unit}")


def certificate_settings(planner: Planner) -> dict:
    """What the per-step certificate checks and its tolerances (control.json settings)."""
    return {
        "predicted": "the plan's F_1(alpha) at both ends of the measurement band, its local "
                     "extrema polished between the grid points by golden section on a "
                     "Chebyshev series of the exact rows (its deviation on the grid, "
                     "interpolation_error, added to the margins); the QP gets a cutting plane "
                     "(the exact rows at that alpha) wherever a polished point violates a "
                     "condition beyond its tolerance, until none does",
        "certified": "polished min F^v >= eps - vertical_force_tolerance and polished max "
                     "|F^h|/F^v <= mu + friction_ratio_tolerance over the measurement band, the "
                     "QP feasible, the impact admissible",
        "friction_ratio_tolerance": RATIO_TOL,
        "vertical_force_tolerance": planner.tolerance["vertical_force"],
        "zeta_tolerance": planner.tolerance["zeta"],
        "polish_iterations": POLISH_ITERATIONS, "max_cut_rounds": MAX_CUT_ROUNDS,
        "realised": f"F_1 on {REALISED_SAMPLES} samples of the step's dense output (every "
                    f"integration piece end to end) and the simulation kernel's statistics, "
                    f"the local extrema polished by golden section ({REALISED_POLISH} steps)",
        "in_cone": f"realised min F^v >= eps - {CONE_TOL:g} x weight, max |F^h|/F^v <= mu + "
                   f"{CONE_TOL:g} (the simulation's accuracy), impact ratio <= mu",
        "flagged": f"the realised F_1 (81 samples) or zeta^- outside the prediction's band "
                   f"over the measurement band, widened by {REL_TOL:g} x (weight + max "
                   f"|F_1|) and the fit error bound",
    }


# ----------------------------------------------------------------------------- the study
def _check_profile_pairs(profile) -> list[tuple[float, float]]:
    """``profile`` as (step, value) pairs of finite numbers (their meaning: check_profile)."""
    if profile is None:
        return []
    if isinstance(profile, (str, bytes, dict)) or not hasattr(profile, "__iter__"):
        raise InputError.param("profile", f"must be a sequence of (step, value) pairs, got "
                                          f"{type(profile).__name__} {profile!r:.40}")
    out = []
    for p in profile:
        pair = check_numbers("profile", p, min_len=2, max_len=2)
        out.append((pair[0], pair[1]))
    return out


# a SimConfig's fields control's plant does not take (their defaults only): the closed loop
# runs the compiled DOP853 kernel with its own samples, step-time bound and contact cone
_NOT_TAKEN = ("method", "integrator", "samples_per_step", "guard_s", "ground_tol",
              "max_step_time", "cone_mu", "cone_eps")
# the fields it takes besides steps, recorded in settings.integrator where not the default
_TAKEN = ("scuff_tol", "min_impact_s", "torque_limit", "max_s")
_DEFAULT_STEPS = 40  # control's default number of steps (its signature)


def _config_steps(config: SimConfig | None, steps: int) -> int:
    """The number of steps: ``config.steps`` when a :class:`SimConfig` is given (``steps``
    must then stay at its default, as in ``simulate``), else ``steps``; the config's fields
    checked (:meth:`SimConfig.validate`) and those the plant does not take refused."""
    check_instance("config", config, SimConfig, "a SimConfig (tw.SimConfig(steps=...))",
                   optional=True)
    if config is None:
        return steps
    if steps != _DEFAULT_STEPS:
        raise InputError.param("config", "a SimConfig holds the run's settings: leave `steps` "
                                         "unset")
    default = SimConfig()
    other = [f for f in _NOT_TAKEN if getattr(config, f) != getattr(default, f)]
    if other:
        raise InputError.param("config", f"control runs the compiled DOP853 kernel with its "
                                         f"own samples, step-time bound and contact cone: "
                                         f"leave {', '.join(other)} at their defaults")
    config.validate()
    return check_count("steps", config.steps, le=MAX_STEPS)


def _config_record(cfg: SimConfig) -> dict:
    """The plant's integration settings that differ from a default :class:`SimConfig`."""
    default = SimConfig()
    return {f: getattr(cfg, f) for f in _TAKEN if getattr(cfg, f) != getattr(default, f)}


def _start(start: Start | None, zeta0: float | None) -> tuple[float | None, float]:
    """``(zeta_minus, 1 + perturb)`` of the start: ``zeta0`` [kg^2 m^4/s^2] or a
    :class:`Start` on Z (None: zeta*_0), not both."""
    check_instance("start", start, Start, "a Start (tw.Start(zeta_minus=...))", optional=True)
    if start is None:
        return zeta0, 1.0
    if zeta0 is not None:
        raise InputError.param("start", "a Start holds the initial condition: leave `zeta0` "
                                        "unset")
    if start.q is not None or start.dq is not None:
        raise InputError.param("start", "control starts just after an impact on the "
                                        "zero-dynamics surface (it measures zeta^-): give the "
                                        "Start a zeta_minus and/or perturb, not q and dq")
    check_choice("start", start.orbit, ("predicted", "nominal"))
    zeta = check_number("start", start.zeta_minus, gt=0, optional=True, unit="kg^2 m^4/s^2")
    perturb = check_number("start", start.perturb, gt=-1)
    return zeta, 1.0 + perturb


def _plant(walker: Walker, plant_scale: dict[str, float]) -> tuple[ZeroDynamics, dict]:
    if not plant_scale:
        return walker.zd, {"same_as_model": True, "scale": {}}
    for name, f in plant_scale.items():
        if not (np.isfinite(f) and f > 0):
            raise InputError.param("plant_scale", f"factor of {name} must be > 0 (got {f:g})")
    plant = plant_walker(walker, plant_scale)
    return plant.zd, {"same_as_model": False, "scale": dict(plant_scale),
                      "parameters": dict(plant.robot.parameters),
                      "note": "the plant's robot parameters (the robot file's, with the "
                              "model's overrides) scaled; the controller keeps the model's "
                              "virtual constraints and step map"}


def control(walker: Walker, *, reference: str = "speed",
            profile: Sequence[tuple[float, float]] | None = None, ramp: bool = False,
            knots: Sequence[float] = (0.0, 0.5, 1.0), steps: int = 40,
            thrust_model: str | ThrusterDynamics = "ideal", wn: float = 20.0, xi: float = 1.0,
            tau: float = 0.05,
            thruster: Sequence[str] | None = None,
            push: Sequence[tuple[int, float, float, float]] = (),
            plant_scale: dict[str, float] | None = None, noise: float = 0.0, seed: int = 0,
            mu: float | None = None, min_vertical_force: float = 0.0,
            zeta_min: float | None = None, max_thrust: float | None = None,
            rate_limit: float | None = None, tracking_weight: float | None = None,
            effort_weight: float = 1.0, rate_weight: float = 0.0, terms: str = "exact",
            fit_tol: float = 1e-3, points: int = 401, zeta0: float | None = None,
            compare: bool = True, progress: Callable[[int], None] | None = None,
            check_only: bool = False, slope: float = 0.0,
            terrain: str | Path | Terrain | None = None, objective: str = "effort",
            config: SimConfig | None = None, start: Start | None = None
            ) -> ControlResult | None:
    """Step-to-step thrust control (SPEC 11) in closed loop with the full-order simulation.

    ``reference``: ``speed`` [m/s], ``zeta`` [kg^2 m^4/s^2] (``profile`` of ``(step, value)``,
    held or ``ramp``-ed) or ``nominal``. ``knots``: fractions of the step, 0 first, 1 last,
    increasing (slow thrusters: one setpoint per step, knots 0, 1). ``thrust_model``: ``ideal``
    (the thrust is the command), ``first-order`` (``tau`` [s]) or ``second-order`` (``wn``
    [rad/s], ``xi``), or a :class:`~thrustwalk_cli.thrust.dynamics.ThrusterDynamics` built once
    (``tw.thruster_dynamics``; its own parameters hold). ``thruster``: driven thrusters
    (default: the first). ``push``: ``(step, phase s, P_x, P_y)`` [N s] at the hip.
    ``plant_scale``: robot parameter factors of the plant. ``noise``: relative bound of the
    uniform error of the measured zeta^- (seeded by ``seed``). ``mu`` (default: the gait's),
    ``min_vertical_force`` [N], ``zeta_min`` (default 1 % of zeta*_0) [kg^2 m^4/s^2],
    ``max_thrust`` [N] (within the robot file's ``limits``), ``rate_limit`` [N per step].
    Weights: see :mod:`thrustwalk_cli.controller.planner`. ``terms``: ``exact`` Lambdas or
    ``fitted`` polynomials (relative tolerance ``fit_tol``) with their error bound added to the
    margins.
    ``zeta0``: the start's zeta^- (default zeta*_0). ``compare``: also run the uncontrolled
    walker (and, for slow thrusters, the controller that ignores the lag). ``check_only``:
    check every argument, compute nothing and return None (a command checks its options before
    it compiles the simulation kernel). A push is at most 10 m/s of the whole robot's velocity
    (:meth:`~thrustwalk_cli.description.robot.Robot.push_bound`).
    ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground angle (SPEC 14): the model,
    the step map, the contact terms and the simulated plant in the slope frame (a push's
    impulse stays in the world frame); speeds are along the ground; 0: level ground.
    ``terrain``: a terrain file (path) or :class:`~thrustwalk_cli.description.terrain.Terrain`
    (SPEC 14, as ``simulate``'s): its slope (unless ``slope`` is given: not both) and the
    height ``h_k`` [m] each step of the plant lands on (the guard, step-downs on the continued
    virtual constraints up to its ``s_max``, past it ``missed_footing``); the controller's step
    model is that of the plane (level or sloped) ground and meets the steps through the
    measured zeta^-. Every step records its ``terrain_height``, the settings the terrain.
    ``objective``: ``effort`` (the QP of :mod:`thrustwalk_cli.controller.planner`) or
    ``energy``: each plan puts tracking first and minimises the driven thrusters' input energy
    over the predicted step under the same constraints (:mod:`thrustwalk_cli.controller.
    energy_plan`; every driven thruster needs a ``power:`` model, ideal thrust, no
    ``tracking_weight`` nor ``rate_weight``); a speed reference's zeta^- stays the least-effort
    steady state's.
    Built once, reused (as ``simulate``'s): ``config`` a :class:`SimConfig` (``tw.SimConfig``)
    replaces ``steps`` (which then stays at its default) and sets the plant's integration:
    ``rtol``, ``atol``, ``scuff_tol`` [m], ``min_impact_s``, ``torque_limit`` [N m] and
    ``max_s`` (a terrain's ``s_max`` replaces it, as in ``simulate``); the run is the compiled
    DOP853 kernel with control's own samples, step-time bound and cone, so a SimConfig whose
    ``method``, ``integrator``, ``samples_per_step``, ``guard_s``, ``ground_tol``,
    ``max_step_time``, ``cone_mu`` or ``cone_eps`` differ from their defaults is refused.
    ``start`` a :class:`Start` (``tw.Start``) replaces ``zeta0`` (which then stays unset): the
    post-impact state on Z of ``zeta^- = (1 + perturb) zeta_minus`` [kg^2 m^4/s^2]
    (``zeta_minus`` None: zeta*_0, the zero-thrust fixed point, which is also the predicted
    orbit of the uncontrolled walker); a Start with an explicit state ``q``, ``dq`` is refused
    (the step-to-step controller measures zeta^- on Z).
    """
    check_walker(walker)
    slope, terrain = check_ground(slope, terrain)
    walker = walker.on_slope(slope)
    check_choice("reference", reference, REFERENCES)
    check_choice("objective", objective, OBJECTIVES)
    profile = _check_profile_pairs(profile)
    ramp = check_flag("ramp", ramp)
    knots = check_numbers("knots", knots, min_len=0)
    steps = check_count("steps", steps, le=MAX_STEPS)
    given = given_dynamics(thrust_model, walker.model.n_thrusters)  # a model built once
    if given is not None and given.n_states == 0:
        given, thrust_model = None, "ideal"  # no thruster states: the thrust is the command
    # the deprecated `constant` is `ideal`; a model given as an object is named by its kind
    thrust_model = given.kind if given is not None else check_model(thrust_model)
    wn = check_number("wn", wn, gt=0, unit="rad/s")
    xi = check_number("xi", xi, gt=0)
    tau = check_number("tau", tau, gt=0, unit="s")
    thruster = check_texts("thruster", thruster, optional=True)
    push = check_pushes("push", push, walker.robot, steps)
    plant_scale = check_number_map("plant_scale", plant_scale, optional=True, gt=0)
    noise = check_number("noise", noise)
    seed = check_count("seed", seed, ge=0)
    mu = check_number("mu", mu, optional=True)  # its range: check_contact_options
    min_vertical_force = check_number("min_vertical_force", min_vertical_force)
    zeta_min = check_number("zeta_min", zeta_min, gt=0, optional=True, unit="kg^2 m^4/s^2")
    max_thrust = check_number("max_thrust", max_thrust, gt=0, optional=True, unit="N")
    rate_limit = check_number("rate_limit", rate_limit, gt=0, optional=True, unit="N per step")
    tracking_weight = check_number("tracking_weight", tracking_weight, gt=0, optional=True)
    effort_weight = check_number("effort_weight", effort_weight)
    rate_weight = check_number("rate_weight", rate_weight)
    check_choice("terms", terms, TERMS)
    fit_tol = check_number("fit_tol", fit_tol, gt=0, lt=1)
    points = check_count("points", points, ge=21, le=10_000)
    zeta0 = check_number("zeta0", zeta0, gt=0, optional=True, unit="kg^2 m^4/s^2")
    compare = check_flag("compare", compare)
    check_callable("progress", progress)
    steps = _config_steps(config, steps)
    start_zeta, start_scale = _start(start, zeta0)
    if thrust_model != "ideal" and given is None:
        check_thruster_rate(thrust_model, wn, xi, tau, walker.model.n_thrusters)
    zd, model, robot = walker.zd, walker.model, walker.robot
    problems = []
    if reference not in REFERENCES:
        raise InputError.param("reference", f"unknown reference {reference!r} (choose from "
                                            f"{', '.join(REFERENCES)})")
    if given is None:
        thrust_model = canonical(thrust_model)  # the deprecated `constant` is `ideal`
    if given is None and thrust_model not in model_names():
        raise InputError.param("thrust_model", f"unknown thrust model {thrust_model!r} "
                                               f"(choose from {', '.join(model_names())})")
    if terms not in TERMS:
        raise InputError.param("terms", f"unknown terms {terms!r} (choose from "
                                        f"{', '.join(TERMS)})")
    if not robot.thrusters:
        raise InputError.param("thruster", f"robot {robot.name} has no thruster: nothing to "
                                           "control (`thrusters: []`)")
    names = list(thruster) if thruster else [robot.thruster_names[0]]
    driven = [robot.thruster_index(n) for n in names]
    if len(set(driven)) != len(driven):
        raise InputError.param("thruster", "a thruster is named twice")
    if max_thrust is not None:
        robot.check_thrust_bound("max_thrust", max_thrust, driven)
    if objective == "energy":  # every driven thruster's power model, before anything runs
        energy_powers(zd, driven, dynamic=thrust_model != "ideal",
                      tracking_weight=tracking_weight, rate_weight=rate_weight)
    fr = [float(k) for k in knots]
    if len(fr) < 2 or fr[0] != 0.0 or fr[-1] != 1.0 or any(
            b <= a for a, b in zip(fr[:-1], fr[1:])):
        raise InputError.param("knots", f"knots are fractions of the step, 0 first, 1 last, "
                                        f"strictly increasing (got {', '.join(map(str, fr))})")
    if thrust_model != "ideal" and len(fr) != 2:
        raise InputError.param("knots", f"a thruster with dynamics (`thrust_model` "
                                        f"{thrust_model}) takes one setpoint per step: use "
                                        "knots 0,1")
    if not 1 <= steps <= MAX_STEPS:
        raise InputError.param("steps", f"must be 1..{MAX_STEPS} (got {steps})")
    check_profile(list(profile or []), reference)
    mu = zd.gait.mu if mu is None else float(mu)
    check_contact_options(mu, min_vertical_force)
    if not 0.0 <= noise < 0.5:
        raise InputError.param("noise", f"the relative measurement error bound must lie in "
                                        f"[0, 0.5) (got {noise:g})")
    for name, v, lo in (("wn", wn, 0.0), ("tau", tau, 0.0), ("xi", xi, 0.0),
                        ("effort_weight", effort_weight, -1.0), ("rate_weight", rate_weight,
                                                                 -1.0)):
        if not (np.isfinite(v) and v > lo):
            problems.append((name, f"must be > {max(lo, 0):g} (got {v:g})"))
    if effort_weight <= 0 and rate_weight <= 0:
        problems.append(("effort_weight", "`effort_weight` or `rate_weight` must be > 0 (the "
                                          "QP must be strictly convex)"))
    if rate_limit is not None and not rate_limit > 0:
        problems.append(("rate_limit", f"must be > 0 N per step (got {rate_limit:g})"))
    if max_thrust is not None and not max_thrust > 0:
        problems.append(("max_thrust", f"must be > 0 N (got {max_thrust:g})"))
    if tracking_weight is not None and not tracking_weight > 0:
        problems.append(("tracking_weight", f"must be > 0 (got {tracking_weight:g})"))
    if not 21 <= points <= 10_000:
        problems.append(("points", f"must be 21..10000 (got {points})"))
    pushes = []
    for p in push:
        stp, s, px, py = p
        if not (stp == int(stp) and 1 <= stp <= steps and 0.0 <= s < 1.0):
            problems.append(("push", f"a push needs a step in 1..{steps} and a phase in "
                                     f"[0, 1) (got step {stp:g}, phase {s:g})"))
        pushes.append(Push(int(stp), float(s), (float(px), float(py))))
    if problems:
        raise InputError([InputError.param(n, m).problems[0] for n, m in problems])
    if plant_scale:  # the plant's robot: its names, and a file to scale (before any compile)
        plant_robot(robot, plant_scale)
    if not zd.valid:
        raise InputError.param("gait", f"the gait has no walking orbit to control: "
                                       f"{zd.invalid_reason}")
    if check_flag("check_only", check_only):
        return None
    span = zd.alpha_f - zd.alpha_i
    kn = zd.alpha_i + np.array(fr) * span
    fits = fit_terms(model, zd, tol=fit_tol) if terms == "fitted" else None
    tm = Terms(model, zd, fits)
    dyn = given if given is not None else (
        None if thrust_model == "ideal" else
        make(thrust_model, model.n_thrusters, wn=wn, xi=xi, tau=tau))
    planner, lc0 = regulator(
        zd, kn, driven, mu=mu, eps=min_vertical_force, zeta_min=zeta_min,
        max_thrust=max_thrust, rate_limit=rate_limit, tracking_weight=tracking_weight,
        effort_weight=effort_weight, rate_weight=rate_weight, noise=noise, points=points,
        terms=tm, thrust=None if dyn is None else ResponseThrust(zd, dyn, driven),
        continuous=True, objective=objective)
    settings_qp = planner.st
    lo, hi, zs0 = settings_qp.lo, settings_qp.hi, settings_qp.zeta_scale
    # references
    speed_refs = None
    speed_plan: dict[float, SpeedReference] = {}
    if reference == "nominal":
        refs = np.full(steps, zs0)
    else:
        vals = reference_values(list(profile), steps, ramp)
        if reference == "zeta":
            refs = vals
        else:
            speed_refs = vals
            steady = planner if dyn is None else Planner(zd, Terms(model, zd, fits),
                                                         IdealThrust(zd, kn, driven),
                                                         settings_qp)
            speed_plan = speed_references(steady, zd, vals, zs0)
            refs = np.array([speed_plan[float(v)].zeta_minus for v in vals])
    plant, plant_doc = _plant(walker, dict(plant_scale or {}))
    cfg = SimConfig(steps=1) if config is None else replace(config, steps=1)
    heights = None
    if terrain is not None:
        cfg = replace(cfg, max_s=terrain.s_max)
        heights = tuple(float(h) for h in terrain.heights(steps))
    t_max = 10.0 * float(lc0.step_time)
    x0 = (zs0 if start_zeta is None else start_zeta) * start_scale
    common = dict(steps=steps, x0=x0, knots=kn,
                  driven=driven, dynamics=dyn, pushes=tuple(pushes), config=cfg,
                  t_max=t_max, mu=mu, eps=float(min_vertical_force), progress=progress,
                  heights=heights)
    if zeta0 is not None and not zeta0 > 0:
        raise InputError.param("zeta0", f"must be > 0 kg^2 m^4/s^2 (got {zeta0:g})")
    controlled = run_loop(plant, planner, label="controlled", refs=refs, noise=noise,
                          seed=seed, **common)
    uncontrolled = naive = None
    if compare:
        uncontrolled = run_loop(plant, None, label="uncontrolled", refs=refs, **common)
        if dyn is not None:
            naive_planner = Planner(zd, Terms(model, zd, fits), IdealThrust(zd, kn, driven),
                                    settings_qp)
            naive = run_loop(plant, naive_planner, label="lag ignored", refs=refs,
                             noise=noise, seed=seed, **common)
    imp = impact_data(model, zd)
    warnings = list(walker.warnings)
    if not imp.admissible(mu):
        warnings.append("the impact is inadmissible for every step (it does not depend on "
                        "thrust): " + "; ".join(imp.reasons(mu)))
    settings = {
        "reference": reference, "profile": [list(map(float, p)) for p in (profile or [])],
        "ramp": ramp, "knot_fractions": fr, "knots_alpha": list(map(float, kn)),
        "steps": steps, "thrust_model": thrust_model,
        "thruster_dynamics": None if dyn is None else (
            dynamics_record(dyn) if given is not None else
            {"kind": dyn.kind, "wn": wn, "xi": xi, "tau": tau}),
        "slow_thrusters": None if dyn is None else (
            "the controller uses the thruster's linear response: the delivered thrust over "
            "the step is affine in the setpoint and the thruster state at impact, on the "
            "step's own zero-dynamics time map (fixed-point iteration); `lag_ignored` is the "
            "same plant under a controller that plans as if the thrust were the command"),
        "thrusters": names, "thrust_bounds": {"lower": list(map(float, lo)),
                                              "upper": list(map(float, hi))},
        "rate_limit": rate_limit, "mu": mu, "min_vertical_force": float(min_vertical_force),
        "zeta_min": settings_qp.zeta_min, "tracking_weight": tracking_weight,
        "effort_weight": effort_weight, "rate_weight": rate_weight, "terms": terms,
        "fit_tolerance": fit_tol, "grid_points": points,
        "pushes": [{"step": p.step, "phase": p.s, "impulse": list(p.impulse),
                    "at": walker.robot.stance_end_text()} for p in pushes],
        "noise": {"relative_bound": noise, "distribution": "uniform", "seed": seed},
        "start_zeta_minus": common["x0"], "nominal_zeta_star": zs0,
        "nominal_speed": float(lc0.speed),
        **({"nominal_climb_rate": climb_rate(float(lc0.speed), walker.slope)}
           if walker.slope != 0.0 else {}),
        "integrator": {"method": "compiled DOP853", "rtol": cfg.rtol, "atol": cfg.atol,
                       **_config_record(cfg)},
        **({"terrain": terrain.record()} if terrain is not None else {}),
        "tracked": "speed" if reference == "speed" else "zeta_minus",
        "speed_reference": None if speed_refs is None else {
            "method": "zeta^- reference = the zeta^- of the controller's own steady state "
                      "(x_k = x_{k+1}, least effort under the contact conditions with their "
                      "cutting planes, the thrust limits and zeta_min) whose average speed, "
                      "step length over the zero-dynamics step time of that thrust, is the "
                      "reference (Brent's method over the steady-feasible zeta^- range)",
            "values": [{"speed": r.speed, "zeta_minus": r.zeta_minus,
                        "steady_speed": r.steady_speed, "reachable": r.reachable,
                        "steady_thrust": list(r.thrust)} for r in speed_plan.values()]},
        "certificate": certificate_settings(planner),
        **({"objective": "energy", "energy_objective": ENERGY_WORDS} if objective == "energy"
           else {}),
    }
    return ControlResult(walker, settings, planner, refs, speed_refs, controlled, uncontrolled,
                         naive, plant_doc, tuple(warnings))
