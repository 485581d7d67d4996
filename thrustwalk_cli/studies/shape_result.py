"""The result of the ``shape`` study (SPEC 5, and the paper's erratum of SPEC 4):
:class:`ShapeResult` and its records, the JSON document and CSV rows (every shaped orbit's
fixed point, its pre- and post-impact states and the shifts, the paper's one-step value beside
the true one) and the vector fields of its figures. Running the study is :mod:`.shape`. Units
SI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..hzd.shaping import (
    Intervals,
    KnotSolution,
    TargetSolution,
    VectorField,
    true_shift,
    vector_field,
)
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics
from ..thrust.schedule import Schedule
from ..walker import Walker
from .documents import (
    SCHEMA_VERSION,
    Table,
    climb_rate,
    col,
    gait_record,
    result_repr,
    robot_record,
    slope_record,
    units,
)


@dataclass(frozen=True)
class ShapeResult:
    """Nominal and shaped limit cycles for one family of piecewise schedules (SPEC 4).

    source: ``"pattern"`` (T_j or F_j = pattern(j, k) for each k), ``"gait"`` (the gait file's
    ``thrust:`` section), ``"target-zeta"`` or ``"target-speed"`` (solver a). ``labels`` and
    ``values`` (k, or None) name the shaped schedules; ``one_step`` and ``shift`` are the paper's
    one-step value and the true fixed-point shift [kg^2 m^4/s^2] per schedule. ``success``: every
    shaped schedule has a stable orbit (and the gait is valid); when nothing could be shaped
    (no shape-only knots, target out of reach) the shaped fields are empty; ``reason`` says
    which.
    """

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    success: bool
    reason: str
    source: str
    mode: str
    thruster: int | None
    pattern: str | None
    nominal: LimitCycle
    labels: tuple[str, ...] = ()
    values: tuple[float, ...] | None = None
    knot_solution: KnotSolution | None = None
    target: TargetSolution | None = None
    intervals: Intervals | None = None
    schedule: Schedule | None = None
    cycles: tuple[LimitCycle, ...] = ()
    one_step: np.ndarray | None = None
    shift: np.ndarray | None = None
    field_label: str | None = None
    field_schedule: Schedule | None = None
    field_cycle: LimitCycle | None = None
    base: Schedule | None = field(default=None, repr=False)

    name = "shape"

    def document(self) -> dict:
        """The JSON body of ``shape.json`` (keys fixed by the shaping issue; SI units)."""
        return shape_records(self.walker.zd, self)[0]

    def tables(self) -> dict[str, Table]:
        """``shape.csv``: nominal and shaped orbits (none when nothing was shaped)."""
        return {"shape": shape_records(self.walker.zd, self)[1]} if self.cycles else {}

    def figures(self, titles: bool = False) -> dict:
        """``shape`` (shaped limit cycles, black every 10) and ``vector_field`` (nominal vs
        shaped zero-dynamics field, the paper's figures 4 and 5); none when nothing was
        shaped (no shape-only knots, a target out of reach)."""
        if not self.cycles:
            return {}
        from ..plots.shape import shape_portrait, vector_field_figure

        zd, w = self.walker.zd, self.walker

        def curve(lc, key="alpha_dot"):
            if not lc.exists:
                return None, None
            jump = ((zd.alpha_f, lc.alpha_dot_minus, zd.alpha_i, lc.alpha_dot_plus)
                    if key == "alpha_dot" else
                    (zd.alpha_f, lc.sigma_minus, zd.alpha_i, lc.sigma_plus))
            return lc.orbit, jump

        knots = self.intervals.knots.tolist()
        unit = "N m" if self.mode == "generalized" else "N"
        what = (f"T_j = {self.pattern} [{unit}]" if self.mode == "generalized"
                else f"F_j = {self.pattern} [{unit}], "
                     f"{w.robot.thruster_names[self.thruster]}")
        curves = [curve(lc) for lc in self.cycles]
        portrait = shape_portrait(
            self.values, self.labels, [c[0] for c in curves], [c[1] for c in curves],
            curve(self.nominal), knots, value_label=f"k ({what})",
            title=f"{w.name}: shaped limit cycles ({len(knots)} knots)" if titles else "")
        fc = self.field_cycle
        note = "" if fc.exists else f"no shaped orbit: {fc.reason}"
        planes = ("alpha_dot", "sigma")
        field = vector_field_figure(
            study_fields(zd, self), {k: curve(self.nominal, k) for k in planes},
            {k: curve(fc, k) for k in planes}, knots, shaped_label=self.field_label,
            note=note, title=f"{w.name}: zero-dynamics vector field, nominal vs shaped"
            if titles else "")
        return {"shape": portrait, "vector_field": field}



def around(sched: Schedule, base: Schedule | None) -> Schedule:
    """``sched`` plus the constant gait thrust ``base`` (none: unchanged)."""
    if base is None:
        return sched
    return Schedule(sched.knots, sched.force + base.force[:, :1, :],
                    sched.generalized + base.generalized[:, :1])


# --------------------------------------------------------------------------- records
SHAPE_UNITS = units("alpha", "alpha_dot", "sigma_N", "zeta", "T_j", "F_j", "b_F", "Gamma_j",
                    "q", "q_dot", "step_time", "speed", shift="kg^2 m^4/s^2")


ERRATUM = ("Erratum: the paper writes zeta* = zeta_0* + sum_j b_F T_j; that sum is the "
           "change of zeta^- in ONE step for a fixed zeta^+ (paper_one_step_shift). The fixed "
           "point moves by true_fixed_point_shift = sum_j b_F T_j / (1 - delta_zero^2). Both "
           "vanish exactly when sum_j b_F T_j = 0 (shape-only shaping).")


def _state(zd: ZeroDynamics, lc: LimitCycle, pre: bool) -> dict:
    """Pre- (alpha_f) or post-impact (alpha_i) state of an orbit: zeta, sigma_N, alpha', q, q'."""
    names = zd.model.robot.coordinate_names
    alpha = zd.alpha_f if pre else zd.alpha_i
    q = zd.maps.q_minus if pre else zd.maps.q_plus
    out = {"alpha": alpha, "q": dict(zip(names, q.tolist()))}
    if not lc.exists:
        return {**out, "zeta": None, "sigma_N": None, "alpha_dot": None, "q_dot": None}
    ad = lc.alpha_dot_minus if pre else lc.alpha_dot_plus
    qd = zd.maps.Phi(np.array(alpha)) * ad
    return {**out, "zeta": lc.zeta_star if pre else lc.zeta_plus,
            "sigma_N": lc.sigma_minus if pre else lc.sigma_plus, "alpha_dot": ad,
            "q_dot": dict(zip(names, qd.tolist()))}


def _cycle_summary(lc: LimitCycle, slope: float = 0.0) -> dict:
    """An orbit's summary; on a slope (SPEC 14) with its climb rate beside the speed."""
    return {"exists": lc.exists, "stable": lc.stable, "reason": lc.reason,
            "zeta_star": lc.zeta_star, "step_time": lc.step_time, "speed": lc.speed,
            **({"climb_rate": climb_rate(lc.speed, slope)} if slope != 0.0 else {}),
            "min_abs_alpha_dot": lc.min_abs_alpha_dot, "alpha_at_min": lc.alpha_at_min}


def _values(zd: ZeroDynamics, study: ShapeResult, sched: Schedule, i: int) -> dict:
    if study.mode == "generalized":
        return {"T_j": sched.generalized[i].tolist()}
    names = zd.model.robot.thruster_names
    used = [t for t in range(len(names)) if np.any(sched.force[:, :, t])]
    if study.thruster is not None:
        used = [study.thruster]
    return {"F_j": {names[t]: sched.force[i, :, t].tolist() for t in used}}


def shape_records(zd: ZeroDynamics, study: ShapeResult) -> tuple[dict, Table]:
    """JSON document body and CSV rows (orbits) of a study (keys fixed by the shaping issue)."""
    r = zd.model.robot
    nom = study.nominal
    ks = study.knot_solution
    doc: dict = {
        "schema_version": SCHEMA_VERSION,
        "units": ({**SHAPE_UNITS, "slope": "rad", "climb_rate": "m/s"} if zd.slope != 0.0
                  else SHAPE_UNITS),
        "robot": robot_record(zd),
        "gait": gait_record(zd),
        **({"slope": slope_record(zd.slope)} if zd.slope != 0.0 else {}),
        "success": study.success, "reason": study.reason,
        "warnings": list(study.walker.warnings), "source": study.source,
        "base_thrust": None if study.base is None else {
            "force": dict(zip(r.thruster_names, study.base.force[0, 0].tolist())),
            "generalized": float(study.base.generalized[0, 0]),
            "note": "the gait's constant thrust: the patterns are added to it and the nominal "
                    "orbit is the gait's own"},
        "mode": study.mode, "pattern": study.pattern,
        "thruster": None if study.thruster is None else r.thruster_names[study.thruster],
        "zero_dynamics": {"delta_zero": zd.delta_zero, "delta_zero_sq": zd.delta_zero_sq,
                          "kappa1_ok": zd.kappa1_ok, "kappa1_reason": zd.kappa1_reason,
                          "integral_error_estimate": zd.integral_error},
        "formulas": {
            "b_F": "b_F(alpha_{j+1}, alpha_j) = int_{alpha_j}^{alpha_{j+1}} dtau / kappa_1",
            "Gamma_j": "Gamma_j = int_{alpha_j}^{alpha_{j+1}} beta / kappa_1 dtau",
            "true_fixed_point_shift": "(sum_j b_F T_j + sum_j Gamma_j F_j) / (1 - delta_zero^2)",
            "paper_one_step_shift": "sum_j b_F T_j + sum_j Gamma_j F_j (zeta^+ held fixed)",
        },
        "erratum": ERRATUM,
        "knot_solver": None if ks is None else {
            "success": ks.success, "reason": ks.reason, "method": ks.method,
            "free_knots": [i + 1 for i in ks.free], "independent_conditions": ks.conditions,
            "relative_residual": ks.residual,
            "coordinate": None if ks.coordinate is None else ks.coordinate.tolist(),
            "coordinate_definition": "u_j = W(alpha_j) / W(alpha_f), W = int 1/kappa_1 "
                                     "(generalized) or int beta/kappa_1 (force)"},
        "target": None if study.target is None else {
            "kind": study.target.kind, "target": study.target.target,
            "success": study.target.success, "reason": study.target.reason,
            "zeta_star": study.target.zeta_star, "speed": study.target.speed,
            "residual": study.target.residual, "evaluations": study.target.evaluations,
            "method": "minimum Euclidean norm of the interval values (exact linear relation)"},
        "nominal": {**_cycle_summary(nom, zd.slope), "pre_impact": _state(zd, nom, True),
                    "post_impact": _state(zd, nom, False)},
    }
    iv = study.intervals
    doc["knots"] = None if iv is None else {"alpha": iv.knots.tolist(),
                                            "fraction": iv.fractions.tolist()}
    doc["b_F"] = None if iv is None else iv.b_F.tolist()
    doc["Gamma_j"] = None if iv is None else {
        n: iv.Gamma[:, t].tolist() for t, n in enumerate(r.thruster_names)}
    rows: list[list] = []
    header = ["schedule", "k", "exists", "segment", col("alpha", "rad"),
              col("alpha_dot", "rad/s"), col("sigma", "kg m^2/s"),
              col("zeta", "kg^2 m^4/s^2"), "reason"]

    def orbit_rows(label: str, k: float | None, lc: LimitCycle) -> None:
        if not lc.exists:
            rows.append([label, k, "false", "none", None, None, None, None, lc.reason])
            return
        o = lc.orbit
        for a, ad, sg, z in zip(o["alpha"], o["alpha_dot"], o["sigma"], o["zeta"]):
            rows.append([label, k, "true", "stance", float(a), float(ad), float(sg), float(z),
                         ""])
        rows.append([label, k, "true", "impact", zd.alpha_f, lc.alpha_dot_minus,
                     lc.sigma_minus, lc.zeta_star, ""])
        rows.append([label, k, "true", "impact", zd.alpha_i, lc.alpha_dot_plus, lc.sigma_plus,
                     lc.zeta_plus, ""])

    orbit_rows("nominal", None, nom)
    scheds = []
    for i, lc in enumerate(study.cycles):
        k = None if study.values is None else study.values[i]
        change = None
        if lc.exists and nom.exists:
            change = float(np.max(np.abs(lc.orbit["alpha_dot"] - nom.orbit["alpha_dot"])))
        scheds.append({
            "label": study.labels[i], "k": k, **_values(zd, study, study.schedule, i),
            **{key: v for key, v in _cycle_summary(lc, zd.slope).items() if key != "zeta_star"},
            "zeta_star": {"nominal": nom.zeta_star, "shaped": lc.zeta_star},
            "shift": {"true_fixed_point_shift": float(study.shift[i]),
                      "paper_one_step_shift": float(study.one_step[i]),
                      "observed": (lc.zeta_star - nom.zeta_star
                                   if lc.zeta_star is not None and nom.zeta_star is not None
                                   else None)},
            "pre_impact": {"nominal": _state(zd, nom, True), "shaped": _state(zd, lc, True)},
            "post_impact": {"nominal": _state(zd, nom, False), "shaped": _state(zd, lc, False)},
            "max_orbit_change_alpha_dot": change,
        })
        orbit_rows(study.labels[i], k, lc)
    doc["schedules"] = scheds
    if study.field_schedule is not None:
        fc = study.field_cycle
        doc["vector_field"] = {"label": study.field_label,
                               **_values(zd, study, study.field_schedule, 0),
                               **_cycle_summary(fc, zd.slope),
                               "shift": {"true_fixed_point_shift": float(
                                   true_shift(zd, study.field_schedule)[0]
                                   - (0.0 if study.base is None else
                                      true_shift(zd, study.base)[0]))}}
    csv = Table(header, rows, [
        f"thrustwalk shape: robot {r.name}, gait {zd.gait.name}, mode {study.mode}, "
        f"source {study.source}" + (f", pattern {study.pattern}" if study.pattern else ""),
        "units: alpha rad, alpha_dot rad/s, sigma kg m^2/s, zeta kg^2 m^4/s^2; k as in the "
        "pattern (T_j in N m, F_j in N)",
        "segment 'impact' rows: pre-impact state then post-impact state (the jump)",
    ])
    return doc, csv


def field_range(orbits: Sequence[LimitCycle], key: str) -> tuple[float, float]:
    """y-range of the vector-field grid: 0 and 1.25x the extreme of the orbits' ``key``."""
    vals = [v for lc in orbits if lc is not None and lc.exists for v in lc.orbit[key]]
    if not vals:
        return (-1.0, 1.0)
    lo, hi = min(0.0, 1.25 * min(vals)), max(0.0, 1.25 * max(vals))
    return (lo, hi) if hi > lo else (lo - 1.0, hi + 1.0)


def study_fields(zd: ZeroDynamics, study: ShapeResult) -> dict[str, tuple[VectorField, ...]]:
    """Nominal and shaped vector fields in both planes, sized to hold both limit cycles."""
    out = {}
    nom_s = around(Schedule.zero(study.field_schedule.knots, zd.model.n_thrusters),
                    study.base)
    for plane, key in (("alpha_dot", "alpha_dot"), ("sigma", "sigma")):
        rng = field_range([study.nominal, study.field_cycle], key)
        out[plane] = (vector_field(zd, nom_s, plane, rng),
                      vector_field(zd, study.field_schedule, plane, rng))
    return out
