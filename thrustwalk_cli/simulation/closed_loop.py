"""The closed loop of SPEC 7: thrust models, controller, events, dynamics details.

Stance phase, pinned model (SPEC 1), state ``x = [q; q'; z]`` (``z`` the thruster states):

    D(q) q'' + h(q, q') = B_tau u + B_F(q) F_T (+ e_N T for generalised thrust, SPEC 4)

Controller: input-output linearisation of ``y = H_0 q - h_d(alpha)``, ``alpha = c q``, so that
``y'' = -K_p y - K_d y'`` exactly. With ``J_y = H_0 - h_d'(alpha) c``,
``y' = J_y q'`` and ``y'' = J_y q'' - h_d''(alpha) (c q')^2``. Since ``B_tau = [I; 0]``,
``q''`` solves the N x N system

    [ J_y       ] q'' = [ -K_p y - K_d y' + h_d'' (c q')^2 ]
    [ e_N^T D   ]       [ e_N^T (-h + B_F F_T + e_N T)     ]

and ``u = rows 1..N-1 of (D q'' + h - B_F F_T)``: the thrust term ``b_b F_T`` is cancelled.
Optional torque limits clip ``u`` (then ``q'' = D^-1 (-h + B_tau u + B_F F_T)``). Ground
reaction on the stance foot (SPEC 5): ``F_1 = rows N+1..N+2 of
(D_u [q''; 0] + h_u(q, [q'; 0]) - B_Fu F_T)`` [N].

Thrust models (:class:`ThrustModel`): a command, constant ``F_ss`` or piecewise constant in
alpha (a :class:`~thrustwalk_cli.thrust.schedule.Schedule`, force [N] or generalised [N m]
mode), through the thrusters' linear dynamics (:mod:`thrustwalk_cli.thrust.dynamics`: ideal,
first-order lag ``tau F' = F_ss - F``, second-order ``F'' + 2 xi w F' + w^2 F = w^2 F_ss``,
the paper's slow thruster, or any model of that family). SI units.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from math import comb
from operator import mul

import numpy as np

from ..errors import InputError, param_problem
from ..hzd.constraints import bezier_derivatives
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics, limit_cycles
from ..thrust.command import MAX_THRUSTER_RATE as MAX_THRUSTER_RATE
from ..thrust.command import PIECEWISE as PIECEWISE
from ..thrust.command import THRUST_MODELS as THRUST_MODELS
from ..thrust.command import ThrustModel as ThrustModel
from ..thrust.command import check_thruster_rate as check_thruster_rate
from ..thrust.command import thrust_model_names as thrust_model_names
from ..thrust.command import thruster_rate as thruster_rate
from ..thrust.schedule import Schedule

SIMULATORS = ("compiled", "scipy")  # the compiled kernel (default) or solve_ivp (reference)
METHODS = ("DOP853", "RK45", "Radau", "LSODA", "BDF")  # solve_ivp integrators
MAX_STEPS = 10_000  # steps per run
MAX_SAMPLES = 10_000  # output samples per step
MAX_TOTAL_STEPS = 20_000  # runs x steps in one call (about 70 ms per step with SciPy)


def alpha_pieces(zd: ZeroDynamics, thrust: ThrustModel, extra: tuple[float, ...] = ()
                 ) -> tuple[list[float], list[list[float]], list[float]]:
    """Split the step at the schedule knots strictly inside (0, 1) and at ``extra`` (values of
    s). Returns the breakpoints (ascending s) and, per segment (one more than breakpoints), the
    thrust [N] and generalised force [N m] of a piecewise schedule (zero outside its knots;
    all zero for the other models). The first and last segments extend beyond the step."""
    m = zd.model.n_thrusters
    bps = set(extra)
    knots_s: list[float] = []
    if thrust.piecewise:
        knots_s = list((np.asarray(thrust.schedule.knots) - zd.alpha_i) / zd.maps.span)
        bps |= {k for k in knots_s if 1e-12 < k < 1 - 1e-12}
    breaks = sorted(bps)
    edges = [-np.inf] + breaks + [np.inf]
    forces, gens = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        mid = 0.5 * (max(lo, 0.0) + min(hi, 1.0))
        F, T = [0.0] * m, 0.0
        if thrust.piecewise:
            j = int(np.searchsorted(knots_s, mid, side="right")) - 1
            if 0 <= j < len(knots_s) - 1:
                F = thrust.schedule.force[0, j].tolist()
                T = float(thrust.schedule.generalized[0, j])
        forces.append(F)
        gens.append(T)
    return breaks, forces, gens


def predicted_cycle(zd: ZeroDynamics, thrust: ThrustModel) -> LimitCycle:
    """Zero-dynamics limit cycle the run should converge to (SPEC 3, 4): the schedule for
    piecewise thrust, else constant ``F_ss`` (the dynamic models settle at ``F_ss``)."""
    sched = thrust.schedule if thrust.piecewise else Schedule.constant(
        zd, np.asarray(thrust.target, float)[None, :])
    # kept on the zero dynamics per schedule (a simulation asks for it several times per run)
    key = tuple(np.asarray(a, float).tobytes() for a in (sched.knots, sched.force,
                                                          sched.generalized))
    cache = zd.__dict__.setdefault("_predicted_cycles", {})
    lc = cache.get(key)
    if lc is None:
        if len(cache) > 256:
            cache.clear()
        lc = cache[key] = limit_cycles(zd, sched)[0]
    return lc


def zeta_star_at(zd: ZeroDynamics, F: np.ndarray) -> float:
    """Fixed point for constant thrust ``F``: ``zeta* = V_Z(alpha_f; F) / (1 - delta_zero^2)``
    [kg^2 m^4/s^2] (SPEC 4; may be <= 0 when no orbit exists)."""
    return float(zd.fixed_point(Schedule.constant(zd, np.asarray(F, float)[None, :]))[0])


# ----------------------------------------------------------------------------- config
@dataclass(frozen=True)
class SimConfig:
    """Numerical and physical settings of a full-order run.

    steps: number of steps. rtol/atol: integrator tolerances (``atol`` on rad and rad/s).
    method: ``compiled`` (the numba kernel: DOP853 with solve_ivp's step-size control and
    event location, compiled once per machine) or ``scipy`` (``solve_ivp``, the reference).
    integrator: the ``solve_ivp`` method (``scipy`` only; the compiled kernel is DOP853).
    samples_per_step: stored trajectory samples per step.
    torque_limit: |u| bound [N m] (None: unlimited). scuff_tol: how far below the ground the
    swing foot may dip below the ground before the guard is armed [m]. min_impact_s: the
    early-strike threshold: the guard (swing foot crossing the ground downward) is armed for
    s > min_impact_s; before it a dip deeper than scuff_tol is a scuff (an early strike), a
    shallower touch is tolerated (a straight-leg foot passing the stance foot at mid-step).
    guard_s: the earliest s at which the guard may be armed (min_impact_s in [guard_s, 1)).
    max_s: no strike by this s fails the run. ground_tol: depth below which a dip of the
    swing foot between two integrator steps counts as a missed strike [m].
    max_step_time: a step longer than this fails [s] (None: 10 x the predicted step time,
    or 10 s without a prediction).
    cone_mu [1], cone_eps [N]: the contact cone (SPEC 5) whose first exit within a step its
    record times (``StepRecord.low_force_at``: the first ``F_1^v <= cone_eps``;
    ``cone_exit_at``: the first ``|F_1^h| > cone_mu F_1^v``, None: not timed). They time,
    never stop, a run.
    """

    steps: int = 30
    rtol: float = 1e-9
    atol: float = 1e-9
    method: str = "compiled"
    integrator: str = "DOP853"
    samples_per_step: int = 80
    torque_limit: float | None = None
    scuff_tol: float = 1e-4
    min_impact_s: float = 0.75
    guard_s: float = 0.5
    max_s: float = 1.5
    ground_tol: float = 1e-10
    max_step_time: float | None = None
    cone_mu: float | None = None
    cone_eps: float = 0.0

    def validate(self) -> None:
        """Raise :class:`InputError` naming every setting out of range (steps, tolerances,
        method, integrator, samples, torque limit, guard, cone); return None when all are valid."""
        problems = []
        if not 1 <= self.steps <= MAX_STEPS:
            problems.append(param_problem("steps", f"must be 1..{MAX_STEPS} (got {self.steps})"))
        if not (0 < self.rtol < 0.1) or not (0 < self.atol < 0.1):
            problems.append(param_problem(("rtol", "atol"), "tolerances must lie in (0, 0.1)"))
        if self.method not in SIMULATORS:
            problems.append(param_problem("method", f"unknown method {self.method!r} "
                                                    f"(choose from {', '.join(SIMULATORS)})"))
        if self.integrator not in METHODS:
            problems.append(param_problem("integrator", f"unknown integrator "
                                          f"{self.integrator!r} (choose from "
                                          f"{', '.join(METHODS)})"))
        elif self.method == "compiled" and self.integrator != "DOP853":
            problems.append(param_problem("integrator", f"the compiled method integrates with "
                                          f"DOP853 only; {self.integrator} needs method "
                                          f"`scipy`"))
        if not 2 <= self.samples_per_step <= MAX_SAMPLES:
            problems.append(param_problem("samples", f"must be 2..{MAX_SAMPLES} samples per "
                                                     f"step (got {self.samples_per_step})"))
        if self.torque_limit is not None and not self.torque_limit > 0:
            problems.append(param_problem("torque_limit", "must be > 0 N m"))
        if not self.guard_s <= self.min_impact_s < 1.0:
            problems.append(param_problem("min_impact_s", f"must lie in [{self.guard_s:g}, 1), "
                                                          "the guard is armed from s = "
                                                          f"{self.guard_s:g} (got "
                                                          f"{self.min_impact_s:g})"))
        if self.cone_mu is not None and not self.cone_mu > 0:
            problems.append(param_problem("mu", f"must be > 0 (got {self.cone_mu:g})"))
        if not self.cone_eps >= 0:
            problems.append(param_problem("min_vertical_force", f"must be >= 0 N (got "
                                                                f"{self.cone_eps:g})"))
        if problems:
            raise InputError(problems)


# ----------------------------------------------------------------------------- simulator
class ScalarGait:
    """Fast scalar evaluation of the virtual constraints (SPEC 2) from power-basis rows.

    ``H(s)`` returns ``[h_d; dh_d/dalpha; d^2h_d/dalpha^2]`` (3 (N-1) values) [rad, 1, 1/rad];
    ``zero_dynamics_state(alpha)`` returns ``q_Z(alpha)`` [rad] and ``Phi(alpha)`` [1].
    """

    def __init__(self, maps):
        A = np.asarray(maps.A, float)
        M = A.shape[1] - 1
        T = np.zeros((M + 1, M + 1))  # Bernstein -> power basis in s
        for k in range(M + 1):
            for j in range(k, M + 1):
                T[k, j] = comb(M, k) * comb(M - k, j - k) * (-1) ** (j - k)
        P = A @ T
        span = maps.span
        P1 = np.zeros_like(P)
        P1[:, :M] = P[:, 1:] * np.arange(1, M + 1) / span
        P2 = np.zeros_like(P)
        P2[:, :M] = P1[:, 1:] * np.arange(1, M + 1) / span
        self.rows = np.vstack([P, P1, P2]).tolist()
        self.order = M
        self.nb = A.shape[0]
        self.ai, self.span = maps.alpha_i, span
        self.Hinv = np.asarray(maps.Hinv, float).tolist()

    def H(self, s: float) -> list[float]:
        pw = [1.0]
        for _ in range(self.order):
            pw.append(pw[-1] * s)
        return [sum(map(mul, row, pw)) for row in self.rows]

    def zero_dynamics_state(self, alpha: float) -> tuple[list[float], list[float]]:
        nb = self.nb
        H = self.H((alpha - self.ai) / self.span)
        v = H[:nb] + [alpha]
        w = H[nb:2 * nb] + [1.0]
        return ([sum(map(mul, r, v)) for r in self.Hinv],
                [sum(map(mul, r, w)) for r in self.Hinv])


class ClosedLoop:
    """Right-hand side, events and batch details of the closed loop for one thrust model.

    The scalar path (:meth:`rhs`) uses the model's list-in/list-out functions (PERF_NOTES);
    :meth:`details` is the vectorised path used for sampling and statistics.
    """

    def __init__(self, zd: ZeroDynamics, thrust: ThrustModel, config: SimConfig):
        model = zd.model
        self.zd, self.model, self.thrust, self.config = zd, model, thrust, config
        self.N = N = model.n
        self.nb = N - 1
        self.m = model.n_thrusters
        mp = zd.maps
        self.c = mp.c.copy()
        self.ai, self.span = mp.alpha_i, mp.span
        self.direction = zd.direction
        self.kp, self.kd = float(zd.gait.kp), float(zd.gait.kd)
        self.gait_s = ScalarGait(mp)
        self._cl = self.c.tolist()
        self._Jy0 = np.hstack([np.eye(self.nb), np.zeros((self.nb, 1))])
        self.root_end = 4 * model.robot.link_index(model.robot.root.name) + 3
        self.nfev = 0
        #: the height [m] above the stance foot (normal to the slope) of the ground where the
        #: current step's swing foot lands: the guard (SPEC 14; 0: level ground)
        self.ground = 0.0
        #: the ground [m] the scuff checks measure from before the guard is armed: the lower
        #: of the stance level and the level the swing foot left (SPEC 14; 0: level ground)
        self.behind = 0.0
        self._segments_setup()

    # -- segments in alpha: guard arming and schedule knots --------------------------------
    def _segments_setup(self) -> None:
        """Breakpoints (in s, ascending) where the right-hand side or the events change."""
        self.breaks, self._piece_force, self._piece_T = alpha_pieces(
            self.zd, self.thrust, (self.arm_s,))

    def force(self, z, seg: int) -> list[float]:
        """Thrust per thruster [N] in segment ``seg`` with thruster states ``z``."""
        if self.thrust.piecewise:
            return self._piece_force[seg]
        return self.thrust.force(z)

    def generalized(self, seg: int) -> float:
        """Generalised force on q_N [N m] (piecewise generalised mode, SPEC 4), else 0."""
        return self._piece_T[seg] if self.thrust.piecewise else 0.0

    def segment_of(self, s: float) -> int:
        return int(np.searchsorted(self.breaks, s, side="right"))

    def guard_armed(self, seg: int) -> bool:
        return seg > self.breaks.index(self.arm_s)

    @property
    def arm_s(self) -> float:
        """s from which the guard is armed: ``min_impact_s`` (never before ``guard_s``)."""
        return max(self.config.guard_s, self.config.min_impact_s)

    # -- scalar right-hand side ------------------------------------------------------------
    def _accel(self, x: list, seg: int, want_u: bool = False):
        """q'', u (None unless ``want_u`` or torque limits), F, T at one state ``x`` (a list).

        Pure Python: for these small systems NumPy's per-call overhead dominates (PERF_NOTES).
        The N x N system of the module docstring reduces to 2 x 2 in ``(alpha'', q_N'')``:
        ``q_b'' = b_y + g alpha''`` with ``g = dh_d/dalpha``, ``b_y = -K_p y - K_d y' +
        h_d'' alpha'^2``, then ``c q'' = alpha''`` and ``e_N^T D q'' = rhs_N``.
        """
        N, nb, m = self.N, self.nb, self.m
        q, dq = x[:N], x[N:2 * N]
        F = self.force(x[2 * N:], seg)
        mod = self.model
        D = mod.D_s(q)
        rhs = [-v for v in mod.h_s(q, dq)]
        if m:
            BF = mod.B_F_s(q)
            for i in range(N):
                rhs[i] += sum(map(mul, BF[i * m:(i + 1) * m], F))
        T = self.generalized(seg)
        rhs[N - 1] += T
        c = self._cl
        alpha = sum(map(mul, c, q))
        adot = sum(map(mul, c, dq))
        s = (alpha - self.ai) / self.span
        H = self.gait_s.H(s)
        # J_y q'' = qb'' - g (c q'') with g = dh_d/dalpha: qb'' = b_y + g a, a = c q'' = alpha'';
        # with the last row e_N^T D q'' = rhs_N this leaves a 2 x 2 system in (a, qN'')
        kp, kd, ad2 = self.kp, self.kd, adot * adot
        g = H[nb:2 * nb]
        cdq = adot
        by = [-kp * (q[i] - H[i]) - kd * (dq[i] - g[i] * cdq) + H[2 * nb + i] * ad2
              for i in range(nb)]
        cb, cN = c[:nb], c[nb]
        DN = D[(N - 1) * N:]
        DNb, DNN = DN[:nb], DN[nb]
        a11 = 1.0 - sum(map(mul, cb, g))
        a21 = sum(map(mul, DNb, g))
        r1 = sum(map(mul, cb, by))
        r2 = rhs[N - 1] - sum(map(mul, DNb, by))
        det = a11 * DNN + cN * a21
        if det == 0.0:
            raise np.linalg.LinAlgError("singular decoupling matrix")
        a = (r1 * DNN + cN * r2) / det
        ddq = [by[i] + g[i] * a for i in range(nb)] + [(a11 * r2 - a21 * r1) / det]
        lim = self.config.torque_limit
        u = None
        if want_u or lim is not None:
            u = [sum(map(mul, D[i * N:(i + 1) * N], ddq)) - rhs[i] for i in range(nb)]
            if lim is not None and max(map(abs, u)) > lim:
                u = [min(max(v, -lim), lim) for v in u]
                r2 = [rhs[i] + (u[i] if i < nb else 0.0) for i in range(N)]
                ddq = _solve([D[i * N:(i + 1) * N] for i in range(N)], r2)
        return ddq, u, F, T

    def rhs(self, t: float, x: np.ndarray, seg: int) -> list:
        """``x' = [q'; q''; z']`` (SPEC 7)."""
        self.nfev += 1
        xl = x.tolist()
        ddq = self._accel(xl, seg)[0]
        N = self.N
        if self.thrust.n_states:
            return xl[N:2 * N] + ddq + self.thrust.derivatives(xl[2 * N:])
        return xl[N:2 * N] + ddq

    def vertical_force(self, x: np.ndarray, seg: int) -> float:
        """``F_1^v`` [N] at one state: row N+2 of ``D_u [q''; 0] + h_u - B_Fu F_T`` (SPEC 5)."""
        N, m = self.N, self.m
        xl = x.tolist()
        ddq, _, F, _ = self._accel(xl, seg)
        q = xl[:N]
        mod = self.model
        Du = mod.D_u_s(q)
        r = (N + 1) * (N + 2)
        f = sum(map(mul, Du[r:r + N], ddq)) + mod.h_u_s(q, xl[N:2 * N] + [0.0, 0.0])[N + 1]
        if m:
            f -= sum(map(mul, mod.B_Fu_s(q)[(N + 1) * m:], F))
        return f

    def foot_velocity(self, x: np.ndarray) -> float:
        """Vertical swing-foot velocity ``E_2,y q'`` [m/s]."""
        N = self.N
        E = self.model.E_swing_s(x[:N].tolist())
        return sum(map(mul, E[N:], x[N:2 * N].tolist()))

    # -- events --------------------------------------------------------------------------
    def events(self, seg: int, rising: bool = True) -> list[tuple[str, Callable]]:
        """Event functions ``f(t, x, seg)`` of one segment, as (name, f).

        ``break``: alpha reaches the next breakpoint; ``guard`` (armed segments, s >
        ``min_impact_s``): swing-foot height crosses :attr:`ground` (0 on level ground)
        downward; ``scuff`` (before arming):
        height crosses ``-scuff_tol`` (above :attr:`behind`);
        ``overshoot``: s reaches ``max_s``; ``foot_min``/``foot_max``: the swing foot's vertical
        velocity crosses 0 upward/downward, so that a dip below the ground between two
        integrator steps is never missed (armed: terminal, alternating with ``rising``;
        before: ``foot_min`` only, recorded, not terminal); ``reverse``: alpha' = 0;
        ``horizontal``: the stance link's far end reaches the ground; ``force``: F_1^v = 0.
        """
        N, mod, c, d = self.N, self.model, self.c, self.direction
        out: list[tuple[str, Callable, int]] = []
        if seg < len(self.breaks):
            a_next = self.ai + self.breaks[seg] * self.span
            out.append(("break", lambda t, x, j: d * (float(c @ x[:N]) - a_next), 1))
        if self.guard_armed(seg):
            out.append(("guard", lambda t, x, j: mod.p_swing_s(x[:N].tolist())[1] - self.ground,
                        -1))
            a_max = self.ai + self.config.max_s * self.span
            out.append(("overshoot", lambda t, x, j: d * (float(c @ x[:N]) - a_max), 1))
        else:
            tol = self.config.scuff_tol
            out.append(("scuff", lambda t, x, j: mod.p_swing_s(x[:N].tolist())[1] - self.behind
                        + tol, -1))
        if self.guard_armed(seg) and rising:
            out.append(("foot_max", lambda t, x, j: self.foot_velocity(x), -1))
        else:
            out.append(("foot_min", lambda t, x, j: self.foot_velocity(x), 1))
        out.append(("reverse", lambda t, x, j: d * float(c @ x[N:2 * N]), -1))
        re = self.root_end
        out.append(("horizontal", lambda t, x, j: mod.link_points_s(x[:N].tolist())[re], -1))
        out.append(("force", lambda t, x, j: self.vertical_force(x, j), -1))
        fns = []
        for name, f, direction in out:
            f.terminal = name != "foot_min" or self.guard_armed(seg)
            f.direction = direction
            fns.append((name, f))
        return fns

    def swing_height(self, x: np.ndarray) -> float:
        """Swing-foot height [m] at one state."""
        return self.model.p_swing_s(np.asarray(x)[: self.N].tolist())[1]

    # -- batch evaluation ----------------------------------------------------------------
    def law(self, X: np.ndarray, seg: np.ndarray, force: np.ndarray | None = None
            ) -> dict[str, np.ndarray]:
        """The closed loop's law at states ``X`` (K, dim) in segments ``seg`` (K,), vectorised
        (SPEC 7): q, dq, z, the thrust F [N] and T [N m], D, the right-hand side ``-h + B_F F``
        (with T on q_N), B_F [m] (None without thrusters), the outputs y, dy, alpha, its rate,
        s, and ddq, u [N m] with the torque limit applied (``saturated`` rows solved again
        with the clipped torques). What :meth:`details` and the energies of a run read.
        ``force``: the thrust per row (K, m) [N] instead of the thrust model's, T = 0 (a step
        walked with thrust set as data, e.g. a controller's per-step piecewise thrust)."""
        X = np.atleast_2d(np.asarray(X, float))
        seg = np.broadcast_to(np.asarray(seg, int), X.shape[:1])
        N, nb, m, mod = self.N, self.nb, self.m, self.model
        q, dq, z = X[:, :N], X[:, N:2 * N], X[:, 2 * N:]
        if force is not None:
            F = np.asarray(force, float).reshape(len(X), m)
            T = np.zeros(len(X))
        elif self.thrust.piecewise:  # per segment, as :meth:`force` and :meth:`generalized`
            F = np.asarray(self._piece_force, float).reshape(len(self._piece_force), m)[seg]
            T = np.asarray(self._piece_T, float)[seg]
        else:
            F = self.thrust.dynamics.thrust_rows(z, self.thrust._target)
            T = np.zeros(len(X))
        D = mod.D(q)
        rhs = -mod.h(q, dq)
        BF = mod.B_F(q) if m else None
        if m:
            rhs += np.einsum("kij,kj->ki", BF, F)
        rhs[:, N - 1] += T
        alpha, adot = q @ self.c, dq @ self.c
        s = (alpha - self.ai) / self.span
        A = self.zd.maps.A
        hd, hd1, hd2 = bezier_derivatives(A, s)  # bit for bit bezier(A, s, 0, 1, 2)
        hd1 = hd1 / self.span
        hd2 = hd2 / self.span**2
        Jy = self._Jy0[None] - hd1[:, :, None] * self.c[None, None, :]
        y = q[:, :nb] - hd
        dy = np.einsum("kij,kj->ki", Jy, dq)
        Mx = np.concatenate([Jy, D[:, N - 1:N, :]], axis=1)
        b = np.concatenate([-self.kp * y - self.kd * dy + hd2 * adot[:, None] ** 2,
                            rhs[:, N - 1:N]], axis=1)
        ddq = np.linalg.solve(Mx, b[..., None])[..., 0]
        u = (np.einsum("kij,kj->ki", D, ddq) - rhs)[:, :nb]
        sat = np.zeros(len(X), bool)
        lim = self.config.torque_limit
        if lim is not None:
            sat = np.abs(u).max(axis=1) > lim
            if sat.any():
                u[sat] = np.clip(u[sat], -lim, lim)
                r2 = rhs[sat].copy()
                r2[:, :nb] += u[sat]
                ddq[sat] = np.linalg.solve(D[sat], r2[..., None])[..., 0]
        return {"q": q, "dq": dq, "z": z, "F": F, "T": T, "D": D, "rhs": rhs, "B_F": BF,
                "y": y, "dy": dy, "alpha": alpha, "alpha_dot": adot, "s": s, "ddq": ddq,
                "u": u, "saturated": sat}

    # -- batch details -------------------------------------------------------------------
    def details(self, X: np.ndarray, seg: np.ndarray) -> dict[str, np.ndarray]:
        """Vectorised evaluation at states ``X`` (K, dim) in segments ``seg`` (K,): q, dq,
        ddq, u, y, dy, alpha, alpha_dot, sigma, F, T, F1, swing height, energy [SI]
        (:meth:`law`, then the ground force and the energy)."""
        w = self.law(X, seg)
        N, m, mod = self.N, self.m, self.model
        q, dq, ddq, F, D = w["q"], w["dq"], w["ddq"], w["F"], w["D"]
        dqu = np.concatenate([dq, np.zeros((len(q), 2))], axis=1)
        ddqu = np.concatenate([ddq, np.zeros((len(q), 2))], axis=1)
        gen = np.einsum("kij,kj->ki", mod.D_u(q), ddqu) + mod.h_u(q, dqu)
        if m:
            gen -= np.einsum("kij,kj->ki", mod.B_Fu(q), F)
        F1 = gen[:, N:N + 2]
        sigma = np.einsum("kj,kj->k", D[:, N - 1, :], dq)
        return {"q": q, "dq": dq, "ddq": ddq, "u": w["u"], "saturated": w["saturated"],
                "y": w["y"], "dy": w["dy"], "alpha": w["alpha"], "alpha_dot": w["alpha_dot"],
                "s": w["s"], "sigma": sigma, "F": F, "T": w["T"], "F1": F1,
                "swing_height": mod.p_swing(q)[:, 1], "energy": mod.energy(q, dq, D),
                "z": w["z"]}


def _solve(rows: list[list[float]], b: list[float]) -> list[float]:
    """Gaussian elimination with partial pivoting for a small dense system (pure Python, no
    per-call NumPy overhead); used for ``D q'' = rhs`` when torques saturate."""
    n = len(b)
    A = [list(r) + [bi] for r, bi in zip(rows, b)]
    for k in range(n):
        p, big = k, abs(A[k][k])
        for i in range(k + 1, n):
            if abs(A[i][k]) > big:
                p, big = i, abs(A[i][k])
        if big == 0.0:
            raise np.linalg.LinAlgError("singular matrix")
        if p != k:
            A[k], A[p] = A[p], A[k]
        piv = A[k]
        pk = piv[k]
        for i in range(k + 1, n):
            Ai = A[i]
            f = Ai[k] / pk
            if f:
                for j in range(k + 1, n + 1):
                    Ai[j] -= f * piv[j]
    x = [0.0] * n
    for i in range(n - 1, -1, -1):
        Ai = A[i]
        x[i] = (Ai[n] - sum(map(mul, Ai[i + 1:n], x[i + 1:]))) / Ai[i]
    return x


