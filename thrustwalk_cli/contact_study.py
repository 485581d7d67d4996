"""The ``thrustwalk feasibility`` study (SPEC 5): the feasible region over thrust scale and
pre-impact zeta, the JSON records and the figure data, from the exact contact terms of
:mod:`thrustwalk_cli.contact`.

The schedule of ``--schedule FILE`` is read by :func:`thrustwalk_cli.schedules.schedule_from_gait`
(padded with zero thrust where it does not cover the step). Units: SI (see ``UNITS``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contact import (
    SCUFF_TOL,
    SWING_WINDOW,
    CaseResult,
    Fits,
    ImpactData,
    check_contact_options,
    evaluate,
    fit_terms,
    friction_ratio,
    impact_data,
    stance_terms,
    step_grid,
)
from .errors import InputError
from .model import CompiledModel
from .schedules import gait_file_where, schedule_from_gait
from .zero_dynamics import Schedule, ZeroDynamics, thruster_index

UNITS = {
    "force": "N", "impulse": "N s", "torque": "N m", "alpha": "rad", "thrust": "N",
    "zeta": "kg^2 m^4 / s^2", "velocity": "m / s", "height": "m",
    "Lambda_0": "N", "Lambda_1": "N per (kg^2 m^4/s^2)", "Lambda_2": "N per N",
    "Lambda_T": "N per N m (generalised couple)", "friction_ratio": "1 (|F^h| / F^v)",
    "impulse_per_sigma": "N s per (kg m^2/s)",
}


# -------------------------------------------------------------------------- feasible region
@dataclass(frozen=True)
class Region:
    """Feasibility over a grid of schedule scale (thrust [N] for a unit constant thrust) and
    pre-impact zeta^- [kg^2 m^4/s^2] for one step starting at ``zeta^+ = delta_zero^2 zeta^-``.

    ``completes``: zeta > 0 along the step (the walker does not stop); ``feasible`` adds
    ``F^v >= eps``, the friction cone and the impact conditions. ``fixed_point``: zeta*(scale)
    on the limit-cycle curve (NaN-free: ``fixed_point_valid`` masks scales without an orbit).
    """

    scale: np.ndarray
    zeta: np.ndarray
    min_vertical: np.ndarray  # (ns, nz)
    max_ratio: np.ndarray  # (ns, nz), inf where F^v <= 0
    completes: np.ndarray
    feasible: np.ndarray
    fixed_point: np.ndarray  # (ns,)
    fixed_point_valid: np.ndarray
    fixed_point_feasible: np.ndarray
    impact_ok: bool


def feasible_region(model: CompiledModel, zd: ZeroDynamics, unit: Schedule,
                    scale: np.ndarray, zeta: np.ndarray, *, mu: float, eps: float = 0.0,
                    points: int = 201) -> Region:
    """Evaluate the contact conditions on a (scale, zeta^-) grid (SPEC 5), using affinity:
    ``zeta(alpha) = delta_zero^2 zeta^- + V_0 + s W``, ``F_1 = s (Lambda_2 F_u + Lambda_T T_u) +
    Lambda_1 zeta + Lambda_0`` with ``W = V_Z(unit) - V_0``."""
    scale, zeta = np.asarray(scale, float), np.asarray(zeta, float)
    alpha, idx = step_grid(unit.knots, points)
    t = stance_terms(model, zd.maps, alpha)
    V0 = zd.V0(alpha)
    W = zd.V_Z(alpha, unit)[0] - V0
    Fu, Tu = unit.force[0, idx, :], unit.generalized[0, idx]
    per_s = np.einsum("gim,gm->gi", t.L2, Fu) + t.LT * Tu[:, None]  # (g, 2)
    z = (zd.delta_zero_sq * zeta[None, :, None] + V0 + scale[:, None, None] * W)  # (s, z, g)
    F1 = (scale[:, None, None, None] * per_s + t.L1 * z[..., None] + t.L0)
    completes = z.min(axis=-1) > 0
    minv = F1[..., 1].min(axis=-1)
    maxr = friction_ratio(F1).max(axis=-1)
    imp_ok = impact_data(model, zd).admissible(mu)
    feas = completes & (minv >= eps) & (maxr <= mu) & imp_ok
    Vf = zd.V0(np.array(zd.alpha_f)) + scale * W[-1]
    d2 = zd.delta_zero_sq
    valid = np.zeros(scale.shape, bool)
    zs = np.zeros(scale.shape)
    fp_feas = np.zeros(scale.shape, bool)
    if 0 < d2 < 1 and zd.kappa1_ok:
        zs = Vf / (1 - d2)
        zfp = d2 * zs[:, None] + V0 + scale[:, None] * W
        valid = (zs > 0) & (zfp.min(axis=-1) > 0)
        F1fp = scale[:, None, None] * per_s + t.L1 * zfp[..., None] + t.L0
        fp_feas = (valid & (F1fp[..., 1].min(-1) >= eps) & (friction_ratio(F1fp).max(-1) <= mu)
                   & imp_ok)
    return Region(scale, zeta, minv, maxr, completes, feas, zs, valid, fp_feas, imp_ok)


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
        "liftoff_velocity": c.liftoff_velocity, "max_abs_torque": c.max_abs_torque,
        "margins": c.margins,
        "polynomial": c.poly,
        "fit_errors": None if c.poly is None else {"max_force_error": c.poly["max_force_error"]},
    }


# ----------------------------------------------------------------------- the command's study
FRICTION_NOTE = ("exact planar friction cone |F^h| <= mu F^v; an inscribed pyramid "
                 "|F^h| <= mu/sqrt(2) F^v, used by some tools, is about 29 % too strict")


def schedule_from_spec(zd: ZeroDynamics, spec, source: str | None = None) -> Schedule:
    """A :class:`Schedule` from the ``thrust:`` section of the gait-format file ``source``
    (:func:`thrustwalk_cli.schedules.schedule_from_gait`, SPEC 4; default: the gait's own file).

    Knots are fractions of the step or alpha values [rad]; a schedule that does not cover the
    whole step is padded with zero-thrust intervals. Raises InputError naming ``file:line`` and
    the key."""
    where = gait_file_where(source) if source else None
    return schedule_from_gait(zd, spec, where, pad=True)[0]


def check_options(mu: float, eps: float, degree: int | None, fit_tol: float) -> None:
    """Bad option values -> InputError naming the option."""
    check_contact_options(mu, eps)
    if degree is not None and not 1 <= degree <= 30:
        raise InputError(f"option --degree: expected 1 ... 30 (got {degree})")
    if not (np.isfinite(fit_tol) and 0 < fit_tol < 1):
        raise InputError(f"option --fit-tol: expected a relative error in (0, 1) "
                         f"(got {fit_tol:g})")


def feasibility_study(model: CompiledModel, zd: ZeroDynamics, *, values: list[float] | None,
                      spec=None, spec_source: str = "", thruster: str | None = None,
                      mu: float, eps: float = 0.0, degree: int | None = None,
                      fit_tol: float = 1e-3, region_shape: tuple[int, int] = (61, 81)
                      ) -> tuple[dict, dict]:
    """Everything ``thrustwalk feasibility`` writes: the JSON body and the figure data."""
    check_options(mu, eps, degree, fit_tol)
    names = model.robot.thruster_names
    m = model.n_thrusters
    fits = fit_terms(model, zd, degree=degree, tol=fit_tol)
    if spec is None:
        j = thruster_index(model, thruster)
        F = np.zeros((len(values), m))
        F[:, j] = values
        sched = Schedule.constant(zd, F)
        e = np.zeros((1, m))
        e[0, j] = 1.0
        unit = Schedule.constant(zd, e)
        lo, hi = min(min(values), 0.0), max(max(values), 0.0)
        pad = 0.2 * (hi - lo) if hi > lo else 10.0
        scale_label = f"thrust {names[j]} [N]"
        labels = [f"{v:g} N" for v in values]
        thrust = [float(v) for v in values]
        thruster_name = names[j]
    else:
        sched = schedule_from_spec(zd, spec, spec_source)
        unit = sched
        lo, hi, pad = 0.0, 1.0, 0.5
        scale_label = "schedule scale factor [-] (1 = the given schedule)"
        labels = ["schedule"]
        fr = (sched.knots - zd.alpha_i) / (zd.alpha_f - zd.alpha_i)
        vals = ({"T": sched.generalized[0].tolist()} if spec.mode == "generalized" else
                {n: sched.force[0, :, i].tolist() for i, n in enumerate(names)
                 if np.any(sched.force[0, :, i])})
        thrust = [{"mode": spec.mode, "knots_fraction": fr.tolist(),
                   "knots_alpha": sched.knots.tolist(), "values": vals}]
        thruster_name = None
    rep = evaluate(model, zd, sched, mu=mu, eps=eps, fits=fits, labels=labels, thrust=thrust)
    scales = np.union1d(np.linspace(lo - pad, hi + pad, region_shape[0]), [0.0])
    if spec is not None:
        scales = np.union1d(scales, [1.0])
    d2 = zd.delta_zero_sq
    zs_cases = [c.cycle.zeta_star for c in rep.cases if c.cycle.exists]
    zmax_guess = max(zs_cases, default=0.0)
    if 0 < d2 < 1:
        Vf = zd.V_Z(np.array(zd.alpha_f), unit)[0]
        V0f = zd.V0(np.array(zd.alpha_f))
        curve = (V0f + scales * (Vf - V0f)) / (1 - d2)
        zmax_guess = max(zmax_guess, float(curve.max()))
    zmax = 1.3 * zmax_guess if zmax_guess > 0 else 1000.0
    zetas = np.linspace(zmax / region_shape[1], zmax, region_shape[1])
    region = feasible_region(model, zd, unit, scales, zetas, mu=mu, eps=eps)
    case_pts = ([(v, c.cycle.zeta_star) for v, c in zip(values, rep.cases)] if spec is None
                else [(1.0, rep.cases[0].cycle.zeta_star)])
    fit_rec = fits_record(fits, names)
    fit_err = {k: fit_rec[k]["max_error"] for k in ("L_0", "L_1", "L_2", "L_T")}
    sw = {k: v for k, v in rep.swing.items() if k not in ("alpha", "height")}
    cases = []
    for c in rep.cases:
        r = case_record(c)
        r["min_swing_foot_height"] = sw["min_height"]
        r["fit_errors"] = {**fit_err, **(r["fit_errors"] or {})}
        cases.append(r)
    fp = region.scale[region.fixed_point_feasible]
    doc = {
        "units": UNITS,
        "thruster": thruster_name,
        "mode": "constant" if spec is None else "schedule",
        "mu": mu, "eps": eps, "friction_cone": FRICTION_NOTE,
        "verdict": ("feasible" if all(c["feasible"] for c in cases) else
                    "infeasible" if not any(c["feasible"] for c in cases) else "mixed"),
        "impact": impact_record(rep.impact, mu),
        "swing_foot": {**sw, "window_s": list(SWING_WINDOW), "scuff_tolerance": SCUFF_TOL,
                       "note": "swing-foot height [m] above the stance foot; min_height over "
                               "s in window_s (it is 0 at lift-off and touch-down); deepest = "
                               "most negative height strictly inside the step"},
        "fits": fit_rec,
        "cases": cases,
        "region": {
            "x": scale_label, "y": "pre-impact zeta^- [kg^2 m^4/s^2]",
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
    figs = {"profiles": [c.profile for c in rep.cases],
            "values": thrust if spec is None else None, "swing": rep.swing, "region": region,
            "scale_label": scale_label, "case_points": case_pts,
            "joints": [c.name for c in model.robot.coordinates if c.actuated]}
    return doc, figs
