"""The ``feasibility`` study: is this gait, with this thrust, physically walkable? (SPEC 5)

For each constant thrust value [N] (or one piecewise schedule from a gait-format file): the
exact ground reaction ``F_1(alpha) = Lambda_2 F + Lambda_1 zeta + Lambda_0`` [N] along the
periodic orbit, joint torques [N m], swing-foot height [m], the impact impulse [N s] and the
trailing foot's lift-off velocity [m/s], with a verdict per case; the polynomial fits L_k and
their verdict; the feasible region over (thrust scale, zeta^-). Units: SI (see ``UNITS``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..contact.evaluate import CaseResult, ContactReport, check_contact_options, evaluate
from ..contact.region import Region, feasible_region
from ..contact.terms import SCUFF_TOL, SWING_WINDOW, Fits, ImpactData, fit_terms
from ..errors import (
    InputError,
    Problem,
    Where,
    check_count,
    check_number,
    check_numbers,
    check_path,
    check_text,
)
from ..files.gait_file import load_gait
from ..hzd.zero_dynamics import grazing_warning
from ..thrust.schedule import Schedule, WrittenSchedule
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, climb_rate, fmt, result_repr, slope_record, units

UNITS = units("force", "impulse", "torque", "alpha", "thrust", "zeta", "velocity", "height",
              "Lambda_0", "Lambda_1", "Lambda_2", "Lambda_T", "friction_ratio",
              "impulse_per_sigma")


# ------------------------------------------------------------------------------ records
def fits_record(fits: Fits, names: list[str]) -> dict:
    """JSON of the polynomial fits (Chebyshev basis, see :class:`TermFit`)."""
    out = {"basis": "Chebyshev T_k(x), x = 2 (alpha - alpha_i) / (alpha_f - alpha_i) - 1",
           "tolerance_relative": fits.tol}
    comp = ("horizontal", "vertical")
    for key, label in (("L0", "L_0"), ("L1", "L_1"), ("L2", "L_2"), ("LT", "L_T")):
        f = fits.fits[key]
        coef = f.coef
        if key == "L2":
            coefs = {n: {c: coef[:, i, j].tolist() for i, c in enumerate(comp)}
                     for j, n in enumerate(names)}
        else:
            coefs = {c: coef[:, i].tolist() for i, c in enumerate(comp)}
        out[label] = {"degree": f.degree, "max_error": f.max_error,
                      "relative_error": f.relative_error, "target_reached": f.reached,
                      "coefficients": coefs}
    return out


def impact_record(imp: ImpactData, mu: float) -> dict:
    return {
        "impulse_per_unit_sigma": imp.impulse_per_sigma.tolist(),
        "trailing_foot_velocity_per_unit_sigma": imp.trailing_foot_velocity_per_sigma.tolist(),
        "touchdown_velocity_per_unit_sigma": imp.touchdown_per_sigma,
        "friction_ratio": imp.friction_ratio,
        "admissible": imp.admissible(mu),
        "reasons": imp.reasons(mu),
        "note": "per unit |sigma_N^-| in the walking direction; F_2 is proportional to "
                "sigma_N^-, so its direction and friction ratio do not depend on speed",
    }


def case_record(c: CaseResult) -> dict:
    """One JSON entry per case (keys fixed by the feasibility issue; SI units)."""
    lc = c.cycle
    return {
        "label": c.label, "thrust": c.thrust, "feasible": c.feasible, "reason": c.reason,
        "orbit_exists": lc.exists, "zeta_star": lc.zeta_star, "speed": lc.speed,
        "min_vertical_force": c.min_vertical_force,
        "alpha_at_min_vertical_force": c.alpha_at_min_vertical_force,
        "max_friction_ratio": c.max_friction_ratio,
        "alpha_at_max_friction_ratio": c.alpha_at_max_friction_ratio,
        "impact_impulse": c.impact_impulse, "impact_friction_ratio": c.impact_friction_ratio,
        "liftoff_velocity": c.liftoff_velocity, "touchdown_velocity": lc.touchdown_velocity,
        "max_abs_torque": c.max_abs_torque,
        "margins": c.margins,
        "polynomial": c.poly,
        "fit_errors": None if c.poly is None else {"max_force_error": c.poly["max_force_error"]},
    }


# ----------------------------------------------------------------------- the command's study
FRICTION_NOTE = ("exact planar friction cone |F^h| <= mu F^v; an inscribed pyramid "
                 "|F^h| <= mu/sqrt(2) F^v, used by some tools, is about 29 % too strict")




@dataclass(frozen=True)
class FeasibilityResult:
    """Contact feasibility of a walker under constant thrust values or one schedule (SPEC 5).

    ``report``: per case (``report.cases``) the verdict, worst points and margins; ``region``:
    the feasible region over (scale, zeta^-); ``values`` [N] (constant thrust) or ``schedule``
    (with ``schedule_source``, the file it came from). ``success``: every case is feasible;
    ``verdict``: ``feasible``, ``infeasible`` or ``mixed``.
    """

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    mu: float
    eps: float
    fits: Fits
    report: ContactReport
    region: Region
    scale_label: str
    case_points: list
    thrust: list
    thruster: str | None
    schedule: WrittenSchedule | None = None
    schedule_source: str | None = None

    name = "feasibility"

    @property
    def cases(self) -> list[CaseResult]:
        """Per thrust case its contact verdict, worst points and margins (SPEC 5)."""
        return self.report.cases

    @property
    def impact(self) -> ImpactData:
        """The impact on the orbit per unit momentum (SPEC 5): impulse, lift-off, friction ratio."""
        return self.report.impact

    @property
    def verdict(self) -> str:
        """``feasible`` (every case), ``infeasible`` (none) or ``mixed``."""
        feas = [c.feasible for c in self.cases]
        return "feasible" if all(feas) else "infeasible" if not any(feas) else "mixed"

    @property
    def success(self) -> bool:
        """Every case is feasible."""
        return self.verdict == "feasible"

    @property
    def reason(self) -> str:
        """Each infeasible case and why, or ``every case is feasible``."""
        bad = [c for c in self.cases if not c.feasible]
        return "every case is feasible" if not bad else "; ".join(
            f"{c.label}: {c.reason}" for c in bad)

    def document(self) -> dict:
        """The JSON body of ``feasibility.json`` (keys fixed by the feasibility issue)."""
        w, zd = self.walker, self.walker.zd
        rob, g = w.robot, w.gait
        names = rob.thruster_names
        fit_rec = fits_record(self.fits, names)
        fit_err = {k: fit_rec[k]["max_error"] for k in ("L_0", "L_1", "L_2", "L_T")}
        rep = self.report
        sw = {k: v for k, v in rep.swing.items() if k not in ("alpha", "height")}
        cases = []
        for c in rep.cases:
            r = case_record(c)
            if zd.slope != 0.0:
                r["climb_rate"] = climb_rate(c.cycle.speed, zd.slope)
            r["min_swing_foot_height"] = sw["min_height"]
            r["fit_errors"] = {**fit_err, **(r["fit_errors"] or {})}
            cases.append(r)
        region = self.region
        fp = region.scale[region.fixed_point_feasible]
        mu = self.mu
        return {
            "schema_version": SCHEMA_VERSION,
            "robot": {"name": rob.name, "file": rob.source_file,
                      "coordinates": rob.coordinate_names, "thrusters": rob.thruster_names,
                      "total_mass": rob.total_mass, "gravity": rob.gravity},
            "gait": {"name": g.name, "file": g.source_file, "alpha_i": zd.alpha_i,
                     "alpha_f": zd.alpha_f, "delta_zero_sq": zd.delta_zero_sq},
            "units": ({**UNITS, "slope": "rad", "climb_rate": "m/s"} if zd.slope != 0.0
                      else UNITS),
            **({"slope": slope_record(zd.slope)} if zd.slope != 0.0 else {}),
            "thruster": self.thruster,
            "mode": "constant" if self.schedule is None else "schedule",
            "schedule_source": self.schedule_source,
            "mu": mu, "min_vertical_force": self.eps, "friction_cone": FRICTION_NOTE,
            "verdict": self.verdict, "success": self.success, "reason": self.reason,
            "warnings": list(w.warnings) + [f"{c.label}: {gw}" for c in rep.cases
                                            if (gw := grazing_warning(c.cycle))],
            "impact": impact_record(rep.impact, mu),
            "swing_foot": {**sw, "window_s": list(SWING_WINDOW), "scuff_tolerance": SCUFF_TOL,
                           "note": "swing-foot height [m] above the stance foot; min_height "
                                   "over s in window_s (it is 0 at lift-off and touch-down); "
                                   "deepest = most negative height strictly inside the step; "
                                   "scuffs (deeper than scuff_tolerance) makes every case "
                                   "infeasible"},
            "fits": fit_rec,
            "cases": cases,
            "region": {
                "x": self.scale_label, "y": "pre-impact zeta^- [kg^2 m^4/s^2]",
                "scale": region.scale.tolist(), "zeta": region.zeta.tolist(),
                "feasible": ["".join("1" if v else "0" for v in row) for row in region.feasible],
                "walker_completes_step": ["".join("1" if v else "0" for v in row)
                                          for row in region.completes],
                "mask_format": "one string per scale value, one character per zeta value "
                               "('1' true, '0' false)",
                "fixed_point_feasible_range": [float(fp.min()), float(fp.max())] if fp.size
                else None,
                "note": "one step from zeta^+ = delta_zero^2 zeta^- with the given thrust; "
                        "feasible = completes the step, F^v >= eps, friction cone, admissible "
                        "impact. fixed_point_feasible_range: scales whose periodic orbit is "
                        "feasible (grid resolution)",
            },
        }

    def tables(self) -> dict:
        """No CSV table (``{}``): the command writes ``feasibility.json`` and the figures."""
        return {}

    def figures(self, titles: bool = False) -> dict:
        """``grf`` (ground force, friction ratio, torques and swing foot along the step) and
        ``feasible_region``."""
        from ..plots.feasibility import grf_figure, region_figure

        w, rep = self.walker, self.report
        joints = [c.name for c in w.robot.coordinates if c.actuated]
        values = self.thrust if self.schedule is None else None
        return {
            "grf": grf_figure([c.profile for c in rep.cases], values,
                              value_label=self.scale_label, mu=self.mu, eps=self.eps,
                              swing=rep.swing, joint_names=joints,
                              impacts=[{"impulse": c.impact_impulse,
                                        "ratio": c.impact_friction_ratio if c.cycle.exists
                                        else None} for c in rep.cases],
                              title=f"{w.name}: stance phase" if titles else ""),
            "feasible_region": region_figure(self.region, scale_label=self.scale_label,
                                             mu=self.mu, eps=self.eps, cases=self.case_points,
                                             title=f"{w.name}: feasible region" if titles
                                             else ""),
        }

    def attachments(self, doc: dict) -> dict[str, str]:
        """``feasibility.md``: the verdict, tables and figures, from the written document."""
        return {"feasibility.md": markdown(doc)}


def check_options(mu: float, eps: float, degree: int | None, fit_tol: float) -> None:
    """Bad parameter values -> :class:`InputError` naming the parameter."""
    check_contact_options(mu, eps)
    if degree is not None and not 1 <= degree <= 30:
        raise InputError.param("degree", f"expected 1 ... 30 (got {degree})")
    if not (np.isfinite(fit_tol) and 0 < fit_tol < 1):
        raise InputError.param("fit_tol", f"expected a relative error in (0, 1) (got "
                                          f"{fit_tol:g})")


def load_schedule(path: str) -> tuple[WrittenSchedule, Where]:
    """The ``thrust:`` section of a gait-format YAML file, and where to report its problems."""
    sg, source = load_gait(path)
    if sg.thrust is None:
        raise InputError(Problem(path, None, "thrust", "the file has no `thrust:` section "
                                 "(a gait-format YAML with a thrust schedule is expected)"))
    return sg.thrust, source.where


DEFAULT_THRUST = (0.0, -10.0, -20.0, -30.0, -40.0, -50.0)


def feasibility(walker: Walker, thrust: Sequence[float] | None = None, *,
                schedule: str | WrittenSchedule | None = None, schedule_where: Where = "schedule",
                thruster: str | None = None, mu: float | None = None,
                min_vertical_force: float = 0.0, degree: int | None = None,
                fit_tol: float = 1e-3, region_shape: tuple[int, int] = (61, 81),
                slope: float = 0.0) -> FeasibilityResult:
    """Contact feasibility (SPEC 5) of ``walker`` for constant ``thrust`` values [N] on
    ``thruster`` (default: the first), or for one piecewise ``schedule`` (a gait-format file
    path, or a :class:`~thrustwalk_cli.thrust.schedule.WrittenSchedule` whose problems are
    reported at ``schedule_where``);
    with neither, the gait's own ``thrust:`` schedule, else 0 to -50 N in steps of 10 (only 0
    for a robot without thrusters, which accepts no other value).
    ``mu`` [-] defaults to the gait's; ``min_vertical_force`` [N] is the least F^v allowed;
    ``degree``/``fit_tol`` set the polynomial fits L_k.
    ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground angle (SPEC 14,
    :meth:`Walker.on_slope`): the forces are tangential (F^h) and normal (F^v) to the slope,
    the friction cone is the slope's; 0: level ground, bit for bit as without it."""
    check_walker(walker)
    walker = walker.on_slope(slope)
    thrust = check_numbers("thrust", thrust, optional=True, min_len=0)
    if schedule is not None and not isinstance(schedule, WrittenSchedule):
        schedule = check_path("schedule", schedule)
    if not (isinstance(schedule_where, str) or callable(schedule_where) or (
            isinstance(schedule_where, tuple) and all(isinstance(n, str) for n in schedule_where))):
        raise InputError.param("schedule_where", "must be a parameter name or a function "
                                                 "(key, message) -> Problem")
    check_text("thruster", thruster, optional=True)
    mu = check_number("mu", mu, optional=True)  # its range: check_contact_options
    min_vertical_force = check_number("min_vertical_force", min_vertical_force)
    degree = check_count("degree", degree, ge=1, le=30, optional=True)
    fit_tol = check_number("fit_tol", fit_tol, gt=0, lt=1)
    shape = check_numbers("region_shape", region_shape, min_len=2, max_len=2, integer=True,
                          ge=2, le=1000)
    region_shape = (int(shape[0]), int(shape[1]))
    if thrust is not None and schedule is not None:
        raise InputError.param(("thrust", "schedule"), "give one of them, not both")
    model, zd = walker.model, walker.zd
    mu = walker.gait.mu if mu is None else float(mu)
    eps = float(min_vertical_force)
    check_options(mu, eps, degree, fit_tol)
    source = None
    if thrust is None and schedule is None and walker.gait.thrust is not None:
        source = walker.gait.source_file
        schedule, schedule_where = walker.gait.thrust, walker.where
    if isinstance(schedule, str):
        source = schedule
        schedule, schedule_where = load_schedule(schedule)
    names = model.robot.thruster_names
    m = model.n_thrusters
    fits = fit_terms(model, zd, degree=degree, tol=fit_tol)
    if schedule is None:
        j = model.robot.driven_thruster(thruster)
        default = DEFAULT_THRUST if j is not None else (0.0,)
        values = [float(v) for v in (default if thrust is None else thrust)]
        if not values:
            raise InputError.param("thrust", "no thrust values")
        model.robot.check_no_thrust(values)
        F = np.zeros((len(values), m))
        e = np.zeros((1, m))
        if j is not None:
            F[:, j] = values
            e[0, j] = 1.0
        sched = Schedule.constant(zd, F)
        sched.check_limits(zd.model.robot, "thrust", ())
        unit = Schedule.constant(zd, e)  # no thruster: the region is flat in the thrust axis
        lo, hi = min(min(values), 0.0), max(max(values), 0.0)
        pad = 0.2 * (hi - lo) if hi > lo else 10.0
        scale_label = f"thrust {names[j]} [N]" if j is not None else "thrust [N] (no thruster)"
        labels = [f"{v:g} N" for v in values]
        thrust_rec: list = values
        thruster_name = names[j] if j is not None else None
    else:
        sched = schedule.resolve(zd, zd.model.robot, schedule_where, pad=True)[0]
        sched.check_limits(zd.model.robot, schedule_where)
        unit = sched
        lo, hi, pad = 0.0, 1.0, 0.5
        scale_label = "schedule scale factor [-] (1 = the given schedule)"
        labels = ["schedule"]
        fr = (sched.knots - zd.alpha_i) / (zd.alpha_f - zd.alpha_i)
        vals = ({"T": sched.generalized[0].tolist()} if schedule.mode == "generalized" else
                {n: sched.force[0, :, i].tolist() for i, n in enumerate(names)
                 if np.any(sched.force[0, :, i])})
        thrust_rec = [{"mode": schedule.mode, "knots_fraction": fr.tolist(),
                       "knots_alpha": sched.knots.tolist(), "values": vals}]
        thruster_name = None
    rep = evaluate(model, zd, sched, mu=mu, eps=eps, fits=fits, labels=labels,
                   thrust=thrust_rec)
    scales = np.union1d(np.linspace(lo - pad, hi + pad, region_shape[0]), [0.0])
    if schedule is not None:
        scales = np.union1d(scales, [1.0])
    d2 = zd.delta_zero_sq
    zs_cases = [c.cycle.zeta_star for c in rep.cases if c.cycle.exists]
    zmax_guess = max(zs_cases, default=0.0)
    if 0 < d2 < 1:
        Vf = zd.V_Z(np.array(zd.alpha_f), unit)[0]
        V0f = zd.V0(np.array(zd.alpha_f))
        curve = zd.fixed_point_of(V0f + scales * (Vf - V0f))
        zmax_guess = max(zmax_guess, float(curve.max()))
    zmax = 1.3 * zmax_guess if zmax_guess > 0 else 1000.0
    zetas = np.linspace(zmax / region_shape[1], zmax, region_shape[1])
    region = feasible_region(model, zd, unit, scales, zetas, mu=mu, eps=eps)
    case_pts = ([(v, c.cycle.zeta_star) for v, c in zip(thrust_rec, rep.cases)]
                if schedule is None else [(1.0, rep.cases[0].cycle.zeta_star)])
    return FeasibilityResult(walker, mu, eps, fits, rep, region, scale_label, case_pts,
                             thrust_rec, thruster_name, schedule, source)


def thrust_text(t) -> str:
    if isinstance(t, dict):
        return "schedule " + ", ".join(f"{k}: [{', '.join(fmt(x, '.3g') for x in v)}]"
                                       for k, v in t["values"].items())
    return fmt(t, "g")


def markdown(doc: dict) -> str:
    """``feasibility.md``: the verdict, tables and the figures, from the JSON document."""
    imp, sw, fits = doc["impact"], doc["swing_foot"], doc["fits"]
    p = doc["provenance"]
    lines = [
        f"# Contact feasibility: {doc['robot']['name']} / {doc['gait']['name']}",
        "",
        f"thrustwalk {p['version']}, {p['created_utc']}; robot `{p['robot']['file']}` "
        f"(sha256 {p['robot']['sha256'][:12]}), gait `{p['gait']['file']}` "
        f"(sha256 {p['gait']['sha256'][:12]}); command `{p['command']}`.",
        "",
        f"**Verdict: {doc['verdict']}** (mu = {doc['mu']:g}, minimum vertical force "
        f"{doc['min_vertical_force']:g} N"
        + (f", thruster `{doc['thruster']}`" if doc["thruster"] else "") + ").",
        "",
        f"Friction: {doc['friction_cone']}.",
        "",
        "## Cases",
        "",
        "| thrust [N] | verdict | zeta* | min F^v [N] | at alpha [rad] | max abs(F^h)/F^v "
        "| at alpha [rad] | impact impulse (h, v) [N s] | lift-off [m/s] | touchdown [m/s] "
        "| polynomial verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in doc["cases"]:
        poly = c["polynomial"]
        pv = "—" if poly is None else (("feasible" if poly["feasible"] else "infeasible")
                                       + ("" if poly["agrees"] else " (disagrees)"))
        imp_c = c["impact_impulse"]
        lines.append(
            f"| {thrust_text(c['thrust'])} | {'feasible' if c['feasible'] else 'INFEASIBLE'} "
            f"| {fmt(c['zeta_star'])} | {fmt(c['min_vertical_force'])} "
            f"| {fmt(c['alpha_at_min_vertical_force'])} | {fmt(c['max_friction_ratio'])} "
            f"| {fmt(c['alpha_at_max_friction_ratio'])} "
            f"| {'—' if imp_c is None else f'({imp_c[0]:.4g}, {imp_c[1]:.4g})'} "
            f"| {fmt(c['liftoff_velocity'])} | {fmt(c['touchdown_velocity'])} | {pv} |")
    bad = [c for c in doc["cases"] if not c["feasible"]]
    if bad:
        lines += ["", "Reasons:", ""]
        lines += [f"- {thrust_text(c['thrust'])}: {c['reason']}" for c in bad]
    if doc["warnings"]:
        lines += ["", "Warnings:", ""]
        lines += [f"- {w}" for w in doc["warnings"]]
    lines += [
        "",
        "## Impact",
        "",
        "The impulse is proportional to sigma_N^-; its direction does not depend on speed.",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| impulse per unit abs(sigma_N^-) (h, v) [N s per kg m^2/s] | "
        f"({imp['impulse_per_unit_sigma'][0]:.4g}, {imp['impulse_per_unit_sigma'][1]:.4g}) |",
        f"| friction ratio abs(F_2^h)/F_2^v | {fmt(imp['friction_ratio'])} |",
        f"| trailing-foot vertical velocity per unit abs(sigma_N^-) [m/s per kg m^2/s] | "
        f"{imp['trailing_foot_velocity_per_unit_sigma'][1]:.4g} |",
        f"| swing-foot touchdown velocity per unit abs(sigma_N^-) [m/s per kg m^2/s] | "
        f"{imp['touchdown_velocity_per_unit_sigma']:.4g} |",
        f"| admissible | {'yes' if imp['admissible'] else 'no: ' + '; '.join(imp['reasons'])} |",
        "",
        "## Swing foot",
        "",
        f"Minimum height for s in [{sw['window_s'][0]:g}, {sw['window_s'][1]:g}]: "
        f"{1e3 * sw['min_height']:.4g} mm at alpha = {sw['alpha_at_min_height']:.4g} rad; "
        f"maximum {1e3 * sw['max_height']:.4g} mm.",
        ("" if not sw["scuffs"] else
         f"**Infeasible:** the swing foot goes {1e6 * -sw['deepest']:.3g} um below the ground "
         f"near alpha = {sw['alpha_at_deepest']:.4g} rad (tolerance "
         f"{1e6 * sw['scuff_tolerance']:g} um): every case is infeasible."),
        "",
        "## Polynomial fits of Lambda_0..2",
        "",
        f"Chebyshev polynomials in alpha ({fits['basis']}); "
        + ("degree fixed by the user." if fits["tolerance_relative"] is None else
           f"degree chosen for a relative max error <= {fits['tolerance_relative']:g}."),
        "",
        "| term | degree | max error | relative | unit |",
        "|---|---|---|---|---|",
    ]
    for key, unit in (("L_0", "N"), ("L_1", "N per kg^2 m^4/s^2"), ("L_2", "N per N"),
                      ("L_T", "N per N m")):
        f = fits[key]
        lines.append(f"| {key} | {f['degree']} | {f['max_error']:.3g} | "
                     f"{f['relative_error']:.3g} | {unit} |")
    lines += [
        "",
        "## Figures",
        "",
        "Ground reaction force, friction ratio, joint torques (for several cases the worst "
        "|u| over the cases, one curve per joint) and swing-foot height along the step:",
        "",
        "![ground reaction force](grf.png)",
        "",
        f"Feasible region over {doc['region']['x']} and {doc['region']['y']} (every "
        "infeasible region hatched by its condition); "
        + (f"the periodic orbit is feasible for {doc['region']['x']} in "
           f"[{doc['region']['fixed_point_feasible_range'][0]:.4g}, "
           f"{doc['region']['fixed_point_feasible_range'][1]:.4g}] (grid resolution)."
           if doc["region"]["fixed_point_feasible_range"] else
           "no feasible periodic orbit on the grid."),
        "",
        "![feasible region](feasible_region.png)",
        "",
    ]
    return "\n".join(lines)


