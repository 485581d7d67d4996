"""The ``limit-cycle`` study: zero-dynamics limit cycles over a constant-thrust sweep, or for the
gait's own thrust schedule (SPEC 3, 4).

For every case: the Poincare fixed point ``zeta* = V_Z(alpha_f) / (1 - delta_zero^2)``
[kg^2 m^4/s^2], stability (``delta_zero^2``), the step time [s], step length [m], speed [m/s],
``sigma_N^+/-`` [kg m^2/s], ``alpha'^+/-`` [rad/s], the exact minimum and maximum of
``|alpha'|``, the swing foot's touchdown velocity [m/s], the contact verdict on the orbit (SPEC
5: the exact stance force in the friction cone with ``F^v >= eps``, an admissible impact, the
trailing foot lifting off; the same code as the ``feasibility`` command) and a verdict:
``walkable`` only when the orbit exists, is stable, the gait is hybrid-invariant, the swing
foot stays above the ground and every contact condition holds. The sweep is vectorised:
1,000 values cost a few orbits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..contact.evaluate import CaseResult, check_contact_options, evaluate
from ..contact.terms import scuff_reason
from ..energetics.orbit import OrbitEnergy, orbit_energy
from ..errors import InputError, check_flag, check_number, check_numbers, check_text
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics, grazing_warning, limit_cycles
from ..thrust.schedule import Schedule
from ..walker import Walker, check_walker
from .documents import (
    SCHEMA_VERSION,
    Table,
    climb_rate,
    col,
    gait_record,
    result_repr,
    robot_record,
    slope_record,
    units,
)

DEFAULT_THRUST = (0.0, -10.0, -20.0, -30.0, -40.0, -50.0)  # [N] the paper's sweep
ORBIT_SAMPLES = 201  # samples of each orbit in the CSV table
ROW_BYTES = 120  # about the size of one CSV row, for the output-size estimate
MAX_OUTPUT = 100e6  # [bytes] default limit of the CSV table


def contact_record(c: CaseResult) -> dict:
    """The contact verdict of one case on its orbit (SPEC 5; the ``feasibility`` command's
    numbers for the same case)."""
    return {"feasible": c.feasible, "reason": c.reason,
            "min_vertical_force": c.min_vertical_force,
            "alpha_at_min_vertical_force": c.alpha_at_min_vertical_force,
            "max_friction_ratio": c.max_friction_ratio,
            "alpha_at_max_friction_ratio": c.alpha_at_max_friction_ratio,
            "impact_friction_ratio": c.impact_friction_ratio,
            "liftoff_velocity": c.liftoff_velocity}


def cycle_record(lc: LimitCycle, thrust: float | None, zd: ZeroDynamics, verdict: str,
                 walkable: bool, contact: CaseResult, energy: OrbitEnergy | None = None
                 ) -> dict:
    """One JSON entry per case (keys fixed by the limit-cycle issue; SI units); on a slope
    (SPEC 14) with the climb rate beside the speed; with ``energy`` its block (SPEC 15)."""
    rec = _cycle_record(lc, thrust, zd, verdict, walkable, contact)
    if zd.slope != 0.0:
        rec["climb_rate"] = climb_rate(lc.speed, zd.slope)
    if energy is not None:
        rec["energy"] = energy.record()
    return rec


def _cycle_record(lc: LimitCycle, thrust: float | None, zd: ZeroDynamics, verdict: str,
                  walkable: bool, contact: CaseResult) -> dict:
    return {
        "thrust": thrust,
        "delta_zero_sq": lc.delta_zero_sq,
        "zeta_star": lc.zeta_star,
        "exists": lc.exists,
        "stable": lc.stable,
        "walkable": walkable,
        "verdict": verdict,
        "reason": lc.reason,
        "contact": contact_record(contact),
        "step_time": lc.step_time,
        "step_time_error_estimate": lc.step_time_error,
        "step_length": lc.step_length,
        "speed": lc.speed,
        "sigma_minus": lc.sigma_minus,
        "sigma_plus": lc.sigma_plus,
        "alpha_dot_minus": lc.alpha_dot_minus,
        "alpha_dot_plus": lc.alpha_dot_plus,
        "min_abs_alpha_dot": lc.min_abs_alpha_dot,
        "alpha_at_min": lc.alpha_at_min,
        "max_abs_alpha_dot": lc.max_abs_alpha_dot,
        "alpha_at_max": lc.alpha_at_max,
        "min_zeta": lc.min_zeta,
        "touchdown_velocity": lc.touchdown_velocity,
        "V_Z_alpha_f": lc.V_f,
        "invariance_residual": {"position": zd.maps.position_residual,
                                "velocity": zd.maps.velocity_residual},
    }


@dataclass(frozen=True)
class LimitCycleResult:
    """Limit cycles of one walker for constant thrust values of one thruster, or for the
    gait's own schedule (``source == "gait"``) (SPEC 3, 4).

    ``cycles[i]`` belongs to ``thrust[i]`` [N] (None for a piecewise gait schedule); each says
    whether its orbit ``exists``, is ``stable``, and why not (``reason``). ``contact[i]``: the
    contact verdict on that orbit (SPEC 5) at friction coefficient ``mu`` and least vertical
    force ``eps`` [N]. ``walkable[i]`` adds the gait's validity (hybrid invariance), the swing
    foot's clearance and the contact verdict; ``verdict`` says it in words. ``success``: every
    case is walkable. ``thruster`` is None for a robot without thrusters (then every value is
    0) and for a gait schedule on several thrusters.
    """

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    thrust: tuple[float | None, ...]
    thruster: int | None
    cycles: tuple[LimitCycle, ...]
    source: str = "values"
    schedule: Schedule | None = field(default=None, repr=False)
    contact: tuple[CaseResult, ...] = field(default=(), repr=False)
    mu: float = 0.7
    eps: float = 0.0
    energy: tuple[OrbitEnergy, ...] = field(default=(), repr=False)

    name = "limit_cycles"

    @property
    def thruster_name(self) -> str | None:
        """The thruster the constant thrust drives (None: the robot has none)."""
        return None if self.thruster is None else self.walker.robot.thruster_names[self.thruster]

    def _verdict(self, lc: LimitCycle, contact: CaseResult) -> tuple[str, bool]:
        if not lc.exists:
            return lc.missing, False
        if not lc.stable:
            return lc.reason, False
        sw = self.walker.swing
        if sw["scuffs"]:
            return f"not walkable: {scuff_reason(sw)}", False
        if not contact.feasible:
            why = contact.reason.removeprefix("infeasible: ")
            return f"not walkable: stable orbit, contact infeasible: {why}", False
        return (f"walkable: stable periodic orbit, contact-feasible (mu = {self.mu:g}, F^v >= "
                f"{self.eps:g} N)"), True

    @property
    def walkable(self) -> tuple[bool, ...]:
        """Per thrust case: a stable periodic orbit with admissible contact (SPEC 3, 5)."""
        return tuple(self._verdict(c, f)[1] for c, f in zip(self.cycles, self.contact))

    @property
    def verdicts(self) -> tuple[str, ...]:
        """Per thrust case: ``walkable``, or why not in words."""
        return tuple(self._verdict(c, f)[0] for c, f in zip(self.cycles, self.contact))

    @property
    def _label(self) -> str:
        return self.thruster_name or "(no thruster)"

    @property
    def success(self) -> bool:
        """Every thrust case is walkable."""
        return all(self.walkable)

    @property
    def reason(self) -> str:
        """How many cases are walkable and the first verdict of one that is not."""
        n = sum(self.walkable)
        if n == len(self.cycles):
            return f"a walkable periodic orbit for every case ({n})"
        bad = next(v for v, ok in zip(self.verdicts, self.walkable) if not ok)
        return f"a walkable periodic orbit for {n} of {len(self.cycles)} cases; first: {bad}"

    def document(self) -> dict:
        """The JSON body of ``limit_cycles.json`` (SI units, see ``units``)."""
        zd = self.walker.zd
        d2 = zd.delta_zero_sq
        af = np.array(zd.alpha_f)
        j = self.thruster
        sw = {k: v for k, v in self.walker.swing.items() if k not in ("alpha", "height")}
        gamma = None if j is None else float(zd.Gamma(af)[j])
        on_slope = ({"climb_rate": "m/s", "slope": "rad"} if zd.slope != 0.0 else {})
        return {
            "schema_version": SCHEMA_VERSION,
            "units": units("thrust", "zeta", "sigma_N", "alpha", "alpha_dot", "step_time",
                           "step_length", "speed", "height", "delta_zero_sq",
                           "invariance_residual", **on_slope),
            "robot": robot_record(zd),
            "gait": gait_record(zd),
            **({"slope": slope_record(zd.slope)} if zd.slope != 0.0 else {}),
            "source": self.source,
            "thruster": self.thruster_name,
            "success": self.success,
            "reason": self.reason,
            "warnings": list(self.walker.warnings) + self.warnings(),
            "swing_foot": sw,
            "contact": {"mu": self.mu, "min_vertical_force": self.eps,
                        "checks": "on each orbit (SPEC 5, as the feasibility command): "
                                  "F^v >= min_vertical_force and |F^h| <= mu F^v along the "
                                  "step (worst points polished), impact impulse in the cone, "
                                  "trailing foot lifting off"},
            "zero_dynamics": {
                "delta_zero": zd.delta_zero, "delta_zero_sq": d2,
                "quadrature_nodes": zd.nodes, "integral_error_estimate": zd.integral_error,
                "integral_relative_error_estimate": zd.integral_error / zd.integral_scale,
                "kappa1_ok": zd.kappa1_ok, "kappa1_reason": zd.kappa1_reason,
                "hybrid_invariant": zd.invariant,
                "fixed_point_formula": "zeta* = V_Z(alpha_f) / (1 - delta_zero^2)",
                "Gamma_alpha_f": gamma,
                "V0_alpha_f": float(zd.V0(af)),
                "zeta_star_at_zero_thrust": zd.fixed_point() if d2 != 1.0 else None,
                "zeta_star_per_newton": (zd.fixed_point_of(gamma)
                                         if d2 != 1.0 and gamma is not None else None),
            },
            "gait_schedule": (None if self.source != "gait" else {
                "knots_alpha": self.schedule.knots.tolist(),
                "force": {n: self.schedule.force[0, :, t].tolist()
                          for t, n in enumerate(self.walker.robot.thruster_names)},
                "generalized": self.schedule.generalized[0].tolist()}),
            "energy": {
                "method": "on each orbit by quadrature in alpha (SPEC 15, exact: no "
                          "simulation); kinks of max(0, .) and |.| located",
                "cot": "E / (m g d), d the step length; mechanical: joints' positive work + "
                       "thrusters' positive work on the walker; total: joints' electrical "
                       "energy (motor models) + thrusters' input energy (power models)",
                "weight": self.walker.robot.weight,
            },
            "cycles": [cycle_record(lc, v, zd, verdict, ok, f, e) for lc, v, verdict, ok, f, e
                       in zip(self.cycles, self.thrust, self.verdicts, self.walkable,
                              self.contact, self.energy or (None,) * len(self.cycles))],
        }

    def warnings(self) -> list[str]:
        """Grazing touchdowns (:func:`grazing_warning`), one line per thrust value."""
        out = []
        for lc, v in zip(self.cycles, self.thrust):
            w = grazing_warning(lc)
            if w:
                out.append(f"{'gait thrust' if v is None else f'thrust {v:g} N'}: {w}")
        return out

    def tables(self) -> dict[str, Table]:
        """``limit_cycles.csv``: the sampled orbits (stance samples, then the impact jump)."""
        zd = self.walker.zd
        header = [col("thrust", "N"), "exists", "segment", col("alpha", "rad"),
                  col("alpha_dot", "rad/s"), col("sigma", "kg m^2/s"),
                  col("zeta", "kg^2 m^4/s^2"), "reason", "cot_mechanical", "cot_total"]
        rows: list[list] = []
        energies = self.energy or (None,) * len(self.cycles)
        for lc, v, en in zip(self.cycles, self.thrust, energies):
            if not lc.exists:
                rows.append([v, "false", "none", None, None, None, None, lc.reason, None, None])
                continue
            cot = en.cot() if en is not None and en.exists else {}
            c2 = [cot.get("mechanical"), cot.get("total")]
            o = lc.orbit
            for a, ad, s, z in zip(o["alpha"], o["alpha_dot"], o["sigma"], o["zeta"]):
                rows.append([v, "true", "stance", float(a), float(ad), float(s), float(z), ""]
                            + c2)
            rows.append([v, "true", "impact", zd.alpha_f, lc.alpha_dot_minus, lc.sigma_minus,
                         lc.zeta_star, ""] + c2)
            rows.append([v, "true", "impact", zd.alpha_i, lc.alpha_dot_plus, lc.sigma_plus,
                         lc.zeta_plus, ""] + c2)
        notes = [
            "one row per orbit sample; segment 'impact' rows: the pre-impact state, then the "
            "post-impact state (the jump)",
            "thrust_N empty: the gait's piecewise schedule (gait_schedule in the JSON)",
            "cot_mechanical, cot_total: the case's costs of transport (SPEC 15; the JSON's "
            "energy block), empty where a model is missing (energy.missing in the JSON)",
        ]
        if zd.slope != 0.0:
            notes.append(f"on the slope {zd.slope:.17g} rad (positive uphill; SPEC 14)")
        return {"limit_cycles": Table(header, rows, notes)}

    def figures(self, titles: bool = False) -> dict:
        """``limit_cycles`` (the phase portrait, black lines at round thrust values of a fine
        sweep) and ``fixed_point_shift`` (zeta* and speed versus thrust with the exact affine
        law; for constant thrust only)."""
        from ..plots.limit_cycle import fixed_point_shift, phase_portrait
        from ..plots.style import black_step

        zd, w = self.walker.zd, self.walker
        orbits, jumps = [], []
        for lc in self.cycles:
            if not lc.exists:
                orbits.append(None)
                jumps.append(None)
                continue
            o = lc.orbit
            orbits.append({"alpha": o["alpha"], "alpha_dot": o["alpha_dot"], "sigma": o["sigma"]})
            jumps.append((zd.alpha_f, lc.alpha_dot_minus, zd.alpha_i, lc.alpha_dot_plus))
        values = [0.0 if v is None else v for v in self.thrust]
        label = (f"thrust {self.thruster_name} [N]" if self.thruster is not None
                 else "gait thrust schedule" if self.source == "gait"
                 else "thrust [N] (no thruster)")
        out = {"limit_cycles": phase_portrait(
            values, orbits, jumps, value_label=label, black_every=black_step(values, "N"),
            title=f"{w.name}: zero-dynamics limit cycles" if titles else "")}
        if self.thruster is not None and all(v is not None for v in self.thrust):
            doc = self.document()["zero_dynamics"]
            out["fixed_point_shift"] = fixed_point_shift(
                values, [c.zeta_star if c.exists else None for c in self.cycles],
                [c.speed for c in self.cycles], doc["zeta_star_per_newton"],
                doc["zeta_star_at_zero_thrust"], thruster=self.thruster_name,
                title=f"{w.name}: fixed-point shift" if titles else "")
        return out


def limit_cycle(walker: Walker, thrust: Sequence[float] | None = None,
                thruster: str | None = None, max_output: float = MAX_OUTPUT, *,
                mu: float | None = None, min_vertical_force: float = 0.0,
                slope: float = 0.0, energy: bool = True) -> LimitCycleResult:
    """Limit cycles for constant thrust values ``thrust`` [N] on ``thruster`` (default: the
    first) (SPEC 3, 4), in one vectorised evaluation, each with its contact verdict (SPEC 5)
    at friction coefficient ``mu`` [1] (default: the gait's) and least vertical ground force
    ``min_vertical_force`` [N]. Without ``thrust``: the gait's own ``thrust:`` schedule when it
    has one, else the paper's sweep 0 to -50 N.

    ``max_output`` [bytes]: a sweep whose CSV table would be larger is refused before any work.

    ``slope`` [rad, positive uphill, |slope| < pi/2]: the ground angle (SPEC 14; gravity and
    world-frame thrusters turned into the slope frame, :meth:`Walker.on_slope`); the speed
    is along the ground and the document gives the climb rate ``speed sin(slope)`` beside
    it. 0: level ground, bit for bit as without it.

    ``energy``: with False the orbits' energies (SPEC 15) are not computed and the document has
    no per-case ``energy`` block (the benchmark measures their cost this way).
    """
    check_walker(walker)
    walker = walker.on_slope(slope)
    thrust = check_numbers("thrust", thrust, optional=True, min_len=0)
    check_text("thruster", thruster, optional=True)
    max_output = check_number("max_output", max_output, gt=0, largest=1e15)
    mu = check_number("mu", mu, optional=True)  # its range: check_contact_options
    min_vertical_force = check_number("min_vertical_force", min_vertical_force)
    energy = check_flag("energy", energy)
    zd = walker.zd
    mu = walker.gait.mu if mu is None else float(mu)
    eps = float(min_vertical_force)
    check_contact_options(mu, eps)
    gait_thrust = walker.gait.thrust
    if thrust is None and gait_thrust is not None:
        if thruster is not None:
            raise InputError.param("thruster", "the gait's thrust: section names its "
                                               "thrusters; give `thrust` values to sweep one")
        sched = walker.gait_schedule()
        j, value = _constant_part(walker, sched)
        cycles = limit_cycles(zd, sched)
        return LimitCycleResult(walker, (value,), j, tuple(cycles), "gait", sched,
                                _contact(walker, sched, cycles, mu, eps), mu, eps,
                                _energy(zd, sched, cycles, energy))
    default = DEFAULT_THRUST if walker.robot.thrusters else (0.0,)
    values = tuple(float(v) for v in (default if thrust is None else thrust))
    if not values:
        raise InputError.param("thrust", "no thrust values")
    size = len(values) * (ORBIT_SAMPLES + 2) * ROW_BYTES
    if size > max_output:
        raise InputError.param("max_output", f"{len(values)} thrust values make a CSV table of "
                                             f"about {size / 1e6:.0f} MB, above the limit of "
                                             f"{max_output / 1e6:g} MB: sweep fewer values or "
                                             "raise the limit")
    j = walker.robot.driven_thruster(thruster)
    walker.robot.check_no_thrust(values)
    sched = Schedule.on_thruster(zd, values, j, zd.model.n_thrusters)
    sched.check_limits(zd.model.robot, "thrust", ())
    cycles = limit_cycles(zd, sched)
    return LimitCycleResult(walker, values, j, tuple(cycles), "values", sched,
                            _contact(walker, sched, cycles, mu, eps), mu, eps,
                            _energy(zd, sched, cycles, energy))


def _energy(zd: ZeroDynamics, sched: Schedule, cycles: list[LimitCycle], on: bool
            ) -> tuple[OrbitEnergy, ...]:
    """The energies of every case's orbit (SPEC 15); none when ``on`` is false."""
    return tuple(orbit_energy(zd, sched, cycles)) if on else ()


def _contact(walker: Walker, sched: Schedule, cycles: list[LimitCycle], mu: float,
             eps: float) -> tuple[CaseResult, ...]:
    """The contact verdict of every case on its orbit (SPEC 5): the exact terms only (no
    polynomial fits, no torque maxima), the same verdict as the ``feasibility`` command."""
    rep = evaluate(walker.model, walker.zd, sched, mu=mu, eps=eps, cycles=cycles,
                   swing=walker.swing, polynomial=False, torque=False, profiles=False)
    return tuple(rep.cases)


def _constant_part(walker: Walker, sched: Schedule) -> tuple[int | None, float | None]:
    """(thruster, value) when a schedule is one constant thrust on one thruster, else
    (None, None)."""
    F = sched.force[0]
    if F.shape[-1] == 0 or np.any(sched.generalized) or not np.all(F == F[0]):
        return None, None
    used = np.flatnonzero(F[0])
    if len(used) > 1:
        return None, None
    j = int(used[0]) if len(used) else 0
    return j, float(F[0, j])
