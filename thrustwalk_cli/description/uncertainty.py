"""Parameter uncertainty: robot parameters declared as distributions (numpy only).

An uncertainty file names robot-file parameters (numbers of the robot's ``parameters:``
section) and a distribution for each, as a sweep file's random axes do: ``uniform(low, high)``,
``log-uniform(low, high)`` or ``normal(mean, std)``, in the parameter's unit. The draws are
``numpy.random.default_rng(seed)``, ``samples`` values per parameter, parameter after parameter
in file order (the sweep engine's random axes: :func:`thrustwalk_cli.sweep.points.draw`).
"""

from __future__ import annotations

from dataclasses import dataclass

from .sweep import Axis


@dataclass(frozen=True)
class Uncertainty:
    """Distributions of robot parameters: ``axes`` are random axes named ``robot.NAME``;
    ``seed`` seeds the draws."""

    axes: tuple[Axis, ...]
    seed: int = 0
    description: str = ""
    source_file: str = "<memory>"
    source_sha256: str = ""

    @property
    def parameters(self) -> list[str]:
        """The robot parameter each axis draws (``MT`` for ``robot.MT``), in order."""
        return [a.parameter for a in self.axes]
