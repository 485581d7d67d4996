"""The ``inspect`` study: the numeric dynamics of a robot at one state (SPEC 1, 5)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from ..errors import InputError, check_instance, check_numbers
from ..model.compiled import CompiledModel
from .documents import SCHEMA_VERSION, units


def _vector(value: str | Sequence[float], param: str, n: int, names: list[str]) -> list[float]:
    """``value`` as ``n`` floats: a sequence, or a comma-separated string."""
    if isinstance(value, str):
        try:
            vals = [float(v) for v in value.split(",")]
        except ValueError:
            raise InputError.param(param, f"expected {n} comma-separated numbers "
                                          f"({', '.join(names)}), got {value!r}") from None
    else:
        vals = list(check_numbers(param, value, min_len=0, largest=1e6))
    if len(vals) != n:
        raise InputError.param(param, f"expected {n} values ({', '.join(names)}), "
                                      f"got {len(vals)}")
    if not all(abs(v) <= 1e6 for v in vals):
        raise InputError.param(param, f"values must be finite and at most 1e+06 in size (got "
                                      f"{', '.join(f'{v:g}' for v in vals)})")
    return vals


def inspect_state(model: CompiledModel, q: str | Sequence[float],
                  dq: str | Sequence[float] | None = None,
                  thrust: str | Sequence[float] | None = None) -> dict:
    """D [kg m^2], C q' [N m], G [N m], B_F [m], the swing foot [m] at ``q`` [rad] and, with
    ``dq`` [rad/s], the impact map; with ``thrust`` [N] per thruster, ``B_F F_T`` (keys fixed
    by the robot-model issue)."""
    check_instance("model", model, CompiledModel, "a CompiledModel (tw.load_model)")
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
    return doc
