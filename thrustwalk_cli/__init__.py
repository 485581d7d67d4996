"""thrustwalk: thruster-assisted bipedal walking with hybrid zero dynamics.

Use from Python (``import thrustwalk_cli as tw``); every name below loads on first use, so the
import itself is instant. Results render themselves: ``document()`` (the JSON the command
writes), ``tables()`` (its CSV tables), ``figures()`` (matplotlib figures), with ``success``
and ``reason``. Units are SI throughout.

Loading
    load_walker         robot + gait -> :class:`Walker` (compiled model, zero dynamics)
    Walker              a robot, its gait, the compiled model and the zero dynamics
    load_robot          a robot file or bundled name -> :class:`Robot`
    load_model          :class:`Robot` -> :class:`CompiledModel` (cached by structure)
    compile_robot       a robot file or bundled name -> :class:`CompiledModel`
    import_urdf         a URDF (+ side file) -> a commented robot YAML and its :class:`Robot`
                        (SPEC 16; the import-urdf command) -> :class:`ImportResult`
    ImportResult        the imported robot: ``yaml``, ``robot``, notes, document
    robot_to_urdf       :class:`Robot` -> planar URDF text (SPEC 16)
    robot_to_mjcf       :class:`Robot` -> MuJoCo MJCF text (SPEC 16; the export-mjcf command)
    Robot               an immutable robot description (links, coordinates, thrusters)
    Gait                an immutable gait description (Bezier virtual constraints)
    WrittenSchedule     a piecewise-constant thrust schedule as written in a gait file (its
                        ``thrust:`` section, ``gait.thrust``); ``.resolve(zd, robot, where)``
                        -> :class:`Schedule` (SPEC 4)
    ThrusterDynamics    the linear dynamics of a robot's thrusters, (A, B, C, D) per thruster
                        (SPEC 7, 13; ``.matrices()``, ``.layout``)
    thruster_dynamics   build one: ``tw.thruster_dynamics("second-order", m, wn=2.0, xi=1.0)``,
                        ``"first-order"`` with ``tau``, ``"ideal"``
    CompiledModel       the numeric dynamics D, C q' + G, B_F, impact map (SPEC 1)

Zero dynamics (SPEC 3, 4)
    ZeroDynamics        the thrust-independent integrals of one gait (``walker.zd``)
    Schedule            thrust per knot interval, batched (``Schedule.constant(zd, F)``)
    zd_limit_cycles     the core: fixed points and orbits of the zero dynamics for a batch of
                        schedules (one :class:`LimitCycle` each); ``limit_cycle`` is the study
    LimitCycle          one periodic orbit: exists, stable, reason, zeta*, speed, ...

Studies (one per command)
    limit_cycle         limit cycles over a constant-thrust sweep -> :class:`LimitCycleResult`
    LimitCycleResult    the sweep's cycles, document, CSV table and figures
    shape               center-manifold shaping with piecewise thrust: keywords for a pattern
                        and knots, a target, or the gait's schedule -> :class:`ShapeResult`
    ShapeResult         nominal and shaped cycles, shifts (true and the paper's), figures
    feasibility         ground-contact feasibility per thrust case -> :class:`FeasibilityResult`
    FeasibilityResult   verdicts, worst points, margins, feasible region, figures
    slope_map           the walkability map over slope x constant thrust (SPEC 14; the slope
                        command) -> :class:`SlopeMapResult`
    SlopeMapResult      first failing condition, zeta*, speed, climb rate per pair, figures
    energy              cost of transport and power over constant thrust, and with a gait
                        library the cheapest way to each speed (SPEC 15) -> :class:`EnergyResult`
    EnergyResult        per-thrust energies and CoT, the library's Pareto table, figures
    optimize_schedule   minimum-effort thrust schedule, an exact QP, or (objective="energy")
                        the least thruster input energy -> :class:`OptimizeResult`
    OptimizeResult      the optimal schedule (or why none exists), gait file, figure
    simulate            full-order closed-loop simulation -> :class:`SimulationResult`
    SimulationResult    runs, per-step records, comparison with the zero dynamics, figures
    SimConfig           a run's numerical settings (steps, tolerances, method, guard, cone);
                        ``simulate(walker, config=...)`` reuses one
    Start               a run's initial condition (on the orbit, perturbed, or an explicit
                        state); ``simulate(walker, start=...)`` reuses one
    mujoco_run          the gait's controller on MuJoCo's soft contact, each step beside the
                        rigid model (SPEC 16; needs ``pip install 'thrustwalk[mujoco]'``)
                        -> :class:`MujocoResult`
    MujocoResult        MuJoCo runs beside the rigid model's prediction, verdicts, figures
    control             step-to-step thrust control, certified contact -> :class:`ControlResult`
    ControlResult       controlled vs uncontrolled runs, certificate per step, export, figures
    stability           Floquet multipliers of the full-order loop -> :class:`StabilityResult`
    StabilityResult     fixed point, Jacobian two ways, multipliers, verdicts, figures
    robustness          push maps, survivable pushes, basins, uncertainty per thrust strategy
                        (SPEC 12; trials on the sweep engine) -> :class:`RobustnessResult`
    RobustnessResult    outcomes per trial, survivable impulses, basins, samples, figures
    rough_ground        mean first passage time on rough ground against sigma per thrust
                        strategy, Monte-Carlo and mesh chain (SPEC 14) -> :class:`RoughGroundResult`
    RoughGroundResult   MFPT with its interval and the mesh's, agreement, headline, figure
    design_gait         design a stable, walkable gait for a robot (a Robot, its model or a
                        Walker) -> :class:`DesignGaitResult`
    DesignSpec          what a gait design asks for (speed, step length, margins, ...)
    DesignGaitResult    the designed gait, its re-check, report, starts table and figure
    inspect_state       the dynamics at one state -> :class:`InspectResult`
    InspectResult       D, C q', G, B_F, impact map as attributes, items and a document

Sweeps (one study at many points; resumable; local processes or a Dask cluster)
    load_sweep          a sweep file, checked before any work -> :class:`Sweep`
    Sweep               the study, axes and one content-keyed task per point
    run_sweep           run the points not yet finished -> :class:`SweepResult`
    SweepResult         every point's record; results table, sweep document, heat maps

Renamed (the old names work for one release, with a DeprecationWarning)
    ``ShapeStudy`` -> ``ShapeResult``; ``limit_cycles`` -> ``zd_limit_cycles``;
    ``ThrustSchedule`` -> ``WrittenSchedule``;
    ``ShapeRequest`` and ``shape(walker, req)`` -> ``shape(walker, pattern=..., k=...)``
    (``ks`` is ``k``).

Errors
    InputError          bad input: every problem as ``file:line: key.path: message`` or
                        ``parameter: message``
    ComputationError    a numerical failure (never silently ignored)
"""

from ._version import __version__

# public name -> module that defines it, or "module:name" when it is defined under another
# name (imported on first use)
_HOMES = {
    "load_walker": "walker", "Walker": "walker",
    "load_robot": "files.robot_file", "load_model": "model.compiler",
    "compile_robot": "studies.compile", "inspect_state": "studies.inspect",
    "import_urdf": "studies.import_urdf", "ImportResult": "studies.import_urdf",
    "robot_to_urdf": "interchange.urdf", "robot_to_mjcf": "interchange.mjcf",
    "mujoco_run": "studies.mujoco", "MujocoResult": "studies.mujoco",
    "Robot": "description.robot", "Gait": "description.gait",
    "WrittenSchedule": "thrust.schedule", "CompiledModel": "model.compiled",
    "ZeroDynamics": "hzd.zero_dynamics", "Schedule": "thrust.schedule",
    "zd_limit_cycles": "hzd.zero_dynamics:limit_cycles", "LimitCycle": "hzd.zero_dynamics",
    "ThrusterDynamics": "thrust.dynamics", "thruster_dynamics": "thrust.dynamics",
    "limit_cycle": "studies.limit_cycle", "LimitCycleResult": "studies.limit_cycle",
    "shape": "studies.shape", "ShapeResult": "studies.shape_result",
    "feasibility": "studies.feasibility", "FeasibilityResult": "studies.feasibility",
    "slope_map": "studies.slope", "SlopeMapResult": "studies.slope",
    "energy": "studies.energy", "EnergyResult": "studies.energy",
    "optimize_schedule": "studies.optimize", "OptimizeResult": "studies.optimize",
    "simulate": "studies.simulate", "SimulationResult": "studies.simulate_result",
    "SimConfig": "simulation.closed_loop", "Start": "simulation.full_order",
    "InspectResult": "studies.inspect",
    "control": "studies.control", "ControlResult": "studies.control_result",
    "stability": "studies.stability", "StabilityResult": "studies.stability",
    "robustness": "studies.robustness", "RobustnessResult": "studies.robustness_result",
    "rough_ground": "studies.rough_ground", "RoughGroundResult": "studies.rough_ground_result",
    "design_gait": "studies.design_gait", "DesignGaitResult": "studies.design_gait",
    "DesignSpec": "design.spec",
    "load_sweep": "studies.sweep", "Sweep": "studies.sweep", "run_sweep": "studies.sweep",
    "SweepResult": "studies.sweep",
    "InputError": "errors", "ComputationError": "errors",
}

# deprecated name -> (where it lives, what to use instead); not public names: not in __all__,
# not in dir(), a DeprecationWarning on every use; kept for one release
_DEPRECATED = {
    "ShapeStudy": ("studies.shape_result:ShapeResult", "tw.ShapeResult"),
    "ShapeRequest": ("studies.shape:ShapeRequest",
                     "the keywords of tw.shape(walker, pattern=..., k=[...], ...)"),
    "limit_cycles": ("hzd.zero_dynamics:limit_cycles", "tw.zd_limit_cycles"),
    "ThrustSchedule": ("thrust.schedule:WrittenSchedule", "tw.WrittenSchedule"),
}

__all__ = ["__version__", *_HOMES]


def _load(home: str, name: str):
    from importlib import import_module

    module, _, attr = home.partition(":")
    return getattr(import_module(f"{__name__}.{module}"), attr or name)


def __getattr__(name: str):
    """Load a public name from its home module on first use (PEP 562); a deprecated name
    loads with a DeprecationWarning naming its replacement."""
    home = _HOMES.get(name)
    if home is not None:
        value = _load(home, name)
        globals()[name] = value
        return value
    if name in _DEPRECATED:
        import warnings

        home, instead = _DEPRECATED[name]
        warnings.warn(f"thrustwalk_cli.{name} is deprecated (kept for one release): use "
                      f"{instead}", DeprecationWarning, stacklevel=2)
        return _load(home, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
