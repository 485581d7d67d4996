"""The gait-design optimisation problem: layout of the decision variables, scales, starts
and the evaluation of the objective and every constraint family (SPEC 2, 3, 5). Solved by
:func:`thrustwalk_cli.design.solver.solve_design`; :class:`~thrustwalk_cli.design.spec.DesignSpec`
says what to design.

Decision variables ``x`` (all O(1) after scaling):

* the pre-impact configuration ``q^-`` [rad] (N values); ``alpha_f = c q^-`` and the last
  Bezier column ``a_M = H_0 q^-``; the swing foot is put on the ground by an equality constraint
  ``p_2y(q^-) = 0``, so any robot works without a posture parametrisation;
* Bezier columns ``2 .. M-1`` [rad], as offsets from the straight line between ``q_b^+`` and
  ``q_b^-`` (columns 0 and 1 follow from hybrid invariance, ``invariance: auto``, SPEC 2);
* ``zeta^- / zeta_ref``: the pre-impact value of ``zeta = sigma_N^2/2`` [kg^2 m^4/s^2], tied to the
  orbit by the fixed-point equality ``(1 - delta_zero^2) zeta^- = V_Z(alpha_f)`` (SPEC 3), so
  that every quantity below is defined (and smooth) even away from a periodic orbit;
* optionally one constant thrust per thruster [N] (gait and thrust co-design, SPEC 4) and, for
  the peak-torque objective, an epigraph variable.

On Chebyshev-Lobatto nodes ``alpha_j`` (fixed count, so the functions are smooth in ``x``):

    zeta(alpha)  = delta_zero^2 zeta^- + V_Z(alpha),  V_Z = int (kappa_2 + beta F_T)/kappa_1
    alpha'       = kappa_1 sigma_N,   sigma_N = sgn sqrt(2 zeta),   T = int dalpha / alpha'
    u(alpha)     = U_2 F_T + U_1 zeta + U_0,   F_1(alpha) = Lambda_2 F_T + Lambda_1 zeta + Lambda_0

(kappa terms from :func:`hzd.zero_dynamics.zero_dynamics_terms`, exact affine terms of SPEC 5
from :func:`contact.terms.stance_terms`). Integrals use the nodes (Clenshaw-Curtis, cumulative
Chebyshev); the constraints on F_1, u, the swing-foot height and the joint ranges use a dense
uniform grid in ``s`` (the Lambdas and V_Z interpolated from the nodes). Objectives: ``effort``
``J = (1/L) int_0^T |u|^2 dt = (1/L) int |u|^2 / alpha' dalpha`` [N^2 m s] (plus
``w_F |F_T|^2 T / L`` when thrust is designed), ``peak`` ``max_{i, alpha} |u_i|`` [N m], or
``cot``, the mechanical cost of transport of SPEC 15 [1]:

    CoT = (1 / (m g L)) int (sum_j max(0, u_j q_j') + sum_k max(0, F_k d_k . p_k')) dt
        = (1 / (m g L)) int (sum_j max(0, s u_j Phi_j) + sum_k max(0, s F_k (B_F^T Phi)_k)) |dalpha|

(``s = sign(alpha_f - alpha_i)``; no ``1/alpha'``: power times time is work per alpha), the
powers interpolated from the nodes onto the dense grid and ``max(0, p)`` smoothed to
``(p + sqrt(p^2 + e^2)) / 2`` with ``e = COT_SMOOTH u_scale`` (a bias below ``e |alpha_f -
alpha_i| / 2`` per term) so that the solver's objective is differentiable; the re-check
(:mod:`.verify`) reports the exact CoT of the periodic orbit
(:mod:`thrustwalk_cli.energetics.orbit`).

Constraint families (each normalised; the largest violation at the best point names the
family that blocks an infeasible request): ``orbit`` (fixed point, zeta > 0 along the step,
delta_zero^2 > 0, kappa_1 regular, alpha monotonic), ``stability`` (delta_zero^2 <= bound),
``speed``, ``step_length``, ``foot_placement`` (swing foot on the ground ahead of the stance
foot), ``clearance`` (height at mid-step ``s = 1/2``), ``scuffing`` (height >= 0 over the step),
``vertical_force`` (``F_1^v >= eps``), ``friction`` (``|F_1^h| <= mu F_1^v``), ``impact`` (impulse
in the cone, trailing foot lifts off), ``touchdown`` (the swing foot moves down onto the ground
at ``>= min_touchdown_velocity``: ``-E_2y(q^-) Phi(alpha_f) alpha'^-``; a grazing touchdown is a
strike the full-order simulation can miss), ``joint_range`` and ``torque_limit`` (robot file).
With a thrust range, stance, lift-off and torque constraints also hold on the orbits of its
two end thrusts (F_1, u and zeta are affine in a constant thrust, so the whole range follows).

Safety margins inside the solver (so that the re-check on finer grids passes): friction with
``mu - 0.005``, ``F_1^v >= eps + 0.5 %`` of the weight, joint ranges shrunk by 0.01 rad, torques
within 99 % of their limits, ``zeta >= min_zeta_ratio zeta^-``, lift-off >= ``min_liftoff`` and
touch-down >= ``min_touchdown_velocity`` (each + 1e-5 m/s), ``delta_zero^2 <= max_delta_sq - 1e-5``:
a point the solver accepts (normalised violation <= 1e-5) then meets the bounds the re-check
enforces exactly. The foot-placement equality is polished by Newton on q_N (:meth:`polish`).
The swing-foot height is constrained on a dense uniform grid through :func:`cell_minima`
(dips between grid points count), so straight legs may touch the ground (3-link:
``clearance = 0``).

:meth:`Problem.evaluate_many` evaluates many points in one vectorised pass (a leading batch
axis through every step; the forward-difference Jacobian's points), each row equal bit for bit
to :meth:`Problem.evaluate` of that point alone.

One idea in one file (above 600 lines): the gait-design problem, its decision vector,
constraints and their vectorised evaluation, which share one layout of the variables.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import comb

import numpy as np
from scipy.optimize import minimize

from ..contact.terms import stance_terms
from ..description.gait import Gait
from ..hzd.constraints import apply_invariance, bezier, gait_maps
from ..hzd.quadrature import ChebSeries, integrate, lobatto
from ..hzd.zero_dynamics import zero_dynamics_terms
from ..model.compiled import CompiledModel
from ..thrust.schedule import WrittenSchedule
from .spec import STABILITY_MARGIN, VELOCITY_MARGIN, DesignSpec

FAMILIES = ("orbit", "stability", "speed", "step_length", "foot_placement", "clearance",
            "scuffing", "vertical_force", "friction", "impact", "touchdown", "joint_range",
            "torque_limit")
DIP = 0.0  # [m] dip allowed by the design constraint
DENSE = 161  # uniform points in s for the height, range, stance-force and torque constraints
COT_SMOOTH = 1e-2  # cot objective: smoothing of max(0, p), relative to u_scale [N m per rad]
COT_SCALE = 0.01  # cot objective: its scale in the solver [1]


# ------------------------------------------------------------------------- robot geometry
@dataclass(frozen=True)
class Legs:
    """Leg structure read from the relabelling: ``P = T R T^-1`` permutes absolute link
    angles; the member of each swapped pair nearer the root is a stance-leg link."""

    stance: tuple[int, ...]  # link indices
    swing: tuple[int, ...]
    hip: int  # first link on the root -> swing-foot path that is not a stance-leg link


def legs(model: CompiledModel) -> Legs:
    r = model.robot
    T = r.T
    P = T @ model.R @ np.linalg.inv(T)
    names = r.link_names
    depth = {nm: len(r.path_from_root(nm)) for nm in names}
    stance, swing = [], []
    if np.allclose(P, np.round(P), atol=1e-9) and np.allclose(np.abs(np.round(P)).sum(1), 1):
        for i in range(len(names)):
            j = int(np.argmax(np.abs(P[i])))
            if j != i and depth[names[i]] < depth[names[j]]:
                stance.append(i)
                swing.append(j)
    root = names.index(r.root.name)
    if not stance:
        stance, swing = [root], [names.index(r.swing_foot.link)]
    path = r.path_from_root(r.swing_foot.link)
    hip = next((names.index(nm) for nm in path if names.index(nm) not in stance), root)
    return Legs(tuple(stance), tuple(swing), hip)


def default_alpha(model: CompiledModel) -> np.ndarray:
    """``c`` of the virtual stance leg: ``alpha = -mean(theta of the stance-leg links)`` [rad]
    (with RABBIT's equal tibia and femur, the angle of the line from the stance foot to the
    hip; with a single-link leg, minus its absolute angle). Increases when walking forward."""
    lg = legs(model)
    return -model.robot.T[list(lg.stance)].mean(axis=0)


def _rot(theta: float, p) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]])


def leg_length(model: CompiledModel, q: np.ndarray) -> float:
    """Distance from the stance foot to the hip at ``q`` [m]."""
    r = model.robot
    lg = legs(model)
    pts = model.link_points(q).reshape(-1, 4)
    root = r.link_names.index(r.root.name)
    foot = pts[root, :2] + _rot((r.T @ q)[root], r.stance_foot.point)
    return float(np.linalg.norm(pts[lg.hip, :2] - foot))


# ---------------------------------------------------------------------------- evaluation
@dataclass
class Evaluation:
    """One point ``x``: objective (SI and scaled) and constraint values by family (scaled,
    equality families must be 0, inequality families >= 0)."""

    ok: bool
    objective: float  # SI: N^2 m s (effort) or N m (peak)
    scaled: float
    eq: dict[str, np.ndarray]
    ineq: dict[str, np.ndarray]
    info: dict = field(default_factory=dict)

    def violations(self) -> dict[str, float]:
        out = {}
        for fam in FAMILIES:
            v = 0.0
            if fam in self.eq and self.eq[fam].size:
                v = max(v, float(np.abs(self.eq[fam]).max()))
            if fam in self.ineq and self.ineq[fam].size:
                v = max(v, float(np.maximum(-self.ineq[fam], 0).max()))
            if fam in self.eq or fam in self.ineq:
                out[fam] = v
        return out

    @property
    def max_violation(self) -> float:
        return max(self.violations().values(), default=0.0)


class Problem:
    """The design problem for one robot and :class:`DesignSpec` (layout, scales, evaluation)."""

    def __init__(self, model: CompiledModel, spec: DesignSpec):
        spec.validate(model)
        self.model, self.spec = model, spec
        r = model.robot
        self.N = N = model.n
        self.M = M = spec.order
        self.c = (np.asarray(spec.alpha_c, float) if spec.alpha_c is not None
                  else default_alpha(model))
        self.H = np.vstack([np.hstack([np.eye(N - 1), np.zeros((N - 1, 1))]), self.c[None]])
        self.Hinv = np.linalg.inv(self.H)
        self.legs = legs(model)
        lo = np.array([c.range[0] for c in r.coordinates], float)
        hi = np.array([c.range[1] for c in r.coordinates], float)
        self.lo, self.hi = lo, hi
        self.torque_limit = np.array([c.torque_limit for c in r.coordinates if c.actuated])
        self.q_ref = self._reference_posture(0.15)
        self.ell = max(leg_length(model, self.q_ref), 1e-3)
        self.weight = r.total_mass * r.gravity
        self.eps = (0.1 * self.weight if spec.min_vertical_force is None
                    else spec.min_vertical_force)
        v_ref = spec.speed or 0.5
        self.zeta_ref = 0.5 * (r.total_mass * self.ell * v_ref) ** 2
        self.u_scale = 0.1 * self.weight * self.ell
        self.J_scale = self.u_scale**2 * np.sqrt(self.ell / r.gravity) / self.ell
        self.m = model.n_thrusters if spec.thrust_design else 0
        # a fixed constant thrust [N] (spec.thrust) when thrust is not a variable
        self.F_fixed = (np.zeros(model.n_thrusters) if spec.thrust is None
                        else np.asarray(spec.thrust, float))
        lim = np.array([t.limits for t in r.thrusters], float).reshape(-1, 2)
        self.F_lo, self.F_hi = lim[:, 0], lim[:, 1]
        self.F_scale = max(float(np.abs(lim[np.isfinite(lim)]).max(initial=0.0)), self.weight)
        n = spec.nodes
        self.n_nodes = n
        self.x_lobatto = -np.cos(np.pi * np.arange(n) / (n - 1))  # lobatto() on [-1, 1]
        # on [-1, 1] at the Lobatto nodes: cumulative integrals V = Q f and Clenshaw-Curtis
        # weights w (times (alpha_f - alpha_i)/2 on the step)
        unit = np.eye(n)
        self.Q = ChebSeries.from_values(-1.0, 1.0, unit).cumulative()(lobatto(-1.0, 1.0, n))
        self.w_cc = integrate(-1.0, 1.0, unit)[0]
        self.mid = (n - 1) // 2
        self.s_dense = np.linspace(0.0, 1.0, DENSE)  # height, ranges, forces, torques
        self.P = ChebSeries.from_values(-1.0, 1.0, unit)(2.0 * self.s_dense - 1.0)  # nodes->grid
        self.w_dense = np.full(DENSE, 1.0 / (DENSE - 1))  # trapezoid on s in [0, 1]
        self.w_dense[[0, -1]] *= 0.5
        self.n_X = (N - 1) * (M - 2)  # free Bezier entries (columns 2 .. M-1)
        self.shapes: tuple[dict, dict] = ({}, {})  # constraint block sizes (fixed per start)
        self.sign_E = 1.0
        self.E_ref = 1.0
        self.direction = 1.0
        self.evaluations = 0

    # -- layout ---------------------------------------------------------------------------
    def unpack(self, x: np.ndarray):
        N, nX, m = self.N, self.n_X, self.m
        qm = x[:N]
        X = x[N:N + nX].reshape(N - 1, self.M - 2)
        F = self.F_fixed.copy()
        if m:
            F = x[N + nX:N + nX + m] * self.F_scale
        zm = x[N + nX + m] * self.zeta_ref
        t = x[N + nX + m + 1] if self.spec.objective == "peak" else None
        return qm, X, F, zm, t

    def pack(self, qm, X, F, zm, t=None) -> np.ndarray:
        parts = [qm, np.ravel(X)]
        if self.m:
            parts.append(np.asarray(F, float) / self.F_scale)
        parts.append([zm / self.zeta_ref])
        if self.spec.objective == "peak":
            parts.append([0.0 if t is None else t])
        return np.concatenate([np.asarray(p, float) for p in parts])

    def bounds(self) -> list[tuple[float | None, float | None]]:
        b = []
        for i in range(self.N):
            lo = self.lo[i] if np.isfinite(self.lo[i]) else -np.pi
            hi = self.hi[i] if np.isfinite(self.hi[i]) else np.pi
            b.append((lo, hi))
        b += [(-1.5, 1.5)] * self.n_X
        for j in range(self.m):
            b.append((self.F_lo[j] / self.F_scale, self.F_hi[j] / self.F_scale))
        b.append((1e-4, 1e3))
        if self.spec.objective == "peak":
            b.append((0.0, None))
        return b

    def coefficients(self, qm: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, float]:
        """Bezier matrix (columns 0, 1 still to be fixed by invariance) and alpha_f."""
        qp = self.model.relabel(qm)
        k = np.arange(self.M + 1) / self.M
        A = qp[:-1, None] + (qm[:-1] - qp[:-1])[:, None] * k[None, :]
        A[:, 2:self.M] += X
        A[:, self.M] = qm[:-1]
        return A, float(self.c @ qm)

    def gait(self, x: np.ndarray, name: str | None = None) -> Gait:
        qm, X, F, _, _ = self.unpack(x)
        A, af = self.coefficients(qm, X)
        g = Gait(name or self.spec.name, self.model.robot.name, tuple(self.c.tolist()), af,
                 tuple(map(tuple, A.tolist())), "auto", mu=self.spec.mu,
                 thrust=self.thrust_schedule(F))
        return apply_invariance(self.model, g)

    def thrust_schedule(self, F: np.ndarray) -> WrittenSchedule | None:
        """The constant thrust of the gait file (designed, or fixed by ``spec.thrust``)."""
        if not self.m and self.spec.thrust is None:
            return None
        names = self.model.robot.thruster_names
        return WrittenSchedule((0.0, 1.0), tuple((nm, (float(f),)) for nm, f in zip(names, F)))

    def range_cases(self, F: np.ndarray) -> list[np.ndarray]:
        """Thrust vectors [N] at the two ends of ``spec.thrust_range`` (the other thrusters at
        their nominal ``F``); empty without a range."""
        if self.spec.thrust_range is None:
            return []
        name, lo, hi = self.spec.thrust_range
        j = self.model.robot.thruster_names.index(name)
        out = []
        for v in (lo, hi):
            Fk = np.array(F, float)
            Fk[..., j] = v
            out.append(Fk)
        return out

    # -- evaluation -----------------------------------------------------------------------
    def evaluate(self, x: np.ndarray) -> Evaluation:
        """Objective and every constraint at ``x`` (see the module docstring)."""
        return self.evaluate_many(np.asarray(x, float)[None, :], info=True)[0]

    def evaluate_many(self, xs: np.ndarray, info: bool = False) -> list[Evaluation]:
        """:meth:`evaluate` at every row of ``xs`` (shape ``(k, n)``) in one vectorised pass
        (the points of a forward-difference Jacobian): each row is computed with the shapes
        and operations of a single point, so the result equals ``[evaluate(x) for x in xs]``
        bit for bit. ``info`` (the diagnostics :func:`~.solver.describe` reads) is filled only
        when asked. A batch that raises (a singular impact matrix in one row) is evaluated row
        by row, so one bad point fails alone."""
        xs = np.atleast_2d(np.asarray(xs, float))
        try:
            with np.errstate(all="ignore"):
                evs, finite = self._evaluate_batch(xs, info)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError, ZeroDivisionError):
            if len(xs) == 1:
                self.evaluations += 1
                return [self._failed()]
            return [self.evaluate_many(x[None, :], info)[0] for x in xs]
        self.evaluations += len(xs)
        return [ev if ok else self._failed() for ev, ok in zip(evs, finite)]

    def _failed(self) -> Evaluation:
        """A point where the model cannot be evaluated: every constraint badly violated."""
        eq = {k: np.full(n, 10.0) for k, n in self.shapes[0].items()}
        ineq = {k: np.full(n, -10.0) for k, n in self.shapes[1].items()}
        return Evaluation(False, float("inf"), 1e3, eq, ineq, {})

    def _maps(self, xs: np.ndarray):
        """The gait of every row of ``xs`` as :meth:`gait` and ``gait_maps`` make it (Bezier
        columns 0 and 1 by hybrid invariance, :func:`apply_invariance`), batched: the
        :class:`_Maps`, the pre-impact posture, the thrust, ``zeta^-``, the epigraph variable
        and the impact maps at ``q^-``."""
        model, N, M, m, nX = self.model, self.N, self.M, self.m, self.n_X
        B = xs.shape[0]
        c, Hinv = self.c, self.Hinv
        qm = np.ascontiguousarray(xs[:, :N])
        X = xs[:, N:N + nX].reshape(B, N - 1, M - 2)
        F = np.repeat(self.F_fixed[None, :], B, axis=0)
        if m:
            F = xs[:, N + nX:N + nX + m] * self.F_scale
        zm = xs[:, N + nX + m] * self.zeta_ref
        tpk = xs[:, N + nX + m + 1] if self.spec.objective == "peak" else None
        # coefficients(): straight line from q_b^+ to q_b^- plus the offsets X
        qp = _relabel(model, qm)
        k = np.arange(M + 1) / M
        A = qp[:, :-1, None] + (qm[:, :-1] - qp[:, :-1])[:, :, None] * k
        A[:, :, 2:M] += X
        A[:, :, M] = qm[:, :-1]
        af = _dot(c, qm)
        # apply_invariance(): q^-, q^+, alpha_i; columns 0 and 1
        q_minus = _mv(Hinv, np.concatenate([A[:, :, -1], af[:, None]], axis=1))
        q_plus = _relabel(model, q_minus)
        alpha_i = _dot(c, q_plus)
        dh_f = M * (A[:, :, -1] - A[:, :, -2]) / (af - alpha_i)[:, None]
        phi_f = _mv(Hinv, np.concatenate([dh_f, np.ones((B, 1))], axis=1))
        impact = model.impact_maps(q_minus)
        w = _mv(model.R, _mv(impact[2], phi_f))
        A[:, :, 0] = q_plus[:, :-1]
        A[:, :, 1] = A[:, :, 0] + ((af - alpha_i) / M)[:, None] * w[:, :-1] / _dot(c, w)[:, None]
        # gait_maps() of that gait: the same q^-, q^+ and alpha_i (column M is unchanged)
        return _Maps(A, Hinv, alpha_i, af, q_minus, q_plus), qm, F, zm, tpk, impact

    def _evaluate_batch(self, xs: np.ndarray, info: bool) -> tuple[list[Evaluation], np.ndarray]:
        """Objective and constraints at every row of ``xs`` (module docstring; see
        :meth:`evaluate_many` for why each row equals a single evaluation bit for bit: matrix
        products go through :func:`_mv`, :func:`_vm` and :func:`_dot`, stacks of the
        single-point products), and whether each row's values are all finite."""
        model, spec, N = self.model, self.spec, self.N
        B = xs.shape[0]
        maps, qm, F, zm, tpk, (Mu, MF, Delta) = self._maps(xs)
        a_i, a_f = maps.alpha_i, maps.alpha_f
        span = a_f - a_i
        a = (0.5 * (a_i + a_f))[:, None] + (0.5 * (a_f - a_i))[:, None] * self.x_lobatto
        zt = zero_dynamics_terms(model, maps, a)
        st = stance_terms(model, maps, a)
        k1, E = zt["kappa1"], zt["eDPhi"]  # kappa_1 = 1 / (e_N^T D Phi)
        half = (0.5 * span)[:, None]
        V = _mv(self.Q, (zt["kappa2"] + _mv(zt["beta"], F)) * E) * half  # V_Z at the nodes
        phi_f = maps.Phi(a_f[:, None])[:, 0]
        D_plus = model.D(maps.q_plus)
        delta = _dot(_vm(_vm(D_plus[:, N - 1, :], model.R), Delta), phi_f) * k1[:, -1]
        d2 = _square(delta)
        zeta = (d2 * zm)[:, None] + V
        # |alpha'| = |kappa_1| sqrt(2 zeta); the floor keeps T finite at infeasible points
        dT = 1.0 / (np.abs(k1) * np.sqrt(2.0 * np.maximum(zeta, 1e-3 * self.zeta_ref)))
        T = _dot(self.w_cc, dT) * 0.5 * np.abs(span)
        p_sw = model.p_swing(qm)
        L = p_sw[:, 0]
        hgt = st.swing_height
        u = np.einsum("bgim,bm->bgi", st.U2, F) + st.U1 * zeta[:, :, None] + st.U0
        # objective
        Lpos = np.maximum(L, 1e-3 * self.ell)
        if spec.objective == "effort":
            J = _dot(self.w_cc, (u**2).sum(-1) * dT) * 0.5 * np.abs(span) / Lpos
            if self.m:
                J = J + spec.thrust_weight * _dot(F, F) * T / Lpos
            scaled = J / self.J_scale
        elif spec.objective == "cot":
            J = self._cot(maps, a, u, F, span, Lpos)
            scaled = J / COT_SCALE
        else:
            J = np.abs(u).reshape(B, -1).max(axis=1)
            scaled = tpk
        # impact (SPEC 5): q'^- per unit |sigma^-|
        sgn = np.sign(span) * np.sign(k1[:, 0])
        sig = np.sqrt(2.0 * np.maximum(zm, 0.0))
        dq = phi_f * k1[:, -1:] * sgn[:, None]
        F2 = _mv(MF, dq) * sig[:, None]
        v_trail = _mv(Mu, dq)[:, N:] * sig[:, None]
        td_unit = _dot(model.E_swing(qm)[:, 1, :], dq)  # touch-down velocity per |sigma^-|
        nF2 = np.maximum(np.sqrt(_dot(F2, F2)), 1e-12)
        # constraints (scaled); every block has the batch as its first axis
        eq: dict[str, list] = {k: [] for k in FAMILIES}
        iq: dict[str, list] = {k: [] for k in FAMILIES}
        eq["orbit"].append(((1.0 - d2) * zm - V[:, -1]) / self.zeta_ref)
        parts = {"fixed_point": np.abs(eq["orbit"][0]),
                 "zeta": (zeta - (spec.min_zeta_ratio * zm)[:, None]) / self.zeta_ref,
                 "delta": (d2 - 1e-3) * 10.0, "kappa1": self.sign_E * E / self.E_ref - 0.2,
                 "monotonic": (self.direction * span - 0.05) / 0.05}
        iq["orbit"] += [parts["zeta"], parts["delta"], parts["kappa1"], parts["monotonic"]]
        iq["stability"].append((spec.max_delta_sq - STABILITY_MARGIN - d2) * 10.0)
        if spec.speed is not None:
            eq["speed"].append(np.where(T > 0, (L / T - spec.speed) / spec.speed, 10.0))
        if spec.step_length is not None:
            eq["step_length"].append((L - spec.step_length) / (0.1 * self.ell))
        eq["foot_placement"].append(p_sw[:, 1] / (0.1 * self.ell))
        iq["foot_placement"].append((L - 0.05 * self.ell) / (0.1 * self.ell))
        iq["clearance"].append((hgt[:, self.mid] - spec.clearance) / 0.01)
        q_d = maps.q_Z(a_i[:, None] + self.s_dense * span[:, None])
        iq["scuffing"].append((cell_minima(model.p_swing(q_d)[..., 1]) + DIP) / 0.01)
        mu_d = spec.mu - 0.005
        iq["impact"] += [(mu_d * F2[:, 1] - F2[:, 0]) / nF2, (mu_d * F2[:, 1] + F2[:, 0]) / nF2,
                         F2[:, 1] / nF2 - 0.01]
        # stance, lift-off and torques on the nominal orbit and on the orbits of the ends of
        # the thrust range (everything is affine in a constant thrust: the ends suffice), on
        # the dense grid: the Lambdas and V_Z are interpolated from the nodes (Chebyshev)
        P = self.P
        Ld = [np.matmul(P, t.reshape(B, t.shape[1], -1)).reshape((B, P.shape[0]) + t.shape[2:])
              for t in (st.L0, st.L1, st.L2, st.U0, st.U1, st.U2)]

        def on_dense(Fk, zk):
            zk = _mv(P, zk)[:, :, None]
            return (np.einsum("bgim,bm->bgi", Ld[2], Fk) + Ld[1] * zk + Ld[0],
                    np.einsum("bgim,bm->bgi", Ld[5], Fk) + Ld[4] * zk + Ld[3])

        cases = [(*on_dense(F, zeta), v_trail[:, 1], td_unit * sig)]
        range_zeta = []
        for Fk in self.range_cases(F):
            Vk = V + _mv(self.Q, _mv(zt["beta"], Fk - F) * E) * half
            # zeta* = V_Z(alpha_f) / (1 - delta_zero^2) on that thrust's orbit (SPEC 3, 4),
            # inline rather than ZeroDynamics.fixed_point_of: delta_zero^2 (d2) and V_Z are
            # functions of the decision variables here, one row per candidate of the batch,
            # with no ZeroDynamics of a fixed gait behind them; and the floor 1e-3 keeps the
            # constraint finite (and its finite-difference Jacobian defined) at an iterate
            # with delta_zero^2 >= 1, which the max_delta_sq constraint rules out at the
            # solution, where fixed_point_of would give inf or NaN
            zs_k = Vk[:, -1] / np.maximum(1.0 - d2, 1e-3)
            zk = (d2 * zs_k)[:, None] + Vk
            range_zeta += [zs_k / self.zeta_ref - 1e-3,
                           (zk - (spec.min_zeta_ratio * zs_k)[:, None]) / self.zeta_ref]
            sig_k = np.sqrt(2.0 * np.maximum(zs_k, 0.0))
            cases.append((*on_dense(Fk, zk), v_trail[:, 1] / np.maximum(sig, 1e-12) * sig_k,
                          td_unit * sig_k))
        iq["orbit"] += range_zeta
        for F1k, _, lift, td in cases:
            iq["vertical_force"].append(
                (F1k[:, :, 1] - self.eps - 0.005 * self.weight) / self.weight)
            iq["friction"] += [(mu_d * F1k[:, :, 1] - F1k[:, :, 0]) / self.weight,
                               (mu_d * F1k[:, :, 1] + F1k[:, :, 0]) / self.weight]
            iq["impact"].append((lift - spec.min_liftoff - VELOCITY_MARGIN) / 0.1)
            iq["touchdown"].append((-td - spec.min_touchdown_velocity - VELOCITY_MARGIN) / 0.1)
        for i in range(N):
            if np.isfinite(self.lo[i]):
                iq["joint_range"].append((q_d[:, :, i] - self.lo[i] - 0.01) / 0.1)
            if np.isfinite(self.hi[i]):
                iq["joint_range"].append((self.hi[i] - 0.01 - q_d[:, :, i]) / 0.1)
        for i, lim in enumerate(self.torque_limit):
            if np.isfinite(lim):
                for _, uk, _, _ in cases:
                    iq["torque_limit"] += [(0.99 * lim - uk[:, :, i]) / lim,
                                           (0.99 * lim + uk[:, :, i]) / lim]

        def rows(vs):
            return np.concatenate([np.reshape(v, (B, -1)) for v in vs], axis=1)

        eqd = {k: rows(vs) for k, vs in eq.items() if vs}
        iqd = {k: rows(vs) for k, vs in iq.items() if vs}
        if spec.objective == "peak":
            ur = u.reshape(B, -1) / self.u_scale
            iqd["_epigraph"] = np.concatenate([tpk[:, None] - ur, tpk[:, None] + ur], axis=1)
        finite = np.isfinite(scaled)
        for v in (*eqd.values(), *iqd.values()):
            finite &= np.isfinite(v).all(axis=1)
        out = []
        for b in range(B):
            ib = {}
            if info:
                ib = self._info(b, dict(cases=cases, iqd=iqd, F2=F2, T=T, L=L, d2=d2, q_d=q_d,
                                        parts=parts, range_zeta=range_zeta, zm=zm, hgt=hgt,
                                        zeta=zeta, V=V, span=span))
            out.append(Evaluation(True, float(J[b]), float(scaled[b]),
                                  {k: v[b] for k, v in eqd.items()},
                                  {k: v[b] for k, v in iqd.items()}, ib))
        return out, finite

    def _cot(self, maps: _Maps, a: np.ndarray, u: np.ndarray, F: np.ndarray, span: np.ndarray,
             L: np.ndarray) -> np.ndarray:
        """The smoothed mechanical cost of transport of each row [1] (module docstring, SPEC
        15): the joints' powers ``s u_j Phi_j`` and the thrusters' ``s F_k (B_F^T Phi)_k`` per
        ``|dalpha|`` at the nodes ``a`` (B, g), interpolated onto the dense grid, their smoothed
        positive parts integrated by the trapezoid rule over ``|alpha_f - alpha_i|``, over
        ``m g L`` (``L`` [m] the step length)."""
        N, model = self.N, self.model
        phi = maps.Phi(a)  # (B, g, N)
        sgn = np.sign(span)[:, None, None]
        power = u * phi[:, :, :N - 1] * sgn  # (B, g, N-1) [N m per rad]
        if model.n_thrusters:
            bf = model.B_F(maps.q_Z(a))  # (B, g, N, m)
            bt = np.matmul(np.swapaxes(bf, -1, -2), phi[..., None])[..., 0]  # (B, g, m)
            power = np.concatenate([power, bt * sgn * F[:, None, :]], axis=2)
        dense = np.matmul(self.P, power)  # (B, DENSE, terms)
        e = COT_SMOOTH * self.u_scale
        pos = 0.5 * (dense + np.sqrt(dense * dense + e * e))
        work = _dot(self.w_dense, pos.sum(axis=2)) * np.abs(span)  # [J]
        return work / (self.weight * L)

    def _info(self, b: int, v: dict) -> dict:
        """The diagnostics of row ``b`` of :meth:`_evaluate_batch` (``v``: its batched
        intermediate values by name), read by :func:`~.solver.describe`."""
        N, cases, iqd, F2 = self.N, v["cases"], v["iqd"], v["F2"][b]
        T, L, d2 = float(v["T"][b]), float(v["L"][b]), float(v["d2"][b])
        range_margin = np.full(N, np.inf)  # [rad] worst margin to the range less 0.01 rad
        q_d = v["q_d"][b]
        for i in range(N):
            if np.isfinite(self.lo[i]):
                range_margin[i] = min(range_margin[i],
                                      float(((q_d[:, i] - self.lo[i] - 0.01) / 0.1).min() * 0.1))
            if np.isfinite(self.hi[i]):
                range_margin[i] = min(range_margin[i],
                                      float(((self.hi[i] - 0.01 - q_d[:, i]) / 0.1).min() * 0.1))
        parts = {k: p[b] for k, p in v["parts"].items()}
        for k in ("fixed_point", "delta", "monotonic"):
            parts[k] = float(parts[k])
        rz = [np.ravel(r[b]) for r in v["range_zeta"]]
        parts["range"] = np.concatenate(rz) if rz else np.zeros(0)
        F1all = np.concatenate([c[0][b] for c in cases])
        ratio = np.where(F1all[:, 1] > 0,
                         np.abs(F1all[:, 0]) / np.maximum(F1all[:, 1], 1e-300), np.inf)
        return dict(delta_zero_sq=d2, zeta_minus=float(v["zm"][b]), step_time=T, step_length=L,
                    speed=L / T if T > 0 else 0.0, mid_height=float(v["hgt"][b, self.mid]),
                    min_height=float(iqd["scuffing"][b].min() * 0.01 - DIP),
                    min_vertical_force=float(F1all[:, 1].min()),
                    max_friction_ratio=float(ratio.max()),
                    impact_friction_ratio=float(abs(F2[0]) / F2[1]) if F2[1] > 0 else np.inf,
                    liftoff_velocity=float(min(c[2][b] for c in cases)),
                    min_zeta=float(v["zeta"][b].min()),
                    touchdown_velocity=float(max(c[3][b] for c in cases)),
                    V_f=float(v["V"][b, -1]), span=float(v["span"][b]), orbit_parts=parts,
                    joint_range_margin=range_margin,
                    max_abs_torque=np.max([np.abs(c[1][b]).max(axis=0) for c in cases], axis=0))

    def polish(self, x: np.ndarray, tol: float = 1e-13) -> np.ndarray:
        """``x`` with the swing foot exactly on the ground at impact: Newton on the unactuated
        coordinate of q^- (a rotation of the whole pre-impact posture about the stance foot),
        so that the foot-placement equality holds to ``tol`` [m], not just to the solver's
        tolerance. The other variables are unchanged."""
        x = np.array(x, float)
        N, model = self.N, self.model
        for _ in range(30):
            h = float(model.p_swing(x[:N])[1])
            if abs(h) <= tol * self.ell:
                break
            dh = float(model.E_swing(x[:N])[1, N - 1])
            if dh == 0.0:
                break
            x[N - 1] -= h / dh
        return x

    def fix_shapes(self, ev: Evaluation) -> None:
        self.shapes = ({k: v.size for k, v in ev.eq.items()},
                       {k: v.size for k, v in ev.ineq.items()})

    # -- starts ---------------------------------------------------------------------------
    def _reference_posture(self, margin: float) -> np.ndarray:
        """All links upright (q = 0) moved inside the joint ranges by ``margin`` [rad]."""
        q = np.zeros(self.N)
        for i in range(self.N):
            lo, hi = self.lo[i], self.hi[i]
            mgn = min(margin, 0.25 * (hi - lo)) if np.isfinite(hi - lo) else margin
            q[i] = np.clip(q[i], lo + mgn if np.isfinite(lo) else -np.inf,
                           hi - mgn if np.isfinite(hi) else np.inf)
        return q

    def posture(self, step: float, q_ref: np.ndarray) -> np.ndarray:
        """Pre-impact configuration nearest to ``q_ref`` in absolute link angles with the swing
        foot on the ground ``step`` [m] ahead: ``min |T (q - q_ref)|^2`` s.t.
        ``p_2(q) = (step, 0)``, joint ranges (less 0.05 rad) as bounds."""
        model, T = self.model, self.model.robot.T
        target = np.array([step, 0.0])
        bnds = [(lo + 0.05 if np.isfinite(lo) else None, hi - 0.05 if np.isfinite(hi) else None)
                for lo, hi in zip(self.lo, self.hi)]
        lg = self.legs
        # initial guess: stance-leg links lean forward, swing-leg links mirror them
        ang = np.arcsin(np.clip(0.5 * step / self.ell, -0.9, 0.9))
        th0 = T @ q_ref
        th0[list(lg.stance)] -= ang
        th0[list(lg.swing)] += ang
        q0 = np.linalg.solve(T, th0)
        res = minimize(
            lambda q: float(np.sum((T @ (q - q_ref)) ** 2)), q0,
            jac=lambda q: 2.0 * T.T @ (T @ (q - q_ref)), method="SLSQP", bounds=bnds,
            constraints=[{"type": "eq", "fun": lambda q: model.p_swing(q) - target,
                          "jac": lambda q: model.E_swing(q)}],
            options={"maxiter": 200, "ftol": 1e-12})
        return res.x

    def start(self, rng: np.random.Generator | None) -> np.ndarray:
        """Start ``x0``: a posture with the swing foot on the ground, straight-line Bezier rows
        between ``q^+`` and ``q^-`` plus a swing-leg bump that lifts the swing foot to the
        clearance at mid-step, and ``zeta^-`` from the target speed. ``rng`` None: the
        deterministic default start; otherwise a random perturbation of it. Also fixes, for
        this start, the sign of kappa_1 and of alpha_f - alpha_i that the ``orbit`` family
        keeps (kappa_1 may not change sign, alpha stays monotonic)."""
        spec = self.spec
        step = spec.step_length or 0.55 * self.ell
        q_ref = self.q_ref.copy()
        amp = 1.0
        if rng is not None:
            if spec.step_length is None:
                step = self.ell * rng.uniform(0.35, 0.8)
            q_ref = self._reference_posture(rng.uniform(0.05, 0.4))
            q_ref[-1] += rng.normal(0.0, 0.1)
            amp = rng.uniform(0.5, 2.0)
        qm = self.posture(step, q_ref)
        X = np.zeros((self.N - 1, self.M - 2))
        X = self._lift(qm, X, amp)
        if rng is not None:
            X += rng.normal(0.0, 0.05, X.shape)
        return self._oriented(qm, X, None)

    def _oriented(self, qm: np.ndarray, X: np.ndarray, zeta_minus: float | None) -> np.ndarray:
        """``x`` of the posture ``qm`` and Bezier offsets ``X``, fixing for this start the sign
        of kappa_1 and of alpha_f - alpha_i that the ``orbit`` family keeps; ``zeta^-`` given,
        or (None) from the target speed."""
        spec, model = self.spec, self.model
        x = self.pack(qm, X, np.zeros(model.n_thrusters), self.zeta_ref)
        g = self.gait(x)
        maps = gait_maps(model, g)
        a = lobatto(maps.alpha_i, maps.alpha_f, self.n_nodes)
        E = 1.0 / stance_terms(model, maps, a).AT
        self.sign_E = float(np.sign(np.mean(E))) or 1.0
        self.E_ref = max(abs(float(np.mean(E))), 1e-6)
        self.direction = float(np.sign(maps.alpha_f - maps.alpha_i)) or 1.0
        zm = zeta_minus
        if zm is None:
            v = spec.speed or 0.5
            L = max(float(model.p_swing(qm)[0]), 0.05 * self.ell)
            alpha_dot = abs(maps.alpha_f - maps.alpha_i) * v / L
            zm = 0.5 * (self.E_ref * alpha_dot) ** 2
        x = self.pack(qm, X, np.zeros(model.n_thrusters), zm, 0.0)
        if spec.objective == "peak":  # epigraph variable just above the start's peak torque
            ev = self.evaluate(x)
            x[-1] = 1.05 * ev.objective / self.u_scale if ev.ok else 1.0
        return x

    def warm_start(self, q_minus, coefficients, zeta_minus: float) -> np.ndarray | None:
        """Start ``x0`` from a finished design (continuation): its pre-impact posture
        ``q_minus`` [rad], Bezier ``coefficients`` ((N-1) x (M+1) [rad]) and ``zeta_minus``
        [kg^2 m^4/s^2]. None when that design does not fit this problem (another order or
        robot); constant thrust variables start at 0 N."""
        qm = np.asarray(q_minus, float)
        A = np.asarray(coefficients, float)
        if qm.shape != (self.N,) or A.shape != (self.N - 1, self.M + 1) or \
                not (np.all(np.isfinite(A)) and np.all(np.isfinite(qm))) or \
                not zeta_minus > 0:
            return None
        line, _ = self.coefficients(qm, np.zeros((self.N - 1, self.M - 2)))
        X = A[:, 2:self.M] - line[:, 2:self.M]
        return self._oriented(qm, X, float(zeta_minus))

    def _lift(self, qm: np.ndarray, X: np.ndarray, amp: float) -> np.ndarray:
        """Minimum-norm bump ``d sin(pi s)`` on the swing-leg joints raising the mid-step
        swing-foot height to the clearance (+1 cm), capped at 0.8 rad."""
        model, M = self.model, self.M
        act = [c for c in model.robot.coordinates if c.actuated]
        swing_links = {model.robot.link_names[i] for i in self.legs.swing}
        cols = [i for i, c in enumerate(act) if c.link in swing_links]
        if not cols:
            return X
        A, af = self.coefficients(qm, X)
        s = np.array(0.5)
        hd = bezier(A, s)
        q_mid = self.Hinv @ np.append(hd, 0.5 * (af + float(self.c @ model.relabel(qm))))
        h = float(model.p_swing(q_mid)[1])
        J = model.E_swing(q_mid)[1, cols]
        k = np.arange(2, M)
        w = np.array([comb(M, j) for j in k]) * 0.5**M
        beta = float(w @ np.sin(np.pi * k / M))
        need = amp * (self.spec.clearance + 0.01) - h
        if need <= 0 or float(J @ J) < 1e-12:
            return X
        d = need / beta * J / float(J @ J)
        d *= min(1.0, 0.8 / float(np.abs(d).max()))
        X = X.copy()
        X[cols] += d[:, None] * np.sin(np.pi * k / M)[None, :]
        return X


def cell_minima(h: np.ndarray) -> np.ndarray:
    """For every interior sample ``j`` of a uniform grid, the minimum over ``t in [-1, 1]`` of
    the parabola through ``h_{j-1}, h_j, h_{j+1}``: ``h_j + c_1 t + c_2 t^2 / 2``. Catches dips
    narrower than the grid spacing (a straight-leg swing foot passing the stance foot; exact
    for a quadratic dip) and is continuous in the samples."""
    c1 = 0.5 * (h[..., 2:] - h[..., :-2])
    c2 = h[..., 2:] - 2.0 * h[..., 1:-1] + h[..., :-2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(c2 > 0, np.clip(-c1 / c2, -1.0, 1.0), -np.sign(c1))
    return h[..., 1:-1] + c1 * t + 0.5 * c2 * t**2


# ------------------------------------------------------------------ batched evaluation
# Stacks of the products a single point computes, so that every row of a batch is computed
# with the same BLAS call (same shapes, same kernel) as one point alone: a plain (k, n) @ (n,)
# would be one larger product, equal only to rounding.
def _mv(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M @ v`` for a stack of vectors ``v`` (..., c) (``M`` (r, c) or a stack)."""
    return np.matmul(M, v[..., None])[..., 0]


def _vm(v: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``v @ M`` for a stack of row vectors ``v`` (..., r)."""
    return np.matmul(v[..., None, :], M)[..., 0, :]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` of two (stacks of) vectors, one dot product per row."""
    return np.matmul(a[..., None, :], b[..., :, None])[..., 0, 0]


def _square(v: np.ndarray) -> np.ndarray:
    """``v**2`` of each entry as a Python float squares (C ``pow(v, 2)``, which can differ
    from numpy's ``v * v`` in the last bit), as the single-point code did."""
    return np.array([float(x) ** 2 for x in v])


def _relabel(model: CompiledModel, q: np.ndarray) -> np.ndarray:
    """:meth:`CompiledModel.relabel` of a stack of configurations (..., N)."""
    return _vm(q, model.R.T) + model.b


class _Maps:
    """The geometry of a batch of gaits (one per row): ``q_Z``, ``Phi`` and ``dPhi`` of
    :class:`~thrustwalk_cli.hzd.constraints.GaitMaps` (SPEC 2) for ``alpha`` of shape
    ``(k, g)``, row ``r`` computed with the operations and shapes of gait ``r`` alone.
    ``A``: (k, N-1, M+1) [rad]; ``alpha_i``, ``alpha_f``: (k,) [rad]."""

    def __init__(self, A: np.ndarray, Hinv: np.ndarray, alpha_i: np.ndarray,
                 alpha_f: np.ndarray, q_minus: np.ndarray, q_plus: np.ndarray):
        self.A, self.Hinv = A, Hinv
        self.alpha_i, self.alpha_f, self.q_minus, self.q_plus = alpha_i, alpha_f, q_minus, q_plus
        self.span = alpha_f - alpha_i
        self._last: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def _once(self, name: str, alpha: np.ndarray, fn) -> np.ndarray:
        """``fn(alpha)``, reused when called again with the same ``alpha`` object (the zero
        dynamics and the stance terms ask for q_Z and Phi at the same nodes)."""
        last = self._last.get(name)
        if last is None or last[0] is not alpha:
            last = self._last[name] = (alpha, fn(alpha))
        return last[1]

    @staticmethod
    def _rows(v: np.ndarray, ndim: int) -> np.ndarray:
        return v.reshape(v.shape[:1] + (1,) * (ndim - 1))

    def s(self, alpha: np.ndarray) -> np.ndarray:
        return (alpha - self._rows(self.alpha_i, alpha.ndim)) / self._rows(self.span, alpha.ndim)

    def _bezier(self, alpha: np.ndarray, deriv: int) -> np.ndarray:
        """:func:`~thrustwalk_cli.hzd.constraints.bezier` of each row's ``A`` at its ``s``."""
        A = self.A
        for _ in range(deriv):
            M = A.shape[-1] - 1
            A = M * np.diff(A, axis=-1) if M > 0 else np.zeros(A.shape[:-1] + (1,))
        M = A.shape[-1] - 1
        k = np.arange(M + 1)
        binom = np.array([comb(M, j) for j in k], float)
        s = self.s(alpha)
        basis = binom * s[..., None] ** k * (1.0 - s[..., None]) ** (M - k)
        return basis @ np.swapaxes(A, -1, -2)

    def q_Z(self, alpha: np.ndarray) -> np.ndarray:
        return self._once("q_Z", alpha, self._q_Z)

    def Phi(self, alpha: np.ndarray) -> np.ndarray:
        return self._once("Phi", alpha, self._Phi)

    def _q_Z(self, alpha: np.ndarray) -> np.ndarray:
        hd = self._bezier(alpha, 0)
        return np.concatenate([hd, alpha[..., None]], axis=-1) @ self.Hinv.T

    def _Phi(self, alpha: np.ndarray) -> np.ndarray:
        dh = self._bezier(alpha, 1) / self._rows(self.span, alpha.ndim + 1)
        return np.concatenate([dh, np.ones(alpha.shape + (1,))], axis=-1) @ self.Hinv.T

    def dPhi(self, alpha: np.ndarray) -> np.ndarray:
        d2 = self._bezier(alpha, 2) / self._rows(_square(self.span), alpha.ndim + 1)
        return np.concatenate([d2, np.zeros(alpha.shape + (1,))], axis=-1) @ self.Hinv.T

