"""What a gait design asks for: :class:`DesignSpec` and its validation (SPEC 2, 3, 5)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..description.robot import Robot
from ..errors import (
    LARGEST_COUNT,
    InputError,
    check_choice,
    check_count,
    check_flag,
    check_number,
    check_numbers,
    check_text,
    param_problem,
)
from ..model.compiled import CompiledModel

OBJECTIVES = ("effort", "peak", "cot")


FEAS_TOL = 1e-5  # normalised constraint violation accepted at the solver's point


# Margins that keep the solver inside the bounds the re-check enforces exactly, so that a point
# the solver accepts (normalised violation <= FEAS_TOL) always passes the re-check
STABILITY_MARGIN = 1e-5  # [1] delta_zero^2 <= max_delta_sq - this (violation <= 1e-6 accepted)
VELOCITY_MARGIN = 1e-5  # [m/s] lift-off and touch-down velocities (violation <= 1e-6 accepted)


ELASTIC = 100.0  # cost of one unit of normalised violation (elastic mode of the solver)


@dataclass(frozen=True)
class DesignSpec:
    """What to design (SI units). ``None`` targets are free.

    speed [m/s] and/or step_length [m] (at least one); mu [1]; order M of the Bezier
    polynomials; clearance: swing-foot height at mid-step ``s = 1/2`` [m] (height >= 0 over the
    whole step in any case); max_delta_sq: bound on delta_zero^2 (stability margin);
    min_vertical_force ``eps`` [N] (None: 10 % of the robot's weight); min_liftoff: vertical
    velocity of the trailing foot just after impact [m/s]; min_touchdown_velocity: the swing
    foot must move down onto the ground at at least this speed just before impact [m/s] (a
    grazing touchdown, vertical velocity near 0, is a strike a full-order simulation can miss);
    min_zeta_ratio: ``zeta(alpha) >= ratio zeta^-`` (the walker keeps some momentum at
    mid-stance); objective ``effort``, ``peak`` or ``cot`` (the mechanical cost of transport,
    SPEC 15); thrust_design: constant thrust per thruster as variables (within the robot's
    limits), costed ``thrust_weight |F|^2`` [m^2] in the effort objective; thrust_range
    ``(thruster, low, high)`` [N]: the orbit must exist and the stance, lift-off and torque
    constraints hold for every constant thrust of that thruster in the range (checked at the
    ends: zeta*, zeta(alpha), F_1 and u are affine in a constant thrust); thrust: one constant
    thrust per thruster [N] held fixed (not a variable): the gait is designed to walk under it
    (a gait library over thrust; not with ``thrust_design``); alpha_c: gait-timing
    row vector (None: the virtual stance leg, see :func:`default_alpha`); starts, seed,
    max_iter: solver; nodes: Lobatto nodes per evaluation (odd, so that s = 1/2 is a node).
    """

    speed: float | None = None
    step_length: float | None = None
    mu: float = 0.7
    order: int = 6
    clearance: float = 0.03
    max_delta_sq: float = 0.9
    min_vertical_force: float | None = None
    min_liftoff: float = 0.02
    min_touchdown_velocity: float = 0.05
    min_zeta_ratio: float = 0.02
    objective: str = "effort"
    thrust_design: bool = False
    thrust_weight: float = 1.0
    thrust_range: tuple[str, float, float] | None = None
    thrust: tuple[float, ...] | None = None
    alpha_c: tuple[float, ...] | None = None
    starts: int = 8
    seed: int = 0
    max_iter: int = 150
    nodes: int = 33
    name: str = "designed_gait"

    def __post_init__(self) -> None:
        """Every field of the right kind (numbers finite, counts whole, names strings):
        :class:`InputError` naming the field; the ranges are :meth:`validate`'s."""
        for key in ("speed", "step_length", "min_vertical_force"):
            check_number(key, getattr(self, key), optional=True)
        for key in ("mu", "clearance", "max_delta_sq", "min_liftoff", "min_touchdown_velocity",
                    "min_zeta_ratio", "thrust_weight"):
            check_number(key, getattr(self, key))
        for key in ("order", "starts", "seed", "max_iter", "nodes"):
            check_count(key, getattr(self, key), ge=-LARGEST_COUNT)
        check_choice("objective", self.objective, OBJECTIVES)
        check_flag("thrust_design", self.thrust_design)
        check_numbers("thrust", self.thrust, optional=True, min_len=0)
        check_numbers("alpha_c", self.alpha_c, optional=True, min_len=0)
        check_text("name", self.name)
        r = self.thrust_range
        if r is not None and not (isinstance(r, (tuple, list)) and len(r) == 3
                                  and isinstance(r[0], str)):
            raise InputError.param("thrust_range", f"must be (thruster, low, high) [N], got "
                                                   f"{type(r).__name__} {r!r:.40}")
        if r is not None:
            check_numbers("thrust_range", r[1:], min_len=2)

    def validate(self, model: CompiledModel) -> None:
        """Raise :class:`InputError` (one line per problem, naming the parameter)."""
        p = []

        def bad(param, message: str) -> None:
            p.append(param_problem(param, message))

        if self.speed is None and self.step_length is None:
            bad(("speed", "step_length"), "give a target speed, a step length or both")
        if self.speed is not None and not 0 < self.speed <= 20:
            bad("speed", f"must be in (0, 20] m/s (got {self.speed:g})")
        if self.step_length is not None and not 0 < self.step_length <= 10:
            bad("step_length", f"must be in (0, 10] m (got {self.step_length:g})")
        if not 0 < self.mu <= 10:
            bad("mu", f"must be in (0, 10] (got {self.mu:g})")
        if not 3 <= self.order <= 12:
            bad("order", f"Bezier order must be 3..12 (got {self.order})")
        if not 0 <= self.clearance <= 1:
            bad("clearance", f"must be in [0, 1] m (got {self.clearance:g})")
        if not 0 < self.max_delta_sq < 1:
            bad("max_delta_sq", f"must be in (0, 1) (got {self.max_delta_sq:g})")
        if self.min_vertical_force is not None and self.min_vertical_force < 0:
            bad("min_vertical_force", "must be >= 0 N")
        if not (np.isfinite(self.min_touchdown_velocity) and self.min_touchdown_velocity >= 0):
            bad("min_touchdown_velocity", f"must be >= 0 m/s (got "
                                          f"{self.min_touchdown_velocity:g})")
        if self.objective not in OBJECTIVES:
            bad("objective", f"unknown objective {self.objective!r} (choose from "
                             f"{', '.join(OBJECTIVES)})")
        if self.thrust_design and model.n_thrusters == 0:
            bad("thrust_design", f"robot {model.robot.name} has no thruster")
        if self.thrust_range is not None:
            name, lo, hi = self.thrust_range
            names = model.robot.thruster_names
            if name not in names:
                bad("thrust_range", f"unknown thruster {name!r} (robot {model.robot.name} has: "
                                    f"{', '.join(names)})" if names else
                    f"robot {model.robot.name} has no thruster")
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                bad("thrust_range", "need finite NAME:LOW:HIGH with LOW <= HIGH [N]")
        if self.thrust is not None:
            lim = [t.limits for t in model.robot.thrusters]
            if self.thrust_design:
                bad(("thrust", "thrust_design"), "a fixed `thrust` or `thrust_design`, not both")
            elif len(self.thrust) != model.n_thrusters:
                bad("thrust", f"need one value per thruster ({model.n_thrusters} for robot "
                              f"{model.robot.name}), got {len(self.thrust)}")
            elif not all(np.isfinite(f) and lo <= f <= hi
                         for f, (lo, hi) in zip(self.thrust, lim)):
                bad("thrust", "must be finite and within each thruster's limits [N]")
        if self.thrust_weight < 0:
            bad("thrust_weight", "must be >= 0 m^2")
        if not 1 <= self.starts <= 1000:
            bad("starts", f"must be 1..1000 (got {self.starts})")
        if self.seed < 0:
            bad("seed", "must be >= 0")
        if self.max_iter < 1:
            bad("max_iter", "must be >= 1")
        if self.nodes < 9 or self.nodes % 4 != 1:
            bad("nodes", "need 4k + 1 Lobatto nodes (k >= 2), so that s = 1/2 is a node")
        if self.alpha_c is not None:
            c = np.asarray(self.alpha_c, float)
            if c.shape != (model.n,) or c[-1] == 0:
                bad("alpha_c", f"need one coefficient per coordinate and a non-zero coefficient "
                               f"on {model.robot.coordinate_names[-1]}")
        if p:
            raise InputError(p)


def unbounded_warnings(robot: Robot) -> list[str]:
    """What the robot file leaves unbounded in a design: actuated coordinates without a
    ``torque_limit`` [N m] (their torques are bounded by nothing but the objective: a fast
    target may give a deep crouch that needs large torques and is still "feasible") and
    without a ``range`` [rad] (any joint angle is accepted, a folded or hyperextended joint
    included). One line each, naming each coordinate once and the robot-file keys that bound
    them (``coordinates.actuated[].torque_limit`` and ``.range``); empty when every actuated
    coordinate has both."""
    act = [c for c in robot.coordinates if c.actuated]
    out = []
    no_torque = [c.name for c in act if not np.isfinite(c.torque_limit)]
    no_range = [c.name for c in act if not (np.isfinite(c.range[0]) and np.isfinite(c.range[1]))]
    if no_torque:
        which = ("any actuated coordinate" if len(no_torque) == len(act)
                 else f"{len(no_torque)} of its {len(act)} actuated coordinates")
        out.append(f"no torque limits bound the design: robot {robot.name} gives no "
                   f"torque_limit for {which}, so their torques are bounded only by the "
                   "objective (a fast target may give a deep crouch that is still called "
                   f"feasible); add torque_limit: [N m] to {', '.join(no_torque)} in "
                   "coordinates.actuated of the robot file")
    if no_range:
        half = [c.name for c in act if c.name in no_range
                and (np.isfinite(c.range[0]) or np.isfinite(c.range[1]))]
        out.append(f"no joint ranges bound {', '.join(no_range)}: robot {robot.name} gives "
                   "no range for " + ("them" if not half else "them (or only one end)")
                   + ", so any angle of those joints is accepted (a folded or hyperextended "
                   "joint included); add range: [min, max] [rad] to those entries of "
                   "coordinates.actuated in the robot file")
    return out
