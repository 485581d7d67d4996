"""The ``compile`` study: compile a robot file (or load it from the cache) and summarise it
(SPEC 1)."""

from __future__ import annotations

from collections.abc import Callable

from ..errors import check_flag, check_path
from ..files.robot_file import load_robot
from ..model.compiled import CompiledModel
from ..model.compiler import Progress, load_model


def compile_robot(robot: str, rebuild: bool = False,
                  progress: Progress | None = None) -> CompiledModel:
    """The compiled model of the robot file or bundled name ``robot``; ``rebuild`` ignores the
    cache; ``progress(done, total, phase)`` hears about every step of a compile.
    ``model.summary()`` lists links, coordinates, mass [kg], thrusters, time [s] and the cache
    entry."""
    robot = check_path("robot", robot)
    rebuild = check_flag("rebuild", rebuild)
    return load_model(load_robot(robot), rebuild=rebuild, progress=progress)


def compile_kernel(*, rebuild: bool = False,
                   on_wait: Callable[[str], None] | None = None) -> dict:
    """The compiled simulation kernel (SPEC 7), the same for every robot: compiled by numba
    once per machine and cached. ``{"cache_hit": bool, "seconds": float | None, "entry":
    path, "note": str}``: whether it came from the cache and how long the one-time numba
    compile took (measured now, or as recorded then); ``note`` says when the cache folder
    was unusable. A warm cache is checked without importing numba. ``on_wait``: told once
    when another process is compiling it (this one waits for it, then loads it)."""
    from ..simulation.stepper import kernel, kernel_status

    if not rebuild:
        st = kernel_status()
        if st["cached"]:
            return {"cache_hit": True, "seconds": st["compile_seconds"], "entry": st["entry"],
                    "note": ""}
    jm = kernel(rebuild=rebuild, on_wait=on_wait)
    return {"cache_hit": jm.cache_hit, "seconds": jm.compile_seconds, "entry": str(jm.path),
            "note": jm.note}
