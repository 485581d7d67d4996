"""Designed gaits re-checked and recorded: the independent re-check (:func:`verify`: adaptive
:func:`zero_dynamics.zero_dynamics`, :func:`limit_cycles`, :func:`contact.evaluate`, dense
grids), the ``NAME.report.json`` record, the gait YAML with its header, and the reload check
of a written file. Works on :class:`design.DesignResult` and :class:`design.DesignSpec`."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from .contact import evaluate, impact_data, stance_terms, swing_clearance
from .gait import Gait
from .model import CompiledModel
from .quadrature import integrate, lobatto
from .zero_dynamics import Schedule, limit_cycles, zero_dynamics

if TYPE_CHECKING:
    from .design import DesignResult, DesignSpec

HEIGHT_TOL = 1e-6  # [m] swing-foot dips shallower than this count as touching (re-check)
RANGE_TOL = 1e-6  # [rad] joint-range tolerance of the re-check


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
                           "invariance_residual": {"position": zd.maps.position_residual,
                                                   "velocity": zd.maps.velocity_residual}}}
    failed = []
    m: dict = {"stability": spec.max_delta_sq - zd.delta_zero_sq}
    if not (lc.exists and lc.stable):
        out.update(feasible=False, failed=["orbit"], margins=m, objective=None)
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
    umax = np.array(case.max_abs_torque)
    zmin = float(lc.orbit["zeta"].min())
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
        "joint_range": {nm: (float(v) if np.isfinite(v) else None)
                        for nm, v in zip(model.robot.coordinate_names, rng_m)},
        "torque_limit": {c.name: (float(t - u) if np.isfinite(t) else None)
                         for c, t, u in zip([c for c in model.robot.coordinates if c.actuated],
                                            tl, umax)},
    })
    if m["stability"] < 0:
        failed.append("stability")
    if m["zeta_min_ratio"] < -1e-3:
        failed.append("orbit")
    if spec.speed is not None and abs(m["speed_error"]) > 1e-3 * spec.speed:
        failed.append("speed")
    if spec.step_length is not None and abs(m["step_length_error"]) > 1e-4:
        failed.append("step_length")
    if abs(float(model.p_swing(zd.maps.q_minus)[1])) > 1e-9 or lc.step_length <= 0:
        failed.append("foot_placement")
    if m["clearance_mid_step"] < -HEIGHT_TOL:
        failed.append("clearance")
    if sw["deepest"] < -HEIGHT_TOL:
        failed.append("scuffing")
    if m["vertical_force"] < 0:
        failed.append("vertical_force")
    if m["friction"] is None or m["friction"] < 0:
        failed.append("friction")
    if not imp.admissible(spec.mu) or m["liftoff_velocity"] < -1e-6:
        failed.append("impact")
    if spec.thrust_range is not None:
        rr = _range_check(model, zd, spec, thrust, eps)
        m["thrust_range"] = rr
        failed += [f for f in rr["failed"] if f not in failed]
        umax = np.maximum(umax, rr["max_abs_torque"])
    if np.any(rng_m[np.isfinite(rng_m)] < -RANGE_TOL):
        failed.append("joint_range")
    if np.any(umax > tl * (1 + 1e-9)):
        failed.append("torque_limit")
    out.update(feasible=not failed, failed=failed, margins=m,
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
    if vert < 0:
        failed.append("vertical_force")
    if any(f is None or f < 0 for f in fr):
        failed.append("friction")
    if lift < -1e-6:
        failed.append("impact")
    return {"thrusts": F[:, j].tolist(), "failed": failed, "vertical_force": vert,
            "friction": None if any(f is None for f in fr) else min(fr),
            "liftoff_velocity": lift,
            "speed": [c.cycle.speed for c in cases],
            "max_abs_torque": np.max([c.max_abs_torque for c in cases], axis=0),
            "reasons": [c.reason for c in cases if not c.feasible]}


def check_gait(model: CompiledModel, gait: Gait, spec: DesignSpec) -> dict:
    """:func:`verify` for an existing gait (its own constant thrust, if any)."""
    prob_eps = (0.1 * model.robot.total_mass * model.robot.gravity
                if spec.min_vertical_force is None else spec.min_vertical_force)
    F = np.zeros(model.n_thrusters)
    if gait.thrust is not None and gait.thrust.mode == "force":
        for nm, vals in gait.thrust.values:
            F[model.robot.thruster_names.index(nm)] = vals[0]
    return verify(model, gait, spec, F, prob_eps)


# ------------------------------------------------------------------------------ records
def report_record(res: DesignResult) -> dict:
    """JSON body of ``NAME.report.json`` (provenance is added by the command)."""
    s = res.spec
    r = res.check
    return {
        "feasible": res.feasible, "reason": res.reason, "blocking_constraint": res.blocking,
        "objective": {"name": s.objective, "value": res.objective,
                      "solver_value": res.solver_objective,
                      "unit": "N^2 m s" if s.objective == "effort" else "N m",
                      "definition": ("(1/L) int_0^T |u|^2 dt over one step of the periodic "
                                     "orbit" + (" + thrust_weight |F|^2 T / L"
                                                if s.thrust_design else "")
                                     if s.objective == "effort" else "max_i,alpha |u_i|")},
        "spec": {"speed": s.speed, "step_length": s.step_length, "mu": s.mu,
                 "order": s.order, "clearance": s.clearance, "max_delta_sq": s.max_delta_sq,
                 "min_vertical_force": res.eps, "min_liftoff_velocity": s.min_liftoff,
                 "min_zeta_ratio": s.min_zeta_ratio, "objective": s.objective,
                 "thrust_design": s.thrust_design, "thrust_weight": s.thrust_weight,
                 "thrust_range": None if s.thrust_range is None else
                 {"thruster": s.thrust_range[0], "low": s.thrust_range[1],
                  "high": s.thrust_range[2]},
                 "starts": s.starts, "seed": s.seed, "max_iter": s.max_iter,
                 "nodes": s.nodes},
        "units": {"speed": "m/s", "step_length": "m", "clearance": "m", "force": "N",
                  "torque": "N m", "zeta": "kg^2 m^4/s^2", "sigma": "kg m^2/s",
                  "angle": "rad", "time": "s", "thrust": "N",
                  "margins": "SI units of each quantity; >= 0 when satisfied"},
        "thrust": list(res.thrust),
        "fixed_point": r.get("orbit"),
        "margins": r.get("margins"),
        "failed_checks": r.get("failed"),
        "cost": r.get("cost"),
        "contact": r.get("contact"),
        "swing_foot": r.get("swing"),
        "solver_violations": res.violations,
        "alpha_c": list(res.c),
        "coefficients": [list(row) for row in res.gait.A],
        "starts": [{"index": t.index, "status": t.status, "objective": _num(t.objective),
                    "max_violation": _num(t.max_violation), "iterations": t.iterations,
                    "evaluations": t.evaluations, "seconds": t.seconds} for t in res.starts],
        "evaluations": res.evaluations, "seconds": res.seconds,
    }


def _num(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def gait_yaml(res: DesignResult, model: CompiledModel, robot_ref: str,
              header: list[str]) -> str:
    """The gait as YAML (``invariance: auto``, columns 0 and 1 written as ``~``), loadable by
    :func:`robot_io.load_gait_for`; ``header`` lines become ``#`` comments."""
    g, r = res.gait, model.robot
    names = r.coordinate_names
    act = [c.name for c in r.coordinates if c.actuated]
    o = res.check.get("orbit", {})
    c_map = ", ".join(f"{nm}: {_f(v)}" for nm, v in zip(names, g.c) if v != 0.0)
    desc = (f"order-{g.order} Bezier gait designed by thrustwalk design-gait "
            f"({res.spec.objective} objective)")
    if o.get("speed") is not None:
        desc += f", {o['speed']:.3f} m/s, step {o['step_length']:.3f} m"
    lines = [f"# {h}" for h in header]
    lines += [f"name: {g.name}", f"description: {desc}", f"robot: {robot_ref}",
              "parameters:",
              f"  af: {_f(g.alpha_f)}   # [rad] alpha_f = c q^-, the value of alpha at impact",
              "alpha:", f"  c: {{{c_map}}}   # alpha = c q [rad]", "  final: af",
              "bezier:", "  invariance: auto",
              "  coefficients:   # [rad]; column k at s = k/M, s = 0 after impact, "
              "s = 1 before impact"]
    for nm, row in zip(act, g.A):
        lines.append(f"    {nm}: [~, ~, " + ", ".join(_f(v) for v in row[2:]) + "]")
    lines += ["controller:", f"  kp: {_f(g.kp)}   # [1/s^2]", f"  kd: {_f(g.kd)}   # [1/s]",
              f"mu: {_f(res.spec.mu)}"]
    if res.thrust:
        vals = ", ".join(f"{nm}: [{_f(v)}]" for nm, v in zip(r.thruster_names, res.thrust))
        lines += ["thrust:   # designed constant thrust [N]", "  mode: force",
                  "  knots: [0, 1]", "  fractions: true", f"  values: {{{vals}}}"]
    return "\n".join(lines) + "\n"


def yaml_header(res: DesignResult, provenance: dict, report_name: str) -> list[str]:
    """Comment lines recording how the gait was made (command, date, objective, margins)."""
    s, chk = res.spec, res.check
    o, m = chk.get("orbit", {}), chk.get("margins", {})
    con, sw = chk.get("contact", {}), chk.get("swing", {})
    obj_unit = "N^2 m s" if s.objective == "effort" else "N m"
    rng = {k: v for k, v in (m.get("joint_range") or {}).items() if v is not None}
    out = [
        f"Gait designed by thrustwalk design-gait (thrustwalk {provenance.get('version')}), "
        f"{provenance.get('created_utc')}.",
        f"command: {provenance.get('command')}",
        f"Objective ({s.objective}): "
        + ("(1/L) int_0^T |u|^2 dt" if s.objective == "effort" else "max |u_i|")
        + f" = {res.objective:.6g} {obj_unit} on the periodic orbit; peak torque "
        f"{chk['cost']['peak']:.4g} N m.",
        f"Variables: pre-impact posture q^-, Bezier columns 2..{s.order - 1} (order "
        f"{s.order}; invariance: auto), zeta^-" + (", constant thrust" if s.thrust_design
                                                   else "") + f"; SLSQP, {s.starts} start(s), "
        f"seed {s.seed}.",
        f"Orbit: stable, delta_zero^2 = {o['delta_zero_sq']:.4f} (<= {s.max_delta_sq:g}), "
        f"{o['speed']:.4f} m/s, step {o['step_length']:.4f} m, step time "
        f"{o['step_time']:.4f} s, zeta* = {o['zeta_star']:.6g} kg^2 m^4/s^2.",
        f"Swing foot: {sw['mid_step_height'] * 100:.2f} cm at mid-step (>= "
        f"{s.clearance * 100:g} cm), >= {sw['min_height_window'] * 1000:.2f} mm for s in "
        f"[0.05, 0.95], >= 0 over the step.",
        f"Stance: F_v >= {con['min_vertical_force']:.4g} N (>= {res.eps:.4g} N), |F_h|/F_v <= "
        f"{con['max_friction_ratio']:.3f} (mu = {s.mu:g}). Impact: |F_h|/F_v = "
        f"{con['impact_friction_ratio']:.3f}, trailing foot lifts off at "
        f"{con['liftoff_velocity']:.3f} m/s.",
    ]
    tr = m.get("thrust_range")
    if s.thrust_range is not None and tr:
        out.append(f"Also feasible on the orbit of every constant {s.thrust_range[0]} thrust in "
                   f"[{s.thrust_range[1]:g}, {s.thrust_range[2]:g}] N: F_v margin >= "
                   f"{tr['vertical_force']:.4g} N, friction margin >= {tr['friction']:.3f}.")
    if rng:
        out.append("Joint-range margins [rad]: "
                   + ", ".join(f"{k} {v:.3f}" for k, v in rng.items()) + ".")
    out.append(f"Every margin and the fixed point: {report_name}. Re-check: thrustwalk "
               "limit-cycle / feasibility with this file.")
    return out


def reload_check(model: CompiledModel, path, res: DesignResult) -> dict:
    """Load a written gait file back (:func:`robot_io.load_gait_for`) and compare its fixed
    point with the design's: returns ``{zeta_star, reference, relative_error, alpha_f_error}``."""
    from .robot_io import load_gait_for

    _, g = load_gait_for(None, str(path))
    zd = zero_dynamics(model, g)
    F = np.zeros(model.n_thrusters)
    if g.thrust is not None:
        for nm, vals in g.thrust.values:
            F[model.robot.thruster_names.index(nm)] = vals[0]
    lc = limit_cycles(zd, Schedule.constant(zd, F[None, :]))[0]
    ref = res.check["orbit"]["zeta_star"]
    got = lc.zeta_star if lc.exists else None
    err = abs(got - ref) / abs(ref) if got is not None else float("inf")
    return {"zeta_star": got, "reference": ref, "relative_error": err,
            "coefficients_error": float(np.abs(np.array(g.A) - np.array(res.gait.A)).max())}


def _f(v: float) -> str:
    v = float(v)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def with_name(res: DesignResult, name: str) -> DesignResult:
    """The same result with the gait renamed."""
    return replace(res, gait=replace(res.gait, name=name))
