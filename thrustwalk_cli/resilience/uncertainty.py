"""One Monte-Carlo sample of parameter uncertainty (SPEC 3, 11, 12): the walker built from
drawn robot parameters (the *plant*) with the nominal gait, under one strategy.

The sampled robot keeps the gait file (with ``invariance: auto`` its first Bezier columns are
recomputed for the sampled robot, so the gait stays hybrid-invariant and the full-order
closed loop keeps the zero-dynamics manifold invariant). Its walking is then decided exactly
by the reduced model of that robot:

* a fixed strategy (none, constant, schedule): the plant's own fixed point
  ``zeta* = V_Z(alpha_f) / (1 - delta_zero^2)`` must exist, be stable and lie in the plant's
  reduced basin (:func:`~.basin.reduced_basin`: no stop, stance force in the cone, admissible
  impact), and the swing foot must clear the ground; the converged speed is that orbit's;
* ``control``: the controller keeps the *nominal* model (its planner was built for the
  nominal robot) and measures the plant's zeta^-; the plant's step map under the planned
  thrust, ``x_{k+1} = delta_zero,p^2 x_k + V_0,p(alpha_f) + Gamma_p(alpha_f) u_k``, is
  iterated from the nominal orbit until it settles (``|x_{k+1} - x_k| <= 1e-9 x_k``), every
  step's conditions checked on the plant's own affine rows (``zeta > 0``, ``F^v >= eps``,
  ``|F^h| <= mu F^v`` on the alpha grid, SPEC 11); the converged speed is the plant's orbit
  under the settled thrust.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..contact.terms import impact_data, scuff_reason, swing_clearance
from ..controller.planner import Planner
from ..controller.step_model import IdealThrust, Terms, rows, step_grid
from ..hzd.zero_dynamics import ZeroDynamics, limit_cycles
from ..thrust.schedule import Schedule, knots_alpha
from .basin import ReducedBasin
from .strategy import Strategy, realize

MAX_STEPS = 200  # steps of the controlled reduced map before it must have settled


@dataclass(frozen=True)
class SampleResult:
    """One sample under one strategy: ``success`` (it walks: see the module docstring),
    ``reason``, the converged ``zeta_star`` [kg^2 m^4/s^2], ``speed`` [m/s] and step time
    [s] (None when it does not walk), ``steps`` of the controlled map (control)."""

    success: bool
    reason: str
    zeta_star: float | None = None
    speed: float | None = None
    step_time: float | None = None
    steps: int | None = None
    basin: ReducedBasin | None = None

    def fields(self) -> dict:
        b = self.basin
        return {"walks": self.success, "zeta_star": self.zeta_star, "speed": self.speed,
                "step_time": self.step_time, "controlled_steps": self.steps,
                "basin_exists": None if b is None else b.exists,
                "basin_lower": None if b is None else b.lower.value,
                "basin_upper": None if b is None else b.upper.value}


def fixed_sample(zd: ZeroDynamics, strategy: Strategy, *, mu: float, eps: float = 0.0,
                 points: int = 401) -> SampleResult:
    """A fixed strategy on the sampled walker ``zd`` (module docstring)."""
    if not zd.valid:
        return SampleResult(False, f"no walking orbit: {zd.invalid_reason}")
    r = realize(zd, strategy, mu=mu, eps=eps, points=points)
    lc, b = r.cycle, r.basin
    if not lc.exists or not lc.stable:
        return SampleResult(False, f"no stable orbit: {lc.reason}", basin=b)
    if not b.exists:
        return SampleResult(False, b.reason, lc.zeta_star, basin=b)
    sw = swing_clearance(zd.model, zd)
    if sw["scuffs"]:
        return SampleResult(False, scuff_reason(sw), lc.zeta_star, basin=b)
    return SampleResult(True, f"walks at {lc.speed:.4g} m/s (zeta* = {lc.zeta_star:.6g})",
                        float(lc.zeta_star), float(lc.speed), float(lc.step_time), basin=b)


def controlled_sample(plant: ZeroDynamics, planner: Planner, x_ref: float,
                      fractions: np.ndarray, driven: list[int], *, mu: float,
                      eps: float = 0.0) -> SampleResult:
    """The nominal controller (``planner``, reference ``x_ref``) on the sampled walker
    ``plant`` (module docstring); ``fractions``: the controller's knots as fractions of the
    step."""
    if not plant.valid:
        return SampleResult(False, f"no walking orbit: {plant.invalid_reason}")
    imp = impact_data(plant.model, plant)
    if not imp.admissible(mu):
        return SampleResult(False, "the impact is inadmissible: " + "; ".join(imp.reasons(mu)))
    sw = swing_clearance(plant.model, plant)
    if sw["scuffs"]:
        return SampleResult(False, scuff_reason(sw))
    kn = knots_alpha(plant, np.asarray(fractions, float))
    thrust = IdealThrust(plant, kn, driven)
    alpha, idx = step_grid(kn, planner.st.points)
    rw = rows(plant, Terms(plant.model, plant), thrust, alpha, idx)
    d2 = plant.delta_zero_sq
    x, u = float(x_ref), np.zeros(planner.nu)
    for k in range(1, MAX_STEPS + 1):
        plan = planner.plan(x, x_ref, u)
        u = plan.u
        zeta = rw.zeta(x, u, d2)
        F = rw.force(x, u)
        if np.min(zeta) <= 0:
            return SampleResult(False, f"step {k}: the walker stops (zeta reaches 0)", steps=k)
        if np.min(F[:, 1]) < eps:
            return SampleResult(False, f"step {k}: the vertical ground force drops to "
                                       f"{np.min(F[:, 1]):.4g} N", steps=k)
        ratio = float(np.max(np.abs(F[:, 0]) / F[:, 1]))
        if ratio > mu:
            return SampleResult(False, f"step {k}: the stance force leaves the friction cone "
                                       f"(|F^h|/F^v = {ratio:.4g} > mu = {mu:g})", steps=k)
        x_next = float(zeta[-1])
        if abs(x_next - x) <= 1e-9 * abs(x):
            m = plant.model.n_thrusters
            force = np.zeros((1, len(kn) - 1, m))
            force[0][:, driven] = u.reshape(-1, len(driven))
            lc = limit_cycles(plant, Schedule(kn, force, np.zeros((1, len(kn) - 1))))[0]
            if not lc.exists:
                return SampleResult(False, f"the settled thrust has no orbit: {lc.reason}",
                                    steps=k)
            return SampleResult(True, f"settles in {k} steps at {lc.speed:.4g} m/s "
                                      f"(zeta^- = {lc.zeta_star:.6g}, reference {x_ref:.6g})",
                                float(lc.zeta_star), float(lc.speed), float(lc.step_time), k)
        x = x_next
    return SampleResult(False, f"the controlled map has not settled after {MAX_STEPS} steps "
                               f"(zeta^- = {x:.6g})", steps=MAX_STEPS)
