"""The reduced cascade of SPEC 3: zero dynamics plus thruster states, integrated in time.

On Z, with sigma_N the angular momentum about the stance foot [kg m^2/s]:

    alpha'   = kappa_1(alpha) sigma_N
    sigma_N' = kappa_2(alpha) + beta(alpha) F_T (+ T, generalised thrust [N m], SPEC 4)
    z'       = thruster dynamics (:mod:`thrustwalk_cli.thrust.dynamics`, :class:`ThrustModel`)

A step ends when alpha reaches alpha_f; the impact resets ``sigma_N^+ = delta_zero sigma_N^-``
and ``alpha^+ = alpha_i``; thruster states are continuous (SPEC 3). This is the fast preview
of a full-order scenario and the reference it is compared with. kappa_1, kappa_2 and beta are
evaluated directly from the model at every alpha.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from operator import mul

import numpy as np
from scipy.integrate import solve_ivp

from ..hzd.zero_dynamics import ZeroDynamics
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
                     model: ReducedModel | None = None) -> ReducedResult:
    """Integrate the cascade for ``steps`` steps from ``(alpha0, sigma0, z0)`` (SPEC 3).

    Never raises on a physical failure: alpha reversing (the walker cannot pass the
    potential-energy barrier) or no impact within ``max_step_time`` [s] end the run with a
    reason. ``max_step_time`` applies per step.
    """
    t_wall = time.perf_counter()
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
                            atol=atol, events=events, dense_output=True, args=(seg,))
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
                         samples_per_step=2, model=model)
    return r.steps[0].zeta_minus if r.success else None
