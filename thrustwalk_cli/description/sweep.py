"""Sweep descriptions: immutable data read from a sweep file, numpy only.

A sweep runs one study (``limit-cycle``, ``feasibility``, ``simulate``, ``design-gait``, ...)
on a base robot and gait at many points. A point gives a value to every swept quantity (an
:class:`Axis`); the points are the product of three groups, in this order:

* ``grid``: axes combined as a Cartesian product (the last axis varies fastest);
* ``zip``: axes of equal length that vary together (one value of each per point);
* ``random``: ``samples`` seeded draws, every random axis drawn per sample.

An axis names a study parameter (``thrust`` [N], ``target_speed`` [m/s], ``kp`` [1/s^2],
``schedule.2`` the value of interval 2 of a thrust schedule, ...), a named robot parameter
``robot.NAME`` or a named gait parameter ``gait.NAME`` (numbers of the robot's or gait's
``parameters:`` section, substituted as if edited into the file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

GROUPS = ("grid", "zip", "random")
DISTRIBUTIONS = ("uniform", "normal", "log-uniform")


@dataclass(frozen=True)
class Axis:
    """One swept quantity.

    name: what it sets (see the module docstring); unit: its unit ("" when a robot or gait
    parameter has no declared unit); group: ``grid``, ``zip`` or ``random``. ``values``: the
    values in sweep order (grid and zip axes). Random axes: ``distribution`` with
    ``parameters`` ``(low, high)`` (``uniform``, ``log-uniform``) or ``(mean, std)``
    (``normal``), in the axis's unit.
    """

    name: str
    unit: str
    group: str
    values: tuple[float, ...] = ()
    distribution: str | None = None
    parameters: tuple[float, ...] = ()

    @property
    def target(self) -> str:
        """``robot``, ``gait`` or ``study``: where the value goes."""
        head = self.name.split(".", 1)[0]
        return head if head in ("robot", "gait") and "." in self.name else "study"

    @property
    def parameter(self) -> str:
        """The parameter's own name (``MT`` for ``robot.MT``; the name itself otherwise)."""
        return self.name.split(".", 1)[1] if self.target != "study" else self.name


@dataclass(frozen=True)
class SweepSpec:
    """A sweep as written in its file (SI units).

    study: the study run at every point; robot, gait: resolved paths of the base files (gait
    None: the robot's bundled gait, or none for a study that designs the gait) with their
    text (shipped to worker processes and machines, so workers need no shared folder);
    settings: the study's parameters held fixed, ``(name, value)`` pairs with defaults filled
    in; axes: grid axes, then zip axes, then random axes (``samples`` draws with ``seed``);
    collect: the result fields of ``results.csv`` (the first is drawn in the heat maps).
    """

    name: str
    study: str
    robot: str
    robot_text: str
    gait: str | None
    gait_text: str | None
    settings: tuple[tuple[str, object], ...]
    axes: tuple[Axis, ...]
    collect: tuple[str, ...]
    samples: int = 0
    seed: int = 0
    description: str = ""
    source_file: str = "<memory>"
    source_sha256: str = ""

    def axis(self, name: str) -> Axis:
        """The axis named ``name`` (it must exist)."""
        return next(a for a in self.axes if a.name == name)

    def group(self, group: str) -> tuple[Axis, ...]:
        """The axes of one group (``grid``, ``zip`` or ``random``), in file order."""
        return tuple(a for a in self.axes if a.group == group)

    @property
    def count(self) -> int:
        """The number of points: product of the grid lengths, times the zip length, times the
        random samples (each group that is absent counts 1)."""
        n = 1
        for a in self.group("grid"):
            n *= len(a.values)
        zipped = self.group("zip")
        if zipped:
            n *= len(zipped[0].values)
        if self.group("random"):
            n *= self.samples
        return n


def range_values(start: float, step: float, count: int) -> list[float]:
    """The ``count`` values ``start + i step`` of a range, each the nearest float to its
    decimal value when ``start`` and ``step`` are short decimals (``-0.04:0.02:0.02`` gives
    ``0.0`` and ``0.02``, not ``3.5e-18`` and ``0.019999999999999997``: a slope of exactly 0
    is level ground); the plain sums otherwise."""
    def decimals(x: float) -> int | None:
        text = repr(float(x))
        if "e" in text or "inf" in text or "nan" in text:
            return None
        return len(text.split(".")[1].rstrip("0")) if "." in text else 0
    d = [decimals(start), decimals(step)]
    plain = [start + i * step for i in range(count)]
    if None in d or max(d) > 12:  # not a short decimal: the sums as they are
        return plain
    nd = max(d)  # type: ignore[type-var]
    return [round(v, nd) + 0.0 for v in plain]  # + 0.0: -0.0 -> 0.0


def range_count(start: float, stop: float, step: float, limit: int) -> int | str:
    """The number of values of the range ``start:stop:step`` (stop included when a whole
    number of steps reaches it), or why there is no such range: a step of 0, against the
    direction from start to stop, below the resolution of the values (``start + step`` would
    round to ``start``), or more than ``limit`` values. Counted in floats first, so that a tiny
    step (5e-324) is refused instead of overflowing an integer."""
    if not (step != 0 and (stop - start) * step >= 0):
        return "the step must be non-zero and point from start to stop"
    n = abs((stop - start) / step)
    fine = f"the step {step:g} is below the resolution of the values"
    if not math.isfinite(n):
        return fine
    if not n < limit:
        shown = f"{int(n + 1e-9) + 1}" if n < 1e15 else f"{n:.3g}"
        return f"{shown} values: the limit is {limit}"
    if abs(step) <= 1e-12 * max(abs(start), abs(stop)):
        return fine
    return int(n + 1e-9) + 1
