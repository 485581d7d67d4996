"""The reduced cascade of SPEC 3: zero dynamics plus thruster states, integrated in time.

On Z, with sigma_N the angular momentum about the stance foot [kg m^2/s]:

    alpha'   = kappa_1(alpha) sigma_N
    sigma_N' = kappa_2(alpha) + beta(alpha) F_T (+ T, generalised thrust [N m], SPEC 4)
    z'       = thruster dynamics (:mod:`thrustwalk_cli.thrust.dynamics`, :class:`ThrustModel`)

A step ends when alpha reaches alpha_f; the impact resets ``sigma_N^+ = delta_zero sigma_N^-``
and ``alpha^+ = alpha_i``; thruster states are continuous (SPEC 3). This is the fast preview
of a full-order scenario and the reference it is compared with. kappa_1, kappa_2 and beta are
evaluated directly from the model at every alpha.

When no time history is asked for (the cascade beside a full-order run, the per-step
prediction of dynamic thrust) the steps are not integrated in time: for thrust without a
state of its own (ideal thrusters under a constant command, a piecewise schedule in alpha)
they are the closed form of SPEC 3-4 (:func:`closed_form_steps`: ``zeta`` along a step is
``zeta_start + V_Z(alpha) - V_Z(alpha_start)``, the impact maps ``zeta^-`` to ``delta_zero^2
zeta^-``, the step time is the quadrature ``int dalpha / (kappa_1 sigma_N)``); for thrusters
with linear dynamics (first-, second-order) a spectral solution in alpha with the thrust's
closed-form response in time (:func:`spectral_steps`). Both agree with the time integration
at rtol 1e-12 to about 1e-11 (the integration at its default 1e-9 is the less accurate one).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from operator import mul

import numpy as np
from scipy.integrate import solve_ivp

from ..hzd.quadrature import ChebSeries, integrate, lobatto
from ..hzd.zero_dynamics import MAX_NODES, ZeroDynamics
from ..thrust.schedule import Schedule
from .closed_loop import ScalarGait, ThrustModel, alpha_pieces


class ReducedModel:
    """The zero-dynamics terms of one gait (SPEC 3) evaluated directly at one alpha:

        kappa_1 = 1 / (e_N^T D(q_Z) Phi),  kappa_2 = -dV/dq_N (q_Z),  beta = b_N(q_Z)

    from the model's scalar functions (no interpolation; a few microseconds per call).
    """

    def __init__(self, zd: ZeroDynamics):
        self.zd = zd
        self.model = zd.model
        self.N = zd.model.n
        self.m = zd.model.n_thrusters
        self.gait_s = ScalarGait(zd.maps)

    def terms(self, alpha: float) -> list[float]:
        """``[kappa_1, kappa_2, beta_1..beta_m]`` at one alpha [1/(kg m^2), N m, m]."""
        N, m, mod = self.N, self.m, self.model
        q, phi = self.gait_s.zero_dynamics_state(alpha)
        D = mod.D_s(q)
        k1 = 1.0 / sum(map(mul, D[(N - 1) * N:], phi))
        out = [k1, -mod.G_s(q)[N - 1]]
        if m:
            out += mod.B_F_s(q)[(N - 1) * m:]
        return out


@dataclass(frozen=True)
class ReducedStep:
    """One step of the cascade (SI): sigma [kg m^2/s], zeta = sigma^2/2, times [s]."""

    step: int
    t_start: float
    t_impact: float
    step_time: float
    sigma_start: float
    zeta_start: float
    sigma_minus: float
    zeta_minus: float
    sigma_plus: float
    zeta_plus: float
    thrust_at_impact: tuple[float, ...]


@dataclass(frozen=True)
class ReducedResult:
    """A run of the reduced cascade; ``success``/``failure``/``reason`` as for the full order
    (failures: ``fall`` when alpha reverses, ``no-impact``, ``integrator``)."""

    success: bool
    reason: str
    failure: str
    steps: tuple[ReducedStep, ...]
    trajectory: dict[str, np.ndarray] = field(repr=False)
    nfev: int = 0
    wall_time: float = 0.0


class _Cascade:
    def __init__(self, rm: ReducedModel, thrust: ThrustModel):
        self.rm, self.thrust = rm, thrust
        self.breaks, self.forces, self.gens = alpha_pieces(rm.zd, thrust)
        self.nfev = 0
        self.m = rm.m

    def force(self, z, seg: int) -> list[float]:
        return self.forces[seg] if self.thrust.piecewise else self.thrust.force(z)

    def rhs(self, t: float, w: np.ndarray, seg: int) -> list[float]:
        self.nfev += 1
        wl = w.tolist()
        k = self.rm.terms(wl[0])
        F = self.force(wl[2:], seg)
        ds = k[1] + sum(b * f for b, f in zip(k[2:], F)) + self.gens[seg]
        return [k[0] * wl[1], ds] + self.thrust.derivatives(wl[2:])


def simulate_reduced(zd: ZeroDynamics, thrust: ThrustModel, steps: int, alpha0: float,
                     sigma0: float, z0: list[float], *, rtol: float = 1e-9, atol: float = 1e-9,
                     method: str = "DOP853", samples_per_step: int = 80,
                     max_step_time: float = 10.0,
                     progress: Callable[[int], None] | None = None,
                     model: ReducedModel | None = None,
                     trajectory: bool = True) -> ReducedResult:
    """Integrate the cascade for ``steps`` steps from ``(alpha0, sigma0, z0)`` (SPEC 3).

    Never raises on a physical failure: alpha reversing (the walker cannot pass the
    potential-energy barrier) or no impact within ``max_step_time`` [s] end the run with a
    reason. ``max_step_time`` applies per step.

    ``trajectory=False``: no time history is wanted (the result's ``trajectory`` is empty,
    ``nfev`` 0); then thrust without states of its own takes the closed form
    (:func:`closed_form_steps`) and thrusters with linear dynamics the spectral solution in
    alpha (:func:`spectral_steps`), both falling back to the time integration for any run
    they do not cover (a fall or close to one, no impact in time, a start off the step);
    that integration keeps no dense output (the same steps and events: SciPy locates events
    on its step interpolants either way)."""
    t_wall = time.perf_counter()
    if not trajectory:
        steps_cf = (closed_form_steps(zd, thrust, steps, alpha0, sigma0,
                                      max_step_time=max_step_time)
                    if not thrust.time_dependent else
                    spectral_steps(zd, thrust, steps, alpha0, sigma0, z0,
                                   max_step_time=max_step_time))
        if steps_cf is not None:
            if progress is not None:
                for _ in steps_cf:
                    progress(1)
            return ReducedResult(True, f"completed {len(steps_cf)} steps", "",
                                 tuple(steps_cf), {}, 0, time.perf_counter() - t_wall)
    rm = model or ReducedModel(zd)
    cas = _Cascade(rm, thrust)
    d = zd.direction
    span = zd.maps.span
    a_f = zd.alpha_f
    w = np.array([alpha0, sigma0] + list(z0), float)
    t = 0.0
    out: list[ReducedStep] = []
    traj: dict[str, list] = {}
    failure, reason = "", ""

    def ev_impact(t, w, seg):
        return d * (w[0] - a_f)

    def ev_reverse(t, w, seg):
        return d * rm.terms(float(w[0]))[0] * w[1]

    ev_impact.terminal, ev_impact.direction = True, 1
    ev_reverse.terminal, ev_reverse.direction = True, -1
    for k in range(1, steps + 1):
        t0, w0 = t, w.copy()
        seg = int(np.searchsorted(cas.breaks, (w[0] - zd.alpha_i) / span, side="right"))
        pieces = []
        while True:
            events = [ev_impact, ev_reverse]
            if seg < len(cas.breaks):
                a_next = zd.alpha_i + cas.breaks[seg] * span

                def ev_break(t, w, seg, a_next=a_next):
                    return d * (w[0] - a_next)

                ev_break.terminal, ev_break.direction = True, 1
                events.append(ev_break)
            sol = solve_ivp(cas.rhs, (t, t0 + max_step_time), w, method=method, rtol=rtol,
                            atol=atol, events=events, dense_output=trajectory, args=(seg,))
            if sol.status == -1:
                failure, reason = "integrator", f"step {k}: integrator {method} failed: " \
                                                f"{sol.message}"
                break
            pieces.append((t, float(sol.t[-1]), seg, sol.sol))
            t, w = float(sol.t[-1]), sol.y[:, -1].copy()
            if sol.status == 0:
                failure, reason = "no-impact", f"step {k}: no impact within " \
                                               f"{max_step_time:.4g} s"
                break
            if len(sol.t_events[1]):
                failure, reason = "fall", (f"step {k}: alpha reverses (alpha' = 0) at "
                                           f"alpha = {w[0]:.6g} rad, t = {t:.6g} s: the walker "
                                           "cannot pass the potential-energy barrier")
                break
            if len(sol.t_events[0]):
                break
            seg += 1
        if trajectory:
            _sample(traj, pieces, k, cas, samples_per_step)
        if failure:
            break
        s_minus = float(w[1])
        F = tuple(float(v) for v in cas.force(w[2:].tolist(), seg))
        w[0] = zd.alpha_i
        w[1] = zd.delta_zero * s_minus
        out.append(ReducedStep(k, t0, t, t - t0, float(w0[1]), 0.5 * float(w0[1]) ** 2,
                               s_minus, 0.5 * s_minus**2, float(w[1]), 0.5 * float(w[1]) ** 2,
                               F))
        if progress is not None:
            progress(1)
    ok = not failure
    return ReducedResult(ok, reason if failure else f"completed {len(out)} steps", failure,
                         tuple(out), {key: np.concatenate(v) for key, v in traj.items()},
                         cas.nfev, time.perf_counter() - t_wall)


STEP_TIME_RTOL = 1e-13  # relative error estimate the closed-form step time is integrated to
ZETA_MARGIN = 1e-3  # closed form only where zeta stays above this fraction of its largest value


def closed_form_steps(zd: ZeroDynamics, thrust: ThrustModel, steps: int, alpha0: float,
                      sigma0: float, *, max_step_time: float = 10.0
                      ) -> list[ReducedStep] | None:
    """The cascade's steps for thrust without states (ideal or piecewise in alpha) in closed
    form (SPEC 3, 4), or None where it does not apply (then integrate).

    Along a step started at ``(alpha_s, sigma_s)``, ``zeta(alpha) = sigma_s^2/2 + V_Z(alpha) -
    V_Z(alpha_s)`` [kg^2 m^4/s^2] (``V_Z`` the spectral integral of ``(kappa_2 + beta F_T +
    T) / kappa_1`` of :class:`ZeroDynamics`); ``zeta^- = zeta(alpha_f)``, ``sigma^- = sgn
    sqrt(2 zeta^-)``, ``sigma^+ = delta_zero sigma^-`` (the impact, SPEC 3) and the next step
    starts at ``alpha_i``. The step time ``T = int dalpha / (kappa_1 sigma_N)`` [s] is
    Clenshaw-Curtis quadrature per knot interval, ``kappa_1`` evaluated directly from the
    model at the nodes, the nodes doubled until the nested estimate is below
    ``STEP_TIME_RTOL`` relative; all steps that start at ``alpha_i`` share one vectorised
    quadrature.

    None (not a failure: the integration decides) when ``alpha0`` is outside the step
    ``[alpha_i, alpha_f)`` (to rounding: before alpha_i ``V_Z`` holds no thrust, the
    integration the first segment's), ``sigma0`` does not move alpha forward, ``zeta`` comes within
    ``ZETA_MARGIN`` of 0 on a quadrature node (a fall, or too close to one for the quadrature),
    the quadrature does not converge, or a step takes longer than ``max_step_time`` [s].
    """
    if thrust.time_dependent or steps < 1:
        return None
    d = zd.direction
    a_i, a_f = zd.alpha_i, zd.alpha_f
    sgn = zd.sigma_sign
    if not (d * (alpha0 - a_i) >= -1e-12 * abs(a_f - a_i) and d * (a_f - alpha0) > 0.0) \
            or not sgn * sigma0 > 0:
        return None
    if thrust.piecewise:
        sched = thrust.schedule
        force_f = tuple(float(v) for v in alpha_pieces(zd, thrust)[1][-1])
    else:
        sched = Schedule.constant(zd, np.asarray(thrust.target, float)[None, :])
        force_f = tuple(float(v) for v in thrust.force([]))
    kn = np.asarray(sched.knots, float)
    if sched.size != 1 or kn[0] != a_i or kn[-1] != a_f:
        return None

    def V(alpha: np.ndarray) -> np.ndarray:
        return zd.V_Z(np.asarray(alpha, float), sched)[0]

    V_s, V_f = (float(v) for v in V(np.array([alpha0, a_f])))
    # the recurrence of SPEC 3: zeta_start -> zeta^- -> zeta^+ (sigma keeps its sign)
    d0 = zd.delta_zero
    sig_start = [float(sigma0)]
    zeta_minus = []
    for k in range(steps):
        z_m = 0.5 * sig_start[k] ** 2 + V_f - (V_s if k == 0 else 0.0)
        if not z_m > 0:
            return None
        zeta_minus.append(z_m)
        sig_start.append(d0 * sgn * np.sqrt(2.0 * z_m))
    # zeta(alpha) = c + V_Z(alpha), c per step
    c = np.array([0.5 * s**2 for s in sig_start[:steps]])
    c[0] -= V_s
    T = np.empty(steps)
    first = 0 if alpha0 == a_i else 1
    if first:
        t1 = _step_times(zd, sched, alpha0, c[:1], sgn)
        if t1 is None:
            return None
        T[0] = t1[0]
    if first < steps:
        tr = _step_times(zd, sched, a_i, c[first:], sgn)
        if tr is None:
            return None
        T[first:] = tr
    if not np.all(T <= max_step_time):
        return None
    out, t = [], 0.0
    for k in range(steps):
        s0, z_m = sig_start[k], zeta_minus[k]
        s_m = sgn * float(np.sqrt(2.0 * z_m))
        s_p = d0 * s_m
        t1 = t + float(T[k])
        out.append(ReducedStep(k + 1, t, t1, t1 - t, s0, 0.5 * s0 * s0, s_m, 0.5 * s_m**2,
                               s_p, 0.5 * s_p**2, force_f))
        t = t1
    return out


def _step_times(zd: ZeroDynamics, sched: Schedule, a_start: float, c: np.ndarray,
                sgn: float) -> np.ndarray | None:
    """``int_{a_start}^{alpha_f} dalpha / (kappa_1 sgn sqrt(2 (c + V_Z(alpha))))`` [s] for each
    ``c`` (k,), per knot interval of ``sched`` (from ``a_start``), Lobatto nodes doubled until
    the nested estimate is below ``STEP_TIME_RTOL`` relative (SPEC 3); None when zeta comes
    within ``ZETA_MARGIN`` of 0 on a node or the quadrature does not converge."""
    d = zd.direction
    kn = np.asarray(sched.knots, float)
    skey = tuple(np.asarray(x, float).tobytes() for x in (kn, sched.force, sched.generalized))
    edges = [a_start] + [float(x) for x in kn[1:] if d * (x - a_start) > 0]
    cache = zd.__dict__.setdefault("_reduced_nodes", {})
    total = np.zeros(c.size)
    for a, b in zip(edges[:-1], edges[1:]):
        n = 33
        while True:
            key = (a, b, n)
            hit = cache.get(key)
            if hit is None:
                if len(cache) > 256:
                    cache.clear()
                p = lobatto(a, b, n)
                hit = cache[key] = (p, zd.terms(p)["kappa1"])
            p, k1p = hit
            vkey = (a, b, n, skey)
            vz = cache.get(vkey)
            if vz is None:
                if len(cache) > 256:
                    cache.clear()
                    cache[key] = hit
                vz = cache[vkey] = zd.V_Z(p, sched)[0]
            zeta = c[:, None] + vz[None, :]  # (k, n)
            zmax = np.max(zeta, axis=1)
            if np.any(np.min(zeta, axis=1) <= ZETA_MARGIN * zmax):
                return None
            f = 1.0 / (k1p * sgn * np.sqrt(2.0 * zeta))
            val, err = integrate(a, b, f)
            if np.all(err <= STEP_TIME_RTOL * np.abs(val)):
                break
            if n >= MAX_NODES:
                return None
            n = 2 * n - 1
        total += val
    return total


SPECTRAL_TOL = 1e-13  # relative change at which the spectral steps stop refining
SPECTRAL_ITER = 60
START_MARGIN = 0.1  # a step may start this fraction of the step before alpha_i (an impact
#                     away from alpha_f leaves the next step a little off alpha_i)


def spectral_steps(zd: ZeroDynamics, thrust: ThrustModel, steps: int, alpha0: float,
                   sigma0: float, z0: list[float], *, max_step_time: float = 10.0
                   ) -> list[ReducedStep] | None:
    """The cascade's steps for thrusters with linear dynamics under a constant command
    (first-, second-order, SPEC 3, 7), in alpha instead of time; None where it does not
    apply (then integrate in time).

    The thrusters do not feel the walker: from the state ``z_0`` at the start of a step the
    thrust is ``F(tau) = Phi(tau) z_0 + Psi(tau) u`` [N]
    (:meth:`thrust.dynamics.Servo.response`, closed form), ``tau`` [s] the time since the start
    of the step. With alpha as the variable,

        zeta(alpha) = zeta_s + int_{alpha_s}^{alpha} (kappa_2 + beta F(tau)) / kappa_1
        tau(alpha)  = int_{alpha_s}^{alpha} 1 / (kappa_1 sigma_N),  sigma_N = sgn sqrt(2 zeta)

    solved by Picard iteration on Chebyshev-Lobatto nodes (cumulative integrals of the
    interpolating series; ``kappa_1, kappa_2, beta`` evaluated directly from the model at the
    nodes) until the change is below ``SPECTRAL_TOL`` relative, the nodes doubled until two
    node counts agree to ``SPECTRAL_TOL`` (zeta^- and the step time). The state at impact is
    ``z = e^{A tau_f} z_0 + int_0^tau_f e^{A s} ds B u`` (matrix exponential), ``sigma^+ =
    delta_zero sigma^-``; the next step starts at ``alpha_i`` from there.

    None when a thruster has no closed-form response, the start is beyond alpha_f or more
    than ``START_MARGIN`` of the step before alpha_i, sigma moves alpha backward, zeta comes
    within ``ZETA_MARGIN`` of 0 on a node (a fall, or close), the iteration or the node
    refinement does not settle, or a step takes longer than ``max_step_time`` [s].
    """
    dyn = thrust.dynamics
    if not thrust.time_dependent or thrust.piecewise or steps < 1:
        return None
    if any(sv.n and sv.closed_form is None for sv in dyn.servos):
        return None
    d = zd.direction
    a_i, a_f = zd.alpha_i, zd.alpha_f
    sgn = zd.sigma_sign
    span = abs(a_f - a_i)
    if not (d * (alpha0 - a_i) >= -START_MARGIN * span and d * (a_f - alpha0) > 0.0) \
            or not sgn * sigma0 > 0:
        return None
    u = np.asarray(thrust._target, float)
    A, B, _, _ = dyn.matrices()
    nz = dyn.n_states
    M = np.zeros((nz + 1, nz + 1))
    M[:nz, :nz], M[:nz, nz] = A, B @ u
    out, t, sig, z = [], 0.0, float(sigma0), np.asarray(z0, float)
    for k in range(steps):
        a_s = alpha0 if k == 0 else a_i
        prev = None
        n = 33
        while True:
            res = _spectral_step(zd, dyn, u, a_s, sig, z, sgn, n)
            if res is None:
                return None
            if prev is not None and (
                    abs(res[0] - prev[0]) <= SPECTRAL_TOL * abs(res[0])
                    and abs(res[1] - prev[1]) <= SPECTRAL_TOL * abs(res[1])):
                break
            if n >= 513:
                return None
            prev, n = res, 2 * n - 1
        zeta_m, tau_f = res
        if not tau_f <= max_step_time:
            return None
        z_imp = (_expm(M * tau_f) @ np.r_[z, 1.0])[:nz]
        F = tuple(float(v) for v in dyn.thrust(z_imp.tolist(), thrust._target))
        s_m = sgn * float(np.sqrt(2.0 * zeta_m))
        s_p = zd.delta_zero * s_m
        out.append(ReducedStep(k + 1, t, t + tau_f, tau_f, sig, 0.5 * sig * sig, s_m,
                               0.5 * s_m**2, s_p, 0.5 * s_p**2, F))
        t, sig, z = t + tau_f, s_p, z_imp
    return out


@lru_cache(maxsize=16)
def _cumulative_matrix(n: int) -> np.ndarray:
    """``Q`` (n, n) on [-1, 1]: ``(Q f)_i = int_{-1}^{x_i} p_f``, ``p_f`` the polynomial
    interpolating values ``f`` at the ``n`` Lobatto nodes ``x`` (ascending); on ``[a, b]``
    multiply by ``(b - a)/2``."""
    x = lobatto(-1.0, 1.0, n)
    return ChebSeries.from_values(-1.0, 1.0, np.eye(n)).cumulative()(x)


def _expm(M: np.ndarray) -> np.ndarray:
    """``e^M`` of a small matrix: Taylor series of ``M / 2^s`` (inf-norm <= 1/4, terms until
    they fall below 1e-17 relative) squared ``s`` times; rounding-level accurate for the
    thrusters' few states. (Not ``scipy.linalg.expm``: with multi-threaded BLAS it costs
    milliseconds per call on these tiny matrices.)"""
    norm = float(np.abs(M).sum(axis=1).max()) if M.size else 0.0
    sq = max(0, int(np.ceil(np.log2(norm / 0.25)))) if norm > 0.25 else 0
    X = M / 2.0**sq
    E = np.eye(M.shape[0])
    term = E
    for k in range(1, 30):
        term = term @ X / k
        E = E + term
        if np.abs(term).max() <= 1e-17 * np.abs(E).max():
            break
    for _ in range(sq):
        E = E @ E
    return E


def _spectral_step(zd: ZeroDynamics, dyn, u: np.ndarray, a_s: float, sigma_s: float,
                   z_s: np.ndarray, sgn: float, n: int) -> tuple[float, float] | None:
    """One step of :func:`spectral_steps` on ``n`` nodes: ``(zeta^-, tau_f)`` or None."""
    a_f = zd.alpha_f
    cache = zd.__dict__.setdefault("_reduced_spectral", {})
    key = (a_s, n)
    hit = cache.get(key)
    if hit is None:
        if len(cache) > 64:
            cache.clear()
        p = lobatto(a_s, a_f, n)
        tm = zd.terms(p)
        Q = _cumulative_matrix(n) * (0.5 * (a_f - a_s))
        hit = cache[key] = (1.0 / tm["kappa1"], tm["kappa2"] / tm["kappa1"],
                            np.asarray(tm["beta"]).reshape(n, -1) / tm["kappa1"][:, None], Q)
    g, v0, vb, Q = hit
    zeta_s = 0.5 * sigma_s * sigma_s

    def thrust_at(tau: np.ndarray) -> np.ndarray:
        F = np.zeros((tau.size, len(dyn.servos)))
        for j, (sv, pos) in enumerate(zip(dyn.servos, dyn.layout)):
            Phi, Psi = sv.response(tau)
            F[:, j] = Phi @ z_s[list(pos)] + Psi * u[j] if sv.n else sv.d * u[j]
        return F

    tau = np.zeros(n)
    zeta = None
    for _ in range(SPECTRAL_ITER):
        F = thrust_at(tau)
        zeta_new = zeta_s + Q @ (v0 + np.einsum("km,km->k", vb, F))
        if not np.min(zeta_new) > ZETA_MARGIN * np.max(zeta_new):
            return None
        tau_new = Q @ (g / (sgn * np.sqrt(2.0 * zeta_new)))
        done = zeta is not None and (
            np.max(np.abs(zeta_new - zeta)) <= SPECTRAL_TOL * np.max(np.abs(zeta_new))
            and np.max(np.abs(tau_new - tau)) <= SPECTRAL_TOL * abs(tau_new[-1]))
        zeta, tau = zeta_new, tau_new
        if done:
            return float(zeta[-1]), float(tau[-1])
    return None


def _sample(traj: dict, pieces: list, k: int, cas: _Cascade, n: int) -> None:
    """Uniform time samples of one step: t, step, alpha, alpha_dot, sigma, zeta, F [N],
    T (generalised force [N m])."""
    if not pieces:
        return
    times = np.linspace(pieces[0][0], pieces[-1][1], n)
    for j, (a, b, seg, sol) in enumerate(pieces):
        last = j == len(pieces) - 1
        sel = (times >= a) & ((times <= b) if last else (times < b))
        W = sol(times[sel]).T
        k1 = np.array([cas.rm.terms(float(al))[0] for al in W[:, 0]])
        F = np.array([cas.force(row[2:].tolist(), seg) for row in W], float)
        T = np.full(W.shape[0], cas.gens[seg])
        for key, v in (("t", times[sel]), ("step", np.full(W.shape[0], k)),
                       ("alpha", W[:, 0]), ("alpha_dot", k1 * W[:, 1]), ("sigma", W[:, 1]),
                       ("zeta", 0.5 * W[:, 1] ** 2), ("F", F.reshape(W.shape[0], -1)),
                       ("T", T)):
            traj.setdefault(key, []).append(v)


def predict_step(zd: ZeroDynamics, thrust: ThrustModel, alpha: float, sigma: float,
                 z: list[float], *, rtol: float = 1e-10, atol: float = 1e-10,
                 model: ReducedModel | None = None) -> float | None:
    """``zeta^-`` that the cascade predicts for one step started at ``(alpha, sigma, z)``
    (SPEC 3), or None if the cascade does not reach alpha_f."""
    r = simulate_reduced(zd, thrust, 1, alpha, sigma, z, rtol=rtol, atol=atol,
                         samples_per_step=2, model=model, trajectory=False)
    return r.steps[0].zeta_minus if r.success else None
