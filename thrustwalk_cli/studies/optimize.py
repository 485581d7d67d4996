"""The ``optimize`` study: the least thrust that reaches a target while staying walkable
(SPEC 6), around :func:`thrustwalk_cli.optimize.min_effort.optimize`: parameter checks, the JSON
record, the gait file with the optimal schedule, and the figure."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..contact.evaluate import check_contact_options
from ..energetics.orbit import orbit_energy
from ..errors import (
    InputError,
    check_choice,
    check_number,
    check_numbers,
    check_text,
)
from ..files.gait_file import gait_text, robot_reference
from ..hzd.zero_dynamics import LimitCycle
from ..model.compiled import CompiledModel
from ..model.slope import check_slope
from ..optimize.min_effort import OptimalSchedule, describe, optimize
from ..optimize.min_energy import MAX_SCP, TOL_SCP, check_power, objective_quantity, optimize_energy
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, climb_rate, result_repr, slope_record, units


def result_record(res: OptimalSchedule, model: CompiledModel) -> dict:
    """``optimal_schedule.json`` body (SI units)."""
    p = res.problem
    unit = "N" if p.mode == "force" else "N m"
    lc = res.cycle
    out = {
        "feasible": res.feasible, "status": res.status, "reason": res.reason,
        "violated_families": list(res.violated),
        "violated_descriptions": [describe(v) for v in res.violated],
        "target": res.target, "mode": p.mode,
        "thruster": model.robot.thruster_names[p.thruster] if p.mode == "force" else None,
        "unit": unit, "knots_fraction": res.fractions.tolist(), "knots_alpha": p.knots.tolist(),
        "weights": p.weights.tolist(),
        "bounds": {"lower": p.lo.tolist(), "upper": p.hi.tolist()},
        "zeta_star_target": res.zeta_star_target,
        "reachable_zeta_star": None if res.zeta_range is None else list(res.zeta_range),
        "values": None if res.values is None else res.values.tolist(),
        "objective": res.objective,
        "objective_definition": (
            "sum_j w_j x_j^2, w_j = interval alpha-length [rad] or nominal time [s]"
            if res.objective_name == "effort" else
            "thruster input energy per step sum_j int_{interval j} P(x_j, V) dt on the "
            "schedule's own orbit [J] (fuel model without heating value: fuel mass [kg])"),
        "solver": res.solver,
    }
    if res.feasible:
        out.update({
            "zeta_star": lc.zeta_star, "speed": lc.speed, "step_time": lc.step_time,
            "orbit_exists": lc.exists, "stable": lc.stable,
            "active_constraints": res.active,
            "kkt": {k: v for k, v in res.kkt.items() if k not in ("active", "multipliers")},
            "continuous_check": {
                "feasible": res.contact.feasible, "reason": res.contact.reason,
                "min_vertical_force": res.contact.min_vertical_force,
                "max_friction_ratio": res.contact.max_friction_ratio,
                "note": "the QP enforces the contact conditions on the alpha grid; this "
                        "re-check polishes the worst points between grid points",
            },
        })
    return out


# ------------------------------------------------------------------------- the command's study
def check_options(*, fractions: list[float], target_zeta: float | None,
                  target_speed: float | None, max_thrust: float | None, mu: float, eps: float,
                  zeta_min: float | None, mode: str) -> None:
    """Bad parameter values -> :class:`InputError` naming the parameter."""
    err = InputError.param
    if (target_zeta is None) == (target_speed is None):
        raise err(("target_speed", "target_zeta"), "give exactly one of them")
    if target_zeta is not None and not (np.isfinite(target_zeta) and target_zeta > 0):
        raise err("target_zeta", f"zeta* must be > 0 kg^2 m^4/s^2 (got {target_zeta:g})")
    if target_speed is not None and not (np.isfinite(target_speed) and target_speed > 0):
        raise err("target_speed", f"the speed must be > 0 m/s (got {target_speed:g})")
    if any(v is None for v in fractions):
        raise err("knots", "free knots (?) are solved only by shape-only shaping (the shape "
                           "command); give every knot")
    fr = np.asarray(fractions, float)
    if (len(fr) < 2 or abs(fr[0]) > 1e-9 or abs(fr[-1] - 1.0) > 1e-9
            or np.any(np.diff(fr) <= 0)):
        raise err("knots", "fractions of the step from 0 to 1, strictly increasing, at least "
                           f"two (got {', '.join(f'{v:g}' for v in fr)})")
    if max_thrust is not None and not (np.isfinite(max_thrust) and max_thrust >= 0):
        raise err("max_thrust", f"expected a bound >= 0 (got {max_thrust:g})")
    if mode not in ("force", "generalized"):
        raise err("mode", f"expected 'force' or 'generalized', got {mode!r}")
    if mode == "generalized" and max_thrust is None:
        raise err("max_thrust", "required in generalized mode (a bound on T_j in N m)")
    check_contact_options(mu, eps)
    if zeta_min is not None and not (np.isfinite(zeta_min) and zeta_min > 0):
        raise err("zeta_min", f"expected a value > 0 kg^2 m^4/s^2 (got {zeta_min:g})")


def gait_yaml(gait, robot, res: OptimalSchedule, model: CompiledModel,
              robot_ref: str | None = None) -> str:
    """A gait file equal to ``gait`` (coefficients written out, ``invariance: given``) with the
    optimal schedule as its ``thrust:`` section (:func:`files.gait_file.gait_text`).
    ``robot_ref``: its ``robot:`` (default
    :func:`~thrustwalk_cli.files.gait_file.robot_reference` of the robot alone: the bundled
    name or the robot file's absolute path)."""
    p = res.problem
    key = model.robot.thruster_names[p.thruster] if p.mode == "force" else "T"
    if res.objective_name == "energy":
        quantity, unit = objective_quantity(model.robot.thrusters[p.thruster].power)
        kind = "energy-optimal"
        what = (f"Energy-optimal thrust schedule (SPEC 15; least thruster {quantity} per step "
                f"under the SPEC 6 constraints): target {res.target}, {quantity} "
                f"{res.objective!r} {unit} per step")
    else:
        kind = "minimum-effort"
        what = (f"Minimum-effort thrust schedule (SPEC 6): target {res.target}, objective "
                f"{res.objective!r}")
    header = [f"Written by thrustwalk optimize from gait '{gait.name}' ({gait.source_file}).",
              f"{what}; zeta* = {res.cycle.zeta_star!r} kg^2 m^4/s^2, speed "
              f"{res.cycle.speed!r} m/s.",
              "Bezier columns 0 and 1 were computed for hybrid invariance; written out in full."]
    gamma = float(getattr(model, "slope", 0.0))
    if gamma != 0.0:
        header.insert(2, f"Optimized for the slope {gamma!r} rad (positive uphill; SPEC 14): "
                         f"speed along the ground, climb rate "
                         f"{climb_rate(res.cycle.speed, gamma)!r} m/s. Re-check: thrustwalk "
                         "limit-cycle with this file on that slope.")
    return gait_text(replace(gait, name=f"{gait.name}_optimal"), robot,
                     robot_ref=robot_ref or robot_reference(robot), header=header,
                     invariance="given",
                     description=f"{gait.name} with {'an' if kind[0] == 'e' else 'a'} {kind} "
                                 "thrust schedule",
                     thrust=(p.mode, list(res.fractions), {key: list(res.values)},
                             "N" if p.mode == "force" else "N m"))


@dataclass(frozen=True)
class OptimizeResult:
    """A minimum-effort schedule (SPEC 6) for one walker, or the reason there is none.

    ``schedule``: the exact QP result (values, objective, active constraints, KKT residuals,
    continuous re-check); ``nominal``: the zero-thrust limit cycle (for the figure).
    ``success``: a feasible optimum was found; ``reason`` says what happened.
    """

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    schedule: OptimalSchedule
    mu: float
    eps: float
    zeta_min: float | None
    weights: str = "alpha"
    nominal: LimitCycle | None = None
    objective: str = "effort"
    energy: dict | None = None  # the energy objective's block (objective_details)
    # the gait file's robot: (the command sets it relative to the folder it writes into)
    robot_ref: str | None = None

    name = "optimal_schedule"

    @property
    def success(self) -> bool:
        """An optimal schedule was found (SPEC 6)."""
        return self.schedule.optimal

    @property
    def reason(self) -> str:
        """The solver's verdict: the optimum found, or why no schedule exists."""
        return self.schedule.reason

    @property
    def gait_file(self) -> str:
        """The name of the gait file written with the optimal schedule: ``GAIT_optimal.yaml``."""
        return f"{self.walker.gait.name}_optimal.yaml"

    @property
    def files(self) -> list[str]:
        """The files a command writes for this result, the JSON first."""
        out = ["optimal_schedule.json"]
        if self.success:
            out += [self.gait_file, "optimal_orbit.png", "optimal_orbit.pdf"]
        return out

    def document(self) -> dict:
        """The JSON body of ``optimal_schedule.json`` (SI units)."""
        w = self.walker
        unit = "N" if self.schedule.problem.mode == "force" else "N m"
        weight = "rad" if self.weights == "alpha" else "s"
        extra = {}
        obj_unit = f"{unit}^2 {weight}"
        if self.energy is not None:
            extra = {"objective_details": self.energy}
            obj_unit = self.energy["unit"]
        if w.slope != 0.0:  # SPEC 14: the slope it holds for, the climb rate beside the speed
            extra["slope"] = slope_record(w.slope)
            obj_unit = {"objective": obj_unit, "slope": "rad", "climb_rate": "m/s"}
        else:
            obj_unit = {"objective": obj_unit}
        doc = {"schema_version": SCHEMA_VERSION,
               "units": units("zeta", "speed", "step_time", "alpha", "force",
                              "friction_ratio", values=unit, **obj_unit),
               "robot": {"name": w.robot.name, "file": w.robot.source_file},
               "gait": {"name": w.gait.name, "file": w.gait.source_file},
               "success": self.success, "reason": self.reason,
               "warnings": list(w.warnings),
               "mu": self.mu, "min_vertical_force": self.eps,
               "zeta_min": self.zeta_min if self.zeta_min is not None else "1 % of zeta*",
               **result_record(self.schedule, w.model), **extra, "files": self.files}
        if w.slope != 0.0 and "speed" in doc:
            doc["climb_rate"] = climb_rate(doc["speed"], w.slope)
        return doc

    def tables(self) -> dict:
        """No CSV table (``{}``)."""
        return {}

    def figures(self, titles: bool = False) -> dict:
        """``optimal_orbit``: nominal vs optimal orbit, the schedule and the contact margins."""
        if not self.success:
            return {}
        from ..plots.optimize import optimal_figure

        zd, res = self.walker.zd, self.schedule

        def orbit(lc):
            if lc is None or not lc.exists:
                return None
            o = lc.orbit
            return {"alpha": o["alpha"], "alpha_dot": o["alpha_dot"],
                    "jump": (zd.alpha_f, lc.alpha_dot_minus, zd.alpha_i, lc.alpha_dot_plus)}

        unit = "N" if res.problem.mode == "force" else "N m"
        what = "energy-optimal" if self.objective == "energy" else "optimal"
        return {"optimal_orbit": optimal_figure(
            orbit(self.nominal), orbit(res.cycle), res.problem.knots, res.values, unit=unit,
            profile=res.contact.profile, mu=self.mu,
            title=f"{self.walker.name}: {what} schedule" if titles else "")}

    def attachments(self, doc: dict) -> dict[str, str]:
        """The gait file with the optimal schedule as its ``thrust:`` section."""
        if not self.success:
            return {}
        w = self.walker
        return {self.gait_file: gait_yaml(w.gait, w.robot, self.schedule, w.model,
                                          self.robot_ref)}


def optimize_schedule(walker: Walker, *, knots: list[float] = (0.0, 0.25, 0.5, 0.75, 1.0),
                      target_zeta: float | None = None, target_speed: float | None = None,
                      max_thrust: float | None = None, mu: float | None = None,
                      min_vertical_force: float = 0.0, zeta_min: float | None = None,
                      thruster: str | None = None, mode: str = "force",
                      weights: str = "alpha", objective: str = "effort",
                      slope: float = 0.0) -> OptimizeResult:
    """The minimum-effort schedule (SPEC 6) on ``knots`` (fractions of the step) reaching
    ``target_zeta`` [kg^2 m^4/s^2] or ``target_speed`` [m/s], with ``|x_j| <= max_thrust``
    [N, or N m in generalized mode], the friction cone ``mu`` (default: the gait's), vertical
    force ``>= min_vertical_force`` [N] and ``zeta >= zeta_min`` (default 1 % of zeta*). An
    infeasible problem is a result with ``success`` false and the violated constraint
    families. A robot without thrusters has only ``mode="generalized"``.

    ``objective="energy"`` (force mode; the thruster needs a ``power:`` model): the schedule
    of least thruster input energy per step [J] (fuel mass [kg] for a fuel model without a
    heating value) under the same constraints (SPEC 15, :mod:`..optimize.min_energy`:
    sequential convex programming on the orbit's time weights, each convex problem solved
    exactly); its energy is re-computed by :func:`..energetics.orbit.orbit_energy` and
    compared with the minimum-effort schedule's (``weights``: that schedule's).

    ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground angle (SPEC 14,
    :meth:`Walker.on_slope`): the SPEC 6 problem of the slope frame (its fixed-point equation
    and contact terms explicit in cos/sin of the slope, world-frame thrusters turned); the
    target speed is along the ground, the document gains the ``slope`` block and the climb
    rate, the gait file's header the slope. 0: level ground, bit for bit."""
    check_walker(walker)
    walker = walker.on_slope(check_slope(slope))
    check_choice("objective", objective, ("effort", "energy"))
    if isinstance(knots, (list, tuple)) and any(k is None for k in knots):
        raise InputError.param("knots", "free knots (?) are solved only by shape-only shaping "
                                        "(the shape command); give every knot")
    knots = list(check_numbers("knots", knots, min_len=0))
    target_zeta = check_number("target_zeta", target_zeta, optional=True)
    target_speed = check_number("target_speed", target_speed, optional=True)
    max_thrust = check_number("max_thrust", max_thrust, optional=True)
    mu = check_number("mu", mu, optional=True)  # its range: check_contact_options
    min_vertical_force = check_number("min_vertical_force", min_vertical_force)
    zeta_min = check_number("zeta_min", zeta_min, optional=True)
    check_text("thruster", thruster, optional=True)
    check_choice("mode", mode, ("force", "generalized"))
    check_choice("weights", weights, ("alpha", "time"))
    model, zd = walker.model, walker.zd
    mu = walker.gait.mu if mu is None else float(mu)
    eps = float(min_vertical_force)
    check_options(fractions=list(knots), target_zeta=target_zeta, target_speed=target_speed,
                  max_thrust=max_thrust, mu=mu, eps=eps, zeta_min=zeta_min, mode=mode)
    if mode == "force" and not model.robot.thrusters:
        raise InputError.param("mode", f"robot {model.robot.name} has no thruster: force mode "
                                       "needs one (use mode generalized, a generalised force "
                                       "T_j on q_N in N m)")
    j = model.robot.thruster_index(thruster) if mode == "force" else 0
    if mode == "force" and max_thrust is not None:
        model.robot.check_thrust_bound("max_thrust", max_thrust, [j])
    if objective == "energy":
        if mode != "force":
            raise InputError.param("objective", "energy needs force mode (a thruster's "
                                                "physical thrust and its power model)")
        check_power(model, j)
    fr = np.asarray(knots, float)
    fr[0], fr[-1] = 0.0, 1.0
    kw = dict(target_zeta=target_zeta, target_speed=target_speed, thruster=j, mu=mu, eps=eps,
              zeta_min=zeta_min, max_thrust=max_thrust)
    if objective == "effort":
        res = optimize(model, zd, fr, mode=mode, weights=weights, **kw)
    else:
        res = optimize_energy(model, zd, fr, weights=weights, **kw)
    nominal = None
    if res.feasible:
        nominal = zd.nominal_cycle()
    block = None
    if objective == "energy":
        effort = optimize(model, zd, fr, mode=mode, weights=weights, **kw)
        block = _energy_block(walker, res, effort, j)
        res = _cheaper_elsewhere(res, block)
    return OptimizeResult(walker, res, mu, eps, zeta_min, weights, nominal, objective, block)


def _cheaper_elsewhere(res: OptimalSchedule, block: dict) -> OptimalSchedule:
    """No verdict better than the truth: an energy schedule reported ``optimal`` while the
    minimum-effort schedule, feasible for the same target, spends less (both by
    :func:`orbit_energy`) is not optimal. That happens with a target speed: the speed fixes
    zeta* only through the schedule, and the search runs along zeta* (module docstring of
    min_effort), so another zeta* can walk at the speed for less."""
    mine = block.get("orbit_energy")
    other = (block.get("effort_optimal") or {})
    theirs = next((v for k, v in other.items() if k in ("input_energy", "fuel_mass")), None)
    if not (res.optimal and other.get("feasible") and mine is not None and theirs is not None):
        return res
    if theirs >= mine * (1.0 - 1e-9):
        return res
    return replace(res, status="not optimal", reason=(
        f"not optimal: the minimum-effort schedule for the same target spends {theirs:.6g} "
        f"against {mine:.6g} per step; the target speed is met by a search along zeta* and "
        f"the energy's optimum at this zeta* is not the least energy that walks at the speed "
        f"(at fixed zeta*: {res.reason.split(': ', 1)[-1]})"))


def _step_energy(walker: Walker, res: OptimalSchedule, k: int) -> tuple[float | None, str]:
    """Thruster ``k``'s input energy [J] (fuel mass [kg] without heating value) per step of
    ``res``'s schedule on its orbit by :func:`orbit_energy` (independent of the optimiser),
    or None and why."""
    if not res.feasible or res.cycle is None or not res.cycle.exists:
        return None, "no feasible schedule"
    sched = res.problem.schedule(res.values, walker.model.n_thrusters)
    e = orbit_energy(walker.zd, sched, [res.cycle])[0]
    if not e.exists:
        return None, e.reason
    p = walker.robot.thrusters[k].power
    val = e.fuel_mass[k] if objective_quantity(p)[0] == "fuel mass" else e.thruster_input[k]
    if val is None:
        return None, "; ".join(e.missing) or "not computed"
    return float(val), "orbit_energy (exact quadrature on the schedule's periodic orbit)"


def _energy_block(walker: Walker, res: OptimalSchedule, effort: OptimalSchedule,
                  k: int) -> dict:
    """The ``objective_details`` block of an energy objective (SPEC 15)."""
    p = walker.robot.thrusters[k].power
    quantity, unit = objective_quantity(p)
    es = res.energy
    ind, how = _step_energy(walker, res, k)
    eff, eff_how = _step_energy(walker, effort, k)
    agree = None
    if ind is not None and res.objective is not None:
        agree = abs(res.objective - ind) / max(abs(ind), 1e-300) if ind else abs(res.objective)
    saving = None
    if ind is not None and eff is not None and eff > 0:
        saving = 1.0 - ind / eff
    return {
        "name": "energy",
        "quantity": f"thruster {walker.robot.thruster_names[k]} {quantity} per step",
        "unit": f"{unit} per step",
        "power_model": p.kind,
        "definition": ("sum_j int_{interval j} P(x_j, V(alpha)) dt over the schedule's own "
                       "periodic orbit, dt = d alpha / alpha', V the axial air speed through "
                       "the disk (momentum model); SPEC 15" +
                       (" (fuel model without heating value: fuel mass tsfc |x| dt)"
                        if quantity == "fuel mass" else "")),
        "method": ("sequential convex programming: the orbit (time weights dt_j, 1/alpha' and "
                   "the inflow along each interval) frozen at the current schedule, the convex "
                   "problem solved exactly with the orbit's gradient term, repeated to a fixed "
                   "point (a KKT point of the full problem)"),
        "value": res.objective if res.feasible else None,
        "orbit_energy": ind,
        "orbit_energy_method": how,
        "relative_difference": agree,
        "iterations": None if es is None else es.iterations,
        "final_change": None if es is None else es.change,
        "converged": None if es is None else es.converged,
        "tolerance": TOL_SCP, "max_iterations": MAX_SCP,
        "history": None if es is None else list(es.history),
        "interval_times": None if es is None else es.dt.tolist(),
        "effort_optimal": {
            "feasible": effort.feasible,
            "values": None if effort.values is None else effort.values.tolist(),
            "objective": effort.objective,
            quantity.replace(" ", "_"): eff,
            "method": eff_how,
        },
        "saving_vs_effort_optimal": saving,
    }
