"""Pieces shared by every study's result documents: units, tables, number formatting, the gait
and robot records (not to be confused with :mod:`thrustwalk_cli.simulation.records`, the records
of simulated steps).

A study returns a result object that renders itself (the python-control pattern):
``document()`` is the JSON body (SI units, no NaN), ``tables()`` the CSV tables,
``figures()`` the matplotlib figures and ``attachments(doc)`` any other file (Markdown,
YAML, NPZ) made from the written document. Commands only add provenance and write them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..hzd.zero_dynamics import ZeroDynamics

SCHEMA_VERSION = 1  # of every result document; bumped when a key changes meaning or goes

# The one spelling of every unit in result documents (SI; "1" = dimensionless).
UNITS = {
    "thrust": "N", "generalized_thrust": "N m", "force": "N", "impulse": "N s",
    "torque": "N m", "alpha": "rad", "alpha_dot": "rad/s", "angle": "rad", "q": "rad",
    "q_dot": "rad/s", "sigma_N": "kg m^2/s", "zeta": "kg^2 m^4/s^2", "time": "s",
    "step_time": "s", "step_length": "m", "speed": "m/s", "height": "m", "length": "m",
    "velocity": "m/s", "energy": "J", "power": "W", "mass": "kg", "gravity": "m/s^2",
    "inertia": "kg m^2", "friction_ratio": "1", "delta_zero_sq": "1", "output_y": "rad",
    "output_rate": "rad/s", "b_F": "kg m^2 rad", "Gamma_j": "kg m^3 rad", "T_j": "N m",
    "F_j": "N", "Lambda_0": "N", "Lambda_1": "N s^2/(kg^2 m^4)", "Lambda_2": "1",
    "Lambda_T": "1/m", "impulse_per_sigma": "1/m", "wn": "rad/s", "tau": "s",
    "effort": "N^2 m s", "C_dq": "N m", "G": "N m", "B_F": "m", "D": "kg m^2",
    "invariance_residual": "rad", "frequency": "rad/s",
    "multiplier": "1", "kp": "1/s^2", "kd": "1/s", "xi": "1",
}


def units(*keys: str, **extra: str) -> dict[str, str]:
    """The ``units`` block of a document: the canonical unit of each quantity named."""
    return {**{k: UNITS[k] for k in keys}, **extra}


def col(name: str, unit: str = "") -> str:
    """A CSV column name with its unit as suffix, one rule for every file:
    ``col("zeta", "kg^2 m^4/s^2") == "zeta_kg2m4_s2"``, ``col("alpha_dot", "rad/s") ==
    "alpha_dot_rad_s"``, ``col("thrust", "N") == "thrust_N"``; no suffix for "1" or ""."""
    if unit in ("", "1"):
        return name
    num, _, den = unit.partition("/")
    def part(u: str) -> str:
        return u.replace("^", "").replace(" ", "").replace("(", "").replace(")", "")
    return f"{name}_{part(num)}" + (f"_{part(den)}" if den else "")


def result_repr(result) -> str:
    """One line for a study result (its ``success`` and ``reason``): a result holds arrays,
    orbits and the walker, which a notebook should not print by the hundred lines."""
    reason = str(getattr(result, "reason", ""))
    if len(reason) > 120:
        reason = reason[:117] + "..."
    return f"{type(result).__name__}(success={result.success!r}, reason={reason!r})"


@dataclass(frozen=True)
class Table:
    """A CSV table: a header row, data rows and ``#`` comment lines (units, meaning).

    ``table.to_pandas()`` is a pandas DataFrame with the CSV's column names (pandas must be
    installed); ``pandas.DataFrame(table.to_dict())`` the same."""

    header: list[str]
    rows: list[list[Any]]
    comments: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, list]:
        """The columns by name, in order."""
        return {name: [row[i] for row in self.rows] for i, name in enumerate(self.header)}

    def to_pandas(self):
        """The table as a ``pandas.DataFrame`` (columns named as in the CSV file)."""
        try:
            import pandas
        except ImportError as exc:
            raise ImportError("to_pandas() needs pandas (pip install pandas); "
                              "to_dict() gives the columns without it") from exc
        return pandas.DataFrame(self.to_dict(), columns=self.header)


#: the one mark of a missing value in every console table and Markdown (JSON: null; CSV:
#: an empty cell); the lines under a table say why a value is missing
MISSING = "—"


def fmt(v: Any, spec: str = ".4g") -> str:
    """A number for a summary table or Markdown: ``format(v, spec)``, or :data:`MISSING` (an
    em dash) for None."""
    return MISSING if v is None else format(v, spec)


def fmt_margin(v: float | None, spec: str = ".4g", tol: float = 0.0) -> str:
    """A margin (>= 0 when satisfied) for a table or a file's comment: ``format(v, spec)``,
    with a value within the check's tolerance ``|v| <= tol`` (in the unit of ``v``) shown as
    0, and a value that rounds to zero at the shown precision never signed ("0.00", not
    "-0.00"); :data:`MISSING` for None. Only the shown text: documents keep the number."""
    if v is None:
        return MISSING
    v = float(v)
    text = format(0.0 if abs(v) <= tol else v, spec)
    mantissa = text.lower().split("e")[0]
    if text.startswith("-") and not any(ch in "123456789" for ch in mantissa):
        text = text[1:]
    return text


def gait_record(zd: ZeroDynamics) -> dict:
    """Gait description for outputs: layout of the coefficients, sign and range of alpha."""
    g, r, mp = zd.gait, zd.model.robot, zd.maps
    act = [c.name for c in r.coordinates if c.actuated]
    return {
        "name": g.name,
        "file": g.source_file,
        "alpha": {
            "definition": "alpha = c q",
            "c": dict(zip(r.coordinate_names, map(float, g.c))),
            "alpha_i": mp.alpha_i, "alpha_f": mp.alpha_f,
            "direction": "increasing" if mp.alpha_f > mp.alpha_i else "decreasing",
            "s": "s = (alpha - alpha_i) / (alpha_f - alpha_i), 0 just after impact, 1 before",
        },
        "bezier": {
            "order": g.order,
            "layout": "one row per actuated coordinate; column k multiplies binom(M,k) s^k "
                      "(1-s)^(M-k); column 0 = post-impact q_b (s = 0), column M = pre-impact "
                      "q_b (s = 1)",
            "coefficients": {name: list(row) for name, row in zip(act, g.A)},
            "invariance": g.invariance,
        },
        "q_minus": dict(zip(r.coordinate_names, mp.q_minus.tolist())),
        "q_plus": dict(zip(r.coordinate_names, mp.q_plus.tolist())),
        "swing_foot_height_at_impact": float(zd.model.p_swing(mp.q_minus)[1]),
        "invariance_residual": {"position": mp.position_residual,
                                "velocity": mp.velocity_residual},
    }


def robot_record(zd: ZeroDynamics) -> dict:
    """Robot name, file, coordinates and thrusters for outputs."""
    r = zd.model.robot
    return {"name": r.name, "file": r.source_file, "coordinates": r.coordinate_names,
            "thrusters": r.thruster_names}


def slope_record(gamma: float) -> dict:
    """What a result on a slope says about it (SPEC 14): the angle [rad, positive uphill],
    the frame of its numbers."""
    return {"angle": gamma, "degrees": math.degrees(gamma),
            "frame": "slope frame: x along the ground (uphill for a positive angle), y normal "
                     "to it; speed and step length are along the ground, climb_rate = "
                     "speed sin(slope) the vertical rate, ground forces are tangential "
                     "(F^h) and normal (F^v) to the slope"}


def dynamics_record(dyn) -> dict:
    """Thruster dynamics given as an object (``tw.thruster_dynamics`` or built by hand, SPEC
    7, 13) as a document records them: the model's label, its states and the poles of its
    stacked ``A`` [1/s] as ``[real, imaginary]`` pairs, slowest first."""
    import numpy as np

    A = dyn.matrices()[0]
    poles = sorted(np.linalg.eigvals(A).tolist() if A.size else [], key=lambda z: abs(z))
    return {"kind": dyn.kind, "states": int(dyn.n_states),
            "poles": [[float(z.real), float(z.imag)] for z in poles]}


def climb_rate(speed: float | None, gamma: float) -> float | None:
    """``speed sin(gamma)`` [m/s]: the rate of climb of a walker at ``speed`` along a slope
    ``gamma`` [rad] (SPEC 14); None without a speed."""
    return None if speed is None else speed * math.sin(gamma)


def orbit_record(cycle, zeta_ref: float | None, slope: float, what: str) -> dict:
    """The ``orbit`` block of a strategy in the robustness and rough-ground documents: whether
    the orbit the trials start on exists (else why), the fixed point ``zeta_ref`` [kg^2 m^4/s^2]
    recoveries are measured against, the orbit's speed along the ground [m/s], step time [s]
    and step length [m], on a slope ``slope`` [rad] its rate of climb ``speed sin(slope)``
    [m/s] (SPEC 14), and ``what`` the orbit is."""
    ok = bool(cycle.exists)

    def num(v):
        return float(v) if ok and v is not None else None
    speed = num(cycle.speed)
    return {"exists": ok, "reason": cycle.reason, "zeta_star": zeta_ref, "speed": speed,
            "step_time": num(cycle.step_time), "step_length": num(cycle.step_length),
            **({"climb_rate": climb_rate(speed, slope)} if slope != 0.0 else {}),
            "what": what}


def show_options(run, source):
    """Give ``run(..., **options)`` a signature with ``**options`` replaced by the parameters of
    ``source`` (what it passes them to: a plan function, or a settings dataclass) as keyword-only
    parameters with their defaults, so that ``help()``, ``inspect.signature`` and an editor show
    every option; the call itself is unchanged. Returns ``run``."""
    import inspect

    sig = inspect.signature(run)
    own = [p for p in sig.parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
    names = {p.name for p in own}
    extra = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)
             for p in inspect.signature(source).parameters.values()
             if p.name not in names and p.kind not in (inspect.Parameter.VAR_POSITIONAL,
                                                       inspect.Parameter.VAR_KEYWORD)]
    run.__signature__ = sig.replace(parameters=own + extra)
    return run
