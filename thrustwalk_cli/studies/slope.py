"""The ``slope`` study: the walkability map of a gait over slope x constant thrust (SPEC 14).

For every pair (slope, constant thrust): whether the orbit exists, is stable, completes the
step and is contact-feasible, which condition fails first, zeta*, the step time, the speed
along the ground and the climb rate (the definitions: :mod:`thrustwalk_cli.contact.slope_map`).

The mathematics (the map explicit in cos/sin of the slope and affine in the thrust, its
Chebyshev series, the step times and the golden-section polish) is
:mod:`thrustwalk_cli.contact.slope_map`; this module checks the options, calls
:func:`~thrustwalk_cli.contact.slope_map.walkability_map` and renders the result.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..contact.evaluate import check_contact_options
from ..contact.slope_map import (
    FAILURE_TEXT,
    FAILURES,
    POLISH_BAND,
    SAMPLES,
    walkability_map,
)
from ..contact.terms import ImpactData, impact_data
from ..errors import InputError, check_number, check_numbers, check_text
from ..model.slope import check_slope
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, Table, col, gait_record, result_repr, robot_record

MAX_PAIRS = 1_000_000  # slope x thrust pairs of one map
DEFAULT_SLOPES = (-0.2, 0.2, 0.01)  # [rad] start, stop, step
DEFAULT_THRUST = (0.0, -50.0, -5.0)  # [N]


def _values(start: float, stop: float, step: float) -> list[float]:
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    return [start + i * step for i in range(n)]


@dataclass(frozen=True)
class SlopeMapResult:
    """The walkability map of one gait (SPEC 14): arrays of shape ``(len(slopes),
    len(thrust))`` in ``cells`` (module docstring; SI units, NaN where a quantity does not
    exist, written as empty cells and None); ``first`` the index in :data:`FAILURES` of the
    first failing condition. ``impact`` and ``swing`` hold for every pair. ``seconds``: the
    wall time of the map (not of loading the walker)."""

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    slopes: np.ndarray = field(repr=False)
    thrust: np.ndarray = field(repr=False)
    thruster: int | None
    mu: float
    eps: float
    cells: dict = field(repr=False)
    impact: ImpactData = field(repr=False)
    polished: int = 0
    seconds: float = 0.0

    name = "slope"

    @property
    def thruster_name(self) -> str | None:
        """The thruster the constant thrust drives (None: the robot has none)."""
        return None if self.thruster is None else self.walker.robot.thruster_names[self.thruster]

    @property
    def walkable(self) -> np.ndarray:
        """Per (slope, thrust) pair: no condition fails (SPEC 14), shape (len(slopes),
        len(thrust))."""
        return self.cells["first"] == 0

    @property
    def success(self) -> bool:
        """At least one pair is walkable (a map without any is a valid answer, not a tool
        failure; ``reason`` says so)."""
        return bool(self.walkable.any())

    def walkable_range(self, k: int) -> tuple[float, float] | None:
        """(lowest, highest) walkable slope [rad] at thrust index ``k`` (None: none walks).
        Both may lie on one side of level ground: the steepest downhill slope is the lowest
        only when it is <= 0, the steepest uphill the highest only when it is >= 0
        (:meth:`steepest_at`)."""
        w = self.walkable[:, k]
        if not w.any():
            return None
        return float(self.slopes[w].min()), float(self.slopes[w].max())

    def steepest_at(self, k: int) -> tuple[float | None, float | None]:
        """(steepest walkable downhill, steepest walkable uphill) slope [rad] at thrust index
        ``k``: the lowest walkable slope if it is <= 0 (else None: no downhill or level slope
        walks), the highest if it is >= 0 (else None: no uphill or level slope walks)."""
        r = self.walkable_range(k)
        if r is None:
            return None, None
        return (r[0] if r[0] <= 0.0 else None), (r[1] if r[1] >= 0.0 else None)

    @property
    def headline(self) -> str:
        """"without thrust this gait walks slopes from X to Y rad; with F N from X' up to Z
        rad" (F the thrust of the map farthest from 0), and the steepest walkable slopes of
        the whole map; an end of a range at the map's edge says so (steeper slopes may
        walk too)."""
        th = self.thrust
        lo, hi = float(self.slopes.min()), float(self.slopes.max())

        def rad(x: float, end: float) -> str:
            # a lower end at the map's first slope, or an upper end at its last, is the edge
            edge = " (the map's edge)" if x == end and self.slopes.size > 1 else ""
            return f"{0.0 if abs(x) < 1e-12 else x:.4g}{edge}"

        parts = []
        zero = np.flatnonzero(th == 0.0)
        if zero.size:
            r = self.walkable_range(int(zero[0]))
            parts.append("without thrust this gait walks no slope of the map" if r is None else
                         f"without thrust this gait walks slopes from {rad(r[0], lo)} to "
                         f"{rad(r[1], hi)} rad")
        else:
            parts.append("thrust 0 is not in the map")
        far = int(np.argmax(np.abs(th)))
        if th[far] != 0.0:
            r = self.walkable_range(far)
            parts.append(f"with {th[far]:g} N none" if r is None else
                         f"with {th[far]:g} N from {rad(r[0], lo)} up to {rad(r[1], hi)} rad")
        up = self.steepest()
        if self.success:
            parts.append(
                ("steepest walkable uphill " + (f"{rad(up['uphill'], hi)} rad at "
                 f"{up['uphill_thrust']:g} N" if up["uphill"] is not None else "none (no "
                 "uphill or level slope walks)")) + ", downhill " +
                (f"{rad(up['downhill'], lo)} rad at {up['downhill_thrust']:g} N"
                 if up["downhill"] is not None else "none (no downhill or level slope walks)"))
        return "; ".join(parts)

    def steepest(self) -> dict:
        """The steepest walkable uphill slope [rad] of the whole map and its thrust [N] (None
        when no slope >= 0 walks), and the steepest downhill one (None when no slope <= 0
        walks)."""
        w = self.walkable
        out = {"uphill": None, "uphill_thrust": None, "downhill": None, "downhill_thrust": None}
        if not w.any():
            return out
        i, k = np.nonzero(w)
        up, down = np.argmax(self.slopes[i]), np.argmin(self.slopes[i])
        if self.slopes[i[up]] >= 0.0:
            out.update(uphill=float(self.slopes[i[up]]), uphill_thrust=float(self.thrust[k[up]]))
        if self.slopes[i[down]] <= 0.0:
            out.update(downhill=float(self.slopes[i[down]]),
                       downhill_thrust=float(self.thrust[k[down]]))
        return out

    @property
    def reason(self) -> str:
        """How many pairs are walkable and the headline, or the most frequent failure."""
        n, total = int(self.walkable.sum()), self.walkable.size
        if not n:
            first = np.bincount(self.cells["first"].ravel(), minlength=len(FAILURES))
            top = FAILURES[int(np.argmax(first))]
            return f"no walkable pair of the map (most often: {top})"
        return f"{n} of {total} pairs walkable; {self.headline}"

    def document(self) -> dict:
        """The JSON body of ``slope.json`` (per-pair numbers: ``slope.csv``)."""
        zd = self.walker.zd
        first = self.cells["first"]
        counts = np.bincount(first.ravel(), minlength=len(FAILURES))
        per = []
        for k, f in enumerate(self.thrust):
            r = self.walkable_range(k)
            down, up = self.steepest_at(k)
            per.append({"thrust": float(f), "steepest_downhill": down, "steepest_uphill": up,
                        "lowest": None if r is None else r[0],
                        "highest": None if r is None else r[1]})
        sw = {k: v for k, v in self.walker.swing.items() if k not in ("alpha", "height")}
        imp = self.impact
        return {
            "schema_version": SCHEMA_VERSION,
            "units": {"slope": "rad", "thrust": "N", "zeta": "kg^2 m^4/s^2", "speed": "m/s",
                      "climb_rate": "m/s", "step_time": "s", "step_length": "m",
                      "force": "N", "friction_ratio": "1"},
            "robot": robot_record(zd),
            "gait": gait_record(zd),
            "thruster": self.thruster_name,
            "mu": self.mu, "min_vertical_force": self.eps,
            "success": self.success, "reason": self.reason, "headline": self.headline,
            "warnings": list(self.walker.warnings),
            "slopes": {"start": float(self.slopes[0]), "stop": float(self.slopes[-1]),
                       "count": int(self.slopes.size)},
            "thrusts": {"start": float(self.thrust[0]), "stop": float(self.thrust[-1]),
                        "count": int(self.thrust.size)},
            "pairs": int(first.size),
            "walkable_pairs": int(counts[0]),
            "first_failure_counts": {(f or "walkable"): int(c) for f, c in
                                     zip(FAILURES, counts)},
            "first_failure_meaning": {(f or "walkable"): t for f, t in FAILURE_TEXT.items()},
            "checks": "per pair, in this order: the gait is valid, zeta* > 0 (the orbit "
                      "exists), delta_zero^2 < 1 (stable), delta_zero^2 zeta* + min V_Z > 0 "
                      f"on {SAMPLES} samples of the step (completes it), F^v >= "
                      "min_vertical_force and |F^h| <= mu F^v along the step (grid, polished "
                      f"within {100 * POLISH_BAND:g} % of the limit), impact admissible, "
                      "swing foot above the ground; forces in the slope frame",
            "polished_pairs": self.polished,
            "step_length": zd.step_length,
            "delta_zero_sq": zd.delta_zero_sq,
            "impact": {"friction_ratio": imp.friction_ratio,
                       "admissible": imp.admissible(self.mu), "reasons": imp.reasons(self.mu)},
            "swing_foot": sw,
            "steepest": self.steepest(),
            "per_thrust": per,
            "seconds": self.seconds,
        }

    def tables(self) -> dict[str, Table]:
        """``slope.csv``: one row per (slope, thrust) pair."""
        c = self.cells
        header = [col("slope", "rad"), col("thrust", "N"), "walkable", "first_failure",
                  "orbit_exists", "stable", "completes_step", "contact_feasible",
                  col("zeta_star", "kg^2 m^4/s^2"), col("step_time", "s"),
                  col("speed", "m/s"), col("climb_rate", "m/s"),
                  col("min_vertical_force", "N"), "max_friction_ratio", "polished"]
        rows = []
        num = ("zeta_star", "step_time", "speed", "climb_rate", "min_vertical_force",
               "max_friction_ratio")
        vals = {k: np.where(np.isfinite(c[k]), c[k], np.nan).tolist() for k in num}
        flags = {k: c[k].tolist() for k in ("orbit", "stable", "completes", "contact",
                                             "polished")}
        first = c["first"].tolist()
        tf = {True: "true", False: "false"}
        for i, g in enumerate(self.slopes.tolist()):
            for k, f in enumerate(self.thrust.tolist()):
                rows.append([g, f, tf[first[i][k] == 0], FAILURES[first[i][k]] or "none",
                             tf[flags["orbit"][i][k]], tf[flags["stable"][i][k]],
                             tf[flags["completes"][i][k]], tf[flags["contact"][i][k]]]
                            + [None if v[i][k] != v[i][k] else v[i][k]
                               for v in (vals[n] for n in num)]
                            + [tf[flags["polished"][i][k]]])
        return {"slope": Table(header, rows, [
            "one row per (slope, thrust) pair; slope positive uphill; speed along the ground, "
            "climb_rate = speed sin(slope); first_failure: the first condition that fails "
            "(slope.json: first_failure_meaning)",
            "empty cells: the quantity does not exist for that pair (no orbit, or the walker "
            "stops inside the step; max_friction_ratio also where F^v <= 0)",
            f"min_vertical_force_N, max_friction_ratio: exact (golden-section polish) where "
            f"polished is true, i.e. within {100 * POLISH_BAND:g} % of their limits; elsewhere "
            f"the extremes over the {SAMPLES}-point grid of the step (about 1e-4 relative "
            "from the exact ones; the verdict is not affected)"])}

    def figures(self, titles: bool = False) -> dict:
        """``slope_map`` (walkable region with speed contours, the failure that bounds it)
        and ``steepest_slope`` (steepest walkable uphill and downhill slope vs thrust)."""
        from ..plots.slope import steepest_figure, walkability_figure

        w = self.walker
        label = (f"thrust {self.thruster_name} [N]" if self.thruster is not None
                 else "thrust [N] (no thruster)")
        per = [self.walkable_range(k) for k in range(self.thrust.size)]
        return {
            "slope_map": walkability_figure(
                self.slopes, self.thrust, self.cells["first"], self.cells["speed"],
                FAILURES, thrust_label=label,
                title=f"{w.name}: walkable slopes (mu = {self.mu:g})" if titles else ""),
            "steepest_slope": steepest_figure(
                self.thrust, [None if r is None else r[1] for r in per],
                [None if r is None else r[0] for r in per], thrust_label=label,
                title=f"{w.name}: steepest walkable slope" if titles else ""),
        }


def slope_map(walker: Walker, slopes: Sequence[float] | None = None,
              thrust: Sequence[float] | None = None, thruster: str | None = None, *,
              mu: float | None = None, min_vertical_force: float = 0.0,
              progress: Callable[[int, int], None] | None = None) -> SlopeMapResult:
    """The walkability map over ``slopes`` [rad, positive uphill, each |slope| < pi/2] x
    constant ``thrust`` [N] on ``thruster`` (default: the first) at friction coefficient
    ``mu`` (default: the gait's) and least vertical ground force ``min_vertical_force`` [N]
    (module docstring, SPEC 14). Defaults: slopes -0.2 to 0.2 rad by 0.01, thrust 0 to -50 N
    by -5 (0 only for a robot without thrusters). ``progress(done, total)`` hears about each
    block of slopes."""
    check_walker(walker)
    if walker.slope != 0.0:
        raise InputError.param("walker", "give the level-ground walker: the map sets the slope")
    slopes = check_numbers("slopes", slopes, optional=True, min_len=1)
    thrust = check_numbers("thrust", thrust, optional=True, min_len=1)
    check_text("thruster", thruster, optional=True)
    mu = check_number("mu", mu, optional=True)
    min_vertical_force = check_number("min_vertical_force", min_vertical_force)
    mu = walker.gait.mu if mu is None else float(mu)
    eps = float(min_vertical_force)
    check_contact_options(mu, eps)
    g = np.array(_values(*DEFAULT_SLOPES) if slopes is None else slopes, float)
    for v in g:
        check_slope(float(v), "slopes")
    robot = walker.robot
    j = robot.driven_thruster(thruster)
    F = np.array((_values(*DEFAULT_THRUST) if j is not None else [0.0]) if thrust is None
                 else thrust, float)
    robot.check_no_thrust(F.tolist())
    if j is not None:
        lo, hi = robot.thrusters[j].limits
        bad = F[(F < lo) | (F > hi)]
        if bad.size:
            raise InputError.param("thrust", f"{bad[0]:g} N is outside the limits [{lo:g}, "
                                             f"{hi:g}] N of thruster {robot.thrusters[j].name}")
    if g.size * F.size > MAX_PAIRS:
        raise InputError.param(("slopes", "thrust"), f"{g.size} x {F.size} pairs: at most "
                                                     f"{MAX_PAIRS:,} per map")
    t0 = time.perf_counter()
    cells, polished = walkability_map(walker.model, walker.zd, g, F, j, mu, eps,
                                      weight=walker.robot.total_mass * walker.robot.gravity,
                                      scuffs=bool(walker.swing["scuffs"]), progress=progress)
    seconds = time.perf_counter() - t0
    return SlopeMapResult(walker, g, F, j, mu, eps, cells, impact_data(walker.model, walker.zd),
                          polished, seconds)

