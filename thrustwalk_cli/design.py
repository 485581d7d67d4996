"""Gait design: stable, walkable Bezier gaits found by constrained optimisation (SPEC 2, 3, 5).

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

(kappa terms from :func:`zero_dynamics.zero_dynamics_terms`, exact affine terms of SPEC 5 from
:func:`contact.stance_terms`). Integrals use the nodes (Clenshaw-Curtis, cumulative Chebyshev);
the constraints on F_1, u, the swing-foot height and the joint ranges use a dense uniform grid
in ``s`` (the Lambdas and V_Z interpolated from the nodes). Objectives: ``effort``
``J = (1/L) int_0^T |u|^2 dt = (1/L) int |u|^2 / alpha' dalpha`` [N^2 m s] (plus
``w_F |F_T|^2 T / L`` when thrust is designed), or ``peak`` ``max_{i, alpha} |u_i|`` [N m].

Constraint families (each normalised; the largest violation at the best point names the
family that blocks an infeasible request): ``orbit`` (fixed point, zeta > 0 along the step,
delta_zero^2 > 0, kappa_1 regular, alpha monotonic), ``stability`` (delta_zero^2 <= bound),
``speed``, ``step_length``, ``foot_placement`` (swing foot on the ground ahead of the stance
foot), ``clearance`` (height at mid-step ``s = 1/2``), ``scuffing`` (height >= 0 over the step),
``vertical_force`` (``F_1^v >= eps``), ``friction`` (``|F_1^h| <= mu F_1^v``), ``impact`` (impulse
in the cone, trailing foot lifts off), ``joint_range`` and ``torque_limit`` (robot file).
With a thrust range, stance, lift-off and torque constraints also hold on the orbits of its
two end thrusts (F_1, u and zeta are affine in a constant thrust, so the whole range follows).

Safety margins inside the solver (so that the re-check on finer grids passes): friction with
``mu - 0.005``, ``F_1^v >= eps + 0.5 %`` of the weight, joint ranges shrunk by 0.01 rad, torques
within 99 % of their limits, ``zeta >= min_zeta_ratio zeta^-``, lift-off >= ``min_liftoff``. The
swing-foot height is constrained on a dense uniform grid through :func:`cell_minima` (dips
between grid points count), so straight legs may touch the ground (3-link: ``--clearance 0``).

Solver: SciPy SLSQP with one shared forward-difference Jacobian per point, several seeded
starts (start 0 is the deterministic default start). The chosen gait is re-checked by the
independent code paths (adaptive :func:`zero_dynamics.zero_dynamics`, :func:`limit_cycles`,
:func:`contact.evaluate`, dense grids); ``feasible`` is the verdict of that re-check.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from math import comb

import numpy as np
from scipy.optimize import minimize

from .contact import evaluate, impact_data, stance_terms, swing_clearance
from .errors import InputError
from .gait import Gait, ThrustSchedule, apply_invariance, bezier, gait_maps
from .model import CompiledModel
from .quadrature import ChebSeries, integrate, lobatto
from .zero_dynamics import Schedule, limit_cycles, zero_dynamics, zero_dynamics_terms

OBJECTIVES = ("effort", "peak")
FAMILIES = ("orbit", "stability", "speed", "step_length", "foot_placement", "clearance",
            "scuffing", "vertical_force", "friction", "impact", "joint_range", "torque_limit")
HEIGHT_TOL = 1e-6  # [m] swing-foot dips shallower than this count as touching (re-check)
DIP = 0.0  # [m] dip allowed by the design constraint
RANGE_TOL = 1e-6  # [rad] joint-range tolerance of the re-check
FEAS_TOL = 1e-5  # normalised constraint violation accepted at the solver's point
ELASTIC = 100.0  # cost of one unit of normalised violation (elastic mode of the solver)
DENSE = 161  # uniform points in s for the height, range, stance-force and torque constraints


@dataclass(frozen=True)
class DesignSpec:
    """What to design (SI units). ``None`` targets are free.

    speed [m/s] and/or step_length [m] (at least one); mu [1]; order M of the Bezier
    polynomials; clearance: swing-foot height at mid-step ``s = 1/2`` [m] (height >= 0 over the
    whole step in any case); max_delta_sq: bound on delta_zero^2 (stability margin);
    min_vertical_force ``eps`` [N] (None: 10 % of the robot's weight); min_liftoff: vertical
    velocity of the trailing foot just after impact [m/s]; min_zeta_ratio: ``zeta(alpha) >=
    ratio zeta^-`` (the walker keeps some momentum at mid-stance); objective ``effort`` or
    ``peak``; thrust_design: constant thrust per thruster as variables (within the robot's
    limits), costed ``thrust_weight |F|^2`` [m^2] in the effort objective; thrust_range
    ``(thruster, low, high)`` [N]: the orbit must exist and the stance, lift-off and torque
    constraints hold for every constant thrust of that thruster in the range (checked at the
    ends: zeta*, zeta(alpha), F_1 and u are affine in a constant thrust); alpha_c: gait-timing
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
    min_zeta_ratio: float = 0.02
    objective: str = "effort"
    thrust_design: bool = False
    thrust_weight: float = 1.0
    thrust_range: tuple[str, float, float] | None = None
    alpha_c: tuple[float, ...] | None = None
    starts: int = 8
    seed: int = 0
    max_iter: int = 150
    nodes: int = 33
    name: str = "designed_gait"

    def validate(self, model: CompiledModel) -> None:
        """Raise :class:`InputError` (one line per problem, naming the option)."""
        p = []
        if self.speed is None and self.step_length is None:
            p.append("options --speed/--step-length: give a target speed, a step length or both")
        if self.speed is not None and not 0 < self.speed <= 20:
            p.append(f"option --speed: must be in (0, 20] m/s (got {self.speed:g})")
        if self.step_length is not None and not 0 < self.step_length <= 10:
            p.append(f"option --step-length: must be in (0, 10] m (got {self.step_length:g})")
        if not 0 < self.mu <= 10:
            p.append(f"option --mu: must be in (0, 10] (got {self.mu:g})")
        if not 3 <= self.order <= 12:
            p.append(f"option --order: Bezier order must be 3..12 (got {self.order})")
        if not 0 <= self.clearance <= 1:
            p.append(f"option --clearance: must be in [0, 1] m (got {self.clearance:g})")
        if not 0 < self.max_delta_sq < 1:
            p.append(f"option --max-delta-sq: must be in (0, 1) (got {self.max_delta_sq:g})")
        if self.min_vertical_force is not None and self.min_vertical_force < 0:
            p.append("option --min-vertical-force: must be >= 0 N")
        if self.objective not in OBJECTIVES:
            p.append(f"option --objective: unknown objective {self.objective!r} "
                     f"(choose from {', '.join(OBJECTIVES)})")
        if self.thrust_design and model.n_thrusters == 0:
            p.append("option --design-thrust: the robot has no thruster")
        if self.thrust_range is not None:
            name, lo, hi = self.thrust_range
            if name not in model.robot.thruster_names:
                p.append(f"option --thrust-range: unknown thruster {name!r} (robot "
                         f"{model.robot.name} has: {', '.join(model.robot.thruster_names)})")
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                p.append("option --thrust-range: need finite NAME:LOW:HIGH with LOW <= HIGH [N]")
        if self.thrust_weight < 0:
            p.append("option --thrust-weight: must be >= 0 m^2")
        if not 1 <= self.starts <= 1000:
            p.append(f"option --starts: must be 1..1000 (got {self.starts})")
        if self.seed < 0:
            p.append("option --seed: must be >= 0")
        if self.max_iter < 1:
            p.append("option --max-iter: must be >= 1")
        if self.nodes < 9 or self.nodes % 4 != 1:
            p.append("nodes: need 4k + 1 Lobatto nodes (k >= 2), so that s = 1/2 is a node")
        if self.alpha_c is not None:
            c = np.asarray(self.alpha_c, float)
            if c.shape != (model.n,) or c[-1] == 0:
                p.append(f"option --alpha: need one coefficient per coordinate and a non-zero "
                         f"coefficient on {model.robot.coordinate_names[-1]}")
        if p:
            raise InputError(p)


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
        lim = np.array([t.limits for t in r.thrusters], float).reshape(-1, 2)
        self.F_lo, self.F_hi = lim[:, 0], lim[:, 1]
        self.F_scale = max(float(np.abs(lim[np.isfinite(lim)]).max(initial=0.0)), self.weight)
        n = spec.nodes
        self.n_nodes = n
        # on [-1, 1] at the Lobatto nodes: cumulative integrals V = Q f and Clenshaw-Curtis
        # weights w (times (alpha_f - alpha_i)/2 on the step)
        unit = np.eye(n)
        self.Q = ChebSeries.from_values(-1.0, 1.0, unit).cumulative()(lobatto(-1.0, 1.0, n))
        self.w_cc = integrate(-1.0, 1.0, unit)[0]
        self.mid = (n - 1) // 2
        self.s_dense = np.linspace(0.0, 1.0, DENSE)  # height, ranges, forces, torques
        self.P = ChebSeries.from_values(-1.0, 1.0, unit)(2.0 * self.s_dense - 1.0)  # nodes->grid
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
        F = np.zeros(self.model.n_thrusters)
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

    def thrust_schedule(self, F: np.ndarray) -> ThrustSchedule | None:
        if not self.m:
            return None
        names = self.model.robot.thruster_names
        return ThrustSchedule((0.0, 1.0), tuple((nm, (float(f),)) for nm, f in zip(names, F)))

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
            Fk[j] = v
            out.append(Fk)
        return out

    # -- evaluation -----------------------------------------------------------------------
    def evaluate(self, x: np.ndarray) -> Evaluation:
        """Objective and every constraint at ``x`` (see the module docstring)."""
        self.evaluations += 1
        try:
            with np.errstate(all="ignore"):
                ev = self._evaluate(np.asarray(x, float))
        except (np.linalg.LinAlgError, FloatingPointError, ValueError, ZeroDivisionError):
            ev = None
        if ev is None or not np.isfinite(ev.scaled) or not all(
                np.all(np.isfinite(v)) for v in (*ev.eq.values(), *ev.ineq.values())):
            return self._failed()
        return ev

    def _failed(self) -> Evaluation:
        """A point where the model cannot be evaluated: every constraint badly violated."""
        eq = {k: np.full(n, 10.0) for k, n in self.shapes[0].items()}
        ineq = {k: np.full(n, -10.0) for k, n in self.shapes[1].items()}
        return Evaluation(False, float("inf"), 1e3, eq, ineq, {})

    def _evaluate(self, x: np.ndarray) -> Evaluation:
        model, spec, N = self.model, self.spec, self.N
        qm, X, F, zm, tpk = self.unpack(x)
        g = self.gait(x)
        maps = gait_maps(model, g)
        a_i, a_f = maps.alpha_i, maps.alpha_f
        span = a_f - a_i
        a = lobatto(a_i, a_f, self.n_nodes)
        zt = zero_dynamics_terms(model, maps, a)
        st = stance_terms(model, maps, a)
        k1, E = zt["kappa1"], zt["eDPhi"]  # kappa_1 = 1 / (e_N^T D Phi)
        V = self.Q @ ((zt["kappa2"] + zt["beta"] @ F) * E) * (0.5 * span)  # V_Z at the nodes
        Mu, MF, Delta = model.impact_maps(maps.q_minus)
        phi_f = maps.Phi(np.array(a_f))
        D_plus = model.D(maps.q_plus)
        delta = float(D_plus[N - 1] @ model.R @ Delta @ phi_f * k1[-1])
        d2 = delta**2
        zeta = d2 * zm + V
        # |alpha'| = |kappa_1| sqrt(2 zeta); the floor keeps T finite at infeasible points
        dT = 1.0 / (np.abs(k1) * np.sqrt(2.0 * np.maximum(zeta, 1e-3 * self.zeta_ref)))
        T = float(self.w_cc @ dT * 0.5 * abs(span))
        L = float(model.p_swing(qm)[0])
        hgt = st.swing_height
        u = np.einsum("gim,m->gi", st.U2, F) + st.U1 * zeta[:, None] + st.U0
        # objective
        Lpos = max(L, 1e-3 * self.ell)
        if spec.objective == "effort":
            J = float(self.w_cc @ ((u**2).sum(1) * dT) * 0.5 * abs(span)) / Lpos
            if self.m:
                J += spec.thrust_weight * float(F @ F) * T / Lpos
            scaled = J / self.J_scale
        else:
            J = float(np.abs(u).max())
            scaled = float(tpk)
        # impact (SPEC 5): q'^- per unit |sigma^-|
        sgn = np.sign(span) * np.sign(k1[0])
        sig = np.sqrt(2.0 * max(zm, 0.0))
        dq = phi_f * k1[-1] * sgn
        F2 = MF @ dq * sig
        v_trail = (Mu @ dq)[N:] * sig
        nF2 = max(float(np.linalg.norm(F2)), 1e-12)
        # constraints (scaled)
        eq: dict[str, list] = {k: [] for k in FAMILIES}
        iq: dict[str, list] = {k: [] for k in FAMILIES}
        eq["orbit"].append([((1.0 - d2) * zm - V[-1]) / self.zeta_ref])
        iq["orbit"] += [(zeta - spec.min_zeta_ratio * zm) / self.zeta_ref,
                        [(d2 - 1e-3) * 10.0],
                        self.sign_E * E / self.E_ref - 0.2,
                        [(self.direction * span - 0.05) / 0.05]]
        iq["stability"].append([(spec.max_delta_sq - d2) * 10.0])
        if spec.speed is not None:
            eq["speed"].append([(L / T - spec.speed) / spec.speed if T > 0 else 10.0])
        if spec.step_length is not None:
            eq["step_length"].append([(L - spec.step_length) / (0.1 * self.ell)])
        eq["foot_placement"].append([model.p_swing(qm)[1] / (0.1 * self.ell)])
        iq["foot_placement"].append([(L - 0.05 * self.ell) / (0.1 * self.ell)])
        iq["clearance"].append([(hgt[self.mid] - spec.clearance) / 0.01])
        q_d = maps.q_Z(a_i + self.s_dense * span)
        iq["scuffing"].append((cell_minima(model.p_swing(q_d)[:, 1]) + DIP) / 0.01)
        mu_d = spec.mu - 0.005
        iq["impact"].append([(mu_d * F2[1] - F2[0]) / nF2, (mu_d * F2[1] + F2[0]) / nF2,
                             F2[1] / nF2 - 0.01])
        # stance, lift-off and torques on the nominal orbit and on the orbits of the ends of
        # the thrust range (everything is affine in a constant thrust: the ends suffice), on
        # the dense grid: the Lambdas and V_Z are interpolated from the nodes (Chebyshev)
        P = self.P
        Ld = [np.tensordot(P, t, axes=(1, 0)) for t in (st.L0, st.L1, st.L2, st.U0, st.U1,
                                                         st.U2)]

        def on_dense(Fk, zk):
            zk = P @ zk
            return (np.einsum("gim,m->gi", Ld[2], Fk) + Ld[1] * zk[:, None] + Ld[0],
                    np.einsum("gim,m->gi", Ld[5], Fk) + Ld[4] * zk[:, None] + Ld[3])

        cases = [(*on_dense(F, zeta), v_trail[1])]
        for Fk in self.range_cases(F):
            Vk = V + self.Q @ ((zt["beta"] @ (Fk - F)) * E) * (0.5 * span)
            zs_k = Vk[-1] / max(1.0 - d2, 1e-3)  # zeta* on that thrust's orbit
            zk = d2 * zs_k + Vk
            iq["orbit"] += [[zs_k / self.zeta_ref - 1e-3],
                            (zk - spec.min_zeta_ratio * zs_k) / self.zeta_ref]
            cases.append((*on_dense(Fk, zk),
                          v_trail[1] / max(sig, 1e-12) * np.sqrt(2.0 * max(zs_k, 0.0))))
        for F1k, _, lift in cases:
            iq["vertical_force"].append(
                (F1k[:, 1] - self.eps - 0.005 * self.weight) / self.weight)
            iq["friction"] += [(mu_d * F1k[:, 1] - F1k[:, 0]) / self.weight,
                               (mu_d * F1k[:, 1] + F1k[:, 0]) / self.weight]
            iq["impact"].append([(lift - spec.min_liftoff) / 0.1])
        q_all = q_d
        for i in range(N):
            if np.isfinite(self.lo[i]):
                iq["joint_range"].append((q_all[:, i] - self.lo[i] - 0.01) / 0.1)
            if np.isfinite(self.hi[i]):
                iq["joint_range"].append((self.hi[i] - 0.01 - q_all[:, i]) / 0.1)
        for i, lim in enumerate(self.torque_limit):
            if np.isfinite(lim):
                for _, uk, _ in cases:
                    iq["torque_limit"] += [(0.99 * lim - uk[:, i]) / lim,
                                           (0.99 * lim + uk[:, i]) / lim]
        eqd = {k: np.concatenate([np.ravel(v) for v in vs]) for k, vs in eq.items() if vs}
        iqd = {k: np.concatenate([np.ravel(v) for v in vs]) for k, vs in iq.items() if vs}
        if spec.objective == "peak":
            iqd["_epigraph"] = np.concatenate([tpk - u.ravel() / self.u_scale,
                                               tpk + u.ravel() / self.u_scale])
        F1all = np.concatenate([c[0] for c in cases])
        ratio = np.where(F1all[:, 1] > 0,
                         np.abs(F1all[:, 0]) / np.maximum(F1all[:, 1], 1e-300), np.inf)
        info = dict(delta_zero_sq=d2, zeta_minus=zm, step_time=T, step_length=L,
                    speed=L / T if T > 0 else 0.0, mid_height=float(hgt[self.mid]),
                    min_height=float(iqd["scuffing"].min() * 0.01 - DIP),
                    min_vertical_force=float(F1all[:, 1].min()),
                    max_friction_ratio=float(ratio.max()),
                    impact_friction_ratio=float(abs(F2[0]) / F2[1]) if F2[1] > 0 else np.inf,
                    liftoff_velocity=float(min(c[2] for c in cases)), min_zeta=float(zeta.min()),
                    max_abs_torque=np.max([np.abs(c[1]).max(axis=0) for c in cases], axis=0))
        return Evaluation(True, J, scaled, eqd, iqd, info)

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
        spec, model = self.spec, self.model
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
        # orientation of kappa_1 and alpha for the regularity constraints
        x = self.pack(qm, X, np.zeros(model.n_thrusters), self.zeta_ref)
        g = self.gait(x)
        maps = gait_maps(model, g)
        a = lobatto(maps.alpha_i, maps.alpha_f, self.n_nodes)
        E = 1.0 / stance_terms(model, maps, a).AT
        self.sign_E = float(np.sign(np.mean(E))) or 1.0
        self.E_ref = max(abs(float(np.mean(E))), 1e-6)
        self.direction = float(np.sign(maps.alpha_f - maps.alpha_i)) or 1.0
        v = spec.speed or 0.5
        L = max(float(model.p_swing(qm)[0]), 0.05 * self.ell)
        alpha_dot = abs(maps.alpha_f - maps.alpha_i) * v / L
        zm = 0.5 * (self.E_ref * alpha_dot) ** 2
        x = self.pack(qm, X, np.zeros(model.n_thrusters), zm, 0.0)
        if spec.objective == "peak":  # epigraph variable just above the start's peak torque
            ev = self.evaluate(x)
            x[-1] = 1.05 * ev.objective / self.u_scale if ev.ok else 1.0
        return x

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
    c1 = 0.5 * (h[2:] - h[:-2])
    c2 = h[2:] - 2.0 * h[1:-1] + h[:-2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(c2 > 0, np.clip(-c1 / c2, -1.0, 1.0), -np.sign(c1))
    return h[1:-1] + c1 * t + 0.5 * c2 * t**2


# ------------------------------------------------------------------------------- solver
class _Cache:
    """Objective, constraints and a forward-difference Jacobian shared by every callback."""

    def __init__(self, prob: Problem):
        self.p = prob
        self.x = None
        self.ev: Evaluation | None = None
        self.jx = None
        self.jac = None

    def at(self, x) -> Evaluation:
        x = np.asarray(x, float)
        if self.x is None or not np.array_equal(x, self.x):
            self.x, self.ev = x.copy(), self.p.evaluate(x)
        return self.ev

    @staticmethod
    def flat(ev: Evaluation) -> tuple[float, np.ndarray, np.ndarray]:
        eq = np.concatenate(list(ev.eq.values())) if ev.eq else np.zeros(0)
        iq = np.concatenate(list(ev.ineq.values())) if ev.ineq else np.zeros(0)
        return ev.scaled, eq, iq

    def jacobian(self, x):
        x = np.asarray(x, float)
        if self.jx is not None and np.array_equal(x, self.jx):
            return self.jac
        f0, e0, i0 = self.flat(self.at(x))
        n = x.size
        gf, ge, gi = np.zeros(n), np.zeros((e0.size, n)), np.zeros((i0.size, n))
        for j in range(n):
            h = 1e-7 * max(1.0, abs(x[j]))
            xp = x.copy()
            xp[j] += h
            f1, e1, i1 = self.flat(self.p.evaluate(xp))
            gf[j], ge[:, j], gi[:, j] = (f1 - f0) / h, (e1 - e0) / h, (i1 - i0) / h
        self.jx, self.jac = x.copy(), (gf, ge, gi)
        return self.jac


@dataclass(frozen=True)
class StartResult:
    """One solver run: its start index, SciPy status, objective [SI], worst normalised
    violation, iterations, evaluations and wall time [s]."""

    index: int
    x: np.ndarray = field(repr=False)
    status: str
    objective: float
    max_violation: float
    iterations: int
    evaluations: int
    seconds: float


def _selection(blocks: dict[str, np.ndarray], slack: dict[str, int]) -> np.ndarray:
    """0/1 matrix adding family ``k``'s slack to each of its constraint rows."""
    n = sum(v.size for v in blocks.values())
    S = np.zeros((n, len(slack)))
    r = 0
    for k, v in blocks.items():
        if k in slack:
            S[r:r + v.size, slack[k]] = 1.0
        r += v.size
    return S


def solve_start(prob: Problem, x0: np.ndarray, index: int = 0) -> StartResult:
    """SLSQP from ``x0`` in elastic mode (``prob.start`` must have set up this start).

    One slack ``s_k >= 0`` per constraint family relaxes it (``g + s_k >= 0``,
    ``|h| <= s_k``) and costs ``ELASTIC s_k``: the linearised subproblems stay consistent from
    any start, the exact penalty drives the slacks to 0 when the family can be satisfied, and a
    slack left at the end measures that family's violation.
    """
    t0 = time.perf_counter()
    e0 = prob.evaluations
    ev0 = prob.evaluate(x0)
    if not ev0.ok:
        return StartResult(index, x0, "the start point cannot be evaluated", float("inf"),
                           float("inf"), 0, prob.evaluations - e0, time.perf_counter() - t0)
    prob.fix_shapes(ev0)
    cache = _Cache(prob)
    fams = [k for k in FAMILIES if k in ev0.eq or k in ev0.ineq]
    slack = {k: i for i, k in enumerate(fams)}
    Si, Se = _selection(ev0.ineq, slack), _selection(ev0.eq, slack)
    n = x0.size
    viol = ev0.violations()
    z0 = np.concatenate([x0, [viol[k] * 1.01 + 1e-9 for k in fams]])

    def fun(z):
        return cache.flat(cache.at(z[:n]))[0] + ELASTIC * z[n:].sum()

    def grad(z):
        return np.concatenate([cache.jacobian(z[:n])[0], np.full(len(fams), ELASTIC)])

    def cons(z):
        _, e, g = cache.flat(cache.at(z[:n]))
        sl = z[n:]
        return np.concatenate([g + Si @ sl, e + Se @ sl, Se @ sl - e])

    def cons_jac(z):
        _, je, jg = cache.jacobian(z[:n])
        return np.vstack([np.hstack([jg, Si]), np.hstack([je, Se]), np.hstack([-je, Se])])

    bounds = prob.bounds() + [(0.0, None)] * len(fams)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(fun, z0, jac=grad, method="SLSQP", bounds=bounds,
                       constraints=[{"type": "ineq", "fun": cons, "jac": cons_jac}],
                       options={"maxiter": prob.spec.max_iter, "ftol": 1e-10})
    x = res.x[:n]
    ev = prob.evaluate(x)
    return StartResult(index, x, str(res.message), ev.objective, ev.max_violation,
                       int(res.nit), prob.evaluations - e0, time.perf_counter() - t0)


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class DesignResult:
    """Outcome of :func:`design_gait` (SI units).

    feasible: the chosen gait passed the independent re-check (:func:`verify`); reason says
    why not otherwise, and ``blocking`` names the constraint family with the largest
    normalised violation at the best point. objective: value on the re-checked periodic orbit
    (``effort`` [N^2 m s] or ``peak`` [N m]). check: the re-check record (every margin).
    """

    feasible: bool
    reason: str
    blocking: str | None
    spec: DesignSpec
    gait: Gait
    thrust: tuple[float, ...]
    objective: float | None
    solver_objective: float
    violations: dict[str, float]
    check: dict
    starts: tuple[StartResult, ...]
    evaluations: int
    seconds: float
    c: tuple[float, ...]
    eps: float


def design_gait(model: CompiledModel, spec: DesignSpec,
                progress: Callable[[int, int, str], None] | None = None) -> DesignResult:
    """Design a gait for ``spec`` (module docstring): ``spec.starts`` seeded SLSQP runs, the
    best feasible one re-checked by :func:`verify`. ``progress(done, total, message)`` is
    called after every start. Deterministic for a given spec (seed included)."""
    t0 = time.perf_counter()
    prob = Problem(model, spec)
    rng = np.random.default_rng(spec.seed)
    runs: list[StartResult] = []
    for k in range(spec.starts):
        x0 = prob.start(None if k == 0 else rng)
        r = solve_start(prob, x0, k)
        runs.append(r)
        if progress is not None:
            ok = "feasible" if r.max_violation <= FEAS_TOL else f"violation {r.max_violation:.2g}"
            progress(k + 1, spec.starts, f"start {k}: objective {r.objective:.5g}, {ok}")
    order = sorted(runs, key=lambda r: (r.max_violation > FEAS_TOL, r.objective
                                        if r.max_violation <= FEAS_TOL else r.max_violation))
    chosen, check = None, None
    for r in order:
        if r.max_violation > FEAS_TOL:
            break
        g = prob.gait(r.x)
        F = prob.unpack(r.x)[2]
        chk = verify(model, g, spec, F, prob.eps)
        if chk["feasible"]:
            chosen, check = r, chk
            break
        if check is None:
            chosen, check = r, chk
    if chosen is None:
        chosen = order[0]
        check = verify(model, prob.gait(chosen.x), spec, prob.unpack(chosen.x)[2], prob.eps)
    ev = prob.evaluate(chosen.x)
    viol = ev.violations()
    feasible = bool(check["feasible"]) and chosen.max_violation <= FEAS_TOL
    blocking = None
    if not feasible:
        solver_bad = {k: v for k, v in viol.items() if v > FEAS_TOL}
        if solver_bad:
            blocking = max(solver_bad, key=solver_bad.get)
        else:
            blocking = check["failed"][0] if check["failed"] else "orbit"
        reason = (f"no feasible gait found in {spec.starts} start(s): blocked by {blocking} "
                  f"({describe(blocking, ev, prob)}; normalised violation "
                  f"{viol.get(blocking, 0.0):.3g} at the best point)")
        others = [k for k, v in sorted(viol.items(), key=lambda kv: -kv[1])
                  if v > FEAS_TOL and k != blocking]
        if others:
            reason += "; also violated: " + ", ".join(others)
        if check["failed"]:
            reason += "; re-check failed: " + ", ".join(check["failed"])
    else:
        reason = "feasible: every constraint re-checked on the periodic orbit"
    F = prob.unpack(chosen.x)[2]
    return DesignResult(feasible, reason, blocking, spec, prob.gait(chosen.x),
                        tuple(map(float, F)) if prob.m else (), check.get("objective"),
                        chosen.objective, viol, check, tuple(runs), prob.evaluations,
                        time.perf_counter() - t0, tuple(prob.c.tolist()), prob.eps)


def describe(family: str, ev: Evaluation, prob: Problem) -> str:
    """What family ``family`` asks for and what the point ``ev`` achieves (one phrase)."""
    s, i = prob.spec, ev.info
    if not ev.ok or not i:
        return "the point cannot be evaluated"
    mu = s.mu
    text = {
        "orbit": f"a periodic orbit with zeta > {s.min_zeta_ratio:g} zeta^- along the step: "
                 f"min zeta = {i['min_zeta']:.4g}, zeta^- = {i['zeta_minus']:.4g} kg^2 m^4/s^2",
        "stability": f"delta_zero^2 <= {s.max_delta_sq:g}: got {i['delta_zero_sq']:.4g}",
        "speed": f"speed {s.speed} m/s: reached {i['speed']:.4g} m/s",
        "step_length": f"step length {s.step_length} m: got {i['step_length']:.4g} m",
        "foot_placement": f"swing foot on the ground ahead of the stance foot at impact: "
                          f"step length {i['step_length']:.4g} m",
        "clearance": f"swing foot >= {s.clearance:g} m at mid-step: {i['mid_height']:.4g} m",
        "scuffing": f"swing foot above the ground over the step: lowest "
                    f"{i['min_height']:.4g} m",
        "vertical_force": f"F_1^v >= {prob.eps:.4g} N: min {i['min_vertical_force']:.4g} N",
        "friction": f"|F_1^h| <= mu F_1^v with mu = {mu:g}: max ratio "
                    f"{i['max_friction_ratio']:.4g}",
        "impact": f"impulse in the cone (mu = {mu:g}) and lift-off >= {s.min_liftoff:g} m/s: "
                  f"ratio {i['impact_friction_ratio']:.4g}, lift-off "
                  f"{i['liftoff_velocity']:.4g} m/s",
        "joint_range": "joint angles inside the robot file's ranges",
        "torque_limit": "joint torques inside the robot file's limits: max |u| = "
                        + ", ".join(f"{v:.4g}" for v in i["max_abs_torque"]) + " N m",
    }
    return text.get(family, family)


# -------------------------------------------------------------------- independent re-check
def orbit_cost(model: CompiledModel, zd, sched: Schedule, zeta_plus: float,
               thrust_weight: float = 0.0, nodes: int = 129) -> dict:
    """Objectives on the periodic orbit: ``effort = (1/L) int (|u|^2 + w_F |F_T|^2) dt``
    [N^2 m s] (torques ``u`` from the affine stance terms, SPEC 5, ``dt = dalpha/alpha'``,
    constant thrust ``F_T`` [N] weighted by ``w_F`` [m^2]) and ``peak = max |u_i|`` [N m], with
    the step time [s] of that quadrature."""
    a = lobatto(zd.alpha_i, zd.alpha_f, nodes)
    st = stance_terms(model, zd.maps, a)
    F = sched.force[0, 0, :]
    zeta = zeta_plus + zd.V_Z(a, sched)[0]
    u = np.einsum("gim,m->gi", st.U2, F) + st.U1 * zeta[:, None] + st.U0
    dT = 1.0 / (np.abs(st.AT) * np.sqrt(2.0 * np.maximum(zeta, 1e-300)))
    span = abs(zd.alpha_f - zd.alpha_i)
    L = float(model.p_swing(zd.maps.q_minus)[0])
    T = float(integrate(0.0, span, dT)[0])
    return {"effort": float(integrate(0.0, span, (u**2).sum(1) * dT)[0]) / L
            + thrust_weight * float(F @ F) * T / L,
            "peak": float(np.abs(u).max()), "step_time": T}


def verify(model: CompiledModel, gait: Gait, spec: DesignSpec, thrust: np.ndarray,
           eps: float) -> dict:
    """Re-check a gait with the adaptive zero dynamics, :func:`limit_cycles`,
    :func:`contact.evaluate` (polished extremes) and dense grids for the swing foot, joint
    ranges and torques. Returns every margin (SI units, >= 0 when satisfied), the orbit and
    ``failed`` (the families that fail)."""
    zd = zero_dynamics(model, gait)
    sched = Schedule.constant(zd, np.asarray(thrust, float)[None, :])
    lc = limit_cycles(zd, sched)[0]
    out: dict = {"orbit": {"exists": lc.exists, "stable": lc.stable, "reason": lc.reason,
                           "delta_zero_sq": zd.delta_zero_sq, "zeta_star": lc.zeta_star,
                           "zeta_plus": lc.zeta_plus, "sigma_minus": lc.sigma_minus,
                           "sigma_plus": lc.sigma_plus, "step_time": lc.step_time,
                           "step_length": lc.step_length, "speed": lc.speed,
                           "alpha_i": zd.alpha_i, "alpha_f": zd.alpha_f,
                           "min_abs_alpha_dot": lc.min_abs_alpha_dot,
                           "invariance_residual": {"position": zd.maps.position_residual,
                                                   "velocity": zd.maps.velocity_residual}}}
    failed = []
    m: dict = {"stability": spec.max_delta_sq - zd.delta_zero_sq}
    if not (lc.exists and lc.stable):
        out.update(feasible=False, failed=["orbit"], margins=m, objective=None)
        return out
    rep = evaluate(model, zd, sched, mu=spec.mu, eps=eps, profiles=False)
    case = rep.cases[0]
    imp = impact_data(model, zd)
    sw = swing_clearance(model, zd, points=2001)
    a_mid = zd.alpha_i + 0.5 * (zd.alpha_f - zd.alpha_i)
    h_mid = float(model.p_swing(zd.maps.q_Z(np.array(a_mid)))[1])
    grid = np.linspace(zd.alpha_i, zd.alpha_f, 2001)
    q = zd.maps.q_Z(grid)
    lo = np.array([c.range[0] for c in model.robot.coordinates])
    hi = np.array([c.range[1] for c in model.robot.coordinates])
    with np.errstate(invalid="ignore"):
        rng_m = np.minimum(q - lo, hi - q).min(axis=0)
    tl = np.array([c.torque_limit for c in model.robot.coordinates if c.actuated])
    cost = orbit_cost(model, zd, sched, lc.zeta_plus,
                      spec.thrust_weight if spec.thrust_design else 0.0)
    umax = np.array(case.max_abs_torque)
    zmin = float(lc.orbit["zeta"].min())
    m.update({
        "zeta_min_ratio": zmin / lc.zeta_star - spec.min_zeta_ratio,
        "speed_error": None if spec.speed is None else lc.speed - spec.speed,
        "step_length_error": (None if spec.step_length is None
                              else lc.step_length - spec.step_length),
        "clearance_mid_step": h_mid - spec.clearance,
        "min_swing_height": float(min(sw["deepest"], 0.0)) if sw["deepest"] < 0 else
        float(sw["min_height"]),
        "vertical_force": case.margins["vertical_force"],
        "friction": case.margins["friction"],
        "impact_friction": case.margins["impact_friction"],
        "impact_vertical_impulse": case.margins["impact_vertical_impulse"],
        "liftoff_velocity": case.margins["liftoff_velocity"] - spec.min_liftoff,
        "joint_range": {nm: (float(v) if np.isfinite(v) else None)
                        for nm, v in zip(model.robot.coordinate_names, rng_m)},
        "torque_limit": {c.name: (float(t - u) if np.isfinite(t) else None)
                         for c, t, u in zip([c for c in model.robot.coordinates if c.actuated],
                                            tl, umax)},
    })
    if m["stability"] < 0:
        failed.append("stability")
    if m["zeta_min_ratio"] < -1e-3:
        failed.append("orbit")
    if spec.speed is not None and abs(m["speed_error"]) > 1e-3 * spec.speed:
        failed.append("speed")
    if spec.step_length is not None and abs(m["step_length_error"]) > 1e-4:
        failed.append("step_length")
    if abs(float(model.p_swing(zd.maps.q_minus)[1])) > 1e-9 or lc.step_length <= 0:
        failed.append("foot_placement")
    if m["clearance_mid_step"] < -HEIGHT_TOL:
        failed.append("clearance")
    if sw["deepest"] < -HEIGHT_TOL:
        failed.append("scuffing")
    if m["vertical_force"] < 0:
        failed.append("vertical_force")
    if m["friction"] is None or m["friction"] < 0:
        failed.append("friction")
    if not imp.admissible(spec.mu) or m["liftoff_velocity"] < -1e-6:
        failed.append("impact")
    if spec.thrust_range is not None:
        rr = _range_check(model, zd, spec, thrust, eps)
        m["thrust_range"] = rr
        failed += [f for f in rr["failed"] if f not in failed]
        umax = np.maximum(umax, rr["max_abs_torque"])
    if np.any(rng_m[np.isfinite(rng_m)] < -RANGE_TOL):
        failed.append("joint_range")
    if np.any(umax > tl * (1 + 1e-9)):
        failed.append("torque_limit")
    out.update(feasible=not failed, failed=failed, margins=m,
               objective=cost[spec.objective], cost=cost,
               contact={"feasible": case.feasible, "reason": case.reason,
                        "min_vertical_force": case.min_vertical_force,
                        "max_friction_ratio": case.max_friction_ratio,
                        "impact_friction_ratio": case.impact_friction_ratio,
                        "liftoff_velocity": case.liftoff_velocity,
                        "max_abs_torque": case.max_abs_torque},
               swing={"mid_step_height": h_mid, "min_height_window": sw["min_height"],
                      "max_height": sw["max_height"], "deepest": sw["deepest"]})
    return out


def _range_check(model: CompiledModel, zd, spec: DesignSpec, thrust: np.ndarray, eps: float,
                 samples: int = 5) -> dict:
    """Contact feasibility (:func:`contact.evaluate`) on the orbit of ``samples`` constant
    thrusts spanning ``spec.thrust_range`` [N] (ends included): worst margins over them."""
    name, lo, hi = spec.thrust_range
    j = model.robot.thruster_names.index(name)
    F = np.tile(np.asarray(thrust, float), (samples, 1))
    F[:, j] = np.linspace(lo, hi, samples)
    cases = evaluate(model, zd, Schedule.constant(zd, F), mu=spec.mu, eps=eps,
                     profiles=False).cases
    failed = []
    if not all(c.cycle.exists for c in cases):
        failed.append("orbit")
        return {"thrusts": F[:, j].tolist(), "failed": failed,
                "max_abs_torque": np.zeros(model.n - 1),
                "reasons": [c.reason for c in cases if not c.feasible]}
    vert = min(c.margins["vertical_force"] for c in cases)
    fr = [c.margins["friction"] for c in cases]
    lift = min(c.margins["liftoff_velocity"] for c in cases) - spec.min_liftoff
    if vert < 0:
        failed.append("vertical_force")
    if any(f is None or f < 0 for f in fr):
        failed.append("friction")
    if lift < -1e-6:
        failed.append("impact")
    return {"thrusts": F[:, j].tolist(), "failed": failed, "vertical_force": vert,
            "friction": None if any(f is None for f in fr) else min(fr),
            "liftoff_velocity": lift,
            "speed": [c.cycle.speed for c in cases],
            "max_abs_torque": np.max([c.max_abs_torque for c in cases], axis=0),
            "reasons": [c.reason for c in cases if not c.feasible]}


def check_gait(model: CompiledModel, gait: Gait, spec: DesignSpec) -> dict:
    """:func:`verify` for an existing gait (its own constant thrust, if any)."""
    prob_eps = (0.1 * model.robot.total_mass * model.robot.gravity
                if spec.min_vertical_force is None else spec.min_vertical_force)
    F = np.zeros(model.n_thrusters)
    if gait.thrust is not None and gait.thrust.mode == "force":
        for nm, vals in gait.thrust.values:
            F[model.robot.thruster_names.index(nm)] = vals[0]
    return verify(model, gait, spec, F, prob_eps)


# ------------------------------------------------------------------------------ records
def report_record(res: DesignResult) -> dict:
    """JSON body of ``NAME.report.json`` (provenance is added by the command)."""
    s = res.spec
    r = res.check
    return {
        "feasible": res.feasible, "reason": res.reason, "blocking_constraint": res.blocking,
        "objective": {"name": s.objective, "value": res.objective,
                      "solver_value": res.solver_objective,
                      "unit": "N^2 m s" if s.objective == "effort" else "N m",
                      "definition": ("(1/L) int_0^T |u|^2 dt over one step of the periodic "
                                     "orbit" + (" + thrust_weight |F|^2 T / L"
                                                if s.thrust_design else "")
                                     if s.objective == "effort" else "max_i,alpha |u_i|")},
        "spec": {"speed": s.speed, "step_length": s.step_length, "mu": s.mu,
                 "order": s.order, "clearance": s.clearance, "max_delta_sq": s.max_delta_sq,
                 "min_vertical_force": res.eps, "min_liftoff_velocity": s.min_liftoff,
                 "min_zeta_ratio": s.min_zeta_ratio, "objective": s.objective,
                 "thrust_design": s.thrust_design, "thrust_weight": s.thrust_weight,
                 "thrust_range": None if s.thrust_range is None else
                 {"thruster": s.thrust_range[0], "low": s.thrust_range[1],
                  "high": s.thrust_range[2]},
                 "starts": s.starts, "seed": s.seed, "max_iter": s.max_iter,
                 "nodes": s.nodes},
        "units": {"speed": "m/s", "step_length": "m", "clearance": "m", "force": "N",
                  "torque": "N m", "zeta": "kg^2 m^4/s^2", "sigma": "kg m^2/s",
                  "angle": "rad", "time": "s", "thrust": "N",
                  "margins": "SI units of each quantity; >= 0 when satisfied"},
        "thrust": list(res.thrust),
        "fixed_point": r.get("orbit"),
        "margins": r.get("margins"),
        "failed_checks": r.get("failed"),
        "cost": r.get("cost"),
        "contact": r.get("contact"),
        "swing_foot": r.get("swing"),
        "solver_violations": res.violations,
        "alpha_c": list(res.c),
        "coefficients": [list(row) for row in res.gait.A],
        "starts": [{"index": t.index, "status": t.status, "objective": _num(t.objective),
                    "max_violation": _num(t.max_violation), "iterations": t.iterations,
                    "evaluations": t.evaluations, "seconds": t.seconds} for t in res.starts],
        "evaluations": res.evaluations, "seconds": res.seconds,
    }


def _num(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def gait_yaml(res: DesignResult, model: CompiledModel, robot_ref: str,
              header: list[str]) -> str:
    """The gait as YAML (``invariance: auto``, columns 0 and 1 written as ``~``), loadable by
    :func:`robot_io.load_gait_for`; ``header`` lines become ``#`` comments."""
    g, r = res.gait, model.robot
    names = r.coordinate_names
    act = [c.name for c in r.coordinates if c.actuated]
    o = res.check.get("orbit", {})
    c_map = ", ".join(f"{nm}: {_f(v)}" for nm, v in zip(names, g.c) if v != 0.0)
    desc = (f"order-{g.order} Bezier gait designed by thrustwalk design-gait "
            f"({res.spec.objective} objective)")
    if o.get("speed") is not None:
        desc += f", {o['speed']:.3f} m/s, step {o['step_length']:.3f} m"
    lines = [f"# {h}" for h in header]
    lines += [f"name: {g.name}", f"description: {desc}", f"robot: {robot_ref}",
              "parameters:",
              f"  af: {_f(g.alpha_f)}   # [rad] alpha_f = c q^-, the value of alpha at impact",
              "alpha:", f"  c: {{{c_map}}}   # alpha = c q [rad]", "  final: af",
              "bezier:", "  invariance: auto",
              "  coefficients:   # [rad]; column k at s = k/M, s = 0 after impact, "
              "s = 1 before impact"]
    for nm, row in zip(act, g.A):
        lines.append(f"    {nm}: [~, ~, " + ", ".join(_f(v) for v in row[2:]) + "]")
    lines += ["controller:", f"  kp: {_f(g.kp)}   # [1/s^2]", f"  kd: {_f(g.kd)}   # [1/s]",
              f"mu: {_f(res.spec.mu)}"]
    if res.thrust:
        vals = ", ".join(f"{nm}: [{_f(v)}]" for nm, v in zip(r.thruster_names, res.thrust))
        lines += ["thrust:   # designed constant thrust [N]", "  mode: force",
                  "  knots: [0, 1]", "  fractions: true", f"  values: {{{vals}}}"]
    return "\n".join(lines) + "\n"


def yaml_header(res: DesignResult, provenance: dict, report_name: str) -> list[str]:
    """Comment lines recording how the gait was made (command, date, objective, margins)."""
    s, chk = res.spec, res.check
    o, m = chk.get("orbit", {}), chk.get("margins", {})
    con, sw = chk.get("contact", {}), chk.get("swing", {})
    obj_unit = "N^2 m s" if s.objective == "effort" else "N m"
    rng = {k: v for k, v in (m.get("joint_range") or {}).items() if v is not None}
    out = [
        f"Gait designed by thrustwalk design-gait (thrustwalk {provenance.get('version')}), "
        f"{provenance.get('created_utc')}.",
        f"command: {provenance.get('command')}",
        f"Objective ({s.objective}): "
        + ("(1/L) int_0^T |u|^2 dt" if s.objective == "effort" else "max |u_i|")
        + f" = {res.objective:.6g} {obj_unit} on the periodic orbit; peak torque "
        f"{chk['cost']['peak']:.4g} N m.",
        f"Variables: pre-impact posture q^-, Bezier columns 2..{s.order - 1} (order "
        f"{s.order}; invariance: auto), zeta^-" + (", constant thrust" if s.thrust_design
                                                   else "") + f"; SLSQP, {s.starts} start(s), "
        f"seed {s.seed}.",
        f"Orbit: stable, delta_zero^2 = {o['delta_zero_sq']:.4f} (<= {s.max_delta_sq:g}), "
        f"{o['speed']:.4f} m/s, step {o['step_length']:.4f} m, step time "
        f"{o['step_time']:.4f} s, zeta* = {o['zeta_star']:.6g} kg^2 m^4/s^2.",
        f"Swing foot: {sw['mid_step_height'] * 100:.2f} cm at mid-step (>= "
        f"{s.clearance * 100:g} cm), >= {sw['min_height_window'] * 1000:.2f} mm for s in "
        f"[0.05, 0.95], >= 0 over the step.",
        f"Stance: F_v >= {con['min_vertical_force']:.4g} N (>= {res.eps:.4g} N), |F_h|/F_v <= "
        f"{con['max_friction_ratio']:.3f} (mu = {s.mu:g}). Impact: |F_h|/F_v = "
        f"{con['impact_friction_ratio']:.3f}, trailing foot lifts off at "
        f"{con['liftoff_velocity']:.3f} m/s.",
    ]
    tr = m.get("thrust_range")
    if s.thrust_range is not None and tr:
        out.append(f"Also feasible on the orbit of every constant {s.thrust_range[0]} thrust in "
                   f"[{s.thrust_range[1]:g}, {s.thrust_range[2]:g}] N: F_v margin >= "
                   f"{tr['vertical_force']:.4g} N, friction margin >= {tr['friction']:.3f}.")
    if rng:
        out.append("Joint-range margins [rad]: "
                   + ", ".join(f"{k} {v:.3f}" for k, v in rng.items()) + ".")
    out.append(f"Every margin and the fixed point: {report_name}. Re-check: thrustwalk "
               "limit-cycle / feasibility with this file.")
    return out


def reload_check(model: CompiledModel, path, res: DesignResult) -> dict:
    """Load a written gait file back (:func:`robot_io.load_gait_for`) and compare its fixed
    point with the design's: returns ``{zeta_star, reference, relative_error, alpha_f_error}``."""
    from .robot_io import load_gait_for

    _, g = load_gait_for(None, str(path))
    zd = zero_dynamics(model, g)
    F = np.zeros(model.n_thrusters)
    if g.thrust is not None:
        for nm, vals in g.thrust.values:
            F[model.robot.thruster_names.index(nm)] = vals[0]
    lc = limit_cycles(zd, Schedule.constant(zd, F[None, :]))[0]
    ref = res.check["orbit"]["zeta_star"]
    got = lc.zeta_star if lc.exists else None
    err = abs(got - ref) / abs(ref) if got is not None else float("inf")
    return {"zeta_star": got, "reference": ref, "relative_error": err,
            "coefficients_error": float(np.abs(np.array(g.A) - np.array(res.gait.A)).max())}


def _f(v: float) -> str:
    v = float(v)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def with_name(res: DesignResult, name: str) -> DesignResult:
    """The same result with the gait renamed."""
    return replace(res, gait=replace(res.gait, name=name))
