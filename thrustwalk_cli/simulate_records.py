"""Scenarios of ``thrustwalk simulate`` and the records rendered from them (SPEC 3, 7).

A scenario is one thrust model and a sweep of ``F_ss`` values [N] (one full-order run per
value, each with the reduced cascade of SPEC 3 run from the same initial state). Every step of
the full-order run is compared with the zero-dynamics prediction:

* thrust a function of alpha (constant, piecewise): ``zeta^-_pred = zeta_start + V_Z(alpha_f)``
  (SPEC 3, closed form, from the simulated post-impact value);
* thrust a function of time (first-/second-order): one step of the reduced cascade from the
  simulated post-impact ``(alpha, sigma_N, thruster state)``.

Documents for JSON/CSV/NPZ and figure data are plain Python built here, so the command only
writes them. Units: SI (zeta in kg^2 m^4/s^2, sigma in kg m^2/s).
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .closed_loop import (
    THRUST_MODELS,
    ThrustModel,
    predicted_cycle,
    schedule_from_gait,
    zeta_star_at,
)
from .errors import InputError
from .simulate import SimConfig, SimResult, Start, initial_state, simulate
from .simulate_reduced import ReducedModel, ReducedResult, predict_step, simulate_reduced
from .zero_dynamics import Schedule, ZeroDynamics, gait_record, paper_one_step_shift, thruster_index

UNITS = {
    "time": "s", "thrust": "N", "generalized_thrust": "N m", "alpha": "rad",
    "alpha_dot": "rad/s", "sigma_N": "kg m^2/s", "zeta": "kg^2 m^4/s^2 (zeta = sigma_N^2/2)",
    "impulse": "N s", "force": "N", "torque": "N m", "output_y": "rad", "output_rate": "rad/s",
    "energy": "J", "orbit_distance": "rad (q), rad/s (dq), max norm", "wn": "rad/s",
    "tau": "s", "velocity": "m/s",
}
CSV_ROW_LIMIT = 20000  # trajectories with more samples go to .npz


@dataclass(frozen=True)
class Scenario:
    """What to simulate: thrust model ``kind`` driven at each of ``values`` [N] on the
    thrusters ``thrusters`` (indices), ``wn`` [rad/s], ``xi`` [1], ``tau`` [s], initial
    thrust ``f0`` [N]; ``reduced_only`` skips the full-order model (the fast preview)."""

    kind: str
    values: tuple[float, ...]
    thrusters: tuple[int, ...]
    wn: float = 2.0
    xi: float = 1.0
    tau: float = 0.5
    f0: float = 0.0
    start: Start = Start()
    config: SimConfig = SimConfig()
    reduced_only: bool = False


@dataclass(frozen=True)
class Outcome:
    """One run: the sweep value (None for piecewise), its thrust model, the full-order result
    (None for ``reduced_only``), the reduced cascade and the per-step comparison."""

    value: float | None
    thrust: ThrustModel
    full: SimResult | None
    reduced: ReducedResult
    comparison: tuple[dict, ...]


def make_scenario(zd: ZeroDynamics, kind: str, values: list[float] | None,
                  thrusters: list[str] | None, **kw) -> Scenario:
    """Validate options into a :class:`Scenario`; :class:`InputError` names the option."""
    model = zd.model
    problems = []
    if kind not in THRUST_MODELS:
        raise InputError(f"option --thrust-model: unknown model {kind!r} (choose from "
                         f"{', '.join(THRUST_MODELS)})")
    if kind == "piecewise":
        if values is not None:
            raise InputError("option --f-ss: not used with --thrust-model piecewise (the "
                             "schedule comes from the gait's thrust: section)")
        if thrusters:
            raise InputError("option --thruster: not used with --thrust-model piecewise")
        schedule_from_gait(zd, zd.gait.thrust)  # raises when missing or malformed
        idx: tuple[int, ...] = ()
        values = []
    else:
        names = thrusters or [None]
        idx = tuple(thruster_index(model, n) for n in names)
        if len(set(idx)) != len(idx):
            raise InputError("option --thruster: a thruster is named twice")
        for j in idx:
            lo, hi = model.robot.thrusters[j].limits
            for v in list(values or []) + [kw.get("f0", 0.0)]:
                if not lo <= v <= hi:
                    problems.append(f"option --f-ss/--f0: {v:g} N is outside the limits "
                                    f"[{lo:g}, {hi:g}] N of thruster "
                                    f"{model.robot.thruster_names[j]}")
    for key, opt, unit in (("wn", "--wn", "rad/s"), ("xi", "--xi", ""), ("tau", "--tau", "s")):
        if key in kw and not kw[key] > 0:
            problems.append(f"option {opt}: must be > 0{' ' + unit if unit else ''} "
                            f"(got {kw[key]:g})")
    if problems:
        raise InputError(sorted(set(problems)))
    kw["config"].validate()
    return Scenario(kind, tuple(values), idx, **kw)


def thrust_models(zd: ZeroDynamics, sc: Scenario) -> list[tuple[float | None, ThrustModel]]:
    """One :class:`ThrustModel` per sweep value (a single one for piecewise)."""
    m = zd.model.n_thrusters
    if sc.kind == "piecewise":
        sched = schedule_from_gait(zd, zd.gait.thrust)
        return [(None, ThrustModel("piecewise", np.zeros(m), schedule=sched))]
    out = []
    for v in sc.values:
        target = np.zeros(m)
        f0 = np.zeros(m)
        target[list(sc.thrusters)] = v
        f0[list(sc.thrusters)] = sc.f0
        out.append((v, ThrustModel(sc.kind, target, wn=sc.wn, xi=sc.xi, tau=sc.tau,
                                   initial=f0)))
    return out


def run_scenario(zd: ZeroDynamics, sc: Scenario,
                 progress: Callable[[int], None] | None = None) -> list[Outcome]:
    """Run every sweep value (full order unless ``reduced_only``, plus the cascade).
    ``progress(1)`` after every step of the primary model."""
    rm = ReducedModel(zd)
    cfg = sc.config
    N = zd.model.n
    out = []
    for value, th in thrust_models(zd, sc):
        x0 = initial_state(zd, th, sc.start)
        D0 = np.array(zd.model.D_s(x0[:N].tolist())).reshape(N, N)
        a0, s0 = float(zd.maps.c @ x0[:N]), float(D0[N - 1] @ x0[N:2 * N])
        pred = predicted_cycle(zd, th)
        t_max = cfg.max_step_time or (10.0 * pred.step_time if pred.exists else 10.0)
        full = None
        if not sc.reduced_only:
            full = simulate(zd, th, cfg, sc.start, progress)
        red = simulate_reduced(zd, th, cfg.steps, a0, s0, x0[2 * N:].tolist(), rtol=cfg.rtol,
                               atol=cfg.atol, method=cfg.method,
                               samples_per_step=cfg.samples_per_step, max_step_time=t_max,
                               progress=progress if sc.reduced_only else None, model=rm)
        comp = tuple(compare_steps(zd, th, full, red, rm)) if full is not None else ()
        out.append(Outcome(value, th, full, red, comp))
    return out


def compare_steps(zd: ZeroDynamics, th: ThrustModel, full: SimResult, red: ReducedResult,
                  rm: ReducedModel) -> list[dict]:
    """Zero-dynamics prediction of every full-order step (see the module docstring)."""
    V = _V_f(zd, th)
    pred = full.prediction
    ref_q = ref_dq = None
    if pred.exists:
        t = zd.terms(np.array([zd.alpha_f]))
        ref_q = zd.maps.q_minus
        ref_dq = t["Phi"][0] * t["kappa1"][0] * pred.sigma_minus
    out = []
    for st in full.steps:
        if th.time_dependent:
            zp = predict_step(zd, th, st.alpha_start, st.sigma_start, list(st.z_start),
                              rtol=full.config.rtol, atol=full.config.atol, model=rm)
            method = "reduced cascade over one step from the simulated post-impact state"
            zs = zeta_star_at(zd, np.array(st.thrust_at_impact))
        else:
            zp = st.zeta_start + V
            method = "zeta^+ (simulated) + V_Z(alpha_f)"
            zs = pred.zeta_star
        rs = red.steps[st.step - 1] if st.step <= len(red.steps) else None
        rec = {
            "method": method,
            "zeta_minus": zp,
            "relative_error": None if zp is None else (st.zeta_minus - zp) / zp,
            "zeta_star": zs if zs is not None and zs > 0 else None,
            "reduced_zeta_minus": rs.zeta_minus if rs else None,
            "reduced_relative_error": ((st.zeta_minus - rs.zeta_minus) / rs.zeta_minus
                                       if rs else None),
            "reduced_step_time": rs.step_time if rs else None,
        }
        if ref_q is not None:
            rec["orbit_distance"] = {
                "q": float(np.abs(np.array(st.q_minus) - ref_q).max()),
                "dq": float(np.abs(np.array(st.dq_minus) - ref_dq).max())}
        else:
            rec["orbit_distance"] = None
        out.append(rec)
    return out


def _V_f(zd: ZeroDynamics, th: ThrustModel) -> float:
    sched = th.schedule if th.kind == "piecewise" else Schedule.constant(
        zd, np.asarray(th.target, float)[None, :])
    return float(zd.V_Z(np.array(zd.alpha_f), sched)[0])


# ----------------------------------------------------------------------------- documents
def _names(zd: ZeroDynamics, values) -> dict:
    return dict(zip(zd.model.robot.thruster_names, map(float, values)))


def step_entries(zd: ZeroDynamics, outcomes: list[Outcome]) -> list[dict]:
    """The ``steps`` list of simulation.json (one entry per step of every run)."""
    out = []
    for i, oc in enumerate(outcomes):
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
        for st, cmp in zip(oc.full.steps, oc.comparison):
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
                "prediction": cmp})
    return out


def run_entries(zd: ZeroDynamics, outcomes: list[Outcome]) -> list[dict]:
    """The ``runs`` list: status, prediction and final agreement of every run."""
    runs = []
    for i, oc in enumerate(outcomes):
        full, red = oc.full, oc.reduced
        lc = predicted_cycle(zd, oc.thrust)
        primary = full if full is not None else red
        last = primary.steps[-1] if primary.steps else None
        warn = []
        if full is not None:
            mu = zd.gait.mu
            for st in full.steps:
                stance = st.max_friction_ratio
                if (stance is not None and stance > mu) or st.impulse_friction_ratio > mu:
                    warn.append(f"step {st.step}: friction cone mu = {mu:g} violated (stance "
                                f"{stance if stance is None else format(stance, '.3g')}, "
                                f"impact {st.impulse_friction_ratio:.3g})")
                if st.torque_saturated:
                    warn.append(f"step {st.step}: joint torques saturated")
        sched = oc.thrust.schedule if oc.thrust.kind == "piecewise" else Schedule.constant(
            zd, np.asarray(oc.thrust.target, float)[None, :])
        zero = Schedule(sched.knots, np.zeros_like(sched.force), np.zeros_like(sched.generalized))
        z0 = limit_cycles_zeta(zd, zero)
        runs.append({
            "run": i, "f_ss": oc.value, "model": "full-order" if full is not None else "reduced",
            "success": primary.success, "failure": primary.failure or None,
            "reason": primary.reason, "steps_completed": len(primary.steps),
            "wall_time": primary.wall_time, "rhs_evaluations": primary.nfev,
            "predicted": {
                "exists": lc.exists, "stable": lc.stable, "reason": lc.reason,
                "zeta_star": lc.zeta_star, "sigma_minus": lc.sigma_minus,
                "step_time": lc.step_time, "speed": lc.speed,
                "paper_one_step_value": (None if z0 is None else
                                         z0 + float(paper_one_step_shift(zd, sched)[0])),
                "note": "zeta* = V_Z(alpha_f)/(1 - delta_zero^2) (SPEC 4); "
                        "paper_one_step_value = zeta*_0 + sum_j b_F T_j, the paper's formula "
                        "without 1/(1 - delta_zero^2) (erratum)",
            },
            "final_zeta_minus": last.zeta_minus if last else None,
            "final_relative_error": ((last.zeta_minus - lc.zeta_star) / lc.zeta_star
                                     if last and lc.exists else None),
            "reduced": {"success": red.success, "reason": red.reason,
                        "steps_completed": len(red.steps), "wall_time": red.wall_time,
                        "final_zeta_minus": red.steps[-1].zeta_minus if red.steps else None},
            "warnings": warn,
        })
    return runs


def limit_cycles_zeta(zd: ZeroDynamics, sched: Schedule) -> float | None:
    """``zeta*`` of a schedule, None when no orbit exists."""
    from .zero_dynamics import limit_cycles

    lc = limit_cycles(zd, sched)[0]
    return lc.zeta_star if lc.exists else None


def simulation_document(zd: ZeroDynamics, sc: Scenario, outcomes: list[Outcome]) -> dict:
    """The body of simulation.json (provenance is added by the command)."""
    runs = run_entries(zd, outcomes)
    bad = [r for r in runs if not r["success"]]
    r = zd.model.robot
    cfg = sc.config
    return {
        "units": UNITS,
        "robot": {"name": r.name, "file": r.source_file, "coordinates": r.coordinate_names,
                  "thrusters": r.thruster_names},
        "gait": gait_record(zd),
        "zero_dynamics": {"delta_zero": zd.delta_zero, "delta_zero_sq": zd.delta_zero_sq,
                          "fixed_point_formula": "zeta* = V_Z(alpha_f) / (1 - delta_zero^2)"},
        "settings": {
            "thrust_model": sc.kind,
            "thrusters": [r.thruster_names[j] for j in sc.thrusters],
            "f_ss": list(sc.values), "wn": sc.wn, "xi": sc.xi, "tau": sc.tau, "f0": sc.f0,
            "start": {"orbit": sc.start.orbit, "zeta_minus": sc.start.zeta_minus,
                      "perturb": sc.start.perturb,
                      "q": None if sc.start.q is None else list(map(float, sc.start.q)),
                      "dq": None if sc.start.dq is None else list(map(float, sc.start.dq))},
            "reduced_only": sc.reduced_only, "steps": cfg.steps, "rtol": cfg.rtol,
            "atol": cfg.atol, "method": cfg.method, "torque_limit": cfg.torque_limit,
            "kp": zd.gait.kp, "kd": zd.gait.kd, "scuff_tolerance": cfg.scuff_tol,
            "guard": f"swing-foot height crosses 0 downward for s > {cfg.guard_s:g}",
        },
        "success": not bad,
        "reason": ("all runs completed" if not bad else
                   "; ".join(f"run {b['run']} (F_ss = {b['f_ss']}): {b['reason']}"
                             for b in bad)),
        "runs": runs,
        "steps": step_entries(zd, outcomes),
    }


STEP_COLUMNS = ["run", "f_ss", "model", "step", "t_start", "step_time", "s_minus",
                "zeta_start", "sigma_minus", "zeta_minus", "sigma_plus", "zeta_plus",
                "impulse_x", "impulse_y", "min_vertical_force", "max_friction_ratio",
                "max_abs_output", "max_abs_torque", "impact_energy_loss",
                "predicted_zeta_minus", "relative_error", "zeta_star", "reduced_zeta_minus",
                "orbit_distance_q", "orbit_distance_dq"]


def steps_table(doc: dict, thruster_names: list[str]) -> dict:
    """steps.csv (header, rows, comments) from the document's ``steps`` list."""
    header = STEP_COLUMNS + [f"thrust_{n}" for n in thruster_names]
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
                    + [e["thrust_at_impact"][n] for n in thruster_names])
    return {"header": header, "rows": rows, "comments": [
        "thrustwalk simulate: one row per step (pre-impact '_minus', post-impact '_plus')",
        "units: time s, zeta kg^2 m^4/s^2, sigma kg m^2/s, impulse N s, force N, torque N m, "
        "output rad, energy J, thrust N; empty = not computed (reduced model) or no orbit",
    ]}


def trajectory_arrays(zd: ZeroDynamics, outcomes: list[Outcome]) -> dict[str, np.ndarray]:
    """All sampled time histories as named columns (``run`` tells the runs apart)."""
    r = zd.model.robot
    cols: dict[str, list] = {}
    for i, oc in enumerate(outcomes):
        tr = oc.full.trajectory if oc.full is not None else oc.reduced.trajectory
        if not tr:
            continue
        n = tr["t"].size
        base = {"run": np.full(n, i), "f_ss": np.full(n, np.nan if oc.value is None
                                                        else oc.value),
                "step": tr["step"], "t": tr["t"], "alpha": tr["alpha"],
                "alpha_dot": tr["alpha_dot"], "sigma": tr["sigma"],
                "zeta": 0.5 * tr["sigma"] ** 2}
        for j, name in enumerate(r.thruster_names):
            base[f"thrust_{name}"] = tr["F"][:, j]
        base["generalized_T"] = tr["T"]
        if oc.full is not None:
            act = [c.name for c in r.coordinates if c.actuated]
            for j, name in enumerate(r.coordinate_names):
                base[f"q_{name}"] = tr["q"][:, j]
                base[f"dq_{name}"] = tr["dq"][:, j]
            for j, name in enumerate(act):
                base[f"u_{name}"] = tr["u"][:, j]
                base[f"y_{name}"] = tr["y"][:, j]
            base["F1_x"], base["F1_y"] = tr["F1"][:, 0], tr["F1"][:, 1]
            base["swing_height"] = tr["swing_height"]
            base["stance_foot_x"] = tr["foot_x"]
            base["energy"] = tr["energy"]
        for k, v in base.items():
            cols.setdefault(k, []).append(np.asarray(v, float))
    return {k: np.concatenate(v) for k, v in cols.items()}


def trajectory_output(zd: ZeroDynamics, outcomes: list[Outcome],
                      provenance: dict | None = None) -> tuple[str, object]:
    """``("csv", {header, rows, comments})`` or, above CSV_ROW_LIMIT rows, ``("npz", bytes)``.
    Columns missing for a run (reduced model) are empty in CSV and NaN in NPZ; the NPZ holds
    ``provenance`` as a JSON string."""
    arrays = trajectory_arrays(zd, outcomes)
    if not arrays:
        return "csv", {"header": ["t"], "rows": [], "comments": ["no samples"]}
    n = arrays["t"].size
    if n > CSV_ROW_LIMIT:
        buf = io.BytesIO()
        extra = {} if provenance is None else {"provenance": np.array(json.dumps(provenance))}
        np.savez_compressed(buf, **arrays, **extra)
        return "npz", buf.getvalue()
    header = list(arrays)
    mat = np.column_stack([arrays[k] for k in header])
    rows = [[None if not np.isfinite(v) else (int(v) if k in ("run", "step") else float(v))
             for k, v in zip(header, row)] for row in mat]
    return "csv", {"header": header, "rows": rows, "comments": [
        "thrustwalk simulate: sampled time histories (uniform in time within each step)",
        "units: t s, q rad, dq rad/s, alpha rad, alpha_dot rad/s, sigma kg m^2/s, zeta "
        "kg^2 m^4/s^2, thrust N, generalized_T N m (piecewise generalised mode), u N m, "
        "y rad, F1 N (ground reaction on the stance foot), "
        "heights and positions m, energy J",
    ]}


# ----------------------------------------------------------------------------- figure data
def figure_data(zd: ZeroDynamics, sc: Scenario, outcomes: list[Outcome]) -> dict:
    """Thrust histories and phase-plane curves per run, with the predicted orbits."""
    runs = []
    for oc in outcomes:
        tr = oc.full.trajectory if oc.full is not None else oc.reduced.trajectory
        lc = predicted_cycle(zd, oc.thrust)
        j = sc.thrusters[0] if sc.thrusters else None
        steps = []
        if tr:
            for k in np.unique(tr["step"]):
                sel = tr["step"] == k
                steps.append({"alpha": tr["alpha"][sel], "alpha_dot": tr["alpha_dot"][sel]})
        runs.append({
            "value": oc.value,
            "t": tr["t"] if tr else np.zeros(0),
            "thrust": (tr["F"][:, j] if (tr and j is not None) else
                       (tr["F"] if tr else np.zeros((0, zd.model.n_thrusters)))),
            "T": tr["T"] if tr else np.zeros(0),
            "steps": steps,
            "predicted": ({"alpha": lc.orbit["alpha"], "alpha_dot": lc.orbit["alpha_dot"]}
                          if lc.exists else None),
            "failed": not (oc.full or oc.reduced).success,
        })
    generalized = bool(sc.kind == "piecewise" and np.any(
        schedule_from_gait(zd, zd.gait.thrust).generalized))
    return {"runs": runs, "thruster_names": zd.model.robot.thruster_names,
            "generalized": generalized,
            "driven": [zd.model.robot.thruster_names[j] for j in sc.thrusters],
            "kind": sc.kind, "model": "reduced" if sc.reduced_only else "full-order"}


def animation_frames(zd: ZeroDynamics, outcome: Outcome, fps: float = 20.0,
                     max_frames: int = 400) -> dict:
    """Stick-figure frames of a full-order run in world coordinates [m]: per frame the links
    ``(n_links, 2, 2)``, thruster points and thrust vectors ``(m, 2)`` [N], and the time."""
    full = outcome.full
    if full is None or not full.trajectory:
        raise InputError("option --animate: needs a full-order run with at least one sample "
                         "(not --reduced)")
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
    return {"t": t[idx], "links": lp, "points": pts, "thrust": vec,
            "thruster_names": model.robot.thruster_names,
            "title": f"{model.robot.name} / {zd.gait.name}"
                     + (f", F_ss = {outcome.value:g} N" if outcome.value is not None else "")}
