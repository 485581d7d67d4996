"""The Jacobian of the Poincare map by the variational equations along the orbit, with the
saltation matrices at the guard and at the thrust knots (SPEC 13).

Along the stance phase ``x' = f(x)`` (the closed loop of SPEC 7, right-hand side evaluated by
the compiled kernel as :class:`~thrustwalk_cli.simulation.closed_loop.ClosedLoop` evaluates it
in NumPy, :func:`rhs`), the state-transition matrix obeys
``Phi' = f_x(x(t)) Phi``, ``Phi(0) = I``, integrated together with the orbit from
``x^+ = Delta(x*)`` to the guard. The Jacobian of the Poincare map on the pre-impact surface is

    DP = (I - f(x^-) g_x / (g_x f(x^-))) Phi_T DDelta(x*)

the bracket being the time-to-guard correction at the event (``dT/dx = -g_x Phi_T / (g_x
f)``). Equivalently, the monodromy matrix based just after impact, ``M = Xi Phi_T`` with the
saltation matrix ``Xi = DDelta + (f(x^+) - DDelta f(x^-)) g_x / (g_x f(x^-))``, has the
trivial multiplier 1 (eigenvector ``f(x^+)``) and the ``n - 1`` multipliers of ``DP`` restricted
to the guard; its deviation from 1 is reported as a check of the integration. (SPEC 13 writes
the saltation with ``g_x`` acting on the input only; on the guard's tangent space the
input-side term vanishes, and what remains is the output-side projection above, which the
finite-difference Jacobian confirms.) Where a piecewise thrust jumps at a knot ``alpha = a_j``
the flow's Jacobian is multiplied by ``I + (f_+ - f_-) g_x / (g_x f_-)``, ``g = alpha - a_j``.

The right-hand side's Jacobian ``f_x``: complex-step differentiation is not available, since
the generated model functions cast their arguments to float (a complex perturbation would be
dropped silently); exact derivatives use the structure of the closed loop instead. At fixed
``q`` the acceleration solves a linear system whose matrix depends on ``q`` only, with a
right-hand side quadratic in ``q'`` (Coriolis terms, ``h_d'' alpha'^2``, ``-K_d y'``) and linear
in the thrust; the thruster dynamics are linear. So along a ``q'`` or ``z`` column ``f`` is a
polynomial of degree <= 2 and its central difference is exact up to round-off. Along ``q`` the
columns use fourth-order Richardson-extrapolated central differences (truncation ``~h^4``,
``h = 1e-3`` rad: about 1e-10 relative). Units: SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from ..hzd.zero_dynamics import ZeroDynamics
from ..simulation.closed_loop import ClosedLoop
from ..simulation.full_order import _dip
from .poincare import Setting, guard_gradient

# [rad] Richardson step for the q columns of f_x. Measured against the finite-difference
# Jacobian and the SPEC 13 identity (one multiplier = delta_zero^2): 1e-3 left entry errors up
# to 2e-6 near the end of a knee walker's step (f_x entries ~1e4); 1e-4 gives 1e-9..9e-9 and
# the zero-dynamics multiplier to 1e-12..7e-10 on the bundled and the test robots, rounding
# (~eps |f| / H_Q) still far below.
H_Q = 1e-4
H_LIN = 1.0  # [rad/s, N, N/s] step for the columns along which f is a polynomial of degree <= 2


def closed_loop(zd: ZeroDynamics, setting: Setting) -> ClosedLoop:
    """The closed loop of ``setting`` (its thrust model and gains ``K_p``, ``K_d``)."""
    cl = ClosedLoop(zd, setting.thrust, setting.config())
    cl.kp, cl.kd = float(setting.kp), float(setting.kd)
    return cl


def _kernel(cl: ClosedLoop) -> tuple:
    """The compiled kernel's module, ``(fs, ip, par)`` for ``cl`` (``stepper.loop_context``)
    and a work array of its own, made once per closed loop."""
    ctx = cl.__dict__.get("_rhs_kernel")
    if ctx is None:
        from ..simulation import stepper

        mod, fs, ip, par = stepper.loop_context(cl)
        ctx = (mod, fs, ip, par, stepper.work_array(fs, ip))
        cl.__dict__["_rhs_kernel"] = ctx
    return ctx


def rhs(cl: ClosedLoop, X: np.ndarray, seg: int) -> np.ndarray:
    """``x' = [q'; q''; z']`` (SPEC 7) for a batch of states ``X`` (K, n) in segment ``seg``,
    by the compiled kernel (``step_stats.rhs_rows``: the closed loop's and the thrust model's
    equations, as :func:`rhs_numpy` evaluates them, to rounding); where its controller is
    singular, by :func:`rhs_numpy` (which says how)."""
    X = np.ascontiguousarray(np.atleast_2d(X), dtype=float)
    mod, fs, ip, par, w = _kernel(cl)
    out = np.empty_like(X)
    if mod.rhs_rows(X, int(seg), fs, ip, par, w, out) < 0:
        return out
    return rhs_numpy(cl, X, seg)


def rhs_numpy(cl: ClosedLoop, X: np.ndarray, seg: int) -> np.ndarray:
    """:func:`rhs` through NumPy: ``q''`` from the closed loop's vectorised path
    (``ClosedLoop.details``), ``z'`` from the thrust model."""
    X = np.atleast_2d(X)
    N = cl.N
    ddq = cl.details(X, np.full(len(X), seg))["ddq"]
    if cl.thrust.n_states:
        dz = cl.thrust.derivatives_rows(X[:, 2 * N:])
    else:
        dz = np.zeros((len(X), 0))
    return np.concatenate([X[:, N:2 * N], ddq, dz], axis=1)


def rhs_jacobian(cl: ClosedLoop, x: np.ndarray, seg: int) -> tuple[np.ndarray, np.ndarray]:
    """``(f(x), f_x(x))`` in segment ``seg``: exact central differences along ``q'`` and ``z``
    (``f`` is a polynomial of degree <= 2 there) and fourth-order Richardson differences along
    ``q`` (module docstring)."""
    N = cl.N
    n = x.size
    E = np.eye(n)
    rows = [x]
    for j in range(N):
        for s in (H_Q, -H_Q, 2 * H_Q, -2 * H_Q):
            rows.append(x + s * E[j])
    for j in range(N, n):
        rows.append(x + H_LIN * E[j])
        rows.append(x - H_LIN * E[j])
    F = rhs(cl, np.array(rows), seg)
    J = np.empty((n, n))
    for j in range(N):
        p1, m1, p2, m2 = F[1 + 4 * j:5 + 4 * j]
        J[:, j] = (8.0 * (p1 - m1) - (p2 - m2)) / (12.0 * H_Q)
    o = 1 + 4 * N
    for k, j in enumerate(range(N, n)):
        J[:, j] = (F[o + 2 * k] - F[o + 2 * k + 1]) / (2.0 * H_LIN)
    return F[0], J


def impact_jacobian(zd: ZeroDynamics, x: np.ndarray, nz: int) -> np.ndarray:
    """``DDelta`` at the pre-impact state ``x`` (SPEC 1, 5): ``q^+ = R q + b``,
    ``q'^+ = R Delta_q'(q) q'`` (exactly linear in ``q'``), ``z^+ = z``; the ``q`` columns of
    ``q'^+`` by fourth-order Richardson differences of the impact map."""
    model = zd.model
    N = model.n
    q, dq = x[:N], x[N:2 * N]
    n = 2 * N + nz
    D = np.zeros((n, n))
    D[:N, :N] = model.R
    _, _, Delta = model.impact_maps(q)
    D[N:2 * N, N:2 * N] = model.R @ Delta
    Q = []
    for j in range(N):
        for s in (H_Q, -H_Q, 2 * H_Q, -2 * H_Q):
            Q.append(q + s * np.eye(N)[j])
    dqp = model.impact(np.array(Q), np.repeat(dq[None], len(Q), axis=0)).dq_plus
    for j in range(N):
        p1, m1, p2, m2 = dqp[4 * j:4 * j + 4]
        D[N:2 * N, j] = (8.0 * (p1 - m1) - (p2 - m2)) / (12.0 * H_Q)
    D[2 * N:, 2 * N:] = np.eye(nz)
    return D


def impact_state(zd: ZeroDynamics, x: np.ndarray, nz: int) -> np.ndarray:
    """``Delta(x^-) = (R q + b, R Delta_q'(q) q', z)`` (SPEC 1, 5)."""
    N = zd.model.n
    imp = zd.model.impact(x[:N], x[N:2 * N])
    return np.concatenate([imp.q_plus, imp.dq_plus, x[2 * N:]])


@dataclass(frozen=True)
class VariationalJacobian:
    """``DP`` (n, n) on the pre-impact surface by the variational equations (SPEC 13), the end
    state ``x_end`` (the next pre-impact state), the step time ``T`` [s], the monodromy's
    trivial multiplier (should be 1) and ``flow_residual = |Phi_T f(x^+) - f(x^-)|`` (the
    flow direction carried by ``Phi``), the number of right-hand-side Jacobians evaluated;
    ``ok`` false with ``reason`` when the integration did not reach the guard."""

    DP: np.ndarray
    x_end: np.ndarray
    T: float
    trivial_multiplier: complex
    flow_residual: float
    evaluations: int
    ok: bool
    reason: str


def variational_jacobian(zd: ZeroDynamics, setting: Setting, x_star: np.ndarray,
                         rtol: float = 1e-11, atol: float = 1e-11) -> VariationalJacobian:
    """Integrate the orbit and ``Phi' = f_x Phi`` from ``Delta(x*)`` to the guard, segment by
    segment (``solve_ivp``, DOP853), with saltation at the knots and the time-to-guard
    correction at the event (module docstring)."""
    cl = closed_loop(zd, setting)
    N, nz = cl.N, setting.thrust.n_states
    n = 2 * N + nz
    x_plus = impact_state(zd, x_star, nz)
    DDelta = impact_jacobian(zd, x_star, nz)
    counter = [0]

    def aug(t, y, seg):
        x = y[:n]
        f, J = rhs_jacobian(cl, x, seg)
        counter[0] += 1
        return np.concatenate([f, (J @ y[n:].reshape(n, n)).ravel()])

    c, d = cl.c, cl.direction
    s0 = (float(c @ x_plus[:N]) - cl.ai) / cl.span
    seg = cl.segment_of(s0)
    y = np.concatenate([x_plus, np.eye(n).ravel()])
    t = 0.0
    t_max = 20.0 * max(1e-3, _predicted_time(zd, setting))
    fail = VariationalJacobian(np.zeros((n, n)), x_plus, 0.0, complex("nan"), float("inf"), 0,
                               False, "")
    while True:
        events = []
        armed = cl.guard_armed(seg)
        if seg < len(cl.breaks):
            a_next = cl.ai + cl.breaks[seg] * cl.span

            def brk(t, y, seg, a=a_next):
                return d * (float(c @ y[:N]) - a)
            brk.terminal, brk.direction = True, 1
            events.append(brk)
        if armed:
            def guard(t, y, seg):
                return float(zd.model.p_swing(y[:N])[1])
            guard.terminal, guard.direction = True, -1
            events.append(guard)

            # the swing foot's lowest points (recorded, not terminal): a shallow dip below the
            # ground between two integrator steps (a slow touchdown) changes no sign at the
            # steps, so the guard event alone misses it and finds a later crossing; the
            # simulation behind the finite differences looks for it the same way
            def low(t, y, seg):
                return cl.foot_velocity(y[:n])
            low.terminal, low.direction = False, 1
            events.append(low)
        t_start = t
        sol = solve_ivp(aug, (t, t_max), y, method="DOP853", rtol=rtol, atol=atol,
                        events=events, args=(seg,), dense_output=armed)
        dip = (_dip(cl, sol, sol.t_events[-1], seg, t_start, float(sol.t[-1]))
               if armed else None)
        if dip is not None:
            if dip[0] != "guard":
                return _failed(fail, f"the swing foot is below the ground when the guard is "
                                     f"armed (t = {dip[1]:.6g} s)")
            t = dip[1]
            y = sol.sol(t)
            break
        if sol.status != 1:
            return _failed(fail, f"the variational integration stopped at t = {sol.t[-1]:.6g} "
                                 f"s without reaching the guard ({sol.message})")
        t = float(sol.t[-1])
        y = sol.y[:, -1].copy()
        # the terminal event that ended the segment (the guard is the last but one event)
        kind = "guard" if (armed and len(sol.t_events[len(events) - 2])) else "break"
        if kind == "break":
            x = y[:n]
            f_minus = rhs(cl, x, seg)[0]
            f_plus = rhs(cl, x, seg + 1)[0]
            gx = np.concatenate([d * c, np.zeros(N + nz)])
            S = np.eye(n) + np.outer(f_plus - f_minus, gx) / float(gx @ f_minus)
            y[n:] = (S @ y[n:].reshape(n, n)).ravel()
            seg += 1
            continue
        break
    x_end = y[:n]
    Phi = y[n:].reshape(n, n)
    f_end = rhs(cl, x_end, seg)[0]
    gx = guard_gradient(zd, x_end, nz)
    Pi = np.eye(n) - np.outer(f_end, gx) / float(gx @ f_end)
    DP = Pi @ Phi @ DDelta
    # the monodromy based just after impact: Xi Phi_T, with the trivial multiplier 1
    s_start = cl.segment_of(s0)
    f_plus = rhs(cl, x_plus, s_start)[0]
    Xi = DDelta + np.outer(f_plus - DDelta @ f_end, gx) / float(gx @ f_end)
    mu = np.linalg.eigvals(Xi @ Phi)
    trivial = complex(mu[np.argmin(np.abs(mu - 1.0))])
    flow = float(np.max(np.abs(Phi @ f_plus - f_end)) / max(1.0, np.max(np.abs(f_end))))
    return VariationalJacobian(DP, x_end, t, trivial, flow, counter[0], True, "")


def _failed(base: VariationalJacobian, reason: str) -> VariationalJacobian:
    return VariationalJacobian(base.DP, base.x_end, 0.0, base.trivial_multiplier,
                               base.flow_residual, 0, False, reason)


def _predicted_time(zd: ZeroDynamics, setting: Setting) -> float:
    from ..simulation.closed_loop import predicted_cycle

    lc = predicted_cycle(zd, setting.thrust)
    return float(lc.step_time) if lc.exists else 1.0
