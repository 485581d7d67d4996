"""The result of the ``simulate`` study (SPEC 3, 7): :class:`SimulationResult` and what it
renders from the outcomes of :mod:`thrustwalk_cli.simulation.scenario`: the JSON document,
the step and trajectory tables (CSV, or NPZ above ``CSV_ROW_LIMIT`` rows), figure data and
animation frames, plain Python. Running the study is :mod:`.simulate`. Units: SI (zeta in
kg^2 m^4/s^2, sigma in kg m^2/s).
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass, field

import numpy as np

from ..description.terrain import Terrain
from ..design.problem import legs
from ..energetics.run import run_block, simulation_energy, step_block
from ..errors import (
    InputError,
)
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics, limit_cycles, paper_one_step_shift
from ..simulation.closed_loop import (
    predicted_cycle,
)
from ..simulation.scenario import Outcome, Scenario, deviations
from ..thrust.schedule import Schedule
from ..walker import Walker
from .documents import (
    SCHEMA_VERSION,
    Table,
    climb_rate,
    col,
    dynamics_record,
    gait_record,
    result_repr,
    robot_record,
    slope_record,
    units,
)

UNITS = units("time", "thrust", "generalized_thrust", "alpha", "alpha_dot", "sigma_N", "zeta",
              "impulse", "force", "torque", "output_y", "output_rate", "energy", "wn", "tau",
              "velocity", orbit_distance="rad", power="W", cost_of_transport="1",
              fuel_mass="kg", distance="m")


CSV_ROW_LIMIT = 20000  # trajectories with more samples go to .npz


# ----------------------------------------------------------------------------- documents
def _names(zd: ZeroDynamics, values) -> dict:
    return dict(zip(zd.model.robot.thruster_names, map(float, values)))


def step_entries(zd: ZeroDynamics, outcomes: list[Outcome], terrain: bool = False
                 ) -> list[dict]:
    """The ``steps`` list of simulation.json (one entry per step of every run); on a
    ``terrain`` each full-order step carries the height it landed on."""
    out = []
    for i, oc in enumerate(outcomes):
        if oc.primary is None:
            continue
        if oc.full is None:
            for st in oc.reduced.steps:
                out.append({
                    "run": i, "f_ss": oc.value, "model": "reduced", "step": st.step,
                    "t_start": st.t_start, "t_impact": st.t_impact, "step_time": st.step_time,
                    "zeta_start": st.zeta_start, "sigma_minus": st.sigma_minus,
                    "zeta_minus": st.zeta_minus, "sigma_plus": st.sigma_plus,
                    "zeta_plus": st.zeta_plus, "impulse": None,
                    "thrust_at_impact": _names(zd, st.thrust_at_impact),
                    "min_vertical_force": None, "max_abs_output": None,
                    "prediction": None})
            continue
        energies = simulation_energy(oc.full)
        for st, cmp, en in zip(oc.full.steps, oc.comparison, energies):
            out.append({
                "run": i, "f_ss": oc.value, "model": "full-order", "step": st.step,
                "t_start": st.t_start, "t_impact": st.t_impact, "step_time": st.step_time,
                "alpha_minus": st.alpha_minus, "s_minus": st.s_minus,
                "zeta_start": st.zeta_start, "sigma_minus": st.sigma_minus,
                "zeta_minus": st.zeta_minus, "sigma_plus": st.sigma_plus,
                "zeta_plus": st.zeta_plus, "impulse": list(st.impulse),
                "impulse_friction_ratio": st.impulse_friction_ratio,
                "trailing_foot_lift_velocity": st.trailing_foot_lift_velocity,
                "thrust_at_impact": _names(zd, st.thrust_at_impact),
                "min_vertical_force": st.min_vertical_force,
                "max_friction_ratio": st.max_friction_ratio,
                "max_abs_output": st.max_abs_output,
                "max_abs_output_rate": st.max_abs_output_rate,
                "max_abs_torque": st.max_abs_torque, "torque_saturated": st.torque_saturated,
                "energy_minus": st.energy_minus, "energy_plus": st.energy_plus,
                "impact_energy_loss": st.energy_minus - st.energy_plus,
                **({"terrain_height": st.terrain_height} if terrain else {}),
                "prediction": cmp, "energy": step_block(en)})
    return out


def _steps_text(steps: list[int]) -> str:
    return (f"step {steps[0]}" if len(steps) == 1 else
            f"steps {steps[0]}-{steps[-1]} ({len(steps)} steps)")


def run_entries(zd: ZeroDynamics, sc: Scenario, outcomes: list[Outcome],
                mu: float | None = None) -> list[dict]:
    """The ``runs`` list: status, prediction and final agreement of every run. ``mu`` (default:
    the gait's) is the friction cone the steps are checked against.

    ``status``: ``ok`` (completed, on the prediction, no step out of the friction cone or
    saturating a torque), ``warning`` (completed, but with the deviations of
    :func:`deviations`, slipping or saturated torques; ``reason`` says which and at which
    steps, e.g. ``... (slips at steps 1-2)``) or ``failed`` (stopped early, or no orbit to
    start on: ``failure`` ``no-orbit``). A run is never plain ``ok`` when a step left the
    friction cone or saturated a torque."""
    mu = zd.gait.mu if mu is None else mu
    runs = []
    for i, oc in enumerate(outcomes):
        full, red = oc.full, oc.reduced
        lc = predicted_cycle(zd, oc.thrust)
        primary = oc.primary
        last = primary.steps[-1] if primary is not None and primary.steps else None
        warn = []
        flags: dict[str, list[int]] = {"slips": [], "impact outside the friction cone": [],
                                       "torque saturated": []}
        if full is not None:
            for st in full.steps:
                stance = st.max_friction_ratio
                if stance is not None and stance > mu:
                    flags["slips"].append(st.step)
                if st.impulse_friction_ratio > mu:
                    flags["impact outside the friction cone"].append(st.step)
                broke = ([f"stance {stance:.3g}"] if stance is not None and stance > mu else []) \
                    + ([f"impact {st.impulse_friction_ratio:.3g}"]
                       if st.impulse_friction_ratio > mu else [])
                if broke:  # only the parts that left the cone (|F^h| / F^v)
                    warn.append(f"step {st.step}: friction cone mu = {mu:g} violated "
                                f"({', '.join(broke)})")
                if st.torque_saturated:
                    flags["torque saturated"].append(st.step)
                    warn.append(f"step {st.step}: joint torques saturated")
        if primary is not None:
            warn[:0] = _start_warnings(zd, sc, oc.thrust, lc)
        dev = deviations(oc, sc)
        sched = oc.thrust.schedule if oc.thrust.piecewise else Schedule.constant(
            zd, np.asarray(oc.thrust.target, float)[None, :])
        zero = sched.without_thrust()
        z0 = _zeta_star(zd, zero)
        if primary is None:
            success, failure, reason = False, "no-orbit", oc.no_orbit
        else:
            success, failure, reason = primary.success, primary.failure or None, primary.reason
        status = "failed" if not success else ("warning" if dev or warn else "ok")
        notes = [f"{what} at {_steps_text(st)}" for what, st in flags.items() if st]
        if success and notes:
            reason += f" ({'; '.join(notes)})"
        if success and dev:
            reason += " off the zero-dynamics prediction: " + "; ".join(dev)
        on_slope = {}
        if zd.slope != 0.0:  # SPEC 14: speed along the ground, the climb rate beside it
            v = _speed(zd, full.steps[-1]) if full is not None and full.steps else None
            on_slope = {"speed": v, "climb_rate": climb_rate(v, zd.slope)}
        runs.append({
            "run": i, "f_ss": oc.value, "model": "full-order" if full is not None else "reduced",
            "success": success, "status": status, "failure": failure, "reason": reason,
            "steps_completed": len(primary.steps) if primary is not None else 0,
            "rhs_evaluations": primary.nfev if primary is not None else 0,
            "predicted": {
                "exists": lc.exists, "stable": lc.stable, "reason": lc.reason,
                "zeta_star": lc.zeta_star, "sigma_minus": lc.sigma_minus,
                "step_time": lc.step_time, "speed": lc.speed,
                **({"climb_rate": climb_rate(lc.speed, zd.slope)} if zd.slope != 0.0 else {}),
                "touchdown_velocity": lc.touchdown_velocity,
                "paper_one_step_value": (None if z0 is None else
                                         z0 + float(paper_one_step_shift(zd, sched)[0])),
                "note": "zeta* = V_Z(alpha_f)/(1 - delta_zero^2); "
                        "paper_one_step_value = zeta*_0 + sum_j b_F T_j, the paper's formula "
                        "without 1/(1 - delta_zero^2) (erratum)",
            },
            "final_zeta_minus": last.zeta_minus if last else None,
            "final_relative_error": ((last.zeta_minus - lc.zeta_star) / lc.zeta_star
                                     if last and lc.exists else None),
            "reduced": None if red is None else {
                "success": red.success, "reason": red.reason, "steps_completed": len(red.steps),
                "final_zeta_minus": red.steps[-1].zeta_minus if red.steps else None},
            "deviations": dev,
            "warnings": dev + warn,
            **on_slope,
            "energy": (None if full is None else run_block(simulation_energy(full))),
        })
    return runs


def _start_warnings(zd: ZeroDynamics, sc: Scenario, thrust, lc: LimitCycle) -> list[str]:
    """What a run that started must say about its orbits (SPEC 3): no predicted orbit for its
    thrust (``lc``), and a start on the "predicted" fixed point of a constant thrust at t = 0
    (the thrust itself, or a dynamic thruster's initial value) for which no orbit exists:
    ``zeta* = V_Z(alpha_f)/(1 - delta_zero^2)`` is then a formula's value, not an orbit."""
    st = sc.start
    formula = (st.zeta_minus is None and st.q is None and st.orbit == "predicted"
               and not thrust.piecewise)
    started = ("the run started from the formula's zeta* = V_Z(alpha_f)/(1 - delta_zero^2) "
               "of its thrust at t = 0, which is not an orbit")
    out = [] if lc.exists else [f"{lc.missing}: no prediction to compare with" + (
        f"; {started}" if formula and not thrust.time_dependent else "")]
    if formula and thrust.time_dependent:
        F0 = np.asarray(np.zeros(thrust.m) if thrust.initial is None else thrust.initial, float)
        first = limit_cycles(zd, Schedule.constant(zd, F0[None, :]))[0]
        if not first.exists:
            at = ", ".join(f"{v:g}" for v in F0)
            out.append(f"{started} ({at} N: {first.missing})")
    return out


def _speed(zd: ZeroDynamics, step) -> float | None:
    """Speed of a full-order step along the ground [m/s]: the swing foot's position at the
    impact along the ground (the step length, slope frame) over the step time."""
    length = float(zd.model.p_swing(np.asarray(step.q_minus, float))[0])
    return length / step.step_time if step.step_time > 0 else None


def _zeta_star(zd: ZeroDynamics, sched: Schedule) -> float | None:
    """``zeta*`` of a schedule, None when no orbit exists."""
    lc = limit_cycles(zd, sched)[0]
    return lc.zeta_star if lc.exists else None


def simulation_document(zd: ZeroDynamics, sc: Scenario, outcomes: list[Outcome],
                        mu: float | None = None, warnings: tuple[str, ...] = (),
                        terrain: Terrain | None = None) -> dict:
    """The body of simulation.json (provenance is added by the command). ``success``: every
    run completed its steps; ``status``: ``ok`` (and every run follows the zero-dynamics
    prediction), ``warning`` or ``failed`` (some run did not complete). ``terrain``: the
    terrain the runs walked (SPEC 14), recorded in ``settings.terrain``."""
    runs = run_entries(zd, sc, outcomes, mu)
    bad = [r for r in runs if not r["success"]]
    warned = [r for r in runs if r["status"] == "warning"]
    r = zd.model.robot
    cfg = sc.config
    return {
        "schema_version": SCHEMA_VERSION,
        "units": ({**UNITS, "slope": "rad", "speed": "m/s", "climb_rate": "m/s"}
                  if zd.slope != 0.0 else UNITS),
        "warnings": list(warnings),
        "robot": robot_record(zd),
        "gait": gait_record(zd),
        **({"slope": slope_record(zd.slope)} if zd.slope != 0.0 else {}),
        "zero_dynamics": {"delta_zero": zd.delta_zero, "delta_zero_sq": zd.delta_zero_sq,
                          "fixed_point_formula": "zeta* = V_Z(alpha_f) / (1 - delta_zero^2)"},
        "settings": {
            "thrust_model": sc.kind,
            "thrusters": [r.thruster_names[j] for j in sc.thrusters],
            "f_ss": list(sc.values), "f0": sc.f0,
            **({"wn": sc.wn, "xi": sc.xi, "tau": sc.tau} if sc.dynamics is None else
               {"wn": None, "xi": None, "tau": None,
                "thruster_dynamics": dynamics_record(sc.dynamics)}),
            "start": {"orbit": sc.start.orbit, "zeta_minus": sc.start.zeta_minus,
                      "perturb": sc.start.perturb,
                      "q": None if sc.start.q is None else list(map(float, sc.start.q)),
                      "dq": None if sc.start.dq is None else list(map(float, sc.start.dq))},
            "reduced_only": sc.reduced_only, "steps": cfg.steps, "rtol": cfg.rtol,
            "atol": cfg.atol, "method": cfg.method, "integrator": cfg.integrator,
            "torque_limit": cfg.torque_limit,
            "kp": zd.gait.kp, "kd": zd.gait.kd, "scuff_tolerance": cfg.scuff_tol,
            "mu": zd.gait.mu if mu is None else mu,
            "guard": (f"swing-foot height crosses 0 downward for s > {cfg.min_impact_s:g}"
                      if terrain is None else
                      f"swing-foot height crosses the step's terrain height h_k downward for "
                      f"s > {cfg.min_impact_s:g}, until s = {cfg.max_s:g} (s_max: past it a "
                      f"missed footing)"),
            "min_impact_s": cfg.min_impact_s,
            "early_strike": f"before s = {cfg.min_impact_s:g} the swing foot may touch the "
                            f"ground; a dip deeper than {cfg.scuff_tol:g} m is a scuff",
            "impact_s_tolerance": sc.impact_s_tol, "zeta_tolerance": sc.zeta_tol,
            **({"terrain": terrain.record()} if terrain is not None else {}),
        },
        "success": not bad,
        "status": "failed" if bad else ("warning" if warned else "ok"),
        "reason": ("; ".join(f"run {b['run']} (F_ss = {b['f_ss']}): {b['reason']}"
                             for b in bad + warned) if bad or warned else
                   "all runs completed on the zero-dynamics prediction"),
        "runs": runs,
        "steps": step_entries(zd, outcomes, terrain is not None),
    }


_Z, _S = "kg^2 m^4/s^2", "kg m^2/s"
STEP_COLUMNS = ["run", col("f_ss", "N"), "model", "step", col("t_start", "s"),
                col("step_time", "s"), "s_minus", col("zeta_start", _Z), col("sigma_minus", _S),
                col("zeta_minus", _Z), col("sigma_plus", _S), col("zeta_plus", _Z),
                col("impulse_x", "N s"), col("impulse_y", "N s"),
                col("min_vertical_force", "N"), "max_friction_ratio",
                col("max_abs_output", "rad"), col("max_abs_torque", "N m"),
                col("impact_energy_loss", "J"), col("predicted_zeta_minus", _Z),
                "relative_error", col("zeta_star", _Z), col("reduced_zeta_minus", _Z),
                col("orbit_distance_q", "rad"), col("orbit_distance_dq", "rad/s")]
# the step's energies (SPEC 15), after the thrust and terrain columns
ENERGY_COLUMNS = [col("legs_mechanical", "J"), col("thrust_mechanical", "J"),
                  col("legs_electrical", "J"), col("thrust_input", "J"),
                  col("kinetic_impact_loss", "J"), col("work_energy_residual", "J"),
                  "cot_mechanical", "cot_mechanical_legs", "cot_mechanical_thrust",
                  "cot_total", "cot_total_legs", "cot_total_thrust"]
_COT = ("mechanical", "mechanical_legs", "mechanical_thrust", "total", "total_legs",
        "total_thrust")


def energy_cells(en: dict | None) -> list:
    """The :data:`ENERGY_COLUMNS` cells of a step entry's ``energy`` block (empty: none)."""
    if not en:
        return [None] * len(ENERGY_COLUMNS)
    p, c = en["per_step"], en["cot"]
    return ([p["legs_mechanical"], p["thrust_mechanical"], p["legs_electrical"],
             p["thrust_input"], p["impact_loss"], en["work_energy_residual"]]
            + [c[k] for k in _COT])


def energy_notes(doc: dict) -> list[str]:
    """The CSV comment lines of the runs' missing power models (once each)."""
    seen: list[str] = []
    for r in doc["runs"]:
        for line in (r.get("energy") or {}).get("missing", []):
            if line not in seen:
                seen.append(line)
    return [f"energy: {line}" for line in seen]


def steps_table(doc: dict, thruster_names: list[str]) -> Table:
    """steps.csv (header, rows, comments) from the document's ``steps`` list."""
    terrain = "terrain" in doc["settings"]
    header = (STEP_COLUMNS + [col(f"thrust_{n}", "N") for n in thruster_names]
              + ([col("terrain_height", "m")] if terrain else []) + ENERGY_COLUMNS)
    rows = []
    for e in doc["steps"]:
        p = e.get("prediction") or {}
        od = p.get("orbit_distance") or {}
        imp = e.get("impulse") or [None, None]
        rows.append([e["run"], e["f_ss"], e["model"], e["step"], e["t_start"], e["step_time"],
                     e.get("s_minus"), e["zeta_start"], e["sigma_minus"], e["zeta_minus"],
                     e["sigma_plus"], e["zeta_plus"], imp[0], imp[1],
                     e.get("min_vertical_force"), e.get("max_friction_ratio"),
                     e.get("max_abs_output"), e.get("max_abs_torque"),
                     e.get("impact_energy_loss"), p.get("zeta_minus"),
                     p.get("relative_error"), p.get("zeta_star"), p.get("reduced_zeta_minus"),
                     od.get("q"), od.get("dq")]
                    + [e["thrust_at_impact"][n] for n in thruster_names]
                    + ([e.get("terrain_height")] if terrain else [])
                    + energy_cells(e.get("energy")))
    return Table(header, rows, [
        "thrustwalk simulate: one row per step (pre-impact '_minus', post-impact '_plus')",
        "units: time s, zeta kg^2 m^4/s^2, sigma kg m^2/s, impulse N s, force N, torque N m, "
        "output rad, energy J, thrust N; empty = not computed (reduced model) or no orbit",
        "energy columns (SPEC 15): along the full-order step; cot over m g times the step's "
        "length; empty = not computed (reduced model, or the model named below is missing)",
        *energy_notes(doc),
    ])


def trajectory_arrays(zd: ZeroDynamics, outcomes: list[Outcome]) -> dict[str, np.ndarray]:
    """All sampled time histories as named columns (``run`` tells the runs apart)."""
    r = zd.model.robot
    cols: dict[str, list] = {}
    for i, oc in enumerate(outcomes):
        tr = oc.primary.trajectory if oc.primary is not None else {}
        if not tr:
            continue
        n = tr["t"].size
        base = {"run": np.full(n, i), col("f_ss", "N"): np.full(
                    n, np.nan if oc.value is None else oc.value),
                "step": tr["step"], col("t", "s"): tr["t"], col("alpha", "rad"): tr["alpha"],
                col("alpha_dot", "rad/s"): tr["alpha_dot"], col("sigma", _S): tr["sigma"],
                col("zeta", _Z): 0.5 * tr["sigma"] ** 2}
        for j, name in enumerate(r.thruster_names):
            base[col(f"thrust_{name}", "N")] = tr["F"][:, j]
        base[col("generalized_T", "N m")] = tr["T"]
        if oc.full is not None:
            act = [c.name for c in r.coordinates if c.actuated]
            for j, name in enumerate(r.coordinate_names):
                base[col(f"q_{name}", "rad")] = tr["q"][:, j]
                base[col(f"dq_{name}", "rad/s")] = tr["dq"][:, j]
            for j, name in enumerate(act):
                base[col(f"u_{name}", "N m")] = tr["u"][:, j]
                base[col(f"y_{name}", "rad")] = tr["y"][:, j]
            base[col("F1_x", "N")], base[col("F1_y", "N")] = tr["F1"][:, 0], tr["F1"][:, 1]
            base[col("swing_height", "m")] = tr["swing_height"]
            base[col("stance_foot_x", "m")] = tr["foot_x"]
            base[col("energy", "J")] = tr["energy"]
        for k, v in base.items():
            cols.setdefault(k, []).append(np.asarray(v, float))
    return {k: np.concatenate(v) for k, v in cols.items()}


def trajectory_rows(outcomes: list[Outcome]) -> int:
    """The rows :func:`trajectory_arrays` has, without sampling a run whose samples were not
    read yet (``Trajectory.rows``)."""
    total = 0
    for oc in outcomes:
        tr = oc.primary.trajectory if oc.primary is not None else {}
        if tr:
            total += tr.rows if hasattr(tr, "rows") else int(np.asarray(tr["t"]).size)
    return total


def trajectory_output(zd: ZeroDynamics, outcomes: list[Outcome],
                      provenance: dict | None = None) -> tuple[str, object]:
    """``("csv", {header, rows, comments})`` or, above CSV_ROW_LIMIT rows, ``("npz", bytes)``.
    Columns missing for a run (reduced model) are empty in CSV and NaN in NPZ; the NPZ holds
    ``provenance`` as a JSON string."""
    arrays = trajectory_arrays(zd, outcomes)
    if not arrays:
        return "csv", Table(["t"], [], ["no samples"])
    n = arrays[col("t", "s")].size
    if n > CSV_ROW_LIMIT:
        buf = io.BytesIO()
        extra = {} if provenance is None else {"provenance": np.array(json.dumps(provenance))}
        np.savez_compressed(buf, **arrays, **extra)
        return "npz", buf.getvalue()
    header = list(arrays)
    mat = np.column_stack([arrays[k] for k in header])
    rows = [[None if not np.isfinite(v) else (int(v) if k in ("run", "step") else float(v))
             for k, v in zip(header, row)] for row in mat]
    return "csv", Table(header, rows, [
        "thrustwalk simulate: sampled time histories (uniform in time within each step)",
        "units: t s, q rad, dq rad/s, alpha rad, alpha_dot rad/s, sigma kg m^2/s, zeta "
        "kg^2 m^4/s^2, thrust N, generalized_T N m (piecewise generalised mode), u N m, "
        "y rad, F1 N (ground reaction on the stance foot), "
        "heights and positions m, energy J",
    ])


# ----------------------------------------------------------------------------- figure data
def figure_data(zd: ZeroDynamics, sc: Scenario, outcomes: list[Outcome]) -> dict:
    """Thrust histories and phase-plane curves per run, with the predicted orbits."""
    runs = []
    for oc in outcomes:
        tr = oc.primary.trajectory if oc.primary is not None else {}
        lc = predicted_cycle(zd, oc.thrust)
        j = sc.thrusters[0] if sc.thrusters else None
        steps = []
        curves = getattr(oc.primary, "phase_curves", None)
        if tr and curves is not None:  # the full-order run's dense output, fast parts refined
            for pieces in curves(sc.config.samples_per_step):
                steps.append({key: np.concatenate([p[key] for p in pieces])
                              for key in ("alpha", "alpha_dot")})
        elif tr:
            for k in np.unique(tr["step"]):
                sel = tr["step"] == k
                steps.append({"alpha": tr["alpha"][sel], "alpha_dot": tr["alpha_dot"][sel]})
        runs.append({
            "value": oc.value,
            "t": tr["t"] if tr else np.zeros(0),
            "thrust": (tr["F"][:, j] if (tr and j is not None) else
                       np.zeros(tr["t"].size) if (tr and sc.kind != "piecewise") else
                       (tr["F"] if tr else np.zeros((0, zd.model.n_thrusters)))),
            "T": tr["T"] if tr else np.zeros(0),
            "steps": steps,
            "predicted": ({"alpha": lc.orbit["alpha"], "alpha_dot": lc.orbit["alpha_dot"]}
                          if lc.exists else None),
            "failed": not oc.success,
        })
    generalized = bool(sc.kind == "piecewise" and np.any(sc.schedule.generalized))
    return {"runs": runs, "thruster_names": zd.model.robot.thruster_names,
            "generalized": generalized,
            "driven": [zd.model.robot.thruster_names[j] for j in sc.thrusters],
            "kind": sc.kind, "model": "reduced" if sc.reduced_only else "full-order"}


def animation_frames(zd: ZeroDynamics, outcome: Outcome, fps: float = 20.0,
                     max_frames: int = 400) -> dict:
    """Stick-figure frames of a full-order run in world coordinates [m] (on a slope, the slope
    frame: x along the ground, y normal to it): per frame the links
    ``(n_links, 2, 2)``, thruster points and thrust vectors ``(m, 2)`` [N], and the time."""
    full = outcome.full
    if full is None or not full.trajectory:
        raise InputError.param("animate", "needs a full-order run with at least one sample "
                                          "(not `reduced`)")
    tr = full.trajectory
    t = tr["t"]
    n = int(min(max_frames, max(2, (t[-1] - t[0]) * fps)))
    idx = np.unique(np.searchsorted(t, np.linspace(t[0], t[-1], n)).clip(0, t.size - 1))
    model = zd.model
    q = tr["q"][idx]
    lp = model.link_points(q).reshape(idx.size, -1, 2, 2)
    off = np.stack([tr["foot_x"][idx], np.zeros(idx.size)], axis=-1)
    lp = lp + off[:, None, None, :]
    pts = np.swapaxes(model.thruster_points(q), -1, -2) + off[:, None, :]
    dirs = np.swapaxes(model.thruster_dirs(q), -1, -2)
    vec = dirs * tr["F"][idx][:, :, None]
    lg = legs(model)
    roles = ["stance" if i in lg.stance else "swing" if i in lg.swing else "body"
             for i in range(model.n)]
    hip = lp[:, lg.hip, 0, :]  # the hip: origin of the first link past the stance leg
    return {"t": t[idx], "links": lp, "points": pts, "thrust": vec, "roles": roles,
            "hip": hip, "thruster_names": model.robot.thruster_names,
            "title": f"{model.robot.name} / {zd.gait.name}"
                     + (f", F_ss = {outcome.value:g} N" if outcome.value is not None else "")
                     + (f", slope {zd.slope:.4g} rad (slope frame: the ground drawn level)"
                        if zd.slope != 0.0 else "")}



@dataclass(frozen=True)
class SimulationResult:
    """Full-order runs of one scenario (one per steady thrust value), each with the reduced
    cascade and the per-step comparison with the zero-dynamics prediction (SPEC 3, 7).

    ``success``: every run completed its steps; ``status``: ``ok`` when every run also follows
    the zero-dynamics prediction, ``warning`` when a completed run leaves it (an impact away
    from s = 1, zeta^- off the prediction: a grazing or missed touchdown), ``failed``
    otherwise; ``reason`` names the runs that failed or were warned about. A steady thrust
    without a periodic orbit to start on is a failed run (``no-orbit``); the others still run.
    ``tool_failure``: a run ended by an integrator or controller failure (not physics).
    """

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    scenario: Scenario
    outcomes: tuple[Outcome, ...]
    mu: float | None = None
    terrain: Terrain | None = None

    name = "simulation"

    def runs(self) -> list[dict]:
        """Per run: status (``ok``, ``warning``, ``failed``) with its reason, prediction and
        final agreement."""
        return run_entries(self.walker.zd, self.scenario, list(self.outcomes), self.mu)

    @property
    def success(self) -> bool:
        """Every run completed without failing."""
        return all(oc.success for oc in self.outcomes)

    @property
    def status(self) -> str:
        """``ok``, ``warning`` (completed, but off the zero-dynamics prediction: see
        ``reason``) or ``failed``."""
        return simulation_document(self.walker.zd, self.scenario, list(self.outcomes),
                                   self.mu, terrain=self.terrain)["status"]

    @property
    def reason(self) -> str:
        """The document's ``reason``: what failed or left the prediction, or that every run went
        well."""
        return self.document()["reason"]

    @property
    def tool_failure(self) -> bool:
        """Some run failed in the tool (integrator or controller), not as a walker."""
        return any(oc.primary is not None and oc.primary.failure in ("integrator", "controller")
                   for oc in self.outcomes)

    def _trajectory(self, provenance: dict | None = None) -> tuple[str, object]:
        return trajectory_output(self.walker.zd, list(self.outcomes), provenance=provenance)

    def document(self) -> dict:
        """The JSON body of ``simulation.json``."""
        zd = self.walker.zd
        kind = "npz" if trajectory_rows(list(self.outcomes)) > CSV_ROW_LIMIT else "csv"
        return {**simulation_document(zd, self.scenario, list(self.outcomes), self.mu,
                                      self.walker.warnings, self.terrain),
                "trajectory_file": f"trajectory.{kind}"}

    def tables(self) -> dict[str, Table]:
        """``steps`` (one row per step) and ``trajectory`` (sampled time histories, unless
        they are too long for CSV: then ``trajectory.npz`` is an attachment)."""
        out = {"steps": steps_table(self.document(), self.walker.robot.thruster_names)}
        kind, traj = self._trajectory()
        if kind == "csv":
            out["trajectory"] = traj
        return out

    def attachments(self, doc: dict) -> dict[str, bytes]:
        """``trajectory.npz`` (with the provenance of ``doc``) when the trajectory is long."""
        kind, traj = self._trajectory(doc.get("provenance"))
        return {"trajectory.npz": traj} if kind == "npz" else {}

    def figures(self, titles: bool = False) -> dict:
        """``thrust_time`` (the paper's figure 1) and ``phase_portrait`` (figure 2)."""
        from ..plots.simulate import phase_portrait, thrust_time

        data = figure_data(self.walker.zd, self.scenario, list(self.outcomes))
        name = self.walker.name
        return {"thrust_time": thrust_time(data, title=f"{name}: thrust" if titles else ""),
                "phase_portrait": phase_portrait(
                    data, title=f"{name}: limit cycles" if titles else "")}

    def animation(self) -> bytes | None:
        """A GIF of the last full-order run with samples (the stick figure walking, thrust
        vectors drawn), or None when no run has anything to animate."""
        from ..plots.simulate import animate

        runs = [oc for oc in self.outcomes if oc.full is not None and oc.full.trajectory]
        return animate(animation_frames(self.walker.zd, runs[-1])) if runs else None
