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

from dataclasses import dataclass

from .description.gait import Gait
from .description.robot import Robot
from .errors import InputError, Where
from .files.gait_file import bind_gait, load_gait, same_robot_file
from .files.robot_file import load_robot
from .hzd.constraints import apply_invariance
from .hzd.zero_dynamics import ZeroDynamics, zero_dynamics
from .model.compiled import CompiledModel
from .model.compiler import load_model


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

    @property
    def name(self) -> str:
        """``robot / gait``, for titles and tables."""
        return f"{self.robot.name} / {self.gait.name}"


def load_walker(robot: str | None = None, gait: str = "three_link_walk") -> Walker:
    """Load a gait and its robot (``robot`` overrides the gait's own ``robot:``), check them
    against each other, compile (or load) the model, apply ``invariance: auto`` (SPEC 2) and
    precompute the zero dynamics (SPEC 3). ``robot`` and ``gait`` are bundled names or paths.

    Raises :class:`InputError` (``file:line: key.path: message``) on bad files, or when
    ``robot`` is not the robot the gait was written for.
    """
    g, source = load_gait(gait)
    if robot:
        rob = load_robot(robot)
        if not same_robot_file(rob, g.robot):
            try:
                own = load_robot(g.robot).name
            except InputError:
                own = rob.name  # the gait's own robot file is not reachable: trust the user
            if own != rob.name:
                raise InputError(source.where(("robot",), f"gait '{g.name}' is for robot "
                                                          f"'{own}', not '{rob.name}'"))
    else:
        rob = load_robot(g.robot)
    g = bind_gait(g, source, rob)
    model = load_model(rob)
    if g.invariance == "auto":
        g = apply_invariance(model, g)
    return Walker(rob, g, model, zero_dynamics(model, g), source.where)


def walker_from(model: CompiledModel, gait: Gait, where: Where = "gait") -> Walker:
    """A walker from a compiled model and a complete gait already in memory (``A`` with
    invariance applied), e.g. a gait just designed."""
    return Walker(model.robot, gait, model, zero_dynamics(model, gait), where)
