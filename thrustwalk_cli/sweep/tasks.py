"""Sweep tasks: one per point, keyed by a content hash.

The key of a point is the SHA-256 of the tool version, the study, the robot and gait file
contents, the study settings, the point's values and (with continuation) the key of the point
it starts from. The same key means the same computation: a finished point is never computed
again, whichever run, worker or machine computed it.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass

from .._version import __version__


def _sha(text: str | None) -> str | None:
    return None if text is None else hashlib.sha256(text.encode()).hexdigest()


def canonical(value: object) -> str:
    """Canonical JSON (sorted keys, exact floats) of plain values."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


@dataclass(frozen=True)
class PointTask:
    """Everything a worker needs to compute one point (files travel as text, so workers need
    no shared folder).

    index: the point's position in the sweep; key: its content hash; values: the axis values
    ``(name, value)``; settings: the study's fixed parameters ``(name, value)``; after: the key
    of the point whose result starts this one (continuation), and ``start`` that result's
    start data once known; robot_ref: how a gait written by this point names its robot;
    name: the name of what the point writes (a designed gait); label: the point in words.
    """

    index: int
    key: str
    study: str
    values: tuple[tuple[str, float], ...]
    settings: tuple[tuple[str, object], ...]
    robot_file: str
    robot_text: str
    gait_file: str | None
    gait_text: str | None
    version: str = __version__
    after: str | None = None
    start: dict | None = None
    robot_ref: str | None = None
    name: str = ""
    label: str = ""

    @property
    def parameters(self) -> dict[str, object]:
        """Settings overridden by the point's study-parameter values."""
        out = dict(self.settings)
        out.update((k, v) for k, v in self.values if "." not in k or k.startswith("schedule."))
        return out

    def overrides(self, target: str) -> dict[str, float]:
        """The point's ``robot.NAME`` or ``gait.NAME`` values as ``{NAME: value}``."""
        head = target + "."
        return {k[len(head):]: v for k, v in self.values if k.startswith(head)}


def task_key(study: str, robot_text: str, gait_text: str | None,
             settings: Mapping[str, object], values: Mapping[str, float],
             after: str | None = None) -> str:
    """The content hash of one point (module docstring)."""
    blob = {"tool": "thrustwalk", "version": __version__, "study": study,
            "robot": _sha(robot_text), "gait": _sha(gait_text), "settings": dict(settings),
            "point": dict(values), "after": after}
    return hashlib.sha256(canonical(blob).encode()).hexdigest()


def identity(keys: list[str]) -> str:
    """The identity of a sweep: the hash of its points' keys in order (same points, same
    sweep)."""
    return hashlib.sha256("\n".join(keys).encode()).hexdigest()
