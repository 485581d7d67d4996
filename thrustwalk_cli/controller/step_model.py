"""The affine step-to-step model of SPEC section 11: zeta and the stance force of one step as
affine functions of the pre-impact value ``x_k`` that starts it and of its thrust values ``u_k``.

Thrust on knots ``alpha_1 = alpha_i < ... < alpha_n = alpha_f`` (force mode), the values of
step k stacked in ``u_k`` (one per interval and driven thruster, interval-major:
``u[j * m_d + t]``). With ``zeta^+ = delta_zero^2 x_k``:

    zeta_k(alpha) = delta_zero^2 x_k + V_0(alpha) + I_0(alpha) + I_u(alpha) u_k
    x_{k+1}       = zeta_k(alpha_f)
    F_1(alpha)    = Lambda_2(alpha) F(alpha) + Lambda_1(alpha) zeta_k(alpha) + Lambda_0(alpha)
    F(alpha)      = f_0(alpha) + S(alpha) u_k                                   [N]

``I_0 = int beta f_0 / kappa_1`` and ``I_u = int beta S / kappa_1`` from ``alpha_i``. For ideal
thrusters (the thrust is the command): ``f_0 = 0``, ``S`` the indicator of the point's knot
interval, so ``I_u`` holds the SPEC 11 ``Gamma_j(alpha)`` (:class:`IdealThrust`). For a
thruster with its own linear dynamics ``z' = A z + B F_ss``, ``F = C z`` (SPEC 7,
:mod:`thrustwalk_cli.thrust.dynamics`) and one setpoint per step, the delivered thrust is the
linear response ``F(t) = C e^{A t} z_k + C int_0^t e^{A s} ds B u_k``: affine in the command
and the thruster state at impact; the time ``t(alpha) = int dalpha / alpha'`` comes from the
zero dynamics of the same step (:class:`ResponseThrust`). So ``F_1 = P_0 + P_x x_k + P_u u_k``
exactly in both cases (:class:`Rows`).

Units: zeta [kg^2 m^4/s^2], thrust [N], F_1 [N], alpha [rad], t [s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..contact.terms import Fits, stance_terms
from ..errors import ComputationError
from ..hzd.quadrature import ChebSeries, lobatto
from ..hzd.zero_dynamics import ZeroDynamics
from ..model.compiled import CompiledModel
from ..thrust.dynamics import ThrusterDynamics


@dataclass(frozen=True)
class Rows:
    """The affine model at points ``alpha`` (g,) [rad]:

    ``zeta = d2 x + z0 + Zu u`` [kg^2 m^4/s^2]; ``F_1 = P0 + Px x + Pu u`` [N] (columns:
    horizontal, vertical); ``F = f0 + S u`` the delivered thrust [N] (g, m); ``E`` (g,) a bound
    on the error of ``F_1`` from the polynomial fits (0 with the exact terms) [N]."""

    alpha: np.ndarray
    z0: np.ndarray
    Zu: np.ndarray
    P0: np.ndarray
    Px: np.ndarray
    Pu: np.ndarray
    f0: np.ndarray
    S: np.ndarray
    E: np.ndarray

    def zeta(self, x: float, u: np.ndarray, d2: float) -> np.ndarray:
        """``zeta = d2 x + z0 + Zu u`` (g,) [kg^2 m^4/s^2] at ``x_k = x``, thrust values ``u``
        and ``d2 = delta_zero^2`` (SPEC 11)."""
        return d2 * x + self.z0 + self.Zu @ u

    def force(self, x: float, u: np.ndarray) -> np.ndarray:
        """``F_1`` (g, 2) [N] at ``x_k = x`` and thrust values ``u``."""
        return self.P0 + self.Px * x + np.einsum("gcv,v->gc", self.Pu, u)

    def thrust(self, u: np.ndarray) -> np.ndarray:
        """The delivered thrust ``F = f0 + S u`` (g, m) [N] for thrust values ``u`` (SPEC 11)."""
        return self.f0 + np.einsum("gtv,v->gt", self.S, u)

    def concat(self, other: Rows) -> Rows:
        """These rows followed by ``other``'s (e.g. the grid and the cutting planes)."""
        return Rows(*(np.concatenate([getattr(self, f), getattr(other, f)])
                      for f in ("alpha", "z0", "Zu", "P0", "Px", "Pu", "f0", "S", "E")))

    def take(self, sel: np.ndarray) -> Rows:
        """The rows at positions (or mask) ``sel``."""
        return Rows(*(getattr(self, f)[sel]
                      for f in ("alpha", "z0", "Zu", "P0", "Px", "Pu", "f0", "S", "E")))


class Terms:
    """Lambda_0..2 at any alpha, exact (SPEC 5) or from the fitted polynomials L_k with their
    maximum fit errors (``fits``, the paper's online variant)."""

    KEEP = 4  # arrays whose terms are kept (the QP grid, the polishing nodes)

    def __init__(self, model: CompiledModel, zd: ZeroDynamics, fits: Fits | None = None):
        self.model, self.zd, self.fits = model, zd, fits
        self._kept: list[tuple] = []  # (alpha, terms) of the arrays asked for at every step

    def __call__(self, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        for a, out in self._kept:
            if a is alpha:
                return out
        out = self._terms(alpha)
        self._kept = [(alpha, out)] + self._kept[:self.KEEP - 1]
        return out

    def _terms(self, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.fits is None:
            t = stance_terms(self.model, self.zd.maps, alpha)
            return t.L0, t.L1, t.L2
        L0, L1, L2, _ = self.fits.force_terms(alpha)
        return L0, L1, L2

    @property
    def errors(self) -> tuple[float, float, float]:
        """Maximum absolute fit errors of L_0 [N], L_1 [N per kg^2 m^4/s^2], L_2 [1]."""
        if self.fits is None:
            return 0.0, 0.0, 0.0
        f = self.fits.fits
        return f["L0"].max_error, f["L1"].max_error, f["L2"].max_error


def interval_of(knots: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Index of the knot interval holding each alpha (the last interval holds alpha_f)."""
    kn = np.asarray(knots, float)
    s = (np.asarray(alpha, float) - kn[0]) / (kn[-1] - kn[0])
    ks = (kn - kn[0]) / (kn[-1] - kn[0])
    return np.clip(np.searchsorted(ks, s, side="right") - 1, 0, len(kn) - 2)


def step_grid(knots: np.ndarray, points: int) -> tuple[np.ndarray, np.ndarray]:
    """Grid over the step, each knot interval sampled end to end (an inner knot appears twice,
    with the thrust of each side). Returns ``(alpha, interval index)``."""
    kn = np.asarray(knots, float)
    n = len(kn) - 1
    per = max(21, points // n)
    return (np.concatenate([np.linspace(kn[j], kn[j + 1], per) for j in range(n)]),
            np.repeat(np.arange(n), per))


class IdealThrust:
    """The delivered thrust is the command: ``F(alpha) = u_j`` on knot interval j for each
    driven thruster (SPEC 11). ``I_u(alpha)`` column ``(j, t)`` is
    ``Gamma_t(clip(alpha, interval j)) - Gamma_t(alpha_j)``."""

    dynamic = False

    def __init__(self, zd: ZeroDynamics, knots: np.ndarray, driven: list[int]):
        self.zd, self.knots, self.driven = zd, np.asarray(knots, float), list(driven)
        self.m = zd.model.n_thrusters
        self.n_int = len(self.knots) - 1
        self.nu = self.n_int * len(self.driven)

    def parts(self, alpha: np.ndarray, idx: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(f0, S, I0, Iu)`` at ``alpha`` (g,): shapes (g, m), (g, m, nu), (g,), (g, nu)."""
        alpha = np.atleast_1d(np.asarray(alpha, float))
        idx = interval_of(self.knots, alpha) if idx is None else np.asarray(idx, int)
        g, md = alpha.size, len(self.driven)
        kn = self.knots
        lo, hi = np.minimum(kn[:-1], kn[1:]), np.maximum(kn[:-1], kn[1:])
        Gk = self.zd.Gamma(kn)  # (n, m)
        S = np.zeros((g, self.m, self.nu))
        Iu = np.zeros((g, self.nu))
        for j in range(self.n_int):
            Ga = self.zd.Gamma(np.clip(alpha, lo[j], hi[j]))  # (g, m)
            for c, t in enumerate(self.driven):
                v = j * md + c
                Iu[:, v] = Ga[:, t] - Gk[j, t]
                S[idx == j, t, v] = 1.0
        return np.zeros((g, self.m)), S, np.zeros(g), Iu


class StepStops(ComputationError):
    """A slow thruster's predicted step has no time map: zeta reaches 0 along it (the walker
    would stop and fall back) or the time ``t(alpha)`` it gives is not resolved (not
    increasing, not finite: zeta nearly 0 somewhere)."""


class ResponseThrust:
    """A thruster with its own dynamics and one setpoint per step (SPEC 11, "slow
    thrusters"): the delivered thrust over the step is the linear response to the setpoint
    ``u_k`` from the thruster state ``z_k`` at impact, ``F(t) = Phi(t) z_k + Psi(t) u_k``, with
    the time along the step ``t(alpha) = int_{alpha_i}^{alpha} dalpha / alpha'`` from the zero
    dynamics of the step (``alpha' = kappa_1 sigma_N``, ``sigma_N = sgn sqrt(2 zeta)``).

    ``t(alpha)`` depends on the thrust through zeta: :meth:`update` takes the step's zeta on
    the Chebyshev-Lobatto nodes (for a guess of ``u_k``) and rebuilds ``t(alpha)`` and the
    integrals ``I_0``, ``I_u``; the planner repeats solve and update until both settle (a
    fixed-point iteration), so the converged prediction is the zero dynamics with the lagged
    thrust, not a linearisation of it.
    """

    dynamic = True

    def __init__(self, zd: ZeroDynamics, dyn: ThrusterDynamics, driven: list[int],
                 nodes: int = 129):
        """``dyn``: the dynamics of every thruster of the robot (thrust/dynamics.py)."""
        self.zd, self.dyn, self.driven = zd, dyn, list(driven)
        self.m = zd.model.n_thrusters
        self.knots = np.array([zd.alpha_i, zd.alpha_f])
        self.nu = len(self.driven)
        self.a, self.b = zd.alpha_i, zd.alpha_f
        self.nodes = lobatto(self.a, self.b, nodes)
        tm = zd.terms(self.nodes)
        self.k1 = tm["kappa1"]
        self.bk = tm["beta"] * tm["eDPhi"][:, None]  # beta / kappa_1, (n, m)
        self.sgn = zd.sigma_sign
        self.V0n = zd.V0(self.nodes)
        self.z = np.zeros(dyn.n_states)
        self.t_series: ChebSeries | None = None

    def start(self, z: np.ndarray) -> None:
        """The thruster states at the impact that starts the step (stacked as the
        simulation's state vector holds them: ``ThrusterDynamics.layout``)."""
        self.z = np.asarray(z, float)

    def _state(self, t: int) -> np.ndarray:
        return np.array([self.z[j] for j in self.dyn.layout[t]])

    def _response(self, t: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(Phi, Psi)`` of every thruster at times ``t`` (:meth:`~thrustwalk_cli.thrust.
        dynamics.Servo.response`)."""
        return [s.response(t) for s in self.dyn.servos]

    def update(self, zeta_nodes: np.ndarray) -> float:
        """Rebuild ``t(alpha)``, ``F`` and the integrals from zeta on the nodes; returns the
        predicted step time [s]. :class:`StepStops` (nothing changed) when zeta is not > 0 on
        every node or the time it gives does not increase along the step."""
        z = np.asarray(zeta_nodes, float)
        if not (np.all(np.isfinite(z)) and np.min(z) > 0.0):
            i = int(np.nanargmin(np.where(np.isfinite(z), z, -np.inf)))
            raise StepStops(f"the predicted step stops: zeta reaches {z[i]:.3g} kg^2 m^4/s^2 "
                            f"at alpha = {self.nodes[i]:.4g} rad")
        inv = 1.0 / (self.k1 * self.sgn * np.sqrt(2.0 * z))
        t_series = ChebSeries.from_values(self.a, self.b, inv).cumulative()
        t = t_series(self.nodes)
        if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0.0)):
            raise StepStops(f"the predicted step nearly stops (zeta down to {np.min(z):.3g} "
                            "kg^2 m^4/s^2): its time along the step is not resolved")
        self.t_series = t_series
        f0 = np.zeros((t.size, self.m))
        S = np.zeros((t.size, self.m, self.nu))
        resp = self._response(t)
        for t_ in range(self.m):  # thrusters not driven relax towards F_ss = 0
            f0[:, t_] = resp[t_][0] @ self._state(t_)
        for c, t_ in enumerate(self.driven):
            S[:, t_, c] = resp[t_][1]
        I0 = np.einsum("nm,nm->n", self.bk, f0)
        Iu = np.einsum("nm,nmv->nv", self.bk, S)
        self.I0 = ChebSeries.from_values(self.a, self.b, I0).cumulative()
        self.Iu = ChebSeries.from_values(self.a, self.b, Iu).cumulative()
        return float(self.t_series(np.array(self.b)))

    def zeta_nodes(self, x: float, u: np.ndarray) -> np.ndarray:
        """zeta on the nodes for ``x_k = x`` and setpoints ``u`` with the current time map."""
        return (self.zd.delta_zero_sq * x + self.V0n + self.I0(self.nodes)
                + self.Iu(self.nodes) @ u)

    def parts(self, alpha: np.ndarray, idx: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        alpha = np.clip(np.atleast_1d(np.asarray(alpha, float)), min(self.a, self.b),
                        max(self.a, self.b))
        t = self.t_series(alpha)
        resp = self._response(t)
        f0 = np.zeros((alpha.size, self.m))
        S = np.zeros((alpha.size, self.m, self.nu))
        for t_ in range(self.m):
            f0[:, t_] = resp[t_][0] @ self._state(t_)
        for c, t_ in enumerate(self.driven):
            S[:, t_, c] = resp[t_][1]
        return f0, S, self.I0(alpha), self.Iu(alpha)


ROW_FIELDS = ("z0", "Zu", "P0", "Px", "Pu", "f0", "S")


def series_nodes(knots: np.ndarray, nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """``nodes`` Chebyshev-Lobatto points on each knot interval, ends included (an inner knot
    appears once per side). Returns ``(alpha, interval index)``."""
    kn = np.asarray(knots, float)
    n_int = len(kn) - 1
    return (np.concatenate([lobatto(kn[j], kn[j + 1], nodes) for j in range(n_int)]),
            np.repeat(np.arange(n_int), nodes))


class RowSeries:
    """The affine model (:class:`Rows`) between grid points, for polishing the plan's worst
    points (:mod:`.planner`): on each knot interval (where the rows are smooth: the thrust's
    indicator is constant, the integrals and the Lambda terms analytic) a Chebyshev series
    (:class:`~thrustwalk_cli.hzd.quadrature.ChebSeries`) through the exact rows ``at_nodes``
    on the points of :func:`series_nodes`. Evaluating it costs a cosine table and a matrix
    product (tens of microseconds for a batch), where the exact rows cost one evaluation of
    every model function (milliseconds). Its error against the exact rows is measured on the
    QP grid (:meth:`deviation`, points that are not nodes) and added to the polished margins
    by the planner."""

    def __init__(self, at_nodes: Rows, idx: np.ndarray, knots: np.ndarray):
        self.knots = np.asarray(knots, float)
        n_int = len(self.knots) - 1
        g = at_nodes.alpha.size
        self.shapes = {f: getattr(at_nodes, f).shape[1:] for f in ROW_FIELDS}
        stacked = np.concatenate([getattr(at_nodes, f).reshape(g, -1) for f in ROW_FIELDS],
                                 axis=1)
        self.series = [ChebSeries.from_values(self.knots[j], self.knots[j + 1],
                                              stacked[idx == j]) for j in range(n_int)]

    def __call__(self, alpha: np.ndarray, idx: np.ndarray) -> Rows:
        """The rows at ``alpha`` (g,) [rad], each on knot interval ``idx`` (g,)."""
        return self.at(idx)(alpha)

    def at(self, idx: np.ndarray, M: np.ndarray | None = None):
        """An evaluator for a batch whose entries stay on knot intervals ``idx`` (g,):
        ``alpha`` (g,) -> :class:`Rows`; with ``M`` (K, c), a matrix on the stacked fields
        (:attr:`layout`), ``alpha`` -> the (g, c) array ``rows @ M`` (the series of the
        product: a search's iterates then cost one small matrix product per interval)."""
        idx = np.atleast_1d(np.asarray(idx, int))
        coef = [s.coef if M is None else s.coef @ M for s in self.series]
        groups = [(np.flatnonzero(idx == j), ChebSeries(s.a, s.b, coef[j]))
                  for j, s in enumerate(self.series) if np.any(idx == j)]
        width = coef[0].shape[1]

        def evaluate(alpha: np.ndarray):
            alpha = np.asarray(alpha, float)
            out = np.empty((alpha.size, width))
            for sel, ser in groups:
                out[sel] = ser.at_few(alpha[sel])
            if M is not None:
                return out
            g = alpha.size
            return Rows(alpha, E=np.zeros(g),
                        **{f: out[:, sl].reshape((g,) + sh) for f, (sl, sh) in
                           self.layout.items()})
        return evaluate

    @property
    def layout(self) -> dict[str, tuple[slice, tuple]]:
        """Each field's columns in the stacked series and its trailing shape."""
        out, c = {}, 0
        for f in ROW_FIELDS:
            k = int(np.prod(self.shapes[f], dtype=int))
            out[f] = (slice(c, c + k), self.shapes[f])
            c += k
        return out

    def deviation(self, exact: Rows, idx: np.ndarray) -> dict[str, np.ndarray]:
        """Largest absolute difference of each field from the exact rows ``exact`` (on knot
        intervals ``idx``), over those rows: ``{field: array of the field's trailing
        shape}``."""
        approx = self(exact.alpha, idx)
        return {f: np.abs(getattr(approx, f) - getattr(exact, f)).max(axis=0, initial=0.0)
                for f in ROW_FIELDS}


def rows(zd: ZeroDynamics, terms: Terms, thrust, alpha: np.ndarray,
         idx: np.ndarray | None = None) -> Rows:
    """The affine model (:class:`Rows`) at ``alpha`` for ``thrust`` (:class:`IdealThrust` or
    :class:`ResponseThrust`), SPEC 5 and 11 (``E`` zero: the planner adds the fit error bound,
    which depends on the step's zeta and thrust ranges)."""
    alpha = np.atleast_1d(np.asarray(alpha, float))
    d2 = zd.delta_zero_sq
    L0, L1, L2 = terms(alpha)
    f0, S, I0, Iu = thrust.parts(alpha, idx)
    z0 = zd.V0(alpha) + I0
    P0 = L0 + L1 * z0[:, None] + np.einsum("gcm,gm->gc", L2, f0)
    Px = L1 * d2
    Pu = L1[:, :, None] * Iu[:, None, :] + np.einsum("gcm,gmv->gcv", L2, S)
    return Rows(alpha, z0, Iu, P0, Px, Pu, f0, S, np.zeros(alpha.size))
