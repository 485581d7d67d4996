"""The walkability map of a gait over slope x constant thrust (SPEC 14): the mathematics behind
``thrustwalk slope`` (:mod:`thrustwalk_cli.studies.slope` turns options into a call of
:func:`walkability_map` and its cells into a result).

For every pair (slope ``gamma`` [rad, positive uphill], constant thrust ``F`` [N] on one
thruster): whether the zero-dynamics orbit exists (``zeta* > 0``), is stable
(``delta_zero^2 < 1``), completes the step (``delta_zero^2 zeta* + min V_Z > 0``: alpha reaches
``alpha_f``) and is contact-feasible at ``mu`` (SPEC 5 in the slope frame: ``F^v >= eps``,
``|F^h| <= mu F^v`` along the step, an admissible impact, the trailing foot lifting off, the
swing foot striking and staying above the ground), which condition fails first, and
``zeta*``, the step time, the speed along the ground and the climb rate ``speed sin(gamma)``.

The map uses the structure of SPEC 14 instead of one orbit per pair. In the slope frame every
quantity is explicit in ``(cos gamma, sin gamma)`` and affine in the thrust:

    V_Z(alpha; gamma, F) = c V_0 + s V_x + F (c_j Gamma_j + s_j Gamma_perp,j)
    zeta*               = V_Z(alpha_f; gamma, F) / (1 - delta_zero^2)
    F_1(alpha)          = c L0 + s L0_x + L1 zeta(alpha) + F (c_j L2_j + s_j L2_x,j)

(``c = cos gamma``, ``s = sin gamma``; ``c_j, s_j = c, s`` for a world-frame thruster and
``1, 0`` for a link-frame one; ``L0_x, L2_x`` the stance terms of gravity along the ground,
``model.slope.gravity_frame_model(c=0, s=1)``). The level-ground and along-the-ground parts
are Chebyshev series over the step, computed once; a pair then costs a few multiply-adds per
grid point. The impact (``delta_zero``, the impulse's direction, the lift-off) and the swing
foot do not depend on the slope or the thrust (SPEC 14), so they are evaluated once.

Numbers as the ``limit-cycle`` study (:func:`~thrustwalk_cli.hzd.zero_dynamics.limit_cycles`)
gives them for each pair: the existence test on the same grid (201 samples and the step's
ends), the step time by the same nested Clenshaw-Curtis rule refined per pair until ``1e-10``
relative. Contact is checked
on that grid; where a pair's grid margin is within 5 % of its limit (``F^v - eps < 0.05 m g``
or ``|F^h|/F^v > 0.95 mu``), the worst point is polished by golden section between the
neighbouring grid points (as the feasibility command does), so a verdict is not grid-limited.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..hzd.extrema import golden_min, neighbours
from ..hzd.quadrature import ChebSeries, integrate, lobatto
from ..hzd.zero_dynamics import MAX_NODES, RTOL, ZeroDynamics
from ..model.compiled import CompiledModel
from ..model.slope import gravity_frame_model
from .terms import impact_data, stance_terms

SAMPLES = 201  # grid points over the step (plus its ends), as limit_cycle's orbits
CHUNK = 16  # slopes evaluated together (memory: CHUNK x thrusts x grid x 2 doubles)
POLISH_BAND = 0.05  # grid margins within 5 % of the limit are polished
LOCAL_POINTS = 12  # Chebyshev points of the polish's local interpolants (degree 11)
TERMS_TOL = 1e-13  # relative size of the last Chebyshev coefficients of the stance terms

#: first failing condition of a pair, in the order they are checked ('' = walkable)
FAILURES = ("", "invalid gait", "no orbit", "unstable", "stops", "lifts", "slips", "impact",
            "scuffs")
FAILURE_TEXT = {
    "": "walkable: a stable periodic orbit that completes the step, contact-feasible",
    "invalid gait": "the gait is not a walking orbit (not hybrid-invariant, or kappa_1 "
                    "singular)",
    "no orbit": "no periodic orbit: zeta* = V_Z(alpha_f)/(1 - delta_zero^2) <= 0",
    "unstable": "the periodic orbit is unstable (delta_zero^2 >= 1)",
    "stops": "the walker stops before the end of the step (zeta reaches 0: alpha does not "
             "reach alpha_f)",
    "lifts": "the stance foot lifts: F^v < the minimum vertical force somewhere on the step",
    "slips": "the stance foot slips: |F^h| > mu F^v somewhere on the step",
    "impact": "the impact is inadmissible (impulse outside the cone, the trailing foot does "
              "not lift off, or the swing foot grazes)",
    "scuffs": "the swing foot goes below the ground during the step",
}


# ---------------------------------------------------------------------------- the computation
class SlopeBasis:
    """The thrust- and slope-independent series of one gait (zero dynamics ``zd`` on the
    level-ground model ``model``) and thruster ``j`` (module docstring):
    ``zs`` columns ``[V_0, V_x, Gamma_j, Gamma_perp,j]`` (cumulative from alpha_i) and ``ls``
    columns ``[L0 (2), L0_x (2), L1 (2), L2_j (2), L2_x,j (2)]`` (the stance force per unit
    of each part), with ``cj, sj`` the thruster's turning flags."""

    def __init__(self, model: CompiledModel, zd: ZeroDynamics, j: int | None):
        a, b = zd.alpha_i, zd.alpha_f
        self.a, self.b = a, b
        Vx, Gp, _ = zd.slope_series()
        parts = zd.__dict__["_slope_parts"]
        cols = [zd.V0.coef, Vx.coef]
        if j is not None:
            cols += [zd.Gamma.coef[:, j], Gp.coef[:, j]]
            self.world = bool(parts.world[j])
        else:
            cols += [np.zeros(1), np.zeros(1)]
            self.world = False
        rows = max(c.shape[0] for c in cols)
        coef = np.zeros((rows, 4))
        for i, c in enumerate(cols):
            coef[:c.shape[0], i] = c
        self.zs = ChebSeries(a, b, coef)
        model_x = gravity_frame_model(model, 0.0, 1.0, parts)
        flat = model

        def sample(n: int) -> np.ndarray:
            al = lobatto(a, b, n)
            t0, tx = stance_terms(flat, zd.maps, al), stance_terms(model_x, zd.maps, al)
            if j is None:
                l2, l2x = np.zeros((n, 2)), np.zeros((n, 2))
            else:
                l2, l2x = t0.L2[:, :, j], tx.L2[:, :, j]
            return np.hstack([t0.L0, tx.L0, t0.L1, l2, l2x])

        n = 65
        while True:
            ls = ChebSeries.from_values(a, b, sample(n))
            tail = np.abs(ls.coef[-8:]).max(axis=0)
            scale = np.abs(ls.coef).max(axis=0)
            if np.all(tail <= TERMS_TOL * np.maximum(scale, 1e-300)) or n >= 1025:
                break
            n = 2 * n - 1
        self.ls = ls
        self.terms_nodes = n
        grid = np.unique(np.concatenate([np.linspace(a, b, SAMPLES), [a, b]]))
        self.grid = grid[::-1] if b < a else grid
        self.zg = self.zs(self.grid)  # (G, 4)
        self.lg = self.ls(self.grid)  # (G, 10)
        self.zf = self.zs(np.array([b]))[0]
        self.nodes: dict[int, tuple] = {}
        self.zd = zd
        # degree-11 interpolants of both series on the bracket of every grid point (its
        # neighbours): the polish evaluates twelve terms instead of the whole series
        lo, hi = neighbours(self.grid, np.arange(self.grid.size))
        L = LOCAL_POINTS
        theta = np.pi * (np.arange(L) + 0.5) / L
        pts = 0.5 * (lo + hi)[:, None] + 0.5 * (hi - lo)[:, None] * np.cos(theta)[None, :]
        vals = np.concatenate([self.zs(pts), self.ls(pts)], axis=-1)  # (G, L, 14)
        Tm = np.cos(np.outer(np.arange(L), theta)) * (2.0 / L)  # values -> coefficients
        Tm[0] *= 0.5
        self.local = np.einsum("rl,glc->grc", Tm, vals)

    def local_values(self, j: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The series ``zs`` (P, 4) and ``ls`` (P, 10) at ``x`` (P,), each point inside the
        bracket of grid point ``j`` (P,), from the local interpolants."""
        lo, hi = neighbours(self.grid, j)
        span = np.where(hi > lo, hi - lo, 1.0)
        t = (2.0 * x - (lo + hi)) / span
        L = LOCAL_POINTS
        Tv = np.empty((t.size, L))
        Tv[:, 0] = 1.0
        Tv[:, 1] = t
        for r in range(2, L):
            Tv[:, r] = 2.0 * t * Tv[:, r - 1] - Tv[:, r - 2]
        out = np.einsum("pl,plc->pc", Tv, self.local[j])
        return out[:, :4], out[:, 4:]

    def step_nodes(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if n not in self.nodes:
            p = lobatto(self.a, self.b, n)
            self.nodes[n] = (p, self.zd.terms(p)["kappa1"], self.zs(p))
        return self.nodes[n]


def _zeta(z4: np.ndarray, c, s, cj, sj, F, zp) -> np.ndarray:
    """``zeta = zeta^+ + c V_0 + s V_x + F (c_j Gamma + s_j Gamma_perp)`` from series values
    ``z4`` (..., 4); the pair parameters broadcast against ``z4[..., 0]``."""
    return zp + c * z4[..., 0] + s * z4[..., 1] + F * (cj * z4[..., 2] + sj * z4[..., 3])


def _force(l10: np.ndarray, zeta, c, s, cj, sj, F) -> np.ndarray:
    """``F_1 = c L0 + s L0_x + L1 zeta + F (c_j L2 + s_j L2_x)`` (..., 2) [N]."""
    e = (lambda x: np.asarray(x)[..., None])  # noqa: E731
    return (e(c) * l10[..., 0:2] + e(s) * l10[..., 2:4] + e(zeta) * l10[..., 4:6]
            + e(F) * (e(cj) * l10[..., 6:8] + e(sj) * l10[..., 8:10]))


def walkability_map(model: CompiledModel, zd: ZeroDynamics, g: np.ndarray, F: np.ndarray,
                    j: int | None, mu: float, eps: float, *, weight: float, scuffs: bool,
                    progress: Callable[[int, int], None] | None = None) -> tuple[dict, int]:
    """The map's cells over slopes ``g`` [rad] x constant thrust ``F`` [N] on thruster ``j``
    (None: no thruster) of the gait ``zd`` on the level-ground ``model`` (module docstring,
    SPEC 14), at friction coefficient ``mu`` [1] and least vertical force ``eps`` [N];
    ``weight`` [N] = m g scales the polish band of ``F^v``, ``scuffs``: the swing foot goes
    below the ground (slope- and thrust-independent). Returns ``(cells, polished)``:
    arrays of shape ``(len(g), len(F))`` -- ``first`` (index in :data:`FAILURES` of the first
    failing condition), the flags ``orbit``, ``stable``, ``completes``, ``contact``,
    ``polished`` and ``zeta_star`` [kg^2 m^4/s^2] (``zeta* = V_Z(alpha_f)/(1 -
    delta_zero^2)``, SPEC 3, 14), ``step_time`` [s], ``speed`` and ``climb_rate`` [m/s],
    ``min_vertical_force`` [N], ``max_friction_ratio`` [1], NaN where a quantity does not
    exist -- and the number of pairs polished. ``progress(done, total)`` hears about each
    block of slopes."""
    basis = SlopeBasis(model, zd, j)
    d2 = zd.delta_zero_sq
    nS, nT = g.size, F.size
    c_all, s_all = np.cos(g), np.sin(g)
    if basis.world:
        cj_all, sj_all = c_all, s_all
    else:
        cj_all, sj_all = np.ones(nS), np.zeros(nS)
    shape = (nS, nT)
    zstar = np.full(shape, np.nan)
    zmin = np.full(shape, np.nan)
    minv = np.full(shape, np.nan)
    maxr = np.full(shape, np.nan)
    jv = np.zeros(shape, int)
    jr = np.zeros(shape, int)
    valid = zd.valid and 0.0 < d2 != 1.0
    zg, lg, zf = basis.zg, basis.lg, basis.zf
    G = basis.grid.size
    Fb = F[None, :, None]
    buf = [np.empty((CHUNK, nT, G)) for _ in range(3)]
    for i0 in range(0, nS, CHUNK):
        sl = slice(i0, min(i0 + CHUNK, nS))
        k = sl.stop - sl.start
        zeta, fv, fh = (b[:k] for b in buf)
        c, s = c_all[sl, None], s_all[sl, None]
        cj, sj = cj_all[sl, None], sj_all[sl, None]
        Vf = _zeta(zf, c, s, cj, sj, F[None, :], 0.0)  # (k, nT)
        zs = zd.fixed_point_of(Vf) if d2 != 1.0 else np.full(Vf.shape, np.nan)
        zstar[sl] = zs
        # per slope, the parts that do not depend on the thrust; then one pass per term
        A = c * zg[:, 0] + s * zg[:, 1]  # (k, G)
        B = cj * zg[:, 2] + sj * zg[:, 3]
        np.multiply(Fb, B[:, None, :], out=zeta)
        zeta += A[:, None, :]
        zeta += (d2 * zs)[..., None]
        zmin[sl] = zeta.min(axis=-1)
        for f1, r in ((fv, 1), (fh, 0)):  # F_1 = (c L0 + s L0x) + F (..) + L1 zeta
            A = c * lg[:, r] + s * lg[:, 2 + r]
            B = cj * lg[:, 6 + r] + sj * lg[:, 8 + r]
            np.multiply(zeta, lg[:, 4 + r], out=f1)
            f1 += A[:, None, :]
            f1 += Fb * B[:, None, :]
        j = np.argmin(fv, axis=-1)
        jv[sl] = j
        minv[sl] = np.take_along_axis(fv, j[..., None], -1)[..., 0]
        np.abs(fh, out=fh)
        pos = fv > 0
        np.divide(fh, fv, out=fh, where=pos)
        fh[~pos] = np.inf
        j = np.argmax(fh, axis=-1)
        jr[sl] = j
        maxr[sl] = np.take_along_axis(fh, j[..., None], -1)[..., 0]
        if progress is not None:
            progress(sl.stop, nS)
    orbit = valid & (zstar > 0)
    stable = orbit & (d2 < 1.0)
    completes = orbit & (zmin > 0)
    # the pairs with an orbit through the whole step: step time, polished contact margins
    live = np.nonzero(completes)
    C = {"c": c_all[live[0]], "s": s_all[live[0]], "cj": cj_all[live[0]],
         "sj": sj_all[live[0]], "F": F[live[1]], "zp": d2 * zstar[live]}
    T, T_ok = _step_times(basis, zd, C)
    step_time = np.full(shape, np.nan)
    step_time[live] = T
    completes[live] &= T_ok
    polished_cells = np.zeros(shape, bool)
    polished = _polish(basis, C, live, minv, maxr, jv, jr, mu, eps, weight, polished_cells)
    imp = impact_data(model, zd)
    imp_ok = imp.admissible(mu)
    scuffs = bool(scuffs)
    v_ok = minv >= eps
    r_ok = np.isfinite(maxr) & (maxr <= mu)
    contact = completes & v_ok & r_ok & imp_ok & (not scuffs)
    first = np.zeros(shape, int)
    checks = [(not zd.valid, "invalid gait"), (~orbit, "no orbit"), (~stable, "unstable"),
              (~completes, "stops"), (~v_ok, "lifts"), (~r_ok, "slips"),
              (not imp_ok, "impact"), (scuffs, "scuffs")]
    for bad, name in reversed(checks):
        first = np.where(bad, FAILURES.index(name), first)
    speed = np.where(completes, zd.step_length / step_time, np.nan)
    nan_unless = (lambda ok, x: np.where(ok, x, np.nan))  # noqa: E731
    cells = {"first": first, "orbit": orbit, "stable": stable, "completes": completes,
             "contact": contact, "zeta_star": nan_unless(orbit, zstar),
             "step_time": nan_unless(completes, step_time), "speed": speed,
             "climb_rate": speed * np.sin(g)[:, None],
             "min_vertical_force": nan_unless(completes, minv),
             "max_friction_ratio": nan_unless(completes & np.isfinite(maxr), maxr),
             "polished": polished_cells & completes}
    return cells, polished


def _step_times(basis: SlopeBasis, zd, C: dict) -> tuple[np.ndarray, np.ndarray]:
    """``T = int dalpha / alpha'`` per live pair: nested Clenshaw-Curtis, nodes doubled for
    the pairs whose estimate is above ``0.1 RTOL`` relative (as ``limit_cycles``)."""
    P = C["F"].size
    T, ok = np.full(P, np.nan), np.ones(P, bool)
    todo = np.arange(P)
    sgn = zd.sigma_sign
    n = 33
    while todo.size:
        p, k1, z4 = basis.step_nodes(n)
        sub = {k: v[todo, None] for k, v in C.items()}
        z = _zeta(z4[None], sub["c"], sub["s"], sub["cj"], sub["sj"], sub["F"], sub["zp"])
        bad = np.any(z <= 0, axis=1)
        f = 1.0 / (k1 * sgn * np.sqrt(2.0 * np.where(z > 0, z, 1.0)))
        val, err = integrate(p[0], p[-1], f)
        done = bad | (err <= 0.1 * RTOL * np.abs(val)) | (n >= MAX_NODES)
        T[todo[done]] = val[done]
        ok[todo[done]] = ~bad[done]
        todo = todo[~done]
        n = 2 * n - 1
    return T, ok & np.isfinite(T) & (T > 0)


def _polish(basis: SlopeBasis, C: dict, live: tuple, minv: np.ndarray, maxr: np.ndarray,
            jv: np.ndarray, jr: np.ndarray, mu: float, eps: float, weight: float,
            marks: np.ndarray) -> int:
    """Golden-section polish of the least ``F^v`` and the largest ``|F^h|/F^v`` of the live
    pairs whose grid values lie within :data:`POLISH_BAND` of the limits (in place); returns
    the number of pairs polished."""
    mv, mr = minv[live], maxr[live]
    near = ((mv - eps < POLISH_BAND * weight) | (mr > (1.0 - POLISH_BAND) * mu)) & (mv >= eps)
    idx = np.nonzero(near)[0]
    if not idx.size:
        return 0
    sub = {k: v[idx] for k, v in C.items()}
    rows = tuple(a[idx] for a in live)
    marks[rows] = True

    def force(j: np.ndarray, x: np.ndarray) -> np.ndarray:
        z4, l10 = basis.local_values(j, x)
        z = _zeta(z4, sub["c"], sub["s"], sub["cj"], sub["sj"], sub["F"], sub["zp"])
        return _force(l10, z, sub["c"], sub["s"], sub["cj"], sub["sj"], sub["F"])

    j = jv[rows]
    lo, hi = neighbours(basis.grid, j)
    _, fv = golden_min(lambda x: force(j, x)[:, 1], lo, hi)
    minv[rows] = np.minimum(mv[idx], np.where(np.isfinite(fv), fv, mv[idx]))

    def neg_ratio(x: np.ndarray) -> np.ndarray:
        f = force(jr_rows, x)
        with np.errstate(divide="ignore", invalid="ignore"):
            return -np.where(f[:, 1] > 0, np.abs(f[:, 0]) / f[:, 1], np.inf)

    jr_rows = jr[rows]
    lo, hi = neighbours(basis.grid, jr_rows)
    _, nr = golden_min(neg_ratio, lo, hi)
    maxr[rows] = np.maximum(mr[idx], np.where(np.isfinite(nr), -nr, mr[idx]))
    return int(idx.size)

