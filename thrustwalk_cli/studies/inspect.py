"""The ``inspect`` study: the numeric dynamics of a robot at one state (SPEC 1, 5)."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from ..description.robot import Robot
from ..errors import InputError, check_numbers, renamed_keyword
from ..model.compiled import CompiledModel
from ..walker import Walker, as_model
from .documents import SCHEMA_VERSION, Table, units


class InspectResult(Mapping):
    """The dynamics at one state (SPEC 1, 5), as the other results: ``document()`` (the JSON
    body the ``inspect`` command writes), ``tables()`` and ``figures()`` (none: the command
    writes no CSV table and no figure), ``success``/``reason``; every key of the document is
    also an attribute (``res.D`` [kg m^2], ``res.C_dq`` [N m], ``res.G`` [N m], ``res.B_F``
    [m], ``res.swing_foot`` [m], ``res.impact`` with ``dq``, ...) and an item (``res["D"]``:
    the result is a read-only mapping, as the dict it replaces)."""

    name = "inspect"
    success = True
    reason = "the model evaluated at the state"

    def __init__(self, model: CompiledModel, doc: dict) -> None:
        self.model = model
        self._doc = doc

    def __getitem__(self, key: str) -> Any:
        return self._doc[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._doc)

    def __len__(self) -> int:
        return len(self._doc)

    def __getattr__(self, key: str) -> Any:
        doc = self.__dict__.get("_doc")
        if doc is not None and key in doc:
            return doc[key]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {key!r}")

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(self._doc))

    def __repr__(self) -> str:
        return (f"InspectResult(robot={self.model.robot.name!r}, q={self._doc['q']!r}, "
                f"keys={list(self._doc)!r})")

    @property
    def warnings(self) -> list[str]:
        """Angles beyond +-pi (likely degrees given for radians)."""
        return self._doc["warnings"]

    def document(self) -> dict:
        """The JSON body of the ``inspect`` command's ``--json`` file (a copy; provenance is
        added by the command)."""
        return dict(self._doc)

    def tables(self) -> dict[str, Table]:
        """No CSV table (the command writes the JSON document only)."""
        return {}

    def figures(self, titles: bool = False) -> dict:
        """No figure."""
        return {}


def _vector(value: str | Sequence[float], param: str, n: int, names: list[str]) -> list[float]:
    """``value`` as ``n`` floats: a sequence, or a comma-separated string."""
    if isinstance(value, str):
        try:
            vals = [float(v) for v in value.split(",")]
        except ValueError:
            raise InputError.param(param, f"expected {n} comma-separated number{'s' * (n != 1)} "
                                          f"({', '.join(names)}), got {value!r}") from None
    else:
        vals = list(check_numbers(param, value, min_len=0, largest=1e6))
    if len(vals) != n:
        raise InputError.param(param, f"expected {n} value{'s' * (n != 1)} ({', '.join(names)}), "
                                      f"got {len(vals)}")
    if not all(abs(v) <= 1e6 for v in vals):
        raise InputError.param(param, f"values must be finite and at most 1e+06 in size (got "
                                      f"{', '.join(f'{v:g}' for v in vals)})")
    return vals


def inspect_state(robot_or_walker: Robot | CompiledModel | Walker | None = None,
                  q: str | Sequence[float] | None = None,
                  dq: str | Sequence[float] | None = None,
                  thrust: str | Sequence[float] | None = None, *,
                  model: Robot | CompiledModel | Walker | None = None) -> InspectResult:
    """D [kg m^2], C q' [N m], G [N m], B_F [m], the swing foot [m] at ``q`` [rad] and, with
    ``dq`` [rad/s], the impact map; with ``thrust`` [N] per thruster, ``B_F F_T`` (keys fixed
    by the robot-model issue), as an :class:`InspectResult`. ``robot_or_walker``: a
    :class:`CompiledModel`, a :class:`~thrustwalk_cli.description.robot.Robot` (compiled by
    :func:`~thrustwalk_cli.model.compiler.load_model`) or a walker (its model:
    :func:`~thrustwalk_cli.walker.as_model`); ``model=`` is its deprecated old name (one
    release, a DeprecationWarning)."""
    model = as_model(renamed_keyword("inspect_state", "robot_or_walker", robot_or_walker,
                                     "model", model), "robot_or_walker")
    if q is None:
        raise InputError.param("q", "the state's coordinates are required (rad)")
    names = model.robot.coordinate_names
    if thrust is not None and not model.robot.thrusters:
        raise InputError.param("thrust", f"robot {model.robot.name} has no thruster: there is "
                                         "no thrust to give")
    qv = _vector(q, "q", model.n, names)
    doc: dict = {"schema_version": SCHEMA_VERSION,
                 "units": units("q", "q_dot", "D", "C_dq", "G", "B_F", "impulse", "velocity",
                                "energy", "thrust", swing_foot="m", com="m"),
                 "coordinates": names, "q": qv,
                 "warnings": [f"{n} = {v:g} is beyond +-pi: angles are in radians"
                              for n, v in zip(names, qv) if abs(v) > math.pi]}
    F = None if thrust is None else _vector(thrust, "thrust", model.n_thrusters,
                                            model.robot.thruster_names)
    for t, v in zip(model.robot.thrusters, F or ()):
        lo, hi = t.limits
        if not lo <= v <= hi:
            raise InputError.param("thrust", f"{v:g} N is outside the limits [{lo:g}, {hi:g}] N "
                                             f"of thruster {t.name}")
    doc.update(model.evaluate_state(
        qv, None if dq is None else _vector(dq, "dq", model.n, names), F))
    return InspectResult(model, doc)

