"""The ``slope`` study: the walkability map of a gait over slope x constant thrust (SPEC 14).

For every pair (slope ``gamma`` [rad, positive uphill], constant thrust ``F`` [N] on one
thruster): whether the zero-dynamics orbit exists (``zeta* > 0``), is stable
(``delta_zero^2 < 1``), completes the step (``delta_zero^2 zeta* + min V_Z > 0``: alpha reaches
``alpha_f``) and is contact-feasible at ``mu`` (SPEC 5 in the slope frame: ``F^v >= eps``,
``|F^h| <= mu F^v`` along the step, an admissible impact, the trailing foot lifting off, the
swing foot striking and staying above the ground), which condition fails first, and
``zeta*``, the step time, the speed along the ground and the climb rate ``speed sin(gamma)``.

The map uses the structure of SPEC 14 instead of one orbit per pair. In the slope frame every
quantity is explicit in ``(cos gamma, sin gamma)`` and affine in the thrust:

    V_Z(alpha; gamma, F) = c V_0 + s V_x + F (c_j Gamma_j + s_j Gamma_perp,j)
    zeta*               = V_Z(alpha_f; gamma, F) / (1 - delta_zero^2)
    F_1(alpha)          = c L0 + s L0_x + L1 zeta(alpha) + F (c_j L2_j + s_j L2_x,j)

(``c = cos gamma``, ``s = sin gamma``; ``c_j, s_j = c, s`` for a world-frame thruster and
``1, 0`` for a link-frame one; ``L0_x, L2_x`` the stance terms of gravity along the ground,
``model.slope.gravity_frame_model(c=0, s=1)``). The level-ground and along-the-ground parts
are Chebyshev series over the step, computed once; a pair then costs a few multiply-adds per
grid point. The impact (``delta_zero``, the impulse's direction, the lift-off) and the swing
foot do not depend on the slope or the thrust (SPEC 14), so they are evaluated once.

Numbers as :func:`~thrustwalk_cli.studies.limit_cycle.limit_cycle` gives them for each pair:
the existence test on the same grid (201 samples and the step's ends), the step time by the
same nested Clenshaw-Curtis rule refined per pair until ``1e-10`` relative. Contact is checked
on that grid; where a pair's grid margin is within 5 % of its limit (``F^v - eps < 0.05 m g``
or ``|F^h|/F^v > 0.95 mu``), the worst point is polished by golden section between the
neighbouring grid points (as the feasibility command does), so a verdict is not grid-limited.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..contact.evaluate import check_contact_options
from ..contact.terms import ImpactData, impact_data, stance_terms
from ..errors import InputError, check_number, check_numbers, check_text
from ..hzd.extrema import golden_min, neighbours
from ..hzd.quadrature import ChebSeries, integrate, lobatto
from ..hzd.zero_dynamics import MAX_NODES, RTOL
from ..model.slope import check_slope, gravity_frame_model
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, Table, col, gait_record, result_repr, robot_record

SAMPLES = 201  # grid points over the step (plus its ends), as limit_cycle's orbits
MAX_PAIRS = 1_000_000  # slope x thrust pairs of one map
CHUNK = 16  # slopes evaluated together (memory: CHUNK x thrusts x grid x 2 doubles)
POLISH_BAND = 0.05  # grid margins within 5 % of the limit are polished
LOCAL_POINTS = 12  # Chebyshev points of the polish's local interpolants (degree 11)
TERMS_TOL = 1e-13  # relative size of the last Chebyshev coefficients of the stance terms

#: first failing condition of a pair, in the order they are checked ('' = walkable)
FAILURES = ("", "invalid gait", "no orbit", "unstable", "stops", "lifts", "slips", "impact",
            "scuffs")
FAILURE_TEXT = {
    "": "walkable: a stable periodic orbit that completes the step, contact-feasible",
    "invalid gait": "the gait is not a walking orbit (not hybrid-invariant, or kappa_1 "
                    "singular)",
    "no orbit": "no periodic orbit: zeta* = V_Z(alpha_f)/(1 - delta_zero^2) <= 0",
    "unstable": "the periodic orbit is unstable (delta_zero^2 >= 1)",
    "stops": "the walker stops before the end of the step (zeta reaches 0: alpha does not "
             "reach alpha_f)",
    "lifts": "the stance foot lifts: F^v < the minimum vertical force somewhere on the step",
    "slips": "the stance foot slips: |F^h| > mu F^v somewhere on the step",
    "impact": "the impact is inadmissible (impulse outside the cone, the trailing foot does "
              "not lift off, or the swing foot grazes)",
    "scuffs": "the swing foot goes below the ground during the step",
}
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
        return None if self.thruster is None else self.walker.robot.thruster_names[self.thruster]

    @property
    def walkable(self) -> np.ndarray:
        return self.cells["first"] == 0

    @property
    def success(self) -> bool:
        """At least one pair is walkable (a map without any is a valid answer, not a tool
        failure; ``reason`` says so)."""
        return bool(self.walkable.any())

    def walkable_range(self, k: int) -> tuple[float, float] | None:
        """(steepest downhill, steepest uphill) walkable slope [rad] at thrust index ``k``."""
        w = self.walkable[:, k]
        if not w.any():
            return None
        return float(self.slopes[w].min()), float(self.slopes[w].max())

    @property
    def headline(self) -> str:
        """"without thrust this gait walks slopes from X to Y rad; with F N from X' up to Z
        rad" (F the thrust of the map farthest from 0), and the steepest walkable slopes of
        the whole map; an end of a range at the map's edge says so (steeper slopes may
        walk too)."""
        th = self.thrust
        lo, hi = float(self.slopes.min()), float(self.slopes.max())

        def rad(x: float) -> str:
            edge = " (the map's edge)" if x in (lo, hi) and self.slopes.size > 1 else ""
            return f"{0.0 if abs(x) < 1e-12 else x:.4g}{edge}"

        parts = []
        zero = np.flatnonzero(th == 0.0)
        if zero.size:
            r = self.walkable_range(int(zero[0]))
            parts.append("without thrust this gait walks no slope of the map" if r is None else
                         f"without thrust this gait walks slopes from {rad(r[0])} to "
                         f"{rad(r[1])} rad")
        else:
            parts.append("thrust 0 is not in the map")
        far = int(np.argmax(np.abs(th)))
        if th[far] != 0.0:
            r = self.walkable_range(far)
            parts.append(f"with {th[far]:g} N none" if r is None else
                         f"with {th[far]:g} N from {rad(r[0])} up to {rad(r[1])} rad")
        up = self.steepest()
        if up["uphill"] is not None:
            parts.append(f"steepest walkable uphill {rad(up['uphill'])} rad at "
                         f"{up['uphill_thrust']:g} N, downhill {rad(up['downhill'])} rad at "
                         f"{up['downhill_thrust']:g} N")
        return "; ".join(parts)

    def steepest(self) -> dict:
        w = self.walkable
        if not w.any():
            return {"uphill": None, "uphill_thrust": None, "downhill": None,
                    "downhill_thrust": None}
        i, k = np.nonzero(w)
        up, down = np.argmax(self.slopes[i]), np.argmin(self.slopes[i])
        return {"uphill": float(self.slopes[i[up]]), "uphill_thrust": float(self.thrust[k[up]]),
                "downhill": float(self.slopes[i[down]]),
                "downhill_thrust": float(self.thrust[k[down]])}

    @property
    def reason(self) -> str:
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
            per.append({"thrust": float(f), "steepest_downhill": None if r is None else r[0],
                        "steepest_uphill": None if r is None else r[1]})
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
    cells, polished = _map(walker, g, F, j, mu, eps, progress)
    seconds = time.perf_counter() - t0
    return SlopeMapResult(walker, g, F, j, mu, eps, cells, impact_data(walker.model, walker.zd),
                          polished, seconds)


# ---------------------------------------------------------------------------- the computation
class _Basis:
    """The thrust- and slope-independent series of one gait and thruster (module docstring):
    ``zs`` columns ``[V_0, V_x, Gamma_j, Gamma_perp,j]`` (cumulative from alpha_i) and ``ls``
    columns ``[L0 (2), L0_x (2), L1 (2), L2_j (2), L2_x,j (2)]`` (the stance force per unit
    of each part), with ``cj, sj`` the thruster's turning flags."""

    def __init__(self, walker: Walker, j: int | None):
        zd = walker.zd
        a, b = zd.alpha_i, zd.alpha_f
        self.a, self.b = a, b
        Vx, Gp, _ = zd.slope_series()
        parts = zd.__dict__["_slope_parts"]
        cols = [zd.V0.coef, Vx.coef]
        if j is not None:
            cols += [zd.Gamma.coef[:, j], Gp.coef[:, j]]
            self.world = bool(parts.world[j])
        else:
            cols += [np.zeros(1), np.zeros(1)]
            self.world = False
        rows = max(c.shape[0] for c in cols)
        coef = np.zeros((rows, 4))
        for i, c in enumerate(cols):
            coef[:c.shape[0], i] = c
        self.zs = ChebSeries(a, b, coef)
        model_x = gravity_frame_model(walker.model, 0.0, 1.0, parts)
        flat = walker.model

        def sample(n: int) -> np.ndarray:
            al = lobatto(a, b, n)
            t0, tx = stance_terms(flat, zd.maps, al), stance_terms(model_x, zd.maps, al)
            if j is None:
                l2, l2x = np.zeros((n, 2)), np.zeros((n, 2))
            else:
                l2, l2x = t0.L2[:, :, j], tx.L2[:, :, j]
            return np.hstack([t0.L0, tx.L0, t0.L1, l2, l2x])

        n = 65
        while True:
            ls = ChebSeries.from_values(a, b, sample(n))
            tail = np.abs(ls.coef[-8:]).max(axis=0)
            scale = np.abs(ls.coef).max(axis=0)
            if np.all(tail <= TERMS_TOL * np.maximum(scale, 1e-300)) or n >= 1025:
                break
            n = 2 * n - 1
        self.ls = ls
        self.terms_nodes = n
        grid = np.unique(np.concatenate([np.linspace(a, b, SAMPLES), [a, b]]))
        self.grid = grid[::-1] if b < a else grid
        self.zg = self.zs(self.grid)  # (G, 4)
        self.lg = self.ls(self.grid)  # (G, 10)
        self.zf = self.zs(np.array([b]))[0]
        self.nodes: dict[int, tuple] = {}
        self.zd = zd
        # degree-11 interpolants of both series on the bracket of every grid point (its
        # neighbours): the polish evaluates twelve terms instead of the whole series
        lo, hi = neighbours(self.grid, np.arange(self.grid.size))
        L = LOCAL_POINTS
        theta = np.pi * (np.arange(L) + 0.5) / L
        pts = 0.5 * (lo + hi)[:, None] + 0.5 * (hi - lo)[:, None] * np.cos(theta)[None, :]
        vals = np.concatenate([self.zs(pts), self.ls(pts)], axis=-1)  # (G, L, 14)
        Tm = np.cos(np.outer(np.arange(L), theta)) * (2.0 / L)  # values -> coefficients
        Tm[0] *= 0.5
        self.local = np.einsum("rl,glc->grc", Tm, vals)

    def local_values(self, j: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The series ``zs`` (P, 4) and ``ls`` (P, 10) at ``x`` (P,), each point inside the
        bracket of grid point ``j`` (P,), from the local interpolants."""
        lo, hi = neighbours(self.grid, j)
        span = np.where(hi > lo, hi - lo, 1.0)
        t = (2.0 * x - (lo + hi)) / span
        L = LOCAL_POINTS
        Tv = np.empty((t.size, L))
        Tv[:, 0] = 1.0
        Tv[:, 1] = t
        for r in range(2, L):
            Tv[:, r] = 2.0 * t * Tv[:, r - 1] - Tv[:, r - 2]
        out = np.einsum("pl,plc->pc", Tv, self.local[j])
        return out[:, :4], out[:, 4:]

    def step_nodes(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if n not in self.nodes:
            p = lobatto(self.a, self.b, n)
            self.nodes[n] = (p, self.zd.terms(p)["kappa1"], self.zs(p))
        return self.nodes[n]


def _zeta(z4: np.ndarray, c, s, cj, sj, F, zp) -> np.ndarray:
    """``zeta = zeta^+ + c V_0 + s V_x + F (c_j Gamma + s_j Gamma_perp)`` from series values
    ``z4`` (..., 4); the pair parameters broadcast against ``z4[..., 0]``."""
    return zp + c * z4[..., 0] + s * z4[..., 1] + F * (cj * z4[..., 2] + sj * z4[..., 3])


def _force(l10: np.ndarray, zeta, c, s, cj, sj, F) -> np.ndarray:
    """``F_1 = c L0 + s L0_x + L1 zeta + F (c_j L2 + s_j L2_x)`` (..., 2) [N]."""
    e = (lambda x: np.asarray(x)[..., None])  # noqa: E731
    return (e(c) * l10[..., 0:2] + e(s) * l10[..., 2:4] + e(zeta) * l10[..., 4:6]
            + e(F) * (e(cj) * l10[..., 6:8] + e(sj) * l10[..., 8:10]))


def _map(walker: Walker, g: np.ndarray, F: np.ndarray, j: int | None, mu: float, eps: float,
         progress) -> tuple[dict, int]:
    zd = walker.zd
    basis = _Basis(walker, j)
    d2 = zd.delta_zero_sq
    nS, nT = g.size, F.size
    c_all, s_all = np.cos(g), np.sin(g)
    if basis.world:
        cj_all, sj_all = c_all, s_all
    else:
        cj_all, sj_all = np.ones(nS), np.zeros(nS)
    shape = (nS, nT)
    zstar = np.full(shape, np.nan)
    zmin = np.full(shape, np.nan)
    minv = np.full(shape, np.nan)
    maxr = np.full(shape, np.nan)
    jv = np.zeros(shape, int)
    jr = np.zeros(shape, int)
    valid = zd.valid and 0.0 < d2 != 1.0
    zg, lg, zf = basis.zg, basis.lg, basis.zf
    G = basis.grid.size
    Fb = F[None, :, None]
    buf = [np.empty((CHUNK, nT, G)) for _ in range(3)]
    for i0 in range(0, nS, CHUNK):
        sl = slice(i0, min(i0 + CHUNK, nS))
        k = sl.stop - sl.start
        zeta, fv, fh = (b[:k] for b in buf)
        c, s = c_all[sl, None], s_all[sl, None]
        cj, sj = cj_all[sl, None], sj_all[sl, None]
        Vf = _zeta(zf, c, s, cj, sj, F[None, :], 0.0)  # (k, nT)
        zs = Vf / (1.0 - d2) if d2 != 1.0 else np.full(Vf.shape, np.nan)
        zstar[sl] = zs
        # per slope, the parts that do not depend on the thrust; then one pass per term
        A = c * zg[:, 0] + s * zg[:, 1]  # (k, G)
        B = cj * zg[:, 2] + sj * zg[:, 3]
        np.multiply(Fb, B[:, None, :], out=zeta)
        zeta += A[:, None, :]
        zeta += (d2 * zs)[..., None]
        zmin[sl] = zeta.min(axis=-1)
        for f1, r in ((fv, 1), (fh, 0)):  # F_1 = (c L0 + s L0x) + F (..) + L1 zeta
            A = c * lg[:, r] + s * lg[:, 2 + r]
            B = cj * lg[:, 6 + r] + sj * lg[:, 8 + r]
            np.multiply(zeta, lg[:, 4 + r], out=f1)
            f1 += A[:, None, :]
            f1 += Fb * B[:, None, :]
        j = np.argmin(fv, axis=-1)
        jv[sl] = j
        minv[sl] = np.take_along_axis(fv, j[..., None], -1)[..., 0]
        np.abs(fh, out=fh)
        pos = fv > 0
        np.divide(fh, fv, out=fh, where=pos)
        fh[~pos] = np.inf
        j = np.argmax(fh, axis=-1)
        jr[sl] = j
        maxr[sl] = np.take_along_axis(fh, j[..., None], -1)[..., 0]
        if progress is not None:
            progress(sl.stop, nS)
    orbit = valid & (zstar > 0)
    stable = orbit & (d2 < 1.0)
    completes = orbit & (zmin > 0)
    # the pairs with an orbit through the whole step: step time, polished contact margins
    live = np.nonzero(completes)
    C = {"c": c_all[live[0]], "s": s_all[live[0]], "cj": cj_all[live[0]],
         "sj": sj_all[live[0]], "F": F[live[1]], "zp": d2 * zstar[live]}
    T, T_ok = _step_times(basis, zd, C)
    step_time = np.full(shape, np.nan)
    step_time[live] = T
    completes[live] &= T_ok
    polished_cells = np.zeros(shape, bool)
    polished = _polish(basis, C, live, minv, maxr, jv, jr, mu, eps,
                       walker.robot.total_mass * walker.robot.gravity, polished_cells)
    imp = impact_data(walker.model, zd)
    imp_ok = imp.admissible(mu)
    scuffs = bool(walker.swing["scuffs"])
    v_ok = minv >= eps
    r_ok = np.isfinite(maxr) & (maxr <= mu)
    contact = completes & v_ok & r_ok & imp_ok & (not scuffs)
    first = np.zeros(shape, int)
    checks = [(not zd.valid, "invalid gait"), (~orbit, "no orbit"), (~stable, "unstable"),
              (~completes, "stops"), (~v_ok, "lifts"), (~r_ok, "slips"),
              (not imp_ok, "impact"), (scuffs, "scuffs")]
    for bad, name in reversed(checks):
        first = np.where(bad, FAILURES.index(name), first)
    speed = np.where(completes, zd.step_length / step_time, np.nan)
    nan_unless = (lambda ok, x: np.where(ok, x, np.nan))  # noqa: E731
    cells = {"first": first, "orbit": orbit, "stable": stable, "completes": completes,
             "contact": contact, "zeta_star": nan_unless(orbit, zstar),
             "step_time": nan_unless(completes, step_time), "speed": speed,
             "climb_rate": speed * np.sin(g)[:, None],
             "min_vertical_force": nan_unless(completes, minv),
             "max_friction_ratio": nan_unless(completes & np.isfinite(maxr), maxr),
             "polished": polished_cells & completes}
    return cells, polished


def _step_times(basis: _Basis, zd, C: dict) -> tuple[np.ndarray, np.ndarray]:
    """``T = int dalpha / alpha'`` per live pair: nested Clenshaw-Curtis, nodes doubled for
    the pairs whose estimate is above ``0.1 RTOL`` relative (as ``limit_cycles``)."""
    P = C["F"].size
    T, ok = np.full(P, np.nan), np.ones(P, bool)
    todo = np.arange(P)
    sgn = zd.sigma_sign
    n = 33
    while todo.size:
        p, k1, z4 = basis.step_nodes(n)
        sub = {k: v[todo, None] for k, v in C.items()}
        z = _zeta(z4[None], sub["c"], sub["s"], sub["cj"], sub["sj"], sub["F"], sub["zp"])
        bad = np.any(z <= 0, axis=1)
        f = 1.0 / (k1 * sgn * np.sqrt(2.0 * np.where(z > 0, z, 1.0)))
        val, err = integrate(p[0], p[-1], f)
        done = bad | (err <= 0.1 * RTOL * np.abs(val)) | (n >= MAX_NODES)
        T[todo[done]] = val[done]
        ok[todo[done]] = ~bad[done]
        todo = todo[~done]
        n = 2 * n - 1
    return T, ok & np.isfinite(T) & (T > 0)


def _polish(basis: _Basis, C: dict, live: tuple, minv: np.ndarray, maxr: np.ndarray,
            jv: np.ndarray, jr: np.ndarray, mu: float, eps: float, weight: float,
            marks: np.ndarray) -> int:
    """Golden-section polish of the least ``F^v`` and the largest ``|F^h|/F^v`` of the live
    pairs whose grid values lie within :data:`POLISH_BAND` of the limits (in place); returns
    the number of pairs polished."""
    mv, mr = minv[live], maxr[live]
    near = ((mv - eps < POLISH_BAND * weight) | (mr > (1.0 - POLISH_BAND) * mu)) & (mv >= eps)
    idx = np.nonzero(near)[0]
    if not idx.size:
        return 0
    sub = {k: v[idx] for k, v in C.items()}
    rows = tuple(a[idx] for a in live)
    marks[rows] = True

    def force(j: np.ndarray, x: np.ndarray) -> np.ndarray:
        z4, l10 = basis.local_values(j, x)
        z = _zeta(z4, sub["c"], sub["s"], sub["cj"], sub["sj"], sub["F"], sub["zp"])
        return _force(l10, z, sub["c"], sub["s"], sub["cj"], sub["sj"], sub["F"])

    j = jv[rows]
    lo, hi = neighbours(basis.grid, j)
    _, fv = golden_min(lambda x: force(j, x)[:, 1], lo, hi)
    minv[rows] = np.minimum(mv[idx], np.where(np.isfinite(fv), fv, mv[idx]))

    def neg_ratio(x: np.ndarray) -> np.ndarray:
        f = force(jr_rows, x)
        with np.errstate(divide="ignore", invalid="ignore"):
            return -np.where(f[:, 1] > 0, np.abs(f[:, 0]) / f[:, 1], np.inf)

    jr_rows = jr[rows]
    lo, hi = neighbours(basis.grid, jr_rows)
    _, nr = golden_min(neg_ratio, lo, hi)
    maxr[rows] = np.maximum(mr[idx], np.where(np.isfinite(nr), -nr, mr[idx]))
    return int(idx.size)

