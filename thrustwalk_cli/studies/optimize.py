"""The ``optimize`` study: the least thrust that reaches a target while staying walkable
(SPEC 6), around :func:`thrustwalk_cli.optimize.min_effort.optimize`: parameter checks, the JSON
record, the gait file with the optimal schedule, and the figure."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..contact.evaluate import check_contact_options
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
from ..optimize.min_effort import OptimalSchedule, describe, optimize
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, result_repr, units


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
        "objective_definition": "sum_j w_j x_j^2, w_j = interval alpha-length [rad] or "
                                "nominal time [s]",
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


def gait_yaml(gait, robot, res: OptimalSchedule, model: CompiledModel) -> str:
    """A gait file equal to ``gait`` (coefficients written out, ``invariance: given``) with the
    optimal schedule as its ``thrust:`` section (:func:`files.gait_file.gait_text`)."""
    p = res.problem
    key = model.robot.thruster_names[p.thruster] if p.mode == "force" else "T"
    header = [f"Written by thrustwalk optimize from gait '{gait.name}' ({gait.source_file}).",
              f"Minimum-effort thrust schedule (SPEC 6): target {res.target}, objective "
              f"{res.objective!r}; zeta* = {res.cycle.zeta_star!r} kg^2 m^4/s^2, speed "
              f"{res.cycle.speed!r} m/s.",
              "Bezier columns 0 and 1 were computed for hybrid invariance; written out in full."]
    return gait_text(replace(gait, name=f"{gait.name}_optimal"), robot,
                     robot_ref=robot_reference(robot), header=header, invariance="given",
                     description=f"{gait.name} with a minimum-effort thrust schedule",
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

    name = "optimal_schedule"

    @property
    def success(self) -> bool:
        return self.schedule.feasible

    @property
    def reason(self) -> str:
        return self.schedule.reason

    @property
    def gait_file(self) -> str:
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
        return {"schema_version": SCHEMA_VERSION,
                "units": units("zeta", "speed", "step_time", "alpha", "force",
                               "friction_ratio", values=unit, objective=f"{unit}^2 {weight}"),
                "robot": {"name": w.robot.name, "file": w.robot.source_file},
                "gait": {"name": w.gait.name, "file": w.gait.source_file},
                "success": self.success, "reason": self.reason,
                "warnings": list(w.warnings),
                "mu": self.mu, "min_vertical_force": self.eps,
                "zeta_min": self.zeta_min if self.zeta_min is not None else "1 % of zeta*",
                **result_record(self.schedule, w.model), "files": self.files}

    def tables(self) -> dict:
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
        return {"optimal_orbit": optimal_figure(
            orbit(self.nominal), orbit(res.cycle), res.problem.knots, res.values, unit=unit,
            profile=res.contact.profile, mu=self.mu,
            title=f"{self.walker.name}: optimal schedule" if titles else "")}

    def attachments(self, doc: dict) -> dict[str, str]:
        """The gait file with the optimal schedule as its ``thrust:`` section."""
        if not self.success:
            return {}
        w = self.walker
        return {self.gait_file: gait_yaml(w.gait, w.robot, self.schedule, w.model)}


def optimize_schedule(walker: Walker, *, knots: list[float] = (0.0, 0.25, 0.5, 0.75, 1.0),
                      target_zeta: float | None = None, target_speed: float | None = None,
                      max_thrust: float | None = None, mu: float | None = None,
                      min_vertical_force: float = 0.0, zeta_min: float | None = None,
                      thruster: str | None = None, mode: str = "force",
                      weights: str = "alpha") -> OptimizeResult:
    """The minimum-effort schedule (SPEC 6) on ``knots`` (fractions of the step) reaching
    ``target_zeta`` [kg^2 m^4/s^2] or ``target_speed`` [m/s], with ``|x_j| <= max_thrust``
    [N, or N m in generalized mode], the friction cone ``mu`` (default: the gait's), vertical
    force ``>= min_vertical_force`` [N] and ``zeta >= zeta_min`` (default 1 % of zeta*). An
    infeasible problem is a result with ``success`` false and the violated constraint
    families. A robot without thrusters has only ``mode="generalized"``."""
    check_walker(walker)
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
    fr = np.asarray(knots, float)
    fr[0], fr[-1] = 0.0, 1.0
    res = optimize(model, zd, fr, target_zeta=target_zeta, target_speed=target_speed,
                   mode=mode, thruster=j, mu=mu, eps=eps, zeta_min=zeta_min,
                   max_thrust=max_thrust, weights=weights)
    nominal = None
    if res.feasible:
        nominal = zd.nominal_cycle()
    return OptimizeResult(walker, res, mu, eps, zeta_min, weights, nominal)
