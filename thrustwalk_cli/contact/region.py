"""Feasible region of one step over (thrust scale, pre-impact zeta^-) (SPEC 5).

Affinity makes the grid cheap: ``zeta(alpha) = delta_zero^2 zeta^- + V_0 + s W`` and
``F_1 = s (Lambda_2 F_u + Lambda_T T_u) + Lambda_1 zeta + Lambda_0`` for a unit schedule scaled by
``s``. SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..hzd.zero_dynamics import ZeroDynamics
from ..model.compiled import CompiledModel
from ..thrust.schedule import Schedule
from .evaluate import friction_ratio, step_grid
from .terms import impact_data, stance_terms


# -------------------------------------------------------------------------- feasible region
@dataclass(frozen=True)
class Region:
    """Feasibility over a grid of schedule scale (thrust [N] for a unit constant thrust) and
    pre-impact zeta^- [kg^2 m^4/s^2] for one step starting at ``zeta^+ = delta_zero^2 zeta^-``.

    ``completes``: zeta > 0 along the step (the walker does not stop); ``feasible`` adds
    ``F^v >= eps``, the friction cone and the impact conditions. ``fixed_point``: zeta*(scale)
    on the limit-cycle curve (NaN-free: ``fixed_point_valid`` masks scales without an orbit).
    """

    scale: np.ndarray
    zeta: np.ndarray
    min_vertical: np.ndarray  # (ns, nz)
    max_ratio: np.ndarray  # (ns, nz), inf where F^v <= 0
    completes: np.ndarray
    feasible: np.ndarray
    fixed_point: np.ndarray  # (ns,)
    fixed_point_valid: np.ndarray
    fixed_point_feasible: np.ndarray
    impact_ok: bool
    min_zeta: np.ndarray | None = None  # (ns, nz) [kg^2 m^4/s^2]: completes <=> > 0


def feasible_region(model: CompiledModel, zd: ZeroDynamics, unit: Schedule,
                    scale: np.ndarray, zeta: np.ndarray, *, mu: float, eps: float = 0.0,
                    points: int = 201) -> Region:
    """Evaluate the contact conditions on a (scale, zeta^-) grid (SPEC 5), using affinity:
    ``zeta(alpha) = delta_zero^2 zeta^- + V_0 + s W``, ``F_1 = s (Lambda_2 F_u + Lambda_T T_u) +
    Lambda_1 zeta + Lambda_0`` with ``W = V_Z(unit) - V_0``."""
    scale, zeta = np.asarray(scale, float), np.asarray(zeta, float)
    alpha, idx = step_grid(unit.knots, points)
    t = stance_terms(model, zd.maps, alpha)
    V0 = zd.V0(alpha)
    W = zd.V_Z(alpha, unit)[0] - V0
    Fu, Tu = unit.force[0, idx, :], unit.generalized[0, idx]
    per_s = np.einsum("gim,gm->gi", t.L2, Fu) + t.LT * Tu[:, None]  # (g, 2)
    z = (zd.delta_zero_sq * zeta[None, :, None] + V0 + scale[:, None, None] * W)  # (s, z, g)
    F1 = (scale[:, None, None, None] * per_s + t.L1 * z[..., None] + t.L0)
    completes = z.min(axis=-1) > 0
    minv = F1[..., 1].min(axis=-1)
    maxr = friction_ratio(F1).max(axis=-1)
    imp_ok = impact_data(model, zd).admissible(mu)
    feas = completes & (minv >= eps) & (maxr <= mu) & imp_ok
    Vf = zd.V0(np.array(zd.alpha_f)) + scale * W[-1]
    d2 = zd.delta_zero_sq
    valid = np.zeros(scale.shape, bool)
    zs = np.zeros(scale.shape)
    fp_feas = np.zeros(scale.shape, bool)
    if 0 < d2 < 1 and zd.valid:
        zs = zd.fixed_point_of(Vf)
        zfp = d2 * zs[:, None] + V0 + scale[:, None] * W
        valid = (zs > 0) & (zfp.min(axis=-1) > 0)
        F1fp = scale[:, None, None] * per_s + t.L1 * zfp[..., None] + t.L0
        fp_feas = (valid & (F1fp[..., 1].min(-1) >= eps) & (friction_ratio(F1fp).max(-1) <= mu)
                   & imp_ok)
    return Region(scale, zeta, minv, maxr, completes, feas, zs, valid, fp_feas, imp_ok,
                  z.min(axis=-1))
