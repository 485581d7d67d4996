"""Virtual constraints on a compiled model: Bezier outputs and hybrid invariance (SPEC 2).

    alpha = c q,   s = (alpha - alpha_i) / (alpha_f - alpha_i) in [0, 1]
    y = q_b - h_d(alpha),  h_d,i(s) = sum_k a_ik binom(M, k) s^k (1 - s)^(M - k)
    H = [H_0; c],  q_Z(alpha) = H^-1 [h_d(alpha); alpha],  Phi(alpha) = H^-1 [dh_d/dalpha; 1]

Coefficient layout: see :class:`thrustwalk_cli.description.gait.Gait`. Angles in rad.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from math import comb

import numpy as np

from ..description.gait import Gait
from ..model.compiled import CompiledModel


def bezier(A: np.ndarray, s: np.ndarray, deriv: int = 0) -> np.ndarray:
    """Bezier polynomial (or its ``deriv``-th derivative in s) for rows of ``A``.

    ``A``: (rows, M+1); ``s``: any shape; result: ``s.shape + (rows,)``.
    """
    A = np.asarray(A, float)
    s = np.asarray(s, float)
    for _ in range(deriv):
        M = A.shape[1] - 1
        A = M * np.diff(A, axis=1) if M > 0 else np.zeros((A.shape[0], 1))
    M = A.shape[1] - 1
    k = np.arange(M + 1)
    binom = np.array([comb(M, j) for j in k], float)
    basis = binom * s[..., None] ** k * (1.0 - s[..., None]) ** (M - k)
    return basis @ A.T


def bezier_derivatives(A: np.ndarray, s: np.ndarray, upto: int = 2) -> list[np.ndarray]:
    """``[bezier(A, s, d) for d in 0..upto]``, bit for bit, with the powers ``s^k`` and
    ``(1 - s)^k`` computed once for all of them (the costly part for many ``s``)."""
    A = np.asarray(A, float)
    s = np.asarray(s, float)
    M0 = A.shape[1] - 1
    k0 = np.arange(M0 + 1)
    P = s[..., None] ** k0
    Q = (1.0 - s[..., None]) ** k0
    out = []
    for d in range(upto + 1):
        if d:
            M = A.shape[1] - 1
            A = M * np.diff(A, axis=1) if M > 0 else np.zeros((A.shape[0], 1))
        M = A.shape[1] - 1
        if M > M0:  # (a constant's derivative: one column, as bezier makes it)
            out.append(bezier(A, s))
            continue
        binom = np.array([comb(M, j) for j in range(M + 1)], float)
        basis = binom * P[..., :M + 1] * Q[..., M::-1]
        out.append(basis @ A.T)
    return out


@dataclass(frozen=True)
class GaitMaps:
    """Numeric gait geometry for one model: ``H``, boundary states and invariance residuals."""

    H: np.ndarray
    Hinv: np.ndarray
    c: np.ndarray
    A: np.ndarray
    alpha_i: float
    alpha_f: float
    q_minus: np.ndarray
    q_plus: np.ndarray
    position_residual: float
    velocity_residual: float

    @property
    def span(self) -> float:
        """``alpha_f - alpha_i`` [rad] (negative when alpha decreases over the step)."""
        return self.alpha_f - self.alpha_i

    def s(self, alpha: np.ndarray) -> np.ndarray:
        """The Bezier phase ``s = (alpha - alpha_i)/(alpha_f - alpha_i)`` [1] of ``alpha`` [rad]
        (SPEC 2)."""
        return (np.asarray(alpha, float) - self.alpha_i) / self.span

    def q_Z(self, alpha: np.ndarray) -> np.ndarray:
        """``q_Z(alpha) = H^-1 [h_d; alpha]`` [rad], shape ``alpha.shape + (N,)``."""
        alpha = np.asarray(alpha, float)
        hd = bezier(self.A, self.s(alpha))
        return np.concatenate([hd, alpha[..., None]], axis=-1) @ self.Hinv.T

    def Phi(self, alpha: np.ndarray) -> np.ndarray:
        """``Phi(alpha) = H^-1 [dh_d/dalpha; 1]`` (dimensionless), so that q' = Phi alpha'."""
        alpha = np.asarray(alpha, float)
        dh = bezier(self.A, self.s(alpha), 1) / self.span
        return np.concatenate([dh, np.ones(alpha.shape + (1,))], axis=-1) @ self.Hinv.T

    def dPhi(self, alpha: np.ndarray) -> np.ndarray:
        """``dPhi/dalpha = H^-1 [d^2 h_d/dalpha^2; 0]`` [1/rad]."""
        alpha = np.asarray(alpha, float)
        d2 = bezier(self.A, self.s(alpha), 2) / self.span**2
        return np.concatenate([d2, np.zeros(alpha.shape + (1,))], axis=-1) @ self.Hinv.T


def _H(c: np.ndarray) -> np.ndarray:
    n = c.size
    return np.vstack([np.hstack([np.eye(n - 1), np.zeros((n - 1, 1))]), c[None, :]])


def impact_direction(model: CompiledModel, q_minus: np.ndarray, phi_f: np.ndarray) -> np.ndarray:
    """``w = R Delta_q'(q^-) Phi(alpha_f)``: post-impact velocity direction on Z (SPEC 2)."""
    _, _, Delta = model.impact_maps(q_minus)
    return model.R @ (Delta @ phi_f)


def gait_maps(model: CompiledModel, gait: Gait) -> GaitMaps:
    """Boundary states and hybrid-invariance residuals of ``gait`` on ``model`` (SPEC 2).

    ``q^- = H^-1 [a_M; alpha_f]``, ``q^+ = R q^- + b``, ``alpha_i = c q^+``. Residuals:
    position ``|a_0 - H_0 q^+|`` [rad] and velocity ``|Phi(alpha_i) - w / (c w)|``.
    """
    c = np.asarray(gait.c, float)
    H = _H(c)
    Hinv = np.linalg.inv(H)
    A = gait.coefficients
    q_minus = Hinv @ np.append(A[:, -1], gait.alpha_f)
    q_plus = model.relabel(q_minus)
    alpha_i = float(c @ q_plus)
    maps = GaitMaps(H, Hinv, c, A, alpha_i, gait.alpha_f, q_minus, q_plus, 0.0, 0.0)
    w = impact_direction(model, q_minus, maps.Phi(np.array(gait.alpha_f)))
    pos = float(np.abs(A[:, 0] - q_plus[:-1]).max())
    vel = float(np.abs(maps.Phi(np.array(alpha_i)) - w / (c @ w)).max())
    return replace(maps, position_residual=pos, velocity_residual=vel)


def apply_invariance(model: CompiledModel, gait: Gait) -> Gait:
    """Return ``gait`` with columns 0 and 1 of ``A`` fixed by hybrid invariance (SPEC 2).

    ``a_0 = H_0 q^+``; ``a_1 = a_0 + (alpha_f - alpha_i)/M * H_0 w / (c w)`` with
    ``w = R Delta_q'(q^-) Phi(alpha_f)``, which makes ``Phi(alpha_i)`` parallel to ``w``.
    Needs ``M >= 3`` so that columns 0, 1 do not touch columns M-1, M.
    """
    A = gait.coefficients.copy()
    M = A.shape[1] - 1
    c = np.asarray(gait.c, float)
    H = _H(c)
    Hinv = np.linalg.inv(H)
    q_minus = Hinv @ np.append(A[:, -1], gait.alpha_f)
    q_plus = model.relabel(q_minus)
    alpha_i = float(c @ q_plus)
    dh_f = M * (A[:, -1] - A[:, -2]) / (gait.alpha_f - alpha_i)
    phi_f = Hinv @ np.append(dh_f, 1.0)
    w = impact_direction(model, q_minus, phi_f)
    A[:, 0] = q_plus[:-1]
    A[:, 1] = A[:, 0] + (gait.alpha_f - alpha_i) / M * w[:-1] / (c @ w)
    return replace(gait, A=tuple(map(tuple, A.tolist())))
