"""The ``limit-cycle`` study: zero-dynamics limit cycles over a constant-thrust sweep
(SPEC 3, 4).

For every thrust value [N] of one thruster: the Poincare fixed point
``zeta* = V_Z(alpha_f) / (1 - delta_zero^2)`` [kg^2 m^4/s^2], stability (``delta_zero^2``), the
step time [s], step length [m], speed [m/s], ``sigma_N^+/-`` [kg m^2/s], ``alpha'^+/-`` [rad/s],
the exact minimum and maximum of ``|alpha'|`` and the swing foot's touchdown velocity [m/s]. The
sweep is vectorised: 1,000 values cost a few orbits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..hzd.zero_dynamics import (
    LimitCycle,
    Schedule,
    ZeroDynamics,
    grazing_warning,
    limit_cycles,
)
from ..walker import Walker
from .records import Table, constant_thrust, gait_record, robot_record

UNITS = {
    "thrust": "N", "zeta": "kg^2 m^4 / s^2 (zeta = sigma_N^2 / 2)", "sigma_N": "kg m^2 / s",
    "alpha": "rad", "alpha_dot": "rad / s", "step_time": "s", "step_length": "m",
    "speed": "m / s", "invariance_residual": "rad (position), 1 (velocity direction)",
    "touchdown_velocity": "m / s (vertical swing-foot velocity just before impact; < 0 down)",
}


def cycle_record(lc: LimitCycle, thrust: float, zd: ZeroDynamics) -> dict:
    """One JSON entry per thrust value (keys fixed by the limit-cycle issue; SI units)."""
    return {
        "thrust": thrust,
        "delta_zero_sq": lc.delta_zero_sq,
        "zeta_star": lc.zeta_star,
        "exists": lc.exists,
        "stable": lc.stable,
        "reason": lc.reason,
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
    """Limit cycles of one walker for constant thrust values of one thruster (SPEC 3, 4).

    ``cycles[i]`` belongs to ``thrust[i]`` [N]; each says whether its orbit ``exists``, is
    ``stable``, and why not (``reason``). ``thruster`` is None for a robot without thrusters
    (then every value is 0). ``success`` is true when every value has a stable
    periodic orbit; ``reason`` summarises.
    """

    walker: Walker = field(repr=False)
    thrust: tuple[float, ...]
    thruster: int | None  # None: the robot has no thruster (every value is 0)
    cycles: tuple[LimitCycle, ...]

    name = "limit_cycles"

    @property
    def thruster_name(self) -> str | None:
        """The driven thruster, None for a robot without thrusters."""
        return None if self.thruster is None else self.walker.robot.thruster_names[self.thruster]

    @property
    def _label(self) -> str:
        return self.thruster_name or "(no thruster)"

    @property
    def success(self) -> bool:
        return all(c.stable for c in self.cycles)

    @property
    def reason(self) -> str:
        n = sum(c.stable for c in self.cycles)
        if n == len(self.cycles):
            return f"a stable periodic orbit for every thrust value ({n})"
        return f"a stable periodic orbit for {n} of {len(self.cycles)} thrust values"

    def document(self) -> dict:
        """The JSON body of ``limit_cycles.json`` (SI units, see ``units``)."""
        zd, j = self.walker.zd, self.thruster
        d2 = zd.delta_zero_sq
        af = np.array(zd.alpha_f)
        gamma = None if j is None else float(zd.Gamma(af)[j])
        return {
            "units": UNITS,
            "robot": robot_record(zd),
            "gait": gait_record(zd),
            "thruster": self.thruster_name,
            "zero_dynamics": {
                "delta_zero": zd.delta_zero, "delta_zero_sq": d2,
                "quadrature_nodes": zd.nodes, "integral_error_estimate": zd.integral_error,
                "integral_relative_error_estimate": zd.integral_error / zd.integral_scale,
                "kappa1_ok": zd.kappa1_ok, "kappa1_reason": zd.kappa1_reason,
                "fixed_point_formula": "zeta* = V_Z(alpha_f) / (1 - delta_zero^2)",
                "Gamma_alpha_f": gamma,
                "V0_alpha_f": float(zd.V0(af)),
                "zeta_star_at_zero_thrust": (float(zd.V0(af)) / (1.0 - d2)
                                             if d2 != 1.0 else None),
                "zeta_star_per_newton": (gamma / (1.0 - d2)
                                         if d2 != 1.0 and gamma is not None else None),
            },
            "cycles": [cycle_record(lc, v, zd) for lc, v in zip(self.cycles, self.thrust)],
            "warnings": self.warnings(),
        }

    def warnings(self) -> list[str]:
        """Grazing touchdowns (:func:`grazing_warning`), one line per thrust value."""
        out = []
        for lc, v in zip(self.cycles, self.thrust):
            w = grazing_warning(lc)
            if w:
                out.append(f"thrust {v:g} N: {w}")
        return out

    def tables(self) -> dict[str, Table]:
        """``limit_cycles.csv``: the sampled orbits (stance samples, then the impact jump)."""
        zd = self.walker.zd
        header = ["thrust_N", "exists", "segment", "alpha_rad", "alpha_dot_rad_s",
                  "sigma_kg_m2_s", "zeta", "reason"]
        rows: list[list] = []
        for lc, v in zip(self.cycles, self.thrust):
            if not lc.exists:
                rows.append([v, "false", "none", None, None, None, None, lc.reason])
                continue
            o = lc.orbit
            for a, ad, s, z in zip(o["alpha"], o["alpha_dot"], o["sigma"], o["zeta"]):
                rows.append([v, "true", "stance", float(a), float(ad), float(s), float(z), ""])
            rows.append([v, "true", "impact", zd.alpha_f, lc.alpha_dot_minus, lc.sigma_minus,
                         lc.zeta_star, ""])
            rows.append([v, "true", "impact", zd.alpha_i, lc.alpha_dot_plus, lc.sigma_plus,
                         lc.zeta_plus, ""])
        return {"limit_cycles": Table(header, rows, [
            f"thrustwalk limit cycles: robot {zd.model.robot.name}, gait {zd.gait.name}, "
            f"thruster {self._label}",
            "units: thrust N, alpha rad, alpha_dot rad/s, sigma kg m^2/s, zeta kg^2 m^4/s^2",
            "segment 'impact' rows: pre-impact state then post-impact state (the jump)",
        ])}

    def figures(self) -> dict:
        """``limit_cycles`` (the phase portrait, black every 10 N) and ``fixed_point_shift``
        (zeta* and speed versus thrust with the exact affine law)."""
        from ..plots.limit_cycle import fixed_point_shift, phase_portrait

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
        doc = self.document()["zero_dynamics"]
        return {
            "limit_cycles": phase_portrait(
                list(self.thrust), orbits, jumps,
                value_label=f"thrust {self._label} [N]", black_every=10.0,
                title=f"{w.name}: zero-dynamics limit cycles"),
            "fixed_point_shift": fixed_point_shift(
                list(self.thrust), [c.zeta_star if c.exists else None for c in self.cycles],
                [c.speed for c in self.cycles], doc["zeta_star_per_newton"] or 0.0,
                doc["zeta_star_at_zero_thrust"], thruster=self._label,
                title=f"{w.name}: fixed-point shift"),
        }


def limit_cycle(walker: Walker, thrust: Sequence[float] = (0.0,),
                thruster: str | None = None) -> LimitCycleResult:
    """Limit cycles for constant thrust ``thrust`` [N] on ``thruster`` (default: the first)
    (SPEC 3, 4): one vectorised evaluation of the whole sweep. For a robot without thrusters
    ``thruster`` must be None and every value 0 (:class:`InputError` otherwise)."""
    values = tuple(float(v) for v in thrust)
    if not values:
        raise InputError.param("thrust", "no thrust values")
    zd = walker.zd
    j = walker.robot.driven_thruster(thruster)
    walker.robot.check_no_thrust(values)
    cycles = limit_cycles(zd, Schedule.constant(zd, constant_thrust(zd, values, j)))
    return LimitCycleResult(walker, values, j, tuple(cycles))
