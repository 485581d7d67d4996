"""One call from files to ready models: a robot, its gait, the compiled model and the zero
dynamics (SPEC 1-3).

    walker = load_walker("three_link", "three_link_walk")   # bundled names or YAML paths
    walker.zd.delta_zero_sq                                  # Poincare eigenvalue (SPEC 3)

Each file is parsed once: the gait's ``robot:`` reference is parsed again only when a robot is
given explicitly and the gait names a different file (to compare the robot names). The model
comes from the disk cache (SymPy is imported only to compile a new robot). Per-run data never
lives on the walker: it holds immutable descriptions, the compiled model and the
thrust-independent zero dynamics.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property
from math import pi
from pathlib import Path

from .contact.terms import scuff_reason, swing_clearance
from .description.gait import Gait
from .description.robot import Robot
from .description.terrain import Terrain
from .errors import InputError, Where, WrongKind, check_instance, check_number_map, check_path
from .files.bundled import bundled_names, resolve
from .files.gait_file import GaitSource, bind_gait, load_gait, same_robot_file
from .files.robot_file import load_robot, plant_robot
from .files.terrain_file import load_terrain
from .hzd.constraints import apply_invariance, gait_maps
from .hzd.zero_dynamics import ZeroDynamics, zero_dynamics
from .model.compiled import CompiledModel
from .model.compiler import Progress, load_model
from .model.slope import check_slope

FOOT_TOL = 1e-6  # [m] the swing foot must be this close to the ground at impact
DEFAULT_GAIT = "three_link_walk"


@dataclass(frozen=True)
class Walker:
    """A robot and a gait ready for analysis.

    robot, gait: the immutable descriptions (the gait with hybrid invariance applied when it
    asks for ``invariance: auto``); model: the compiled numeric model (SPEC 1); zd: the
    thrust-independent zero dynamics of the gait on the model (SPEC 3); where: locates a
    problem found later at a key path of the gait file (``file:line: key.path``).
    """

    robot: Robot
    gait: Gait
    model: CompiledModel
    zd: ZeroDynamics
    where: Where

    def __repr__(self) -> str:
        return (f"Walker(robot={self.robot.name!r}, gait={self.gait.name!r}, "
                f"coordinates={self.robot.coordinate_names!r}, "
                f"thrusters={self.robot.thruster_names!r}, "
                f"delta_zero_sq={self.zd.delta_zero_sq:.6g}, valid={self.zd.valid})")

    @property
    def name(self) -> str:
        """``robot / gait``, for titles and tables."""
        return f"{self.robot.name} / {self.gait.name}"

    @property
    def slope(self) -> float:
        """The ground angle [rad, positive uphill] the walker stands on (SPEC 14); 0 on level
        ground."""
        return self.zd.slope

    def on_slope(self, gamma: float) -> Walker:
        """The same robot and gait on the slope ``gamma`` [rad, positive uphill] (SPEC 14):
        the slope-frame model and zero dynamics (:meth:`ZeroDynamics.on_slope`); ``self``
        when the slope is the walker's own (level ground: bit for bit). |gamma| < pi/2."""
        zd = self.zd.on_slope(gamma)
        if zd is self.zd:
            return self
        return Walker(self.robot, self.gait, zd.model, zd, self.where)

    def gait_schedule(self, what: str = "the piecewise thrust model"):
        """The gait's ``thrust:`` schedule (SPEC 4) resolved on the walker's zero dynamics
        (one schedule, padded to every thruster) and checked against the thrusters' limits:
        a :class:`~thrustwalk_cli.thrust.schedule.Schedule`. :class:`InputError` at the gait
        file's ``thrust`` key when the gait has none (``what`` needs it) or a value is
        outside a thruster's limits."""
        if self.gait.thrust is None:
            raise InputError(self.where(("thrust",), f"the gait has no thrust schedule "
                                                     f"(needed by {what})"))
        zd = self.zd
        schedule = self.gait.thrust.resolve(zd, zd.model.robot, self.where, pad=True)[0]
        schedule.check_limits(zd.model.robot, self.where)
        return schedule

    @cached_property
    def swing(self) -> dict:
        """Swing-foot height along the step [m] (minimum, deepest dip, ``scuffs``)."""
        return swing_clearance(self.model, self.zd)

    @property
    def warnings(self) -> tuple[str, ...]:
        """What makes every zero-dynamics verdict of this gait invalid or doubtful: not
        hybrid-invariant, kappa_1 singular, the swing foot below the ground (scuffing)."""
        out = []
        if not self.zd.valid:
            out.append(self.zd.invalid_reason)
        sw = self.swing
        if sw["scuffs"]:
            out.append(scuff_reason(sw))
        return tuple(out)


def check_walker(value: object, name: str = "walker") -> Walker:
    """``value`` if it is a :class:`Walker`, else an :class:`InputError` naming ``name`` (the
    first check of every study)."""
    return check_instance(name, value, Walker, "a Walker (tw.load_walker(robot, gait))")


def as_model(value: object, name: str = "robot") -> CompiledModel:
    """The compiled model (SPEC 1) of a :class:`CompiledModel` (itself), a :class:`Robot`
    (:func:`load_model`: cached by structure) or a :class:`Walker` (its model);
    :class:`InputError` naming ``name`` otherwise."""
    if isinstance(value, Walker):
        return value.model
    if isinstance(value, Robot):
        return load_model(value)
    return check_instance(name, value, CompiledModel, "a Robot, a CompiledModel or a Walker "
                          "(tw.load_robot, tw.load_model, tw.load_walker)")


def walker_from(model: CompiledModel, gait: Gait, where: Where = "gait") -> Walker:
    """A walker from a compiled model and a complete gait already in memory (``A`` with
    invariance applied), e.g. a gait just designed or edited in a script."""
    return Walker(model.robot, gait, model, zero_dynamics(model, gait), where)


def plant_walker(walker: Walker, scale: Mapping[str, float]) -> Walker:
    """``walker``'s gait as it is (bound, invariance applied: a controller's virtual
    constraints, not fitted again) on its robot with the named parameters multiplied by
    ``scale`` [1] (:func:`plant_robot`: the robot file read again with the walker's own
    parameter overrides, then scaled), compiled (:func:`load_model`) and on the walker's
    slope (SPEC 14): the plant of a controller whose model is ``walker``. :class:`InputError`
    naming ``plant_scale`` for a robot built in memory."""
    robot = plant_robot(walker.robot, scale)
    return walker_from(load_model(robot), walker.gait, walker.where).on_slope(walker.slope)


def default_gait(robot: Robot | None) -> str:
    """The bundled gait for ``robot`` (the first, by name, whose ``robot:`` names its file),
    or the default gait when no robot is given."""
    if robot is None:
        return DEFAULT_GAIT
    for name in bundled_names("gaits"):
        if same_robot_file(robot, load_gait(name)[0].robot):
            return name
    raise InputError.param("gait", f"no gait given and no bundled gait for robot "
                                   f"{robot.name!r}: give a gait file")


def check_impact_posture(model: CompiledModel, gait: Gait, source: GaitSource) -> None:
    """The swing foot must be on the ground at impact (``q^- = H^-1 [a_M; alpha_f]``, SPEC 2):
    a gait written in degrees, or with the wrong sign of alpha, puts it under or above the
    ground. Raises :class:`InputError` at the gait file's line."""
    maps = gait_maps(model, gait)
    if not abs(maps.span) > 1e-6:
        raise InputError(source.where(("alpha", "c"), (
            f"alpha does not change over the step (alpha_i = {maps.alpha_i:.6g}, alpha_f = "
            f"{maps.alpha_f:.6g} rad): choose c so that alpha = c q runs monotonically from "
            "the post-impact to the pre-impact posture")))
    h = float(model.p_swing(maps.q_minus)[1])
    if abs(h) <= FOOT_TOL:
        return
    big = [(("bezier", "coefficients", name, j), v) for name, row in source.rows.items()
           for j, v in enumerate(row) if v is not None and abs(v) > pi]
    if abs(gait.alpha_f) > pi:
        big.insert(0, (("alpha", "final"), gait.alpha_f))
    where = f"{abs(h):.4g} m {'below' if h < 0 else 'above'} the ground at impact"
    if big:
        key, msg = big[0][0], (f"the swing foot is {where}; angles are in radians "
                               f"({big[0][1]:g} > pi)")
    elif h < 0:
        key, msg = ("alpha", "final"), f"the swing foot is {where}"
    else:
        key, msg = ("alpha", "final"), (
            f"the swing foot is {where}: alpha_f = c q^- must be reached with the swing foot "
            "on the ground (check the sign of alpha.c and alpha.final)")
    raise InputError(source.where(key, msg))


def load_walker(robot: str | None = None, gait: str | None = None, *,
                robot_parameters: Mapping[str, float] | None = None,
                gait_parameters: Mapping[str, float] | None = None,
                progress: Progress | None = None) -> Walker:
    """Load a gait and its robot (``robot`` overrides the gait's own ``robot:``), check them
    against each other, compile (or load) the model, apply ``invariance: auto`` (SPEC 2) and
    precompute the zero dynamics (SPEC 3). ``robot`` and ``gait`` are bundled names or paths;
    without a gait, the robot's bundled gait (or ``three_link_walk`` without a robot); a gait
    given alone in ``robot``'s place (``load_walker("my_walk.yaml")``, a file or a bundled
    gait's name) is that gait on the robot its ``robot:`` names.
    ``robot_parameters`` / ``gait_parameters``: numbers replacing the files' named
    ``parameters:`` (as if edited into the files; e.g. ``{"MT": 12.0}`` [kg]).
    ``progress(done, total, phase)`` hears about every step of a compile (none when the
    model comes from the cache).

    Raises :class:`InputError` (``file:line: key.path: message``) on bad files, when ``robot``
    is not the robot the gait was written for, or when the swing foot is not on the ground at
    impact (angles in degrees, the wrong sign of alpha).
    """
    robot = check_path("robot", robot, optional=True)
    gait = check_path("gait", gait, optional=True)
    robot_parameters = check_number_map("robot_parameters", robot_parameters, optional=True)
    gait_parameters = check_number_map("gait_parameters", gait_parameters, optional=True)
    rob = None
    if robot and gait is None:
        try:  # one file given, and it is a gait (``load_walker("my_walk.yaml")``): its robot
            rob = load_robot(robot, robot_parameters)
        except WrongKind as exc:
            if exc.found != "gait":
                raise
            robot, gait = None, robot
        except InputError:
            if robot not in bundled_names("gaits"):
                raise
            robot, gait = None, robot  # a bundled gait's name
    elif robot:
        rob = load_robot(robot, robot_parameters)
    if gait is None:
        gait = default_gait(rob)
    g, source = load_gait(gait, gait_parameters)
    if rob is not None:
        wrong = gait_robot_mismatch(rob, g)
        if wrong:
            raise InputError(source.where(("robot",), wrong))
    else:
        try:
            resolve(g.robot, "robots")
        except InputError as exc:  # name the gait file's line: that is where to fix it
            raise InputError(source.where(("robot",), str(exc))) from None
        rob = load_robot(g.robot, robot_parameters)
    return assemble_walker(rob, g, source, progress=progress)


def gait_robot_mismatch(robot: Robot, gait: Gait,
                        load: Callable[[str], Robot] = load_robot) -> str | None:
    """Why ``gait`` (loaded, its ``robot:`` as written) is not for ``robot``: its own robot
    file names another robot. None when the gait names ``robot``'s file, or a robot of the
    same name, or its own robot file cannot be read (the user's choice is then trusted).
    ``load`` reads a robot reference (the sweep reads inside its folder). The one check used
    by :func:`load_walker` and the sweeps."""
    if same_robot_file(robot, gait.robot):
        return None
    try:
        own = load(gait.robot).name
    except InputError:
        return None
    return None if own == robot.name else (f"gait '{gait.name}' is for robot '{own}', not "
                                           f"'{robot.name}'")


def gait_on_robot(robot: Robot, gait: str) -> Walker:
    """The gait file ``gait`` on the robot ``robot`` as loaded (its numbers, motors and power
    models; as :func:`load_walker` with the robot given): the gait's ``robot:`` must name that
    robot (:class:`InputError` at its line otherwise)."""
    check_instance("robot", robot, Robot, "a Robot")
    gait = check_path("gait", gait)
    g, source = load_gait(gait)
    wrong = gait_robot_mismatch(robot, g)
    if wrong:
        raise InputError(source.where(("robot",), wrong))
    return assemble_walker(robot, g, source)


def assemble_walker(robot: Robot, gait: Gait, source: GaitSource, *,
                    progress: Progress | None = None,
                    model: CompiledModel | None = None) -> Walker:
    """A walker from a robot and a gait as loaded (:func:`load_gait`, not yet bound): check
    the gait against the robot, compile (or load) the model, check the impact posture, apply
    ``invariance: auto`` and precompute the zero dynamics. Problems name the gait file's
    lines. ``progress``: as for :func:`load_walker`. ``model``: ``robot``'s compiled model when
    the caller holds it already (e.g. a slope-frame model, SPEC 14: the gait's invariance and
    zero dynamics are then those of that model); default :func:`load_model`."""
    g = bind_gait(gait, source, robot)
    if model is None:
        model = load_model(robot, progress=progress)
    check_impact_posture(model, g, source)
    if g.invariance == "auto":
        g = apply_invariance(model, g)
    return Walker(robot, g, model, zero_dynamics(model, g), source.where)


def check_ground(slope: object, terrain: object) -> tuple[float, Terrain | None]:
    """The ground of a full-order run (SPEC 14): the slope [rad] (:func:`check_slope`) and the
    terrain (None, a :class:`Terrain`, or a terrain file's path, loaded); a terrain file's own
    slope is the slope, and giving another one as well is an :class:`InputError` naming both.
    """
    slope = check_slope(slope)
    if terrain is not None and not isinstance(terrain, Terrain):
        check_instance("terrain", terrain, (str, Path), "a terrain file's path or a Terrain")
        terrain = load_terrain(terrain)
    if terrain is not None and terrain.slope != 0.0:
        if slope != 0.0 and slope != terrain.slope:
            raise InputError.param(("slope", "terrain"), f"the terrain sets the slope "
                                   f"({terrain.slope:g} rad): give the slope once")
        slope = check_slope(terrain.slope)
    return slope, terrain
