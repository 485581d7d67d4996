"""Independent re-check of a designed gait (SPEC 2, 3, 5): the adaptive zero dynamics
(:func:`~thrustwalk_cli.hzd.zero_dynamics.zero_dynamics`), :func:`limit_cycles`,
:func:`~thrustwalk_cli.contact.evaluate.evaluate` (polished extremes) and dense grids for the
swing foot, joint ranges and torques; every margin in SI units (>= 0 when satisfied)."""

from __future__ import annotations

import numpy as np

from ..contact.evaluate import evaluate
from ..contact.terms import impact_data, stance_terms, swing_clearance
from ..description.gait import Gait
from ..energetics.orbit import orbit_energy
from ..hzd.quadrature import integrate, lobatto
from ..hzd.zero_dynamics import limit_cycles, zero_dynamics
from ..model.compiled import CompiledModel
from ..thrust.schedule import Schedule
from .spec import DesignSpec


def show(value: float, ref: float, unit: str = "") -> tuple[str, str]:
    """``value`` and ``ref`` formatted with the fewest significant digits (at least 4) that tell
    them apart, so that a violation stays visible (0.9000002 vs 0.9, not 0.9 vs 0.9)."""
    u = f" {unit}" if unit else ""
    for d in range(4, 18):
        a, b = f"{value:.{d}g}", f"{ref:.{d}g}"
        if a != b:
            return a + u, b + u
    return repr(float(value)) + u, repr(float(ref)) + u


HEIGHT_TOL = 1e-6  # [m] swing-foot dips shallower than this count as touching (re-check)


RANGE_TOL = 1e-6  # [rad] joint-range tolerance of the re-check


LIFTOFF_TOL = 1e-6  # [m/s] lift-off velocity tolerance of the re-check

#: the tolerance of the re-check on each margin (SI, the margin's unit): a margin down to
#: minus this passes, and is shown as 0 (the others pass from 0 up)
MARGIN_TOL = {"clearance_mid_step": HEIGHT_TOL, "min_swing_height": HEIGHT_TOL,
              "liftoff_velocity": LIFTOFF_TOL, "joint_range": RANGE_TOL}


# -------------------------------------------------------------------- independent re-check
def orbit_cost(model: CompiledModel, zd, sched: Schedule, zeta_plus: float,
               thrust_weight: float = 0.0, nodes: int = 129) -> dict:
    """Objectives on the periodic orbit: ``effort = (1/L) int (|u|^2 + w_F |F_T|^2) dt``
    [N^2 m s] (torques ``u`` from the affine stance terms, SPEC 5, ``dt = dalpha/alpha'``,
    constant thrust ``F_T`` [N] weighted by ``w_F`` [m^2]) and ``peak = max |u_i|`` [N m], with
    the step time [s] of that quadrature."""
    a = lobatto(zd.alpha_i, zd.alpha_f, nodes)
    st = stance_terms(model, zd.maps, a)
    F = sched.force[0, 0, :]
    zeta = zeta_plus + zd.V_Z(a, sched)[0]
    u = np.einsum("gim,m->gi", st.U2, F) + st.U1 * zeta[:, None] + st.U0
    dT = 1.0 / (np.abs(st.AT) * np.sqrt(2.0 * np.maximum(zeta, 1e-300)))
    span = abs(zd.alpha_f - zd.alpha_i)
    L = float(model.p_swing(zd.maps.q_minus)[0])
    T = float(integrate(0.0, span, dT)[0])
    return {"effort": float(integrate(0.0, span, (u**2).sum(1) * dT)[0]) / L
            + thrust_weight * float(F @ F) * T / L,
            "peak": float(np.abs(u).max()), "step_time": T}


def verify(model: CompiledModel, gait: Gait, spec: DesignSpec, thrust: np.ndarray,
           eps: float) -> dict:
    """Re-check a gait with the adaptive zero dynamics, :func:`limit_cycles`,
    :func:`contact.evaluate` (polished extremes) and dense grids for the swing foot, joint
    ranges and torques. Returns every margin (SI units, >= 0 when satisfied), the orbit and
    ``failed`` (the families that fail)."""
    zd = zero_dynamics(model, gait)
    sched = Schedule.constant(zd, np.asarray(thrust, float)[None, :])
    lc = limit_cycles(zd, sched)[0]
    out: dict = {"orbit": {"exists": lc.exists, "stable": lc.stable, "reason": lc.reason,
                           "delta_zero_sq": zd.delta_zero_sq, "zeta_star": lc.zeta_star,
                           "zeta_plus": lc.zeta_plus, "sigma_minus": lc.sigma_minus,
                           "sigma_plus": lc.sigma_plus, "step_time": lc.step_time,
                           "step_length": lc.step_length, "speed": lc.speed,
                           "alpha_i": zd.alpha_i, "alpha_f": zd.alpha_f,
                           "min_abs_alpha_dot": lc.min_abs_alpha_dot,
                           "touchdown_velocity": lc.touchdown_velocity,
                           "invariance_residual": {"position": zd.maps.position_residual,
                                                   "velocity": zd.maps.velocity_residual}}}
    failed = []
    m: dict = {"stability": spec.max_delta_sq - zd.delta_zero_sq}
    if not (lc.exists and lc.stable):
        out.update(feasible=False, failed=["orbit"], failure_details={"orbit": lc.reason},
                   margins=m, objective=None)
        return out
    rep = evaluate(model, zd, sched, mu=spec.mu, eps=eps, profiles=False)
    case = rep.cases[0]
    imp = impact_data(model, zd)
    sw = swing_clearance(model, zd, points=2001)
    a_mid = zd.alpha_i + 0.5 * (zd.alpha_f - zd.alpha_i)
    h_mid = float(model.p_swing(zd.maps.q_Z(np.array(a_mid)))[1])
    grid = np.linspace(zd.alpha_i, zd.alpha_f, 2001)
    q = zd.maps.q_Z(grid)
    lo = np.array([c.range[0] for c in model.robot.coordinates])
    hi = np.array([c.range[1] for c in model.robot.coordinates])
    with np.errstate(invalid="ignore"):
        rng_m = np.minimum(q - lo, hi - q).min(axis=0)
    tl = np.array([c.torque_limit for c in model.robot.coordinates if c.actuated])
    cost = orbit_cost(model, zd, sched, lc.zeta_plus,
                      spec.thrust_weight if spec.thrust_design else 0.0)
    if spec.objective == "cot":  # exact, by quadrature on the orbit (SPEC 15)
        cost["cot"] = orbit_energy(zd, sched, [lc])[0].cot()["mechanical"]
    umax = np.array(case.max_abs_torque)
    zmin = lc.min_zeta
    m.update({
        "zeta_min_ratio": zmin / lc.zeta_star - spec.min_zeta_ratio,
        "speed_error": None if spec.speed is None else lc.speed - spec.speed,
        "step_length_error": (None if spec.step_length is None
                              else lc.step_length - spec.step_length),
        "clearance_mid_step": h_mid - spec.clearance,
        "min_swing_height": float(min(sw["deepest"], 0.0)) if sw["deepest"] < 0 else
        float(sw["min_height"]),
        "vertical_force": case.margins["vertical_force"],
        "friction": case.margins["friction"],
        "impact_friction": case.margins["impact_friction"],
        "impact_vertical_impulse": case.margins["impact_vertical_impulse"],
        "liftoff_velocity": case.margins["liftoff_velocity"] - spec.min_liftoff,
        "touchdown_velocity": -lc.touchdown_velocity - spec.min_touchdown_velocity,
        "joint_range": {nm: (float(v) if np.isfinite(v) else None)
                        for nm, v in zip(model.robot.coordinate_names, rng_m)},
        "torque_limit": {c.name: (float(t - u) if np.isfinite(t) else None)
                         for c, t, u in zip([c for c in model.robot.coordinates if c.actuated],
                                            tl, umax)},
    })
    why: dict[str, str] = {}

    def fail(family: str, text: str) -> None:
        if family not in failed:
            failed.append(family)
        why.setdefault(family, text)

    d2, bound = show(zd.delta_zero_sq, spec.max_delta_sq)
    if m["stability"] < 0:
        fail("stability", f"delta_zero^2 = {d2} > {bound}")
    if m["zeta_min_ratio"] < -1e-3:
        a, b = show(zmin, spec.min_zeta_ratio * lc.zeta_star)
        fail("orbit", f"min zeta = {a} < {spec.min_zeta_ratio:g} zeta^- = {b} kg^2 m^4/s^2")
    if spec.speed is not None and abs(m["speed_error"]) > 1e-3 * spec.speed:
        fail("speed", f"speed {lc.speed:.6g} m/s, target {spec.speed:g} m/s")
    if spec.step_length is not None and abs(m["step_length_error"]) > 1e-4:
        fail("step_length", f"step length {lc.step_length:.6g} m, target {spec.step_length:g} m")
    h_impact = float(model.p_swing(zd.maps.q_minus)[1])
    if abs(h_impact) > 1e-9 or lc.step_length <= 0:
        fail("foot_placement", f"swing foot {h_impact:.3g} m above the ground at impact "
                               f"(tolerance 1e-9 m), step length {lc.step_length:.6g} m")
    if m["clearance_mid_step"] < -HEIGHT_TOL:
        a, b = show(h_mid, spec.clearance, "m")
        fail("clearance", f"swing foot {a} < {b} at mid-step")
    if sw["deepest"] < -HEIGHT_TOL:
        fail("scuffing", f"swing foot {sw['deepest']:.3g} m below the ground at alpha = "
                         f"{sw['alpha_at_deepest']:.6g} rad (tolerance {HEIGHT_TOL:g} m)")
    if m["vertical_force"] < 0:
        a, b = show(case.min_vertical_force, eps, "N")
        fail("vertical_force", f"min F_1^v = {a} < {b}")
    if m["friction"] is None or m["friction"] < 0:
        if case.max_friction_ratio is None:
            fail("friction", "F_1^v <= 0 somewhere")
        else:
            a, b = show(case.max_friction_ratio, spec.mu)
            fail("friction", f"max |F_1^h|/F_1^v = {a} > mu = {b}")
    if not imp.admissible(spec.mu) or m["liftoff_velocity"] < -LIFTOFF_TOL:
        reasons = imp.reasons(spec.mu)
        if m["liftoff_velocity"] < -LIFTOFF_TOL:
            a, b = show(case.liftoff_velocity, spec.min_liftoff, "m/s")
            reasons.append(f"lift-off velocity {a} < {b}")
        fail("impact", "; ".join(reasons))
    if m["touchdown_velocity"] < 0:
        a, b = show(lc.touchdown_velocity, -spec.min_touchdown_velocity, "m/s")
        fail("touchdown", f"swing-foot vertical velocity at touchdown {a} > {b} (grazing)")
    if spec.thrust_range is not None:
        rr = _range_check(model, zd, spec, thrust, eps)
        m["thrust_range"] = rr
        for f in rr["failed"]:
            fail(f, f"on the orbit of a thrust in the range: {'; '.join(rr['reasons'])}")
        umax = np.maximum(umax, rr["max_abs_torque"])
    if np.any(rng_m[np.isfinite(rng_m)] < -RANGE_TOL):
        k = int(np.nanargmin(np.where(np.isfinite(rng_m), rng_m, np.inf)))
        fail("joint_range", f"{model.robot.coordinate_names[k]} leaves its range by "
                            f"{-rng_m[k]:.3g} rad")
    if np.any(umax > tl * (1 + 1e-9)):
        k = int(np.argmax(umax / tl))
        a, b = show(umax[k], tl[k], "N m")
        act = [c.name for c in model.robot.coordinates if c.actuated]
        fail("torque_limit", f"max |u_{act[k]}| = {a} > limit {b}")
    out.update(feasible=not failed, failed=failed, failure_details=why, margins=m,
               objective=cost[spec.objective], cost=cost,
               contact={"feasible": case.feasible, "reason": case.reason,
                        "min_vertical_force": case.min_vertical_force,
                        "max_friction_ratio": case.max_friction_ratio,
                        "impact_friction_ratio": case.impact_friction_ratio,
                        "liftoff_velocity": case.liftoff_velocity,
                        "max_abs_torque": case.max_abs_torque},
               swing={"mid_step_height": h_mid, "min_height_window": sw["min_height"],
                      "max_height": sw["max_height"], "deepest": sw["deepest"]})
    return out


def _range_check(model: CompiledModel, zd, spec: DesignSpec, thrust: np.ndarray, eps: float,
                 samples: int = 5) -> dict:
    """Contact feasibility (:func:`contact.evaluate`) on the orbit of ``samples`` constant
    thrusts spanning ``spec.thrust_range`` [N] (ends included): worst margins over them."""
    name, lo, hi = spec.thrust_range
    j = model.robot.thruster_names.index(name)
    F = np.tile(np.asarray(thrust, float), (samples, 1))
    F[:, j] = np.linspace(lo, hi, samples)
    cases = evaluate(model, zd, Schedule.constant(zd, F), mu=spec.mu, eps=eps,
                     profiles=False).cases
    failed = []
    if not all(c.cycle.exists for c in cases):
        failed.append("orbit")
        return {"thrusts": F[:, j].tolist(), "failed": failed,
                "max_abs_torque": np.zeros(model.n - 1),
                "reasons": [c.reason for c in cases if not c.feasible]}
    vert = min(c.margins["vertical_force"] for c in cases)
    fr = [c.margins["friction"] for c in cases]
    lift = min(c.margins["liftoff_velocity"] for c in cases) - spec.min_liftoff
    touch = min(-c.cycle.touchdown_velocity for c in cases) - spec.min_touchdown_velocity
    if vert < 0:
        failed.append("vertical_force")
    if any(f is None or f < 0 for f in fr):
        failed.append("friction")
    if lift < -LIFTOFF_TOL:
        failed.append("impact")
    reasons = [c.reason for c in cases if not c.feasible]
    if touch < 0:
        failed.append("touchdown")
        reasons.append(f"touchdown velocity {-touch - spec.min_touchdown_velocity:.4g} m/s > "
                       f"-{spec.min_touchdown_velocity:g} m/s")
    return {"thrusts": F[:, j].tolist(), "failed": failed, "vertical_force": vert,
            "friction": None if any(f is None for f in fr) else min(fr),
            "liftoff_velocity": lift, "touchdown_velocity": touch,
            "speed": [c.cycle.speed for c in cases],
            "max_abs_torque": np.max([c.max_abs_torque for c in cases], axis=0),
            "reasons": reasons}


def check_gait(model: CompiledModel, gait: Gait, spec: DesignSpec) -> dict:
    """:func:`verify` for an existing gait (its own constant thrust, if any)."""
    prob_eps = (0.1 * model.robot.total_mass * model.robot.gravity
                if spec.min_vertical_force is None else spec.min_vertical_force)
    F = np.zeros(model.n_thrusters)
    if gait.thrust is not None and gait.thrust.mode == "force":
        for nm, vals in gait.thrust.values:
            F[model.robot.thruster_names.index(nm)] = vals[0]
    return verify(model, gait, spec, F, prob_eps)
