"""Floquet multipliers of the full-order closed loop with thruster states (SPEC 13).

For one setting (thrust model, gains): the fixed point of the Poincare map by Newton from the
zero-dynamics prediction, its Jacobian on the section two ways (central differences with the
compiled simulation, variational equations with saltation), their agreement, the ``n - 1``
multipliers (eigenvalues of the variational Jacobian, the more accurate; the finite-difference
ones beside them), each with its eigenvector's dominant components and its participation in
the thruster states, the multiplier of the zero dynamics identified and compared with
``delta_zero^2`` (SPEC 3), the spectral radius and a verdict that is never better than the
evidence:

* ``stable`` / ``unstable``: spectral radius below / above 1 by more than ``margin``, the
  Newton residual within its tolerance and the two Jacobians agreeing;
* ``undetermined``: Newton did not converge, a Jacobian failed, the methods disagree, or the
  spectral radius is within ``margin`` of 1;
* ``no orbit``: the zero dynamics predicts no periodic orbit to start from.

Checks of SPEC 13: ``Z`` is invariant under the closed loop (exact input-output linearisation)
and the gait is hybrid-invariant, so ``Z`` intersected with the guard is an invariant curve
and one multiplier is ``delta_zero^2`` exactly (its eigenvector lies along
``(0, Phi(alpha_f), 0)``, the rates on ``Z``); a thruster whose dynamics ``z' = A z + b F_ss``
do not depend on the walker makes the Jacobian block-triangular at the equilibrium thrust, so
its multipliers are the eigenvalues of ``exp(A T*)``; the output dynamics contribute
multipliers of the order of ``exp(Re(lambda) T*)``, ``lambda`` the roots of ``s^2 + K_d s +
K_p``. Units: multipliers [1], times [s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..hzd.zero_dynamics import ZeroDynamics
from .poincare import (
    FDJacobian,
    FixedPoint,
    PoincareMap,
    Setting,
    check_setting,
    fd_jacobian,
    newton,
    predicted_state,
    section_basis,
    state_names,
)
from .variational import VariationalJacobian, variational_jacobian

AGREEMENT_TOL = 1e-6  # max |J_fd - J_var| / max(1, max |J|) for "the methods agree"
MARGIN = 1e-6  # a spectral radius within this of 1 is undetermined


@dataclass(frozen=True)
class Multiplier:
    """One Floquet multiplier [1]: ``value`` (complex), its modulus, ``kind``
    (``zero dynamics``, ``outputs`` or ``thruster``), ``dominant``: the largest components
    of its unit eigenvector in ``x = (q, q', z)`` as (name, modulus), ``thruster_share``: its
    participation factor in the thruster states (0..1), ``alignment``: |cos| of the angle
    between its eigenvector and the zero-dynamics direction ``(0, Phi(alpha_f), 0)``;
    ``finite_difference``: the matching multiplier of the finite-difference Jacobian."""

    value: complex
    kind: str
    dominant: tuple[tuple[str, float], ...]
    thruster_share: float
    alignment: float
    finite_difference: complex

    @property
    def modulus(self) -> float:
        return abs(self.value)


@dataclass(frozen=True)
class Floquet:
    """The analysis of one setting (module docstring). ``exists`` false: no predicted orbit
    (``reason``). ``agreement``: ``max |J_fd - J_var| / max(1, max |J|)``;
    ``multiplier_agreement``: the largest difference between matched multipliers."""

    setting: Setting
    exists: bool
    verdict: str
    reason: str
    names: tuple[str, ...]
    delta_zero_sq: float
    predicted_zeta_star: float | None
    predicted_step_time: float | None
    fixed_point: FixedPoint | None = None
    fd: FDJacobian | None = None
    variational: VariationalJacobian | None = None
    J: np.ndarray | None = None
    J_fd: np.ndarray | None = None
    basis: np.ndarray | None = None
    multipliers: tuple[Multiplier, ...] = ()
    agreement: float | None = None
    multiplier_agreement: float | None = None
    agree: bool = False
    spectral_radius: float | None = None
    zero_dynamics_multiplier: complex | None = None
    output_reference: float | None = None
    simulations: int = 0

    @property
    def stable(self) -> bool:
        return self.verdict == "stable"


def _match(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """For each value of ``a`` the nearest unused value of ``b`` (greedy, nearest first)."""
    out = np.full(a.size, np.nan + 0j)
    used: set[int] = set()
    pairs = sorted((abs(x - y), i, j) for i, x in enumerate(a) for j, y in enumerate(b))
    for _, i, j in pairs:
        if np.isnan(out[i]) and j not in used:
            out[i] = b[j]
            used.add(j)
    return out


def multipliers(zd: ZeroDynamics, J: np.ndarray, J_fd: np.ndarray, B: np.ndarray,
                names: list[str], nz: int, top: int = 3) -> tuple[list[Multiplier], int]:
    """Multipliers of ``J`` sorted by modulus (largest first), classified; returns them and
    the index of the zero-dynamics one (-1 if none is a walker mode)."""
    lam, V = np.linalg.eig(J)
    order = np.argsort(-np.abs(lam), kind="stable")
    lam, V = lam[order], V[:, order]
    try:
        L = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        L = np.linalg.pinv(V)
    k = J.shape[0]
    part = np.abs(L.T * V)  # participation of section coordinate i in mode j: |V_ij L_ji|
    part = part / np.maximum(part.sum(axis=0, keepdims=True), 1e-300)
    share = part[k - nz:, :].sum(axis=0) if nz else np.zeros(k)
    N = zd.model.n
    t = zd.terms(np.array([zd.alpha_f]))
    vz = np.concatenate([np.zeros(N), t["Phi"][0], np.zeros(nz)])
    vz /= np.linalg.norm(vz)
    full = B @ V
    full = full / np.linalg.norm(full, axis=0, keepdims=True)
    align = np.abs(vz @ full)
    walker = [j for j in range(k) if share[j] < 0.5]
    zd_index = max(walker, key=lambda j: align[j]) if walker else -1
    fdv = _match(lam, np.linalg.eigvals(J_fd))
    out = []
    for j in range(k):
        comp = np.abs(full[:, j])
        idx = np.argsort(-comp, kind="stable")[:top]
        kind = ("zero dynamics" if j == zd_index else "thruster" if share[j] >= 0.5
                else "outputs")
        out.append(Multiplier(complex(lam[j]), kind,
                              tuple((names[i], float(comp[i])) for i in idx),
                              float(share[j]), float(align[j]), complex(fdv[j])))
    return out, zd_index


def output_reference(kp: float, kd: float, T: float) -> float:
    """``exp(max Re(lambda) T)``, ``lambda`` the roots of ``s^2 + K_d s + K_p`` [1]: the order
    of the output dynamics' contraction over one step (SPEC 13)."""
    roots = np.roots([1.0, kd, kp])
    return float(np.exp(np.max(roots.real) * T))


def analyse(zd: ZeroDynamics, setting: Setting, *, newton_tol: float = 1e-9,
            agreement_tol: float = AGREEMENT_TOL, margin: float = MARGIN) -> Floquet:
    """Fixed point, Jacobians, multipliers and verdict of one setting (SPEC 13; module
    docstring). Raises :class:`InputError` for bad gains or tolerances; a failed step, a
    Newton that does not converge or methods that disagree come back in the verdict."""
    check_setting(zd, setting)
    names = state_names(zd, setting.thrust)
    nz = setting.thrust.n_states
    d2 = zd.delta_zero_sq
    x0, lc = predicted_state(zd, setting.thrust)
    base = dict(setting=setting, names=tuple(names), delta_zero_sq=d2,
                predicted_zeta_star=lc.zeta_star if lc.exists else None,
                predicted_step_time=lc.step_time if lc.exists else None)
    if x0 is None:
        return Floquet(exists=False, verdict="no orbit", reason=f"no predicted orbit to start "
                       f"from: {lc.reason}", **base)
    P = PoincareMap(zd, setting)
    fp = newton(P, x0, tol=newton_tol)
    if not fp.converged:
        return Floquet(exists=True, verdict="undetermined",
                       reason=f"no full-order fixed point: Newton's method from the "
                              f"zero-dynamics prediction failed: {fp.reason}",
                       fixed_point=fp, simulations=P.calls, **base)
    B = section_basis(zd, fp.x, nz)
    fd = fd_jacobian(P, fp.x, B)
    var = variational_jacobian(zd, setting, fp.x)
    problems = []
    if not fd.ok:
        problems.append(f"finite differences failed: {fd.reason}")
    if not var.ok:
        problems.append(f"variational equations failed: {var.reason}")
    if problems:
        return Floquet(exists=True, verdict="undetermined", reason="; ".join(problems),
                       fixed_point=fp, fd=fd, variational=var, basis=B,
                       simulations=P.calls, **base)
    J = B.T @ var.DP @ B
    scale = max(1.0, float(np.max(np.abs(J))))
    agreement = float(np.max(np.abs(J - fd.J))) / scale
    mults, zi = multipliers(zd, J, fd.J, B, names, nz)
    mult_agree = max(abs(m.value - m.finite_difference) for m in mults)
    agree = agreement <= agreement_tol and mult_agree <= agreement_tol
    rho = max(m.modulus for m in mults)
    zdm = mults[zi].value if zi >= 0 else None
    T = var.T
    ref = output_reference(setting.kp, setting.kd, T)
    if not agree:
        verdict = "undetermined"
        reason = (f"the Jacobians disagree: finite differences vs variational equations "
                  f"differ by {agreement:.3g} (relative), multipliers by {mult_agree:.3g} "
                  f"(tolerance {agreement_tol:g}); spectral radius {rho:.6g}")
    elif abs(rho - 1.0) <= margin:
        verdict = "undetermined"
        reason = f"spectral radius {rho:.9g} is within {margin:g} of 1 (marginal)"
    elif rho < 1.0:
        verdict = "stable"
        reason = (f"spectral radius {rho:.6g} < 1: the full-order orbit is exponentially "
                  f"stable")
    else:
        verdict = "unstable"
        worst = mults[0]
        reason = (f"spectral radius {rho:.6g} > 1 (the {worst.kind} multiplier "
                  f"{_c(worst.value)})")
    return Floquet(exists=True, verdict=verdict, reason=reason, fixed_point=fp, fd=fd,
                   variational=var, J=J, J_fd=fd.J, basis=B, multipliers=tuple(mults),
                   agreement=agreement, multiplier_agreement=mult_agree, agree=agree,
                   spectral_radius=rho, zero_dynamics_multiplier=zdm, output_reference=ref,
                   simulations=P.calls, **base)


def _c(z: complex) -> str:
    return f"{z.real:.6g}" if z.imag == 0 else f"{z.real:.6g}{z.imag:+.6g}i"
