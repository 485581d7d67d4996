"""The ``simulate`` study: full-order closed-loop hybrid simulation with thruster dynamics,
compared step by step with the zero-dynamics prediction and the reduced cascade (SPEC 3, 7).

:func:`simulate` checks the arguments and runs the scenario; its result, documents, tables,
figure data and animation frames are :mod:`.simulate_result`. Units: SI.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

from ..description.terrain import Terrain
from ..errors import (
    InputError,
    check_callable,
    check_choice,
    check_count,
    check_flag,
    check_instance,
    check_number,
    check_numbers,
    check_text,
    check_texts,
)
from ..simulation.closed_loop import (
    MAX_SAMPLES,
    MAX_STEPS,
    MAX_TOTAL_STEPS,
    METHODS,
    SIMULATORS,
    SimConfig,
)
from ..simulation.full_order import Start
from ..simulation.scenario import make_scenario, run_scenario
from ..thrust.dynamics import ThrusterDynamics
from ..walker import Walker, check_ground, check_walker
from .simulate_result import SimulationResult


def default_f_ss(walker: Walker) -> tuple[float, ...]:
    """Steady thrust values [N] run by default: 0 to -50 N in steps of 10, or only 0 for a
    robot without thrusters."""
    return (0.0, -10.0, -20.0, -30.0, -40.0, -50.0) if walker.robot.thrusters else (0.0,)


# the defaults of simulate's settings that a SimConfig replaces
_SIM_DEFAULTS = dict(steps=30, rtol=1e-9, atol=1e-9, method="compiled", integrator="DOP853",
                     samples=80, torque_limit=None, scuff_tol=1e-4, min_impact_s=0.75)


def simulate(walker: Walker, *, steps: int = 30,
             thrust_model: str | ThrusterDynamics | None = None,
             thrust: Sequence[float] | None = None, wn: float = 2.0, xi: float = 1.0,
             tau: float = 0.5, f0: float = 0.0, thruster: Sequence[str] | None = None,
             perturb: float = 0.0, zeta0: float | None = None,
             q0: Sequence[float] | None = None, dq0: Sequence[float] | None = None,
             start: str | Start = "predicted", torque_limit: float | None = None,
             rtol: float = 1e-9,
             atol: float = 1e-9, method: str = "compiled", integrator: str = "DOP853",
             samples: int = 80,
             scuff_tol: float = 1e-4, min_impact_s: float = 0.75, impact_s_tol: float = 1e-3,
             zeta_tol: float = 1e-3, reduced: bool = False, mu: float | None = None,
             progress: Callable[[int], None] | None = None, check_only: bool = False,
             config: SimConfig | None = None, slope: float = 0.0,
             terrain: str | Path | Terrain | None = None) -> SimulationResult | None:
    """Simulate ``steps`` steps of the full-order closed loop (SPEC 7) for each steady thrust
    ``thrust`` [N] (default 0 to -50 N in steps of 10, only 0 for a robot without thrusters;
    not with ``thrust_model="piecewise"``, which uses the gait's ``thrust:`` section) on
    ``thruster`` (default: the first).

    Thrust models: a :class:`~thrustwalk_cli.thrust.dynamics.ThrusterDynamics` built once
    (``tw.thruster_dynamics(kind, m, ...)`` or by hand; its parameters hold, ``wn``, ``xi``,
    ``tau`` are not used), or by name: ``ideal``, ``first-order`` (``tau`` [s]),
    ``second-order`` (``wn`` [rad/s], ``xi``), ``piecewise``; default: ``piecewise`` when the
    gait has a ``thrust:`` section and no ``thrust`` is given (the walker starts on that
    schedule's orbit), else ``second-order``. ``f0`` [N] is the thrust at t = 0 of the dynamic
    models. ``mu`` (default:
    the gait's) is the friction cone every step is checked against: a run that leaves it or
    saturates a torque is never plain ``ok``.
    The start is just after an impact on the predicted orbit (``start="predicted"``) or the
    zero-thrust one (``"nominal"``), with ``zeta^-`` scaled by ``1 + perturb`` or given as
    ``zeta0`` [kg^2 m^4/s^2], or the explicit state ``q0`` [rad], ``dq0`` [rad/s].
    ``reduced``: only the reduced cascade (SPEC 3). ``method``: ``compiled`` (the numba
    kernel, compiled once per machine) or ``scipy`` (``solve_ivp`` with ``integrator``, the
    reference); a ``solve_ivp`` name as ``method`` (e.g. ``"LSODA"``) means ``scipy`` with that
    integrator. ``progress(1)`` after every step.
    A physical failure (a fall, a scuff, no periodic orbit for that thrust) is a run with
    ``success`` false, never an exception; the other values still run. ``scuff_tol`` [m]: dip
    allowed before mid-step; ``min_impact_s``: a strike before this s is a scuff (the
    early-strike threshold, in [0.5, 1)); a completed run whose impacts are farther than
    ``impact_s_tol`` from s = 1, or whose zeta^- differs from the zero-dynamics prediction by
    more than ``zeta_tol`` (relative), gets status ``warning`` with the reason.
    ``check_only``: check every argument, compute nothing and return None (a command checks
    its options before it compiles the simulation kernel).
    Built once, reused: ``start`` may be a :class:`Start` (``tw.Start``; then ``zeta0``,
    ``perturb``, ``q0``, ``dq0`` stay unset) and ``config`` a :class:`SimConfig`
    (``tw.SimConfig``: it replaces ``steps``, ``rtol``, ``atol``, ``method``, ``integrator``,
    ``samples``, ``torque_limit``, ``scuff_tol``, ``min_impact_s``, which then stay at their
    defaults).
    ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground angle (SPEC 14,
    :meth:`Walker.on_slope`): the run is in the slope frame (gravity ``g (-sin, -cos)``,
    world-frame thrusters turned by ``-slope``, link-frame ones not; guard, impact and
    relabelling unchanged), compared with the zero dynamics on that slope; the document gains
    the ``slope`` block and each run its speed along the ground and climb rate. 0: level
    ground, bit for bit as without it.
    ``terrain``: a terrain file (path, read by :func:`~thrustwalk_cli.files.terrain_file.
    load_terrain`) or a :class:`~thrustwalk_cli.description.terrain.Terrain` (SPEC 14): its
    slope (unless ``slope`` is given: not both), and the height ``h_k`` [m] each step's swing
    foot lands on above its stance foot: the guard is the swing foot reaching ``h_k`` once
    armed, a step-down is met on the Bezier polynomials continued past s = 1 until the
    terrain's ``s_max`` (past it: failure ``missed_footing``). Each step records its
    ``terrain_height``; the document records the terrain (its draws are reproducible from its
    seed). The reduced cascade and the zero-dynamics prediction stay those of level steps:
    impacts away from s = 1 are reported as deviations.
    """
    check_walker(walker)
    slope, terrain = check_ground(slope, terrain)
    steps = check_count("steps", steps, le=MAX_STEPS)
    thrust = check_numbers("thrust", thrust, optional=True, min_len=0)
    wn = check_number("wn", wn, gt=0, unit="rad/s")
    xi = check_number("xi", xi, gt=0)
    tau = check_number("tau", tau, gt=0, unit="s")
    f0 = check_number("f0", f0, unit="N")
    thruster = check_texts("thruster", thruster, optional=True)
    perturb = check_number("perturb", perturb, gt=-1)
    zeta0 = check_number("zeta0", zeta0, gt=0, optional=True, unit="kg^2 m^4/s^2")
    q0 = check_numbers("q0", q0, optional=True)
    dq0 = check_numbers("dq0", dq0, optional=True)
    if not isinstance(start, Start):
        check_choice("start", start, ("predicted", "nominal"))
    elif zeta0 is not None or perturb != 0.0 or q0 is not None or dq0 is not None:
        raise InputError.param("start", "a Start holds the initial condition: leave `zeta0`, "
                                        "`perturb`, `q0` and `dq0` unset")
    check_instance("config", config, SimConfig, "a SimConfig (tw.SimConfig(steps=...))",
                   optional=True)
    if config is not None:
        given = dict(steps=steps, rtol=rtol, atol=atol, method=method, integrator=integrator,
                     samples=samples, torque_limit=torque_limit, scuff_tol=scuff_tol,
                     min_impact_s=min_impact_s)
        clash = [k for k, v in given.items() if v != _SIM_DEFAULTS[k]]
        if clash:
            raise InputError.param("config", f"a SimConfig holds the run's settings: leave "
                                             f"{', '.join(f'`{k}`' for k in clash)} unset")
        steps = check_count("steps", config.steps, le=MAX_STEPS)
    torque_limit = check_number("torque_limit", torque_limit, gt=0, optional=True, unit="N m")
    rtol = check_number("rtol", rtol, gt=0, lt=0.1)
    atol = check_number("atol", atol, gt=0, lt=0.1)
    check_choice("method", method, SIMULATORS + METHODS)
    check_text("integrator", integrator)
    samples = check_count("samples", samples, ge=2, le=MAX_SAMPLES)
    scuff_tol = check_number("scuff_tol", scuff_tol, ge=0, unit="m")
    min_impact_s = check_number("min_impact_s", min_impact_s)
    impact_s_tol = check_number("impact_s_tol", impact_s_tol, gt=0)
    zeta_tol = check_number("zeta_tol", zeta_tol, gt=0)
    reduced = check_flag("reduced", reduced)
    mu = check_number("mu", mu, gt=0, optional=True)
    check_callable("progress", progress)
    if (q0 is None) != (dq0 is None):
        raise InputError.param(("q0", "dq0"), "give both or neither")
    if q0 is not None and (zeta0 is not None or perturb != 0.0):
        raise InputError.param(("q0", "dq0"), "replace `zeta0`/`perturb`: give one kind of "
                                              "start")
    values = None if thrust is None else [float(v) for v in thrust]
    if thrust_model is None:
        thrust_model = ("piecewise" if walker.gait.thrust is not None and values is None
                        else "second-order")
    if values is None and thrust_model != "piecewise":
        values = list(default_f_ss(walker))
    runs = 1 if thrust_model == "piecewise" or not values else len(values)
    if runs * steps > MAX_TOTAL_STEPS:
        raise InputError.param(("thrust", "steps"),
                               f"{runs} runs x {steps} steps = {runs * steps} steps, above the "
                               f"limit of {MAX_TOTAL_STEPS} per command: simulate fewer values "
                               f"or fewer steps")
    st = start if isinstance(start, Start) else Start(
        zeta_minus=zeta0, perturb=perturb, q=None if q0 is None else list(q0),
        dq=None if dq0 is None else list(dq0), orbit=start)
    if method in METHODS:  # a solve_ivp name: the SciPy reference with that integrator
        method, integrator = "scipy", method
    if config is None:
        config = SimConfig(steps=steps, rtol=rtol, atol=atol, method=method,
                           integrator=integrator, samples_per_step=samples,
                           torque_limit=torque_limit, scuff_tol=scuff_tol,
                           min_impact_s=min_impact_s)
    heights = None
    if terrain is not None:
        if reduced:
            raise InputError.param(("reduced", "terrain"), "the reduced cascade walks level "
                                   "steps only: simulate a terrain with the full-order model")
        config = replace(config, max_s=terrain.s_max)
        heights = tuple(float(h) for h in terrain.heights(config.steps))
    walker = walker.on_slope(slope)
    zd = walker.zd
    schedule = None
    if thrust_model == "piecewise":
        schedule = walker.gait_schedule()
    sc = make_scenario(zd, thrust_model, values, list(thruster) if thruster else None,
                       schedule=schedule, wn=wn, xi=xi, tau=tau, f0=f0, start=st,
                       config=config, reduced_only=reduced, impact_s_tol=impact_s_tol,
                       zeta_tol=zeta_tol)
    if heights is not None:
        sc = replace(sc, heights=heights)
    if check_flag("check_only", check_only):
        return None
    return SimulationResult(walker, sc, tuple(run_scenario(zd, sc, progress)), mu, terrain)
