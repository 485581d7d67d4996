"""Gait descriptions (SPEC section 2): immutable data, numpy only.

    alpha = c q,   s = (alpha - alpha_i) / (alpha_f - alpha_i) in [0, 1]
    y = q_b - h_d(alpha),  h_d,i(s) = sum_k a_ik binom(M, k) s^k (1 - s)^(M - k)

Coefficient layout: ``A`` has one row per actuated coordinate (in the robot's order) and
``M + 1`` columns; column 0 is the post-impact configuration (s = 0, alpha = alpha_i), column M
the pre-impact configuration (s = 1, alpha = alpha_f). Angles in rad. The numeric geometry
(``q_Z``, ``Phi``, hybrid invariance) is in :mod:`thrustwalk_cli.hzd.constraints`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..thrust.schedule import WrittenSchedule


@dataclass(frozen=True)
class Gait:
    """An immutable gait description (SPEC 2). ``A`` complete (invariance already applied)."""

    name: str
    robot: str
    c: tuple[float, ...]
    alpha_f: float
    A: tuple[tuple[float, ...], ...]
    invariance: str = "given"  # "auto" or "given"
    kp: float = 400.0
    kd: float = 40.0
    mu: float = 0.7
    thrust: WrittenSchedule | None = None  # the gait file's thrust: section as written
    source_file: str = "<memory>"
    source_sha256: str = ""
    given_A: tuple[tuple[float | None, ...], ...] = field(default=(), compare=False, repr=False)

    def __repr__(self) -> str:
        """One line: the name, the robot it was written for, the file, alpha at impact
        ``alpha_f`` [rad] (alpha_i = c (R q^- + b) needs the robot: the zero dynamics' repr
        shows both) and the Bezier order M (SPEC 2); the dataclass repr prints every
        coefficient, which a notebook should not. Equality is the dataclass's, field by
        field."""
        thrust = "" if self.thrust is None else ", thrust=True"
        return (f"Gait(name={self.name!r}, robot={self.robot!r}, file={self.source_file!r}, "
                f"alpha_f={self.alpha_f:.6g}, order={self.order}{thrust})")

    @property
    def order(self) -> int:
        """The Bezier degree M of the virtual constraints (SPEC 2): coefficients per output less
        one."""
        return len(self.A[0]) - 1

    @property
    def coefficients(self) -> np.ndarray:
        """The Bezier coefficients ``A`` as a float array, one row of M + 1 per output [rad]
        (SPEC 2)."""
        return np.array(self.A, dtype=float)


def __getattr__(name: str):
    """``ThrustSchedule``: the old name of a gait's ``thrust:`` section as written, now
    :class:`~thrustwalk_cli.thrust.schedule.WrittenSchedule`; a deprecated alias (one release;
    a DeprecationWarning on every use, PEP 562)."""
    if name == "ThrustSchedule":
        import warnings

        warnings.warn(f"{__name__}.ThrustSchedule is deprecated (kept for one release): use "
                      "thrustwalk_cli.thrust.schedule.WrittenSchedule (tw.WrittenSchedule)",
                      DeprecationWarning, stacklevel=2)
        return WrittenSchedule
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
