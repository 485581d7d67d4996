"""The ``compile`` study: compile a robot file (or load it from the cache) and summarise it
(SPEC 1)."""

from __future__ import annotations

from ..files.robot_file import load_robot
from ..model.compiled import CompiledModel
from ..model.compiler import load_model


def compile_robot(robot: str, rebuild: bool = False) -> CompiledModel:
    """The compiled model of the robot file or bundled name ``robot``; ``rebuild`` ignores the
    cache. ``model.summary()`` lists links, coordinates, mass [kg], thrusters, time [s] and the
    cache entry."""
    return load_model(load_robot(robot), rebuild=rebuild)
