"""The ``design-gait`` study: a stable, walkable Bezier gait for a robot, found by constrained
optimisation (SPEC 2, 3, 5) and re-checked by the independent code paths; the report record,
the gait file text (with a header recording how it was made) and the reload check of that text.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from functools import cached_property

import numpy as np

from ..description.gait import Gait
from ..description.robot import Robot
from ..design.solver import DesignResult, WarmStart, solve_design
from ..design.spec import DesignSpec
from ..design.verify import HEIGHT_TOL, RANGE_TOL, check_gait
from ..energetics.orbit import OrbitEnergy, orbit_energy
from ..errors import (
    ComputationError,
    InputError,
    check_callable,
    check_instance,
    renamed_keyword,
)
from ..files.gait_file import gait_text, load_gait_text, same_robot_file
from ..hzd.zero_dynamics import limit_cycles, zero_dynamics
from ..model.compiled import CompiledModel
from ..model.slope import check_slope, slope_model
from ..thrust.schedule import Schedule
from ..walker import Walker, as_model, assemble_walker, check_walker
from .documents import (
    SCHEMA_VERSION,
    Table,
    climb_rate,
    col,
    fmt_margin,
    result_repr,
    show_options,
    slope_record,
    units,
)

# ------------------------------------------------------------------------------ records
OBJECTIVE_UNITS = {"effort": "N^2 m s", "peak": "N m", "cot": "1"}


def objective_definition(s, short: bool = False) -> str:
    """What the design objective of the spec ``s`` is (the report's ``definition``)."""
    if s.objective == "effort":
        if short:
            return "(1/L) int_0^T |u|^2 dt"
        return ("(1/L) int_0^T |u|^2 dt over one step of the periodic orbit"
                + (" + thrust_weight |F|^2 T / L" if s.thrust_design else ""))
    if s.objective == "cot":
        if short:
            return "mechanical CoT"
        return ("mechanical cost of transport (1/(m g L)) int (sum_j max(0, u_j q_j') + "
                "sum_k max(0, F_k d_k . p_k')) dt over one step of the periodic orbit "
                "(SPEC 15; the solver minimises it with max(0, p) smoothed, the value is "
                "exact)")
    return "max |u_i|" if short else "max_i,alpha |u_i|"


def report_record(res: DesignResult) -> dict:
    """JSON body of ``NAME.report.json`` (provenance is added by the command)."""
    s = res.spec
    r = res.check
    return {
        "feasible": res.feasible, "status": "feasible" if res.feasible else "infeasible",
        "reason": res.reason, "blocking_constraint": res.blocking,
        "warnings": list(res.warnings),
        "optimality": dict(res.optimality),
        "objective": {"name": s.objective, "value": res.objective,
                      "solver_value": res.solver_objective,
                      "unit": OBJECTIVE_UNITS[s.objective],
                      "definition": objective_definition(s)},
        "spec": {"speed": s.speed, "step_length": s.step_length, "mu": s.mu,
                 "order": s.order, "clearance": s.clearance, "max_delta_sq": s.max_delta_sq,
                 "min_vertical_force": res.eps, "min_liftoff_velocity": s.min_liftoff,
                 "min_touchdown_velocity": s.min_touchdown_velocity,
                 "min_zeta_ratio": s.min_zeta_ratio, "objective": s.objective,
                 "thrust_design": s.thrust_design, "thrust_weight": s.thrust_weight,
                 "thrust_range": None if s.thrust_range is None else
                 {"thruster": s.thrust_range[0], "low": s.thrust_range[1],
                  "high": s.thrust_range[2]},
                 "starts": s.starts, "seed": s.seed, "max_iter": s.max_iter,
                 "nodes": s.nodes},
        "units": units("speed", "step_length", "force", "torque", "zeta", "sigma_N", "angle",
                       "time", "thrust", clearance="m", effort="N^2 m s"),
        "margins_note": "margins are in the SI unit of each quantity; >= 0 when satisfied",
        "thrust": list(res.thrust),
        "fixed_point": r.get("orbit"),
        "margins": r.get("margins"),
        "failed_checks": r.get("failed"),
        "failed_check_details": r.get("failure_details"),
        "cost": r.get("cost"),
        "contact": r.get("contact"),
        "swing_foot": r.get("swing"),
        "solver_violations": res.violations,
        "alpha_c": list(res.c),
        "coefficients": [list(row) for row in res.gait.A],
        "starts": [{"index": t.index, "status": t.status, "slsqp_code": t.code,
                    "objective": _num(t.objective),
                    "max_violation": _num(t.max_violation), "iterations": t.iterations,
                    "evaluations": t.evaluations, "seconds": t.seconds,
                    "restoration_iterations": t.restoration, "restored": t.restored}
                   for t in res.starts],
        "evaluations": res.evaluations, "seconds": res.seconds,
    }


def _num(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def gait_yaml(res: DesignResult, model: CompiledModel, robot_ref: str,
              header: list[str]) -> str:
    """The gait as YAML (``invariance: auto``, columns 0 and 1 written as ``~``), loadable by
    :func:`thrustwalk_cli.walker.load_walker`; ``header`` lines become ``#`` comments
    (:func:`files.gait_file.gait_text`)."""
    g, r = res.gait, model.robot
    o = res.check.get("orbit", {})
    desc = (f"order-{g.order} Bezier gait designed by thrustwalk design-gait "
            f"({res.spec.objective} objective)")
    if o.get("speed") is not None:
        desc += f", {o['speed']:.3f} m/s, step {o['step_length']:.3f} m"
    thrust = None
    if res.thrust:
        thrust = ("force", [0.0, 1.0], {nm: [v] for nm, v in zip(r.thruster_names, res.thrust)},
                  "N")
    return gait_text(g, r, robot_ref=robot_ref, description=desc, mu=res.spec.mu,
                     invariance="auto", header=header, thrust=thrust,
                     thrust_comment="designed constant thrust [N]")


def yaml_header(res: DesignResult, provenance: dict, report_name: str,
                render: Callable[[str], str] = str) -> list[str]:
    """Comment lines recording how the gait was made (command, date, objective, margins), with
    a ``WARNING:`` line per warning of the design (an uncertified optimum, unbounded joints);
    ``render`` writes the parameters a warning mentions (in backquotes) as the caller
    names them."""
    s, chk = res.spec, res.check
    o, m = chk.get("orbit", {}), chk.get("margins", {})
    con, sw = chk.get("contact", {}), chk.get("swing", {})
    obj_unit = OBJECTIVE_UNITS[s.objective]
    rng = {k: v for k, v in (m.get("joint_range") or {}).items() if v is not None}
    out = [
        f"Gait designed by thrustwalk design-gait (thrustwalk {provenance.get('version')}), "
        f"{provenance.get('created_utc')}.",
        *(f"WARNING: {render(w)}." for w in res.warnings),
        f"command: {provenance.get('command')}",
        f"Objective ({s.objective}): {objective_definition(s, short=True)}"
        + f" = {res.objective:.6g} {obj_unit} on the periodic orbit; peak torque "
        f"{chk['cost']['peak']:.4g} N m.",
        f"Variables: pre-impact posture q^-, Bezier columns 2..{s.order - 1} (order "
        f"{s.order}; invariance: auto), zeta^-" + (", constant thrust" if s.thrust_design
                                                   else "") + f"; SLSQP, {s.starts} start(s), "
        f"seed {s.seed}.",
        f"Orbit: stable, delta_zero^2 = {o['delta_zero_sq']:.4f} (<= {s.max_delta_sq:g}), "
        f"{o['speed']:.4f} m/s, step {o['step_length']:.4f} m, step time "
        f"{o['step_time']:.4f} s, zeta* = {o['zeta_star']:.6g} kg^2 m^4/s^2.",
        f"Swing foot: {fmt_margin(sw['mid_step_height'] * 100, '.2f', HEIGHT_TOL * 100)} cm "
        f"at mid-step (>= {s.clearance * 100:g} cm), >= "
        f"{fmt_margin(sw['min_height_window'] * 1000, '.2f', HEIGHT_TOL * 1000)} mm for s in "
        f"[0.05, 0.95], >= 0 over the step.",
        f"Stance: F_v >= {con['min_vertical_force']:.4g} N (>= {res.eps:.4g} N), |F_h|/F_v <= "
        f"{con['max_friction_ratio']:.3f} (mu = {s.mu:g}). Impact: |F_h|/F_v = "
        f"{con['impact_friction_ratio']:.3f}, trailing foot lifts off at "
        f"{con['liftoff_velocity']:.3f} m/s; the swing foot touches down at "
        f"{o['touchdown_velocity']:.3f} m/s (<= -{s.min_touchdown_velocity:g}).",
    ]
    tr = m.get("thrust_range")
    if s.thrust_range is not None and tr:
        out.append(f"Also feasible on the orbit of every constant {s.thrust_range[0]} thrust in "
                   f"[{s.thrust_range[1]:g}, {s.thrust_range[2]:g}] N: F_v margin >= "
                   f"{fmt_margin(tr['vertical_force'], '.4g')} N, friction margin >= "
                   f"{fmt_margin(tr['friction'], '.3f')}.")
    if rng:
        out.append("Joint-range margins [rad]: "
                   + ", ".join(f"{k} {fmt_margin(v, '.3f', RANGE_TOL)}" for k, v in rng.items())
                   + ".")
    out.append(f"Every margin and the fixed point: {report_name}. Re-check: thrustwalk "
               "limit-cycle / feasibility with this file.")
    return out


def with_name(res: DesignResult, name: str) -> DesignResult:
    """The same result with the gait renamed."""
    return replace(res, gait=replace(res.gait, name=name))


def reload_check(model: CompiledModel, text: str, file: str, res: DesignResult) -> dict:
    """Load the gait file text back as the file ``file`` would be read (its ``robot:`` reference
    must name the robot's file) and compare its fixed point with the design's: returns
    ``{zeta_star, reference, relative_error, coefficients_error}``."""
    g, source = load_gait_text(text, file)
    robot = model.robot
    if not same_robot_file(robot, g.robot):
        raise ComputationError(f"the written gait names robot {g.robot!r}, which is not the "
                               f"robot file {robot.source_file}")
    # as load_walker reads it (bound, the impact posture checked, invariance applied), on the
    # design's own model (a slope-frame one for a slope design)
    walker = assemble_walker(robot, g, source, model=model)
    g, zd = walker.gait, walker.zd
    schedule = (walker.gait_schedule("the reload check") if g.thrust is not None
                else Schedule.constant(zd, np.zeros((1, model.n_thrusters))))
    lc = limit_cycles(zd, schedule)[0]
    ref = res.check["orbit"]["zeta_star"]
    got = lc.zeta_star if lc.exists else None
    err = abs(got - ref) / abs(ref) if got is not None else float("inf")
    return {"zeta_star": got, "reference": ref, "relative_error": err,
            "coefficients_error": float(np.abs(np.array(g.A) - np.array(res.gait.A)).max())}


@dataclass(frozen=True)
class DesignGaitResult:
    """A gait design (:class:`~thrustwalk_cli.design.solver.DesignResult`) for one robot.

    ``success`` (= ``design.feasible``): the chosen gait passed the independent re-check;
    ``reason`` says why not otherwise (the blocking constraint family). ``compare``: the same
    objective and constraints evaluated on an existing gait, when one was given.
    """

    model: CompiledModel = field(repr=False)
    design: DesignResult
    compare: dict | None = None

    __repr__ = result_repr

    @property
    def robot(self) -> Robot:
        """The robot the gait is designed for (``model.robot``)."""
        return self.model.robot

    @property
    def success(self) -> bool:
        """The design is feasible: it meets every requirement of the spec."""
        return self.design.feasible

    @property
    def reason(self) -> str:
        """The design's verdict in words: what it met, or why it is infeasible."""
        return self.design.reason

    def _thrust(self) -> np.ndarray:
        """The design's constant thrust per thruster [N] (0 where none was designed)."""
        F = np.zeros(self.model.n_thrusters)
        F[:len(self.design.thrust)] = self.design.thrust
        return F

    @cached_property
    def energy(self) -> OrbitEnergy:
        """The designed gait's step energies on its periodic orbit at the design's constant
        thrust (SPEC 15, :func:`~thrustwalk_cli.energetics.orbit.orbit_energy`: the block
        limit-cycle writes per case), computed when first asked for."""
        zd = zero_dynamics(self.model, self.design.gait)
        sched = Schedule.constant(zd, self._thrust()[None, :])
        lc = limit_cycles(zd, sched)
        return orbit_energy(zd, sched, lc)[0]

    def energy_record(self) -> dict:
        """The report's ``energy`` block: the orbit's energies and CoT (SPEC 15; None with the
        reason where a model is missing), at the design's thrust ``thrust`` [N] per thruster."""
        try:
            block = self.energy.record()
        except (ComputationError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            # the report of a search is never lost to its energy: said, not computed
            block = {"exists": False, "reason": f"energy not computed: {exc}"}
        return {"thrust": self._thrust().tolist(), **block,
                "cot_definition": "E / (m g d), d the step length; mechanical: joints' "
                                  "positive work + thrusters' positive work on the walker; "
                                  "total: joints' electrical energy (motor models) + "
                                  "thrusters' input energy (power models)",
                "weight": self.robot.weight}

    def document(self) -> dict:
        """The JSON body of ``NAME.report.json`` (provenance is added by the command), with
        the designed gait's energy block (:meth:`energy_record`)."""
        rob = self.robot
        doc = {"schema_version": SCHEMA_VERSION,
               "robot": {"name": rob.name, "file": rob.source_file},
               "thrusters": rob.thruster_names, **report_record(self.design),
               "energy": self.energy_record()}
        gamma = self.slope
        if gamma != 0.0:  # SPEC 14: which slope the design holds for, the climb rate
            doc["units"] = {**doc["units"], "slope": "rad", "climb_rate": "m/s"}
            doc = {**doc, "slope": slope_record(gamma)}
            orbit = doc.get("fixed_point")
            if isinstance(orbit, dict) and "speed" in orbit:
                doc["fixed_point"] = {**orbit,
                                      "climb_rate": climb_rate(orbit["speed"], gamma)}
        if self.compare is not None:
            doc["compare"] = self.compare
        return doc

    @property
    def slope(self) -> float:
        """The ground angle [rad, positive uphill] the gait is designed for (SPEC 14; 0:
        level ground)."""
        return float(getattr(self.model, "slope", 0.0))

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the design does not guarantee (an optimum SLSQP did not certify, joints the
        robot file leaves without torque limits or ranges); parameters in backquotes."""
        return self.design.warnings

    def gait_text(self, provenance: dict, robot_ref: str, report_name: str,
                  render: Callable[[str], str] = str, failure: str | None = None) -> str:
        """The designed gait as a YAML file (``invariance: auto``), with a header recording the
        command, the objective, every margin and the warnings (``render``: how parameters in
        backquotes are written). ``failure``: the gait could not be verified and kept (the
        reload check or writing failed); the header then opens with a line saying so."""
        head = [] if failure is None else [failed_line(failure)]
        try:
            head += yaml_header(self.design, provenance, report_name, render)
        except Exception:  # noqa: BLE001 - a failed gait is still written, with less header
            if failure is None:
                raise
            head.append(f"Every margin and the fixed point: {report_name}.")
        if self.slope != 0.0:
            g = self.slope
            v = self.design.check.get("orbit", {}).get("speed")
            climb = "" if v is None else f", climb rate {climb_rate(v, g):.4g} m/s"
            head.insert(1 if failure is None else 2, (
                f"Designed for the slope {g!r} rad ({math.degrees(g):.4g} deg, positive "
                f"uphill; SPEC 14): speed and step length along the ground{climb}. Re-check: "
                "thrustwalk limit-cycle with this file on that slope."))
        return gait_yaml(self.design, self.model, robot_ref, head)

    def tables(self) -> dict[str, Table]:
        """``NAME.starts``: one row per solver start (its status, SLSQP exit code, objective
        and largest constraint violation in the objective's unit and the constraints' SI
        units, iterations, evaluations, wall time [s], the feasibility restoration's
        iterations and whether its point was kept); the same values as the report's
        ``starts`` (no number is NaN: a start without a value leaves the cell empty). The
        command writes the report and the gait, not this table."""
        head = ["start", "status", "slsqp_code", "objective", "max_violation", "iterations",
                "evaluations", col("seconds", "s"), "restoration_iterations", "restored"]
        rows = [[t.index, t.status, t.code, _num(t.objective), _num(t.max_violation),
                 t.iterations, t.evaluations, t.seconds, t.restoration, t.restored]
                for t in self.design.starts]
        return {f"{self.design.gait.name}.starts": Table(
            head, rows, [f"solver starts of the design of {self.design.gait.name} "
                         f"({self.design.spec.objective} objective)"])}

    def stick_frames(self, instants: int = 10, path_points: int = 201) -> dict:
        """:func:`stick_frames` of the designed gait."""
        return stick_frames(self.model, self.design.gait, instants, path_points)

    def figures(self, titles: bool = False) -> dict:
        """``NAME.stick``: the designed gait as a stick figure over one step (only for a
        feasible design; :func:`thrustwalk_cli.plots.design_gait.stick_figure`)."""
        if not self.success:
            return {}
        from ..plots.design_gait import stick_figure

        g = self.design.gait
        return {f"{g.name}.stick": stick_figure(
            self.stick_frames(), title=f"{self.robot.name}: {g.name}" if titles else "")}


FAILED_MARK = "NOT A VERIFIED GAIT"


def failed_line(why: str) -> str:
    """The first header line of a gait kept after a failure (see :meth:`gait_text`)."""
    return (f"{FAILED_MARK}: design-gait failed after the search ({why}); this is the design "
            "it found, kept so that the run is not lost. Re-check it (thrustwalk limit-cycle / "
            "feasibility) before using it.")


def stick_frames(model: CompiledModel, gait: Gait, instants: int = 10,
                 path_points: int = 201) -> dict:
    """The gait as a stick figure over one step, in metres with the stance foot at the origin
    (SPEC 1, 2): at ``instants`` phases ``s = k/(instants - 1)`` the configuration
    ``q = q_Z(alpha)``, ``alpha = alpha_i + s (alpha_f - alpha_i)``, on the zero-dynamics
    surface (the orbit passes every ``alpha`` of the step once) and per link its frame origin
    and end point ``links[k, j] = [[x0, y0], [x1, y1]]``; the swing foot ``swing_foot[k]`` =
    ``p_2(q)`` at each instant and its path ``swing_path`` over ``path_points`` phases;
    ``roles[j]``: ``stance`` / ``swing`` / ``body``. Plain arrays, for
    :func:`thrustwalk_cli.plots.design_gait.stick_figure`."""
    from ..design.problem import legs
    from ..hzd.constraints import gait_maps

    if instants < 2 or path_points < 2:
        raise InputError.param("instants", "need at least 2 instants and 2 path points")
    maps = gait_maps(model, gait)
    s = np.linspace(0.0, 1.0, instants)
    q = maps.q_Z(maps.alpha_i + s * maps.span)
    sp = np.linspace(0.0, 1.0, path_points)
    path = model.p_swing(maps.q_Z(maps.alpha_i + sp * maps.span))
    lg = legs(model)
    roles = ["stance" if j in lg.stance else "swing" if j in lg.swing else "body"
             for j in range(len(model.robot.links))]
    return {"s": s, "q": q, "links": model.link_points(q).reshape(instants, -1, 2, 2),
            "swing_foot": model.p_swing(q), "swing_path": path, "roles": roles,
            "link_names": list(model.robot.link_names)}


def design_gait(robot_or_walker: Robot | CompiledModel | Walker | None = None,
                spec: DesignSpec | None = None, *, compare: Walker | None = None,
                progress: Callable[[int, int, str], None] | None = None,
                initial: WarmStart | None = None, slope: float = 0.0,
                robot: Robot | CompiledModel | Walker | None = None,
                **settings) -> DesignGaitResult:
    """Design a gait for a robot (:func:`solve_design`, SPEC 2, 3, 5) and optionally evaluate an
    existing gait (``compare``) with the same objective and constraints. ``robot_or_walker``: a
    :class:`Robot` (compiled by :func:`load_model`, cached by structure), its
    :class:`CompiledModel`, or a :class:`Walker` (its robot; its gait is not a start: pass it
    as ``compare`` to evaluate it); ``robot=`` is its deprecated old name (one release, a
    DeprecationWarning). The design's settings: the fields of :class:`DesignSpec` as keywords
    (``tw.design_gait(robot, speed=0.6, objective="cot")``), or one ``spec`` built once and
    reused (not both). ``progress(done, total, message)``
    after every solver start. ``initial``: a finished neighbouring design to start from
    (continuation; replaces the default start). ``slope`` [rad, positive uphill, |slope| <
    pi/2]: design for that ground (SPEC 14): the design problem's gravity terms, world-frame
    thrusters and contact terms are those of the slope frame
    (:func:`~thrustwalk_cli.model.slope.slope_model`; the kinematics, the impact and the guard
    do not change), so the designed orbit walks the slope at the target speed along the ground;
    the report gains the ``slope`` block and the fixed point its climb rate, the gait file's
    header the slope. 0: level ground, bit for bit."""
    robot = as_model(renamed_keyword("design_gait", "robot_or_walker", robot_or_walker,
                                     "robot", robot), "robot_or_walker")
    slope = check_slope(slope)
    if slope != 0.0:
        robot = slope_model(robot, slope)
    if settings:
        known = [f.name for f in fields(DesignSpec)]
        for name in settings:
            if name not in known:
                raise InputError.param(name, "not a setting of design_gait (they are: "
                                             f"{', '.join(known)})")
        if spec is not None:
            raise InputError.param(next(iter(settings)), "give the design's settings as "
                                   "keywords or as spec=DesignSpec(...), not both")
        spec = DesignSpec(**settings)
    check_instance("spec", spec, DesignSpec, "a DesignSpec (tw.DesignSpec(speed=...)), or "
                                             "the settings as keywords (speed=...)")
    if compare is not None:
        check_walker(compare, "compare")
    check_callable("progress", progress)
    check_instance("initial", initial, WarmStart, "a WarmStart", optional=True)
    spec.validate(robot)
    if compare is not None and compare.robot.name != robot.robot.name:
        raise InputError.param("compare", f"gait {compare.gait.name!r} is for robot "
                                          f"{compare.robot.name!r}, not {robot.robot.name!r}")
    res = solve_design(robot, spec, progress=progress, initial=initial)
    res = with_name(res, spec.name)
    cmp = None
    if compare is not None:
        cmp = {"gait": compare.gait.name, "file": compare.gait.source_file,
               **check_gait(robot, compare.gait, spec)}
    return DesignGaitResult(robot, res, cmp)


show_options(design_gait, DesignSpec)
