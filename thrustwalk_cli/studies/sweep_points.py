"""What a sweep point is to a study: :class:`PointResult` (one point's document, fields and
extras), :class:`SweepStudy` (a registry entry of :data:`.sweep_studies.STUDIES`), and the
worker side every study shares: this process's cache of robots, models and walkers
(:func:`cached`, :func:`fresh`) and the one path from a point to its robot
(:func:`point_robot`), model (:func:`point_model`) and walker (:func:`point_walker`, through
:func:`thrustwalk_cli.walker.assemble_walker` like :func:`~thrustwalk_cli.walker.load_walker`).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from ..description.robot import Robot
from ..files.gait_file import load_gait_text
from ..files.robot_file import load_robot_text
from ..model.compiled import CompiledModel
from ..model.compiler import load_model
from ..sweep.tasks import PointTask
from ..walker import Walker, assemble_walker


@dataclass(frozen=True)
class PointResult:
    """What a study computes at one point: its JSON ``document``, the collectable ``fields``
    (SI, None when not computed), ``extra`` data (e.g. a designed gait file) and the start a
    continuing point may use (``next_start``)."""

    document: dict
    fields: dict[str, object]
    extra: dict = field(default_factory=dict)
    next_start: dict | None = None
    #: what the study's ``finish`` still computes from (never written; None once finished)
    pending: object = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class SweepStudy:
    """A study a sweep can run.

    fields: collectable result fields, name -> (unit, meaning); point(base, params, start):
    the computation of one point (``base`` a :class:`Walker`, or a :class:`CompiledModel` when
    ``uses_gait`` is false); check(base, params): problems with the parameters of a point,
    ``(parameter, message)`` pairs, found before any work; prepare(base, settings): once in
    the calling process before local workers start (e.g. compile a kernel once, not in every
    worker); continuation: points start from their finished neighbour's result;
    finish(results): completes the :class:`PointResult` of several points of one task
    together (their ``pending`` parts, e.g. the push trials' energies batched), returning
    them in order, each the same as if finished alone; verdict: the boolean key of the
    point's document that is false when the study's answer is no (not walkable, fell,
    infeasible), whose document's ``reason`` then becomes the point's.
    """

    name: str
    fields: dict[str, tuple[str, str]]
    point: Callable[[object, dict, dict | None], PointResult]
    uses_gait: bool = True
    check: Callable[[object, dict], list[tuple[str, str]]] | None = None
    prepare: Callable[[object, dict], None] | None = None
    continuation: bool = False
    finish: Callable[[list[PointResult]], list[PointResult]] | None = None
    verdict: str = "success"


# ------------------------------------------------------------------------- worker side
CACHE: OrderedDict = OrderedDict()  # this process's robots and walkers (a few, LRU)
CACHE_SIZE = 8


def cached(key: tuple, make: Callable[[], object]) -> object:
    if key in CACHE:
        CACHE.move_to_end(key)
        return CACHE[key]
    value = make()
    CACHE[key] = value
    if len(CACHE) > CACHE_SIZE:
        CACHE.popitem(last=False)
    return value


def fresh(key: tuple, valid: Callable[[object], bool], make: Callable[[], object]) -> object:
    """:func:`cached` for values made from objects of this cache (keyed by their ``id``):
    a value whose objects were evicted and replaced (``valid`` false) is made again."""
    if key in CACHE and valid(CACHE[key]):
        CACHE.move_to_end(key)
        return CACHE[key]
    CACHE.pop(key, None)
    return cached(key, make)


def point_robot(task: PointTask) -> Robot:
    """The robot of one point: the base robot file with the point's ``robot.NAME`` values
    substituted for its named parameters, exactly as if edited into the file. The one place a
    sweep turns robot parameters into a robot; its model comes from
    :func:`~thrustwalk_cli.model.compiler.load_model`, which binds the robot's numbers to the
    model compiled once for the robot's structure (no compile per parameter value)."""
    return load_robot_text(task.robot_text, task.robot_file, task.overrides("robot"))


def point_model(task: PointTask) -> CompiledModel:
    """The compiled model of the point's robot (kept per process): the model of the base
    robot's structure with the point's numbers bound (compiled once for every value)."""
    key = ("model", task.robot_text, task.robot_file,
           tuple(sorted(task.overrides("robot").items())))
    return cached(key, lambda: load_model(point_robot(task)))


def point_walker(task: PointTask) -> Walker:
    """The point's robot with the base gait (``gait.NAME`` values substituted), its model
    and zero dynamics (kept per process: points that differ only in study parameters share
    it)."""
    key = ("walker", task.robot_text, task.robot_file,
           tuple(sorted(task.overrides("robot").items())), task.gait_text, task.gait_file,
           tuple(sorted(task.overrides("gait").items())))

    def make() -> Walker:
        robot = point_robot(task)
        gait, source = load_gait_text(task.gait_text, task.gait_file, task.overrides("gait"))
        return assemble_walker(robot, gait, source)

    return cached(key, make)


def nominal_of(task: PointTask) -> Callable[[], Walker]:
    """The walker of the base robot with the point's gait (a controller's model when the
    point's robot differs: the plant)."""
    base = replace(task, values=tuple((k, v) for k, v in task.values
                                      if not k.startswith("robot.")))
    return lambda: point_walker(base)


def on_slope(walker: Walker, p) -> Walker:
    """The walker on the point's ``slope`` [rad] (SPEC 14; absent or 0: level ground, the
    walker itself), kept per process so that the points of one slope share it (and what is
    cached by its ``id``: the realized strategies, the trial runners)."""
    gamma = float(p.get("slope") or 0.0)
    if gamma == walker.slope:
        return walker
    return fresh(("slope", id(walker), gamma), lambda v: v[0] is walker,
                 lambda: (walker, walker.on_slope(gamma)))[1]
