"""Records of the full-order simulation shared by the SciPy and the compiled paths: one
step (:class:`StepRecord`), one smooth piece of trajectory (:class:`Segment`) and the
wording of the failures an event reports. SI units."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class StepRecord:
    """One simulated step, from the post-impact state to the next impact (SI units).

    ``*_minus`` just before the impact that ends the step, ``*_plus`` just after it (after
    relabelling). sigma [kg m^2/s], zeta = sigma^2/2 [kg^2 m^4/s^2], impulse F_2 [N s],
    forces [N], torques [N m], outputs y [rad], y' [rad/s].
    """

    step: int
    t_start: float
    t_impact: float
    step_time: float
    alpha_start: float
    z_start: tuple[float, ...]
    alpha_minus: float
    s_minus: float
    sigma_start: float
    zeta_start: float
    sigma_minus: float
    zeta_minus: float
    sigma_plus: float
    zeta_plus: float
    impulse: tuple[float, float]
    impulse_friction_ratio: float
    trailing_foot_lift_velocity: float
    thrust_at_impact: tuple[float, ...]
    min_vertical_force: float
    max_friction_ratio: float | None  # None if F_1^v <= 0 somewhere (then the step failed)
    max_abs_output: float
    max_abs_output_rate: float
    max_abs_torque: float
    torque_saturated: bool
    energy_minus: float
    energy_plus: float
    q_minus: tuple[float, ...]
    dq_minus: tuple[float, ...]
    nfev: int
    # (t [s], s [1]) of the first F_1^v <= SimConfig.cone_eps / the first
    # |F_1^h| > cone_mu F_1^v (F_1^v > 0) in the step; None: none (or not timed)
    low_force_at: tuple[float, float] | None = None
    cone_exit_at: tuple[float, float] | None = None
    # the height [m] above the stance foot, normal to the slope, of the ground the swing foot
    # landed on (SPEC 14; 0: level ground)
    terrain_height: float = 0.0


@dataclass(frozen=True)
class Segment:
    """A smooth piece of the trajectory: one ``solve_ivp`` call (dense solution)."""

    step: int
    t0: float
    t1: float
    interval: int
    sol: object = field(repr=False)


EVENT_REASONS = {
    "scuff": ("scuff", "the swing foot goes more than `scuff_tol` below the ground before the "
                       "guard is armed at s = `min_impact_s` (an early strike: a scuff, not the "
                       "end of the step)"),
    "overshoot": ("no-impact", "the swing foot has not reached the ground by the end of the "
                               "step (s = max_s)"),
    "reverse": ("fall", "alpha reverses (alpha' = 0): the walker stops and falls back"),
    "horizontal": ("fall", "the stance leg passes the horizontal"),
    "force": ("fall", "the vertical ground force becomes negative: the stance foot would "
                      "lift off"),
}


def missed_footing(s_max: float, height: float, t: float) -> tuple[str, str]:
    """``(failure kind, reason)`` of a step on a terrain whose swing foot has not reached the
    ground ``height`` [m] above its stance foot by ``s = s_max`` (SPEC 14), at ``t`` [s]."""
    return "missed_footing", (f"the swing foot has not reached the ground at {height:+.4g} m "
                              f"(height above the stance foot) by s = {s_max:g} (s_max): it "
                              f"missed its footing at t = {t:.6g} s")


def behind_level(heights, k: int) -> float:
    """The ground [m] the scuff checks of step ``k`` (1-based) measure from before the guard
    is armed (SPEC 14): the lower of the stance foot's level (0) and the level the swing foot
    left, ``-heights[k - 2]`` (the previous step landed that much above it); 0 on level
    ground and for the first step."""
    if heights is None or k < 2:
        return 0.0
    return min(0.0, -float(heights[k - 2]))
