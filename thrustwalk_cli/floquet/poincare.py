"""The full-order Poincare map on the impact surface, its fixed point and its finite-difference
Jacobian (SPEC 13), with the compiled simulation.

State just before impact ``x = (q, q', z)`` (``z``: thruster states, continuous across impacts),
``n = 2N + n_z``. Guard ``g(x) = p_2,y(q)`` (swing-foot height [m]). The Poincare map is the
impact map (with relabelling, SPEC 1, 5) followed by the closed-loop flow (SPEC 7) until the
guard: ``P(x^-) = phi(T(x), Delta(x^-))``. It is defined in a neighbourhood of the guard and
maps into it, so its Jacobian ``DP`` has rank at most ``n - 1`` (one trivial multiplier 0,
normal to the guard). We reduce it to a section of dimension ``n - 1``: coordinates
``xi = (B_q^T dq_pos, dq', dz)`` with ``B_q`` an orthonormal basis of the guard's tangent
space in configuration (``g_q B_q = 0``), i.e. ``x = x* + B xi``, ``B = diag(B_q, I_N,
I_nz)``; the Jacobian of the section map is ``J = B^T DP B`` (exact, since the range of
``DP`` lies in the tangent space). The blocks keep their meaning: configuration along the
guard [rad], rates [rad/s], thruster states [N, N/s].

Units: SI (rad, rad/s, N, N/s, s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..hzd.zero_dynamics import ZeroDynamics
from ..simulation.batch import simulate_batch
from ..simulation.closed_loop import SimConfig, ThrustModel, predicted_cycle

FD_STEPS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)  # central-difference steps tried, section units


@dataclass(frozen=True)
class Setting:
    """One closed loop to analyse: the thrust model (with ``F_ss`` [N], ``wn`` [rad/s],
    ``xi`` [1], ``tau`` [s]), the output gains ``kp`` [1/s^2] and ``kd`` [1/s] of
    ``y'' = -K_p y - K_d y'`` (SPEC 7), and the integration tolerances."""

    thrust: ThrustModel
    kp: float
    kd: float
    rtol: float = 1e-12
    atol: float = 1e-12

    def config(self) -> SimConfig:
        """The :class:`SimConfig` of a one-step run of this loop at its tolerances (the Poincare
        map, SPEC 13)."""
        return SimConfig(steps=1, rtol=self.rtol, atol=self.atol, samples_per_step=2)


def state_names(zd: ZeroDynamics, thrust: ThrustModel) -> list[str]:
    """Names of the components of ``x = (q, q', z)``: coordinates, their rates (``q1'``) and
    the thruster states as the thrust model names them (the first-order thrust ``F_hip_x``;
    the second-order thrust and its rate ``F_hip_x'``)."""
    r = zd.model.robot
    q = list(r.coordinate_names)
    return (q + [f"{c}'" for c in q]
            + thrust.dynamics.state_names(r.thruster_names[: thrust.m]))


def thruster_equilibrium(thrust: ThrustModel) -> np.ndarray:
    """Thruster states at rest at ``F_ss``: ``F = F_ss`` (and ``F' = 0``)."""
    return thrust.dynamics.rest(np.asarray(thrust.target, float))


def predicted_state(zd: ZeroDynamics, thrust: ThrustModel) -> tuple[np.ndarray | None, object]:
    """The zero-dynamics prediction of the fixed point (SPEC 3): ``q^- = q_Z(alpha_f)``,
    ``q'^- = Phi(alpha_f) kappa_1(alpha_f) sigma*``, ``sigma* = sgn sqrt(2 zeta*)``, thruster
    at rest at ``F_ss``; None when no orbit exists. Returns ``(x, limit cycle)``."""
    lc = predicted_cycle(zd, thrust)
    if not lc.exists:
        return None, lc
    t = zd.terms(np.array([zd.alpha_f]))
    sigma = zd.sigma_sign * np.sqrt(2.0 * lc.zeta_star)
    dq = t["Phi"][0] * t["kappa1"][0] * sigma
    return np.concatenate([zd.maps.q_minus, dq, thruster_equilibrium(thrust)]), lc


def guard_gradient(zd: ZeroDynamics, x: np.ndarray, nz: int) -> np.ndarray:
    """``dg/dx = [dp_2,y/dq, 0, 0]`` [m/rad] at the state ``x``."""
    N = zd.model.n
    gq = np.asarray(zd.model.E_swing(x[:N]), float)[1]
    return np.concatenate([gq, np.zeros(N + nz)])


def section_basis(zd: ZeroDynamics, x: np.ndarray, nz: int) -> np.ndarray:
    """``B`` (n, n-1): orthonormal, spanning the guard's tangent space at ``x``
    (``dg/dx B = 0``), block-diagonal ``diag(B_q, I_N, I_nz)``."""
    N = zd.model.n
    gq = guard_gradient(zd, x, nz)[:N]
    _, _, vt = np.linalg.svd(gq[None, :])
    Bq = vt[1:].T  # the right singular vectors orthogonal to g_q
    n = 2 * N + nz
    B = np.zeros((n, n - 1))
    B[:N, :N - 1] = Bq
    B[N:, N - 1:] = np.eye(N + nz)
    return B


def project_to_guard(zd: ZeroDynamics, x: np.ndarray, nz: int) -> np.ndarray:
    """``x`` moved along the guard's normal in configuration until the swing foot is on the
    ground (Newton on ``g(q + t g_q^T) = 0``, to 1e-15 m)."""
    N = zd.model.n
    x = np.array(x, float)
    for _ in range(8):
        h = float(zd.model.p_swing(x[:N])[1])
        if abs(h) < 1e-15:
            break
        gq = guard_gradient(zd, x, nz)[:N]
        x[:N] -= h * gq / float(gq @ gq)
    return x


class PoincareMap:
    """``P(x^-)``: impact map then one closed-loop step of the compiled simulation (SPEC 13),
    for a batch of pre-impact states. Failed steps come back as NaN rows with their reasons."""

    def __init__(self, zd: ZeroDynamics, setting: Setting):
        self.zd, self.setting = zd, setting
        self.model = zd.model
        self.N = zd.model.n
        self.nz = setting.thrust.n_states
        self.n = 2 * self.N + self.nz
        self.config = setting.config()
        self.calls = 0  # one-step simulations run

    def __call__(self, X: np.ndarray) -> tuple[np.ndarray, list[str]]:
        X = np.atleast_2d(np.asarray(X, float))
        N = self.N
        imp = self.model.impact(X[:, :N], X[:, N:2 * N])
        x0 = np.concatenate([imp.q_plus, imp.dq_plus, X[:, 2 * N:]], axis=1)
        gains = np.tile([self.setting.kp, self.setting.kd], (len(X), 1))
        res = simulate_batch(self.zd, self.setting.thrust, x0, self.config, gains=gains)
        self.calls += len(X)
        out = res.state_minus()[:, 0, :]
        reasons = [r for ok, r in zip(res.success, res.reason) if not ok]
        return out, reasons

    def one(self, x: np.ndarray) -> tuple[np.ndarray, list[str]]:
        out, reasons = self(x[None, :])
        return out[0], reasons


@dataclass(frozen=True)
class FDJacobian:
    """Central-difference Jacobian of the section map (SPEC 13) at the chosen step.

    ``J`` (n-1, n-1); ``step``: the chosen step [section units: rad, rad/s, N, N/s];
    ``steps``: every step tried with ``change``, the largest entry change to the next smaller
    step (None where a run failed); ``error``: the estimate of the chosen Jacobian's error (the
    smaller change to its neighbours, max over the entries); ``neighbour``: the Jacobian at
    the neighbouring step that gave ``error`` (``neighbour_step``), kept so that the estimate
    can be carried to derived quantities (the multipliers, SPEC 13), None without an
    estimate; ``ok``: false when every step failed."""

    J: np.ndarray
    step: float
    steps: tuple[tuple[float, float | None], ...]
    error: float
    ok: bool
    reason: str
    neighbour: np.ndarray | None = None
    neighbour_step: float | None = None


def central_jacobian(P: PoincareMap, x: np.ndarray, B: np.ndarray, h: float
                     ) -> tuple[np.ndarray | None, list[str]]:
    """``J = B^T (P(x + h b_j) - P(x - h b_j)) / (2h)`` for every column ``b_j`` of ``B``."""
    k = B.shape[1]
    X = np.concatenate([x[None] + h * B.T, x[None] - h * B.T])
    PX, reasons = P(X)
    if reasons or not np.all(np.isfinite(PX)):
        return None, reasons
    D = (PX[:k] - PX[k:]) / (2.0 * h)  # rows: columns of DP B
    return B.T @ D.T, []


def fd_jacobian(P: PoincareMap, x: np.ndarray, B: np.ndarray,
                steps: tuple[float, ...] = FD_STEPS) -> FDJacobian:
    """The Jacobian by central differences at each of ``steps`` (SPEC 13); the chosen step is
    the one in the middle of the plateau: the interior step whose changes to both neighbours
    add up least (truncation error ~h^2 above it, integration noise ~tol/h below)."""
    Js: list[np.ndarray | None] = []
    why: list[str] = []
    for h in steps:
        J, reasons = central_jacobian(P, x, B, h)
        Js.append(J)
        why += reasons
    change: list[float | None] = []
    for a, b in zip(Js[:-1], Js[1:]):
        change.append(None if a is None or b is None else float(np.max(np.abs(a - b))))
    change.append(None)
    best, score = None, np.inf
    for i in range(1, len(steps) - 1):
        if Js[i] is None or change[i - 1] is None or change[i] is None:
            continue
        s = change[i - 1] + change[i]
        if s < score:
            best, score = i, s
    table = tuple((float(h), c) for h, c in zip(steps, change))
    if best is None:
        good = [i for i, J in enumerate(Js) if J is not None]
        if not good:
            k = B.shape[1]
            return FDJacobian(np.zeros((k, k)), float(steps[0]), table, float("inf"), False,
                              "every finite-difference run failed: " + (why[0] if why else
                                                                         "no result"))
        best = good[len(good) // 2]
        return FDJacobian(Js[best], float(steps[best]), table, float("inf"), True,
                          "too few successful steps to estimate the error")
    nb = best - 1 if change[best - 1] <= change[best] else best + 1
    err = change[min(nb, best)]
    return FDJacobian(Js[best], float(steps[best]), table, float(err), True, "",
                      neighbour=Js[nb], neighbour_step=float(steps[nb]))


@dataclass(frozen=True)
class FixedPoint:
    """Newton's method on ``P(x) - x = 0`` in the section (SPEC 13), started at the
    zero-dynamics prediction ``x0``. ``x``: the fixed point; ``residual``: ``|P(x) - x|_inf``
    relative to ``max(1, |x|_inf)``; ``history``: that residual per iterate (the start
    first); ``converged``: residual <= ``tol``; ``reason`` when not."""

    x: np.ndarray
    x0: np.ndarray
    residual: float
    history: tuple[float, ...]
    iterations: int
    converged: bool
    tol: float
    reason: str
    step_time: float


def _relative(r: np.ndarray, x: np.ndarray) -> float:
    return float(np.max(np.abs(r)) / max(1.0, float(np.max(np.abs(x)))))


def newton(P: PoincareMap, x0: np.ndarray, tol: float = 1e-9, max_iter: int = 8,
           h: float = 1e-5) -> FixedPoint:
    """Newton's method for the fixed point of the section map: ``xi = (I - J)^-1 B^T (P(x) -
    x)``, ``x <- x + B xi``, then back onto the guard; ``J`` by central differences with step
    ``h`` at every iterate. Never raises on a failed step: the result says why."""
    zd, nz = P.zd, P.nz
    x = project_to_guard(zd, x0, nz)
    hist: list[float] = []
    reason = ""
    step_time = float("nan")
    for it in range(max_iter + 1):
        Px, why = P.one(x)
        if why or not np.all(np.isfinite(Px)):
            reason = f"the step from iterate {it} failed: {why[0] if why else 'no result'}"
            break
        res = _relative(Px - x, x)
        hist.append(res)
        if res <= tol:
            step_time = _step_time(P, x)
            return FixedPoint(x, x0, res, tuple(hist), it, True, tol, "", step_time)
        if it == max_iter:
            reason = f"no convergence in {max_iter} iterations (residual {res:.3g} > {tol:g})"
            break
        B = section_basis(zd, x, nz)
        J, why = central_jacobian(P, x, B, h)
        if J is None:
            reason = f"the Jacobian at iterate {it} failed: {why[0] if why else 'no result'}"
            break
        try:
            xi = np.linalg.solve(np.eye(J.shape[0]) - J, B.T @ (Px - x))
        except np.linalg.LinAlgError:
            reason = "I - J is singular (a multiplier equals 1): Newton's method is undefined"
            break
        x = project_to_guard(zd, x + B @ xi, nz)
    res = hist[-1] if hist else float("inf")
    return FixedPoint(x, x0, res, tuple(hist), len(hist) - 1, False, tol, reason, step_time)


def _step_time(P: PoincareMap, x: np.ndarray) -> float:
    """Step time [s] of the orbit through ``x`` (one more step, records kept)."""
    N = P.N
    imp = P.model.impact(x[None, :N], x[None, N:2 * N])
    x0 = np.concatenate([imp.q_plus, imp.dq_plus, x[None, 2 * N:]], axis=1)
    res = simulate_batch(P.zd, P.setting.thrust, x0, P.config,
                         gains=np.array([[P.setting.kp, P.setting.kd]]))
    return float(res.field("step_time")[0, 0])


def check_setting(zd: ZeroDynamics, setting: Setting) -> None:
    """Parameters the analysis needs: Hurwitz output gains and integration tolerances."""
    if not (setting.kp > 0 and setting.kd > 0):
        raise InputError.param(("kp", "kd"), f"the output gains must be > 0 (got K_p = "
                                             f"{setting.kp:g}, K_d = {setting.kd:g})")
    setting.config().validate()
