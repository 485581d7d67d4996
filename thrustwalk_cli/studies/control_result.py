"""The result of the ``control`` study (SPEC 11): :class:`ControlResult`, the controlled run
beside the uncontrolled one (and, for slow thrusters, the run whose controller ignores the
lag), rendered as ``control.json``, its CSV tables and its figures. Running the study is
:mod:`.control`. Units SI.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..contact.terms import fit_terms
from ..controller.loop import (
    Run,
)
from ..controller.planner import (
    Planner,
)
from ..controller.step_model import IdealThrust
from ..energetics.run import run_block, run_energy, step_block
from ..walker import Walker
from .documents import (
    SCHEMA_VERSION,
    Table,
    col,
    gait_record,
    result_repr,
    robot_record,
    slope_record,
    units,
)

UNITS = units("thrust", "alpha", "zeta", "speed", "time", "force", "friction_ratio",
              "delta_zero_sq", "impulse", "step_length", "Lambda_0", "Lambda_1", "Lambda_2",
              "Gamma_j", "wn", "tau", rate_limit="N", qp_time="s", noise="1",
              tracking_error="1")


@dataclass(frozen=True)
class ControlResult:
    """A controlled run with its certificate, the uncontrolled walker (and, for slow
    thrusters, the controller that ignores the lag) for comparison (SPEC 11).

    ``success``: the controlled walker completed every step; ``status``: ``ok`` only when it
    also never saturated, never met an infeasible QP, never left the friction cone and never
    left the prediction's error bound; else ``warning`` (or ``failed``), with ``reason``
    naming the steps."""

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    settings: dict
    planner: Planner = field(repr=False)
    refs: np.ndarray
    speed_refs: np.ndarray | None
    controlled: Run
    uncontrolled: Run | None
    naive: Run | None
    plant: dict
    warnings: tuple[str, ...] = ()

    name = "control"

    # -- verdicts ----------------------------------------------------------------------
    def _steps_with(self, pred: Callable) -> list[int]:
        return [s.step for s in self.controlled.steps if pred(s)]

    @property
    def success(self) -> bool:
        """The controlled run completed its steps without failing (``status`` tells ``ok`` from
        ``warning``)."""
        return self.controlled.success

    @property
    def energy_objective(self) -> bool:
        """The plans minimised the thruster input energy (``objective="energy"``, SPEC 15), not
        the effort."""
        return self.settings.get("objective") == "energy"

    @property
    def energy_unit(self) -> str:
        """Unit of the planned input energy: ``J``, or ``kg`` (fuel mass) when the driven
        thrusters' ``fuel`` models give no heating value (SPEC 15; one kind and quantity for
        all driven thrusters, checked before the run)."""
        from ..optimize.min_energy import objective_quantity

        by_name = {t.name: t for t in self.walker.robot.thrusters}
        units = {objective_quantity(by_name[n].power)[1] for n in self.settings["thrusters"]
                 if by_name[n].power is not None}
        return "kg" if units == {"kg"} else "J"

    def findings(self) -> dict[str, list[int]]:
        """Steps that make the run less than ``ok``, by kind (with the energy objective also
        the steps whose plan is not a verified energy plan)."""
        mu = self.settings["mu"]
        extra = {"energy plan not verified (effort plan applied)": self._steps_with(
            lambda s: s.plan.energy["status"] == "effort plan applied")
        } if self.energy_objective else {}
        return {
            "saturated": self._steps_with(lambda s: s.plan.status == "saturated"),
            "infeasible QP": self._steps_with(lambda s: s.plan.status == "infeasible"),
            "out of the friction cone": self._steps_with(
                lambda s: not s.realised["in_cone"]),
            "outside the prediction's error bound": self._steps_with(
                lambda s: s.certificate["flagged"]),
            "uncertified": self._steps_with(lambda s: not s.certificate["certified"]),
            "speed reference out of reach": self._steps_with(
                lambda s: self.speed_refs is not None
                and not self._speed_reachable(float(self.speed_refs[s.step - 1]))),
            **extra,
        } if mu is not None else {}

    def _speed_reachable(self, v: float) -> bool:
        sr = self.settings.get("speed_reference")
        return sr is None or next((e["reachable"] for e in sr["values"] if e["speed"] == v),
                                  True)

    @property
    def status(self) -> str:
        """``ok``, ``warning`` (completed, with steps in :meth:`findings`) or ``failed``."""
        if not self.success:
            return "failed"
        return "warning" if any(self.findings().values()) else "ok"

    @property
    def reason(self) -> str:
        """Why the run is not ``ok`` (its failure, the steps of each finding, an inadmissible
        impact), or what every step met."""
        parts = [] if self.success else [self.controlled.reason]
        for what, steps in self.findings().items():
            if steps:
                parts.append(f"{what} at {_steps_text(steps)}")
        if not self.planner.impact_ok:
            parts.append("impact inadmissible: " + "; ".join(self.planner.impact_reasons))
        if not parts:
            return (f"completed {len(self.controlled.steps)} steps: every step tracked its "
                    "reference, certified and inside the prediction's error bound"
                    + ("; every plan a verified least-input-energy plan"
                       if self.energy_objective else ""))
        head = (f"completed {len(self.controlled.steps)} steps; " if self.success else "")
        return head + "; ".join(parts)

    def zeta_errors(self) -> np.ndarray:
        """``|x_{k+1} - x_ref,k| / x_ref,k`` per completed step [1]: zeta^- at the impact that
        ends step k against the zeta^- reference of that step."""
        return np.array([abs(s.x_next - s.x_ref) / s.x_ref for s in self.controlled.steps])

    def speed_errors(self) -> np.ndarray | None:
        """``|v_k - v_ref,k| / v_ref,k`` per completed step [1] (None without a speed
        reference): the average speed of step k in the simulation (step length over step time)
        against the speed reference of step k. The step in which the reference changes
        starts from the previous reference's zeta^-, so its speed lies in between."""
        if self.speed_refs is None:
            return None
        return np.array([abs(s.speed - v) / v for s, v in
                         zip(self.controlled.steps, self.speed_refs)])

    def tracking_errors(self) -> np.ndarray:
        """Relative error per completed step [1] of the quantity the user asked to track:
        :meth:`speed_errors` for a speed reference, :meth:`zeta_errors` otherwise."""
        sp = self.speed_errors()
        return sp if sp is not None else self.zeta_errors()

    # -- documents ---------------------------------------------------------------------
    def _step_entry(self, s, speed_ref) -> dict:
        names = self.walker.robot.thruster_names
        driven = self.settings["thrusters"]
        p = s.plan
        zeta_err = abs(s.x_next - s.x_ref) / s.x_ref
        speed_err = None if speed_ref is None else abs(s.speed - speed_ref) / speed_ref
        return {
            "step": s.step, "t_start": s.t_start, "t_impact": s.t_impact,
            "reference": {"zeta_minus": s.x_ref, "speed": speed_ref},
            "zeta_minus_start": s.x_true, "zeta_minus_measured": s.x_meas,
            "zeta_minus_end": s.x_next,
            "tracking_error": speed_err if speed_err is not None else zeta_err,
            "speed_error": speed_err, "zeta_minus_error": zeta_err,
            "step_time": s.step_time, "speed": s.speed,
            "thrust_commanded": _command(s.u, driven, self.settings["knot_fractions"],
                                         self.settings["thrust_model"]),
            "thrust_delivered": {"mean": dict(zip(names, map(float, s.samples["F"].mean(0)))),
                                 "at_impact": dict(zip(names, map(float,
                                                                  s.thrust_at_impact)))},
            "qp": {"status": p.status, "active": p.active, "target_zeta_minus": p.x_target,
                   "time": p.qp_time, "iterations": p.iterations,
                   "violation": p.violation, "cut_rounds": p.cut_rounds,
                   "cutting_planes_alpha": [float(a) for a in p.cut_alpha],
                   "polish_time": p.polish_time,
                   **({"energy": p.energy} if p.energy is not None else {})},
            "pushed": s.pushed,
            **({"terrain_height": s.terrain_height} if "terrain" in self.settings else {}),
            "predicted": {**{k: _finite(v) if isinstance(v, float) else v
                             for k, v in s.predicted.items()}, "step_time": p.step_time},
            "realised": {**s.realised, "impact_friction_ratio": s.impact_friction_ratio},
            "certificate": s.certificate,
            "energy": _step_energy_block(s),
        }

    def document(self) -> dict:
        """The JSON body of ``control.json`` (SI units, see ``units``)."""
        zd = self.walker.zd
        sp = self.speed_refs
        steps = [self._step_entry(s, None if sp is None else float(sp[s.step - 1]))
                 for s in self.controlled.steps]
        err = self.tracking_errors()
        zerr, serr = self.zeta_errors(), self.speed_errors()
        qp_times = [s.plan.qp_time for s in self.controlled.steps]
        pol_times = [s.plan.polish_time for s in self.controlled.steps]
        out = {
            "schema_version": SCHEMA_VERSION,
            "units": {**UNITS, "slope": "rad", "climb_rate": "m/s"} if zd.slope != 0.0
            else UNITS,
            **({"slope": slope_record(zd.slope)} if zd.slope != 0.0 else {}),
            "success": self.success,
            "failure": self.controlled.failure or None,
            "status": self.status,
            "reason": self.reason,
            "warnings": list(self.warnings) + [self.reason] * (self.status != "ok"),
            "robot": robot_record(zd),
            "gait": gait_record(zd),
            "settings": self.settings,
            "plant": self.plant,
            "model": {"delta_zero_sq": zd.delta_zero_sq,
                      "V0_alpha_f": float(zd.V0(np.array(zd.alpha_f))),
                      "step_map": "x_{k+1} = delta_zero^2 x_k + V_0(alpha_f) + Gamma(alpha_f) u_k",
                      "impact_admissible": self.planner.impact_ok,
                      "impact_reasons": self.planner.impact_reasons},
            "summary": {
                "steps_completed": len(self.controlled.steps),
                "tracked": self.settings["tracked"],
                "final_tracking_error": float(err[-1]) if err.size else None,
                "max_tracking_error_last_5": float(err[-5:].max()) if err.size else None,
                "final_zeta_minus_error": float(zerr[-1]) if zerr.size else None,
                "final_speed_error": (float(serr[-1]) if serr is not None and serr.size
                                      else None),
                "findings": self.findings(),
                "qp_time_median": float(np.median(qp_times)) if qp_times else None,
                "qp_time_max": float(np.max(qp_times)) if qp_times else None,
                "polish_time_median": float(np.median(pol_times)) if pol_times else None,
                "polish_time_max": float(np.max(pol_times)) if pol_times else None,
                "cut_rounds_total": int(sum(s.plan.cut_rounds for s in self.controlled.steps)),
                "energy": _run_energy_block(self.controlled),
                **(self._planned_energy() if self.energy_objective else {}),
            },
            "uncontrolled": _run_summary(self.uncontrolled),
            "lag_ignored": _run_summary(self.naive, certificate=True),
            "steps": steps,
        }
        return out

    def _planned_energy(self) -> dict:
        """The objective and the plans' predicted input energy over the run [J] (None when a
        step has none), beside the effort plans' of the same states."""
        es = [s.plan.energy for s in self.controlled.steps]

        def total(key):
            v = [e[key] for e in es]
            return None if any(x is None for x in v) else float(sum(v))
        return {"objective": "energy", "planned_input_energy": total("energy"),
                "effort_plan_input_energy": total("effort_plan_energy"),
                "planned_input_energy_unit": self.energy_unit}

    def tables(self) -> dict[str, Table]:
        """``control_steps``: one row per controlled step (reference, measured zeta^- and speed,
        QP, contact margins)."""
        names = self.walker.robot.thruster_names
        header = ["step", col("t_start", "s"), col("reference_zeta", "kg^2 m^4/s^2"),
                  col("reference_speed", "m/s"), col("zeta_minus_measured", "kg^2 m^4/s^2"),
                  col("zeta_minus_end", "kg^2 m^4/s^2"), "tracking_error", "speed_error",
                  "zeta_minus_error", col("step_time", "s"), col("speed", "m/s"), "qp_status",
                  col("qp_time", "s"), "cut_rounds", col("polish_time", "s"), "pushed",
                  col("predicted_min_vertical_force", "N"), "predicted_max_friction_ratio",
                  col("realised_min_vertical_force", "N"), "realised_max_friction_ratio",
                  "in_cone", "certified", "flagged",
                  col("force_outside_bound", "N")]
        ncmd = len(self.controlled.steps[0].u) if self.controlled.steps else 0
        header += [col(f"command_{i}", "N") for i in range(ncmd)]
        header += [col(f"mean_thrust_{n}", "N") for n in names]
        terrain = "terrain" in self.settings
        header += [col("terrain_height", "m")] if terrain else []
        energy = self.energy_objective
        eu = self.energy_unit if energy else "J"
        header += [col("planned_input_energy", eu), col("effort_plan_input_energy", eu),
                   "energy_status"] if energy else []
        rows = []
        for e, s in zip(self.document()["steps"], self.controlled.steps):
            rows.append([e["step"], e["t_start"], e["reference"]["zeta_minus"],
                         e["reference"]["speed"], e["zeta_minus_measured"],
                         e["zeta_minus_end"], e["tracking_error"], e["speed_error"],
                         e["zeta_minus_error"], e["step_time"], e["speed"], e["qp"]["status"],
                         e["qp"]["time"], e["qp"]["cut_rounds"], e["qp"]["polish_time"],
                         e["pushed"],
                         e["predicted"]["min_vertical_force"],
                         _finite(e["predicted"]["max_friction_ratio"]),
                         e["realised"]["min_vertical_force"],
                         e["realised"]["max_friction_ratio"], e["realised"]["in_cone"],
                         e["certificate"]["certified"], e["certificate"]["flagged"],
                         e["certificate"]["max_force_outside_bound"]]
                        + [float(v) for v in s.u]
                        + [e["thrust_delivered"]["mean"][n] for n in names]
                        + ([e["terrain_height"]] if terrain else [])
                        + ([e["qp"]["energy"]["energy"], e["qp"]["energy"]["effort_plan_energy"],
                            e["qp"]["energy"]["status"]] if energy else []))
        return {"control_steps": Table(header, rows, [
            "thrustwalk control: one row per controlled step (zeta^- measured at the impact "
            "that starts it, zeta_minus_end at the impact that ends it)",
            "tracking_error: speed_error for a speed reference, zeta_minus_error otherwise",
            "command_i: the QP's thrust values, interval-major per driven thruster"])}

    def figure_data(self) -> dict:
        """The plain data the figures draw: per run (controlled, uncontrolled) speed, thrust and
        contact force per step."""
        def series(run: Run | None) -> dict | None:
            if run is None:
                return None
            return {"step": [s.step for s in run.steps], "speed": [s.speed for s in run.steps],
                    "failed": not run.success, "reason": run.reason,
                    "t": [s.samples["t"] for s in run.steps],
                    "F": [s.samples["F"] for s in run.steps],
                    "F1": [s.samples["F1"] for s in run.steps],
                    "F1_predicted": [s.samples.get("F1_predicted") for s in run.steps],
                    "commanded": [(s.t_start, s.t_impact, s.u) for s in run.steps],
                    "flagged": [s.step for s in run.steps
                                if s.certificate and s.certificate["flagged"]],
                    "saturated": [s.step for s in run.steps
                                  if s.plan is not None and s.plan.status != "tracking"]}
        names = self.walker.robot.thruster_names
        sp = self.speed_refs
        return {"controlled": series(self.controlled), "uncontrolled": series(self.uncontrolled),
                "naive": series(self.naive),
                "reference_speed": None if sp is None else list(map(float, sp)),
                "reference_zeta": list(map(float, self.refs)),
                "zeta": [s.x_next for s in self.controlled.steps],
                "mu": self.settings["mu"], "eps": self.settings["min_vertical_force"],
                "driven": [names.index(n) for n in self.settings["thrusters"]],
                "thruster_names": names, "thrust_model": self.settings["thrust_model"],
                "knots": self.settings["knot_fractions"],
                "pushes": [p["step"] for p in self.settings["pushes"]]}

    def figures(self, titles: bool = False) -> dict:
        """``speed_tracking``, ``thrust_schedule`` and ``contact_margin`` (matplotlib figures by
        stem)."""
        from ..plots.control import contact_margin, speed_tracking, thrust_schedule

        d = self.figure_data()
        name = self.walker.name
        return {"speed_tracking": speed_tracking(d, title=f"{name}: speed" if titles else ""),
                "thrust_schedule": thrust_schedule(d, title=f"{name}: thrust" if titles else ""),
                "contact_margin": contact_margin(d, title=f"{name}: contact" if titles else "")}

    def export_document(self) -> dict:
        """What an embedded controller needs (SPEC 11): knots, delta_zero^2, V_0(alpha_f),
        Gamma_j(alpha_f), the polynomial fits L_k with their error bounds, and the QP data
        (grid, rows ``A u <= b0 + bx x_k``, weights, bounds)."""
        zd, pl = self.walker.zd, self.planner
        fits = fit_terms(self.walker.model, zd, tol=self.settings["fit_tolerance"])
        rw = pl.grid_rows()
        A, b0, bx, fam = pl.contact_rows(rw, float(self.refs.max()))
        th = pl.thrust
        return {
            "schema_version": SCHEMA_VERSION,
            "units": {**UNITS, "A": "1 (force rows) or kg^2 m^4/s^2 per N (zeta rows)",
                      "b0": "N (force rows) or kg^2 m^4/s^2 (zeta rows)",
                      "bx": "N per kg^2 m^4/s^2 (force rows) or 1 (zeta rows)"},
            "robot": robot_record(zd), "gait": {"name": zd.gait.name},
            "knots": {"alpha": list(map(float, th.knots)),
                      "fractions": self.settings["knot_fractions"]},
            "thrusters": self.settings["thrusters"],
            "variables": "u[j * m_d + t]: interval j, driven thruster t" if not th.dynamic
            else "u[t]: one setpoint per driven thruster (thruster dynamics)",
            "delta_zero_sq": zd.delta_zero_sq,
            "V0_alpha_f": float(zd.V0(np.array(zd.alpha_f))),
            "Gamma_j_alpha_f": list(map(float, IdealThrust(zd, th.knots, th.driven).parts(
                np.array([zd.alpha_f]))[3][0])),
            "step_map": "x_{k+1} = delta_zero_sq x_k + V0_alpha_f + Gamma_j_alpha_f . u",
            "polynomial_fits": {
                "basis": "Chebyshev T_k(x), x = 2 (alpha - alpha_i)/(alpha_f - alpha_i) - 1",
                "alpha_i": zd.alpha_i, "alpha_f": zd.alpha_f,
                **{k: {"degree": f.degree, "coefficients": np.asarray(f.coef).tolist(),
                       "max_error": f.max_error, "relative_error": f.relative_error}
                   for k, f in fits.fits.items() if k in ("L0", "L1", "L2")}},
            "qp": {
                "objective": "w ((x_{k+1} - x_ref)/zeta_scale)^2 + sum_j effort w_j "
                             "(u_j/force_scale)^2 + smooth |u - u_prev|^2/force_scale^2 "
                             "(w = null: x_{k+1} = x_ref first, as an equality)",
                **({"energy_objective": self.settings["energy_objective"]}
                   if self.energy_objective else {}),
                "tracking_weight": pl.st.tracking, "effort_weight": pl.st.effort,
                "rate_weight": pl.st.smooth, "zeta_scale": pl.st.zeta_scale,
                "force_scale": pl.st.force_scale,
                "interval_weights": list(map(float, np.diag(pl.W))),
                "lower": list(map(float, pl.lo)), "upper": list(map(float, pl.hi)),
                "rate_limit": pl.st.rate, "mu": pl.st.mu, "min_vertical_force": pl.st.eps,
                "zeta_min": pl.st.zeta_min, "noise": pl.st.noise,
                "grid_alpha": list(map(float, rw.alpha)),
                "rows": "A u <= b0 + bx x_k (take the worse end of the measurement band)",
                "A": A.tolist(), "b0": list(map(float, b0)), "bx": list(map(float, bx)),
                "family": [str(f) for f in fam],
                "exact_terms": self.settings["terms"] == "exact",
            },
        }


def _finite(v):
    return v if v is None or np.isfinite(v) else None


def _steps_text(steps: list[int]) -> str:
    if len(steps) == 1:
        return f"step {steps[0]}"
    if steps == list(range(steps[0], steps[-1] + 1)):
        return f"steps {steps[0]}-{steps[-1]}"
    return "steps " + ", ".join(map(str, steps[:12])) + (" ..." if len(steps) > 12 else "")


def _command(u: np.ndarray, driven: list[str], fractions: list[float], model: str) -> dict:
    md = len(driven)
    per = np.asarray(u, float).reshape(-1, md)
    return {name: list(map(float, per[:, c])) for c, name in enumerate(driven)}


def _run_summary(run: Run | None, certificate: bool = False) -> dict | None:
    if run is None:
        return None
    out = {"success": run.success, "failure": run.failure or None, "reason": run.reason,
           "steps_completed": len(run.steps),
           "speed": [s.speed for s in run.steps],
           "zeta_minus_end": [s.x_next for s in run.steps],
           "energy": _run_energy_block(run)}
    if certificate:
        out["mismatch"] = [{"step": s.step, "x_next_predicted": s.plan.x_next,
                            "x_next_realised": s.x_next,
                            "relative_mismatch": (s.x_next - s.plan.x_next) / s.plan.x_next,
                            "flagged": s.certificate["flagged"]} for s in run.steps]
    return out


def step_energy(s):
    """The energies of a completed step (``energetics.run.RunStepEnergy``; SPEC 15) on its own
    closed loop and thrust, computed when first asked for and kept with the step (None:
    nothing to compute them from)."""
    if s.energy_input is None:
        return None
    if "energy" not in s.samples:
        cl, step = s.energy_input
        s.samples["energy"] = run_energy(cl, [step])[0]
    return s.samples["energy"]


def _step_energy_block(s) -> dict | None:
    e = step_energy(s)
    return None if e is None else step_block(e)


def _run_energy_block(run: Run) -> dict | None:
    """The run's energy summary over its completed steps (``energetics.run.run_block``)."""
    es = [step_energy(s) for s in run.steps]
    if any(e is None for e in es):
        return None
    return run_block(es)
