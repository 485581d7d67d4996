"""Floquet multipliers of the full-order closed loop with thruster states (SPEC 13).

For one setting (thrust model, gains): the fixed point of the Poincare map by Newton from the
zero-dynamics prediction, its Jacobian on the section two ways (central differences with the
compiled simulation, variational equations with saltation), their agreement, the ``n - 1``
multipliers (eigenvalues of the variational Jacobian, the more accurate; the finite-difference
ones beside them), each with its eigenvector's dominant components and its participation in
the thruster states, the multiplier of the zero dynamics identified and compared with
``delta_zero^2`` (SPEC 3), the spectral radius and a verdict that is never better than the
evidence:

* ``stable`` / ``unstable``: spectral radius below / above 1 by more than its error bar, the
  Newton residual within its tolerance and the two methods' multipliers agreeing;
* ``undetermined``: Newton did not converge, a Jacobian failed, the multipliers disagree, or
  the spectral radius is within its error bar of 1; the reason says what to try;
* ``no orbit``: the zero dynamics predicts no periodic orbit to start from.

Agreement is judged on the multipliers, the quantity the verdict is about (the largest entry
difference of the two Jacobians is reported beside it, not judged). Multiplier ``j`` of the
variational Jacobian, ``lambda_j``, is matched with the nearest eigenvalue ``mu_j`` of the
finite-difference Jacobian; their difference ``d_j = |lambda_j - mu_j|`` must be at most

    tol_j = max(AGREEMENT_FLOOR, SAFETY * e_j, E),    AGREEMENT_FLOOR = 1e-6, SAFETY = 10,

with ``e_j`` the finite-difference Jacobian's own error estimate carried to that multiplier:
``e_j = |mu_j - mu'_j|``, ``mu'_j`` the matching eigenvalue of the finite-difference Jacobian
at the neighbouring step that gave the entry-wise estimate (:class:`FDJacobian`). This is the
step-to-step test of the entries applied to the eigenvalues, so an ill-conditioned or
defective multiplier (a critically damped thruster's double eigenvalue, whose perturbation
grows like the square root of the entries') gets a wider band and a well-conditioned one a
tight band, with no first-order condition number to fail. ``E`` is the finite-difference
Jacobian's own entry error estimate (:class:`FDJacobian` ``error``, the largest entry change to
the neighbouring step): a multiplier is not asked to agree more closely than the entries it
is computed from are known (a tiny, defective multiplier, such as the double ``exp(-20 T)`` of
critically damped gains ``kp = 400``, ``kd = 40``, can move by about that much between the
two methods while its own step-to-step change stays small). Without an estimate (too few
successful steps) ``tol_j = AGREEMENT_FLOOR``; a given ``agreement_tol`` replaces every
``tol_j``. The spectral radius ``rho`` (of the variational Jacobian) is then known to within

    u = max(margin, max_j (d_j + SAFETY * e_j))

(the distance to the finite-difference multiplier plus that one's error), and is called
undetermined when ``|rho - 1| <= u``.

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

from ..errors import InputError, check_number
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

AGREEMENT_FLOOR = 1e-6  # [1] least tolerance on |lambda_var - lambda_fd| (module docstring)
SAFETY = 10.0  # [1] factor on the finite-difference error estimate of a multiplier
MARGIN = 1e-6  # [1] a spectral radius within max(this, its error bar) of 1 is undetermined
AGREEMENT_RULE = ("per multiplier j: |lambda_var - lambda_fd| <= tol_j = max(1e-6, 10 e_j, "
                  "E), e_j = |lambda_fd(h) - lambda_fd(h')| the change of the finite-difference "
                  "multiplier between the chosen step h and the neighbouring step h' that gave "
                  "the Jacobian's error estimate E (its largest entry change; tol_j = 1e-6 "
                  "without an estimate; a given "
                  "agreement_tol replaces every tol_j); spectral radius undetermined within "
                  "max(1e-6, max_j (d_j + 10 e_j)) of 1")


@dataclass(frozen=True)
class Multiplier:
    """One Floquet multiplier [1]: ``value`` (complex), its modulus, ``kind``
    (``zero dynamics``, ``outputs`` or ``thruster``), ``dominant``: the largest components
    of its unit eigenvector in ``x = (q, q', z)`` as (name, modulus), ``thruster_share``: its
    participation factor in the thruster states (0..1), ``alignment``: |cos| of the angle
    between its eigenvector and the zero-dynamics direction ``(0, Phi(alpha_f), 0)``;
    ``finite_difference``: the matching multiplier of the finite-difference Jacobian;
    ``fd_error``: that one's error estimate ``e_j`` (None without one) and ``tolerance``:
    ``tol_j``, the largest accepted ``difference`` (module docstring)."""

    value: complex
    kind: str
    dominant: tuple[tuple[str, float], ...]
    thruster_share: float
    alignment: float
    finite_difference: complex
    fd_error: float | None = None
    tolerance: float = AGREEMENT_FLOOR

    @property
    def modulus(self) -> float:
        """``|lambda|`` [1] (SPEC 13: below 1, a deviation along it decays from step to step)."""
        return abs(self.value)

    @property
    def difference(self) -> float:
        """``|lambda_var - lambda_fd|`` [1]."""
        return abs(self.value - self.finite_difference)

    @property
    def agrees(self) -> bool:
        """The variational and finite-difference values agree: ``difference <= tolerance`` (SPEC
        13)."""
        return self.difference <= self.tolerance


@dataclass(frozen=True)
class Floquet:
    """The analysis of one setting (module docstring). ``exists`` false: no predicted orbit
    (``reason``). ``agreement``: ``max |J_fd - J_var| / max(1, max |J|)`` (reported, not
    judged); ``multiplier_agreement``: the largest difference between matched multipliers;
    ``agree``: every multiplier within its tolerance; ``tolerance_source``: ``scaled`` (from
    the finite-difference error estimate), ``floor`` (no estimate) or ``given``
    (``agreement_tol``); ``agreement_tol``: the given tolerance or None; ``radius_error``: the
    error bar ``u`` of the spectral radius (module docstring)."""

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
    tolerance_source: str | None = None
    agreement_tol: float | None = None
    radius_error: float | None = None
    spectral_radius: float | None = None
    zero_dynamics_multiplier: complex | None = None
    output_reference: float | None = None
    simulations: int = 0

    @property
    def stable(self) -> bool:
        """The verdict is ``stable`` (SPEC 13; ``verdict`` and ``reason`` say more)."""
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
                names: list[str], nz: int, top: int = 3, J_nb: np.ndarray | None = None,
                agreement_tol: float | None = None
                ) -> tuple[list[Multiplier], int]:
    """Multipliers of ``J`` sorted by modulus (largest first), classified, each with its
    finite-difference match, that one's error estimate from ``J_nb`` (the finite-difference
    Jacobian at the neighbouring step; None: no estimate) and its tolerance ``max(1e-6, 10
    e_j, E)`` with ``E = max |J_fd - J_nb|`` (module docstring); returns them and the index
    of the zero-dynamics one (-1 if none is a walker mode)."""
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
    dom = [_dominant(lam, full, j, top) for j in range(k)]
    for j, (_, _, basis) in enumerate(dom):
        if basis is not None:  # a repeated multiplier: its eigenspace's alignment
            align[j] = float(np.linalg.norm(basis.conj().T @ vz))
    walker = [j for j in range(k) if share[j] < 0.5]
    zd_index = max(walker, key=lambda j: align[j]) if walker else -1
    fdv = _match(lam, np.linalg.eigvals(J_fd))
    err = (np.abs(fdv - _match(fdv, np.linalg.eigvals(J_nb))) if J_nb is not None
           else np.full(k, np.nan))
    entries = float(np.max(np.abs(J_fd - J_nb))) if J_nb is not None else 0.0
    out = []
    for j in range(k):
        comp, idx, _ = dom[j]
        kind = ("zero dynamics" if j == zd_index else "thruster" if share[j] >= 0.5
                else "outputs")
        e = float(err[j]) if np.isfinite(err[j]) else None
        tol = (float(agreement_tol) if agreement_tol is not None
               else AGREEMENT_FLOOR if e is None else max(AGREEMENT_FLOOR, SAFETY * e, entries))
        out.append(Multiplier(complex(lam[j]), kind,
                              tuple((names[i], float(comp[i])) for i in idx),
                              float(share[j]), float(align[j]), complex(fdv[j]), e, tol))
    return out, zd_index


REPEATED = 1e-6  # multipliers this close (relative to max(1, |lambda|)) share an eigenspace


def _dominant(lam: np.ndarray, full: np.ndarray, j: int, top: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The components' weights of multiplier ``j``'s mode (``full``: the unit eigenvectors
    in the state's coordinates, columns) and the ``top`` largest. A repeated multiplier (two
    identical thrusters) has an eigenspace, in which any basis is an eigenvector basis: its
    weights are those of the eigenspace, ``sqrt(P_ii)`` for ``P`` the orthogonal projector
    onto it (the row norms of an orthonormal basis), the same for each multiplier of the
    group and for every basis, ordered on 9 significant digits (ties in the order of the
    state's components); also that orthonormal basis (None for a simple multiplier), whose
    projection of a vector is the eigenspace's alignment with it."""
    near = np.flatnonzero(np.abs(lam - lam[j]) <= REPEATED * max(1.0, abs(lam[j])))
    if near.size == 1:
        comp = np.abs(full[:, j])
        return comp, np.argsort(-comp, kind="stable")[:top], None
    q, _ = np.linalg.qr(full[:, near])
    comp = np.sqrt(np.sum(np.abs(q) ** 2, axis=1))
    key = np.array([float(f"{c:.9g}") for c in comp])
    return comp, np.argsort(-key, kind="stable")[:top], q


def output_reference(kp: float, kd: float, T: float) -> float:
    """``exp(max Re(lambda) T)``, ``lambda`` the roots of ``s^2 + K_d s + K_p`` [1]: the order
    of the output dynamics' contraction over one step (SPEC 13)."""
    roots = np.roots([1.0, kd, kp])
    return float(np.exp(np.max(roots.real) * T))


def check_agreement_tol(agreement_tol: float | None) -> None:
    """``agreement_tol`` [1]: None (the scaled rule) or a finite number > 0."""
    v = check_number("agreement_tol", agreement_tol, optional=True)  # a finite number
    if v is not None and not v > 0:
        raise InputError.param("agreement_tol", f"must be a finite number > 0 (got {v:g})")


def _accuracy(setting: Setting) -> str:
    return (f"tighter `rtol`/`atol` (now {setting.rtol:g}/{setting.atol:g}: the compiled "
            f"simulation behind Newton's method and the finite differences)")


def _newton_advice(fp: FixedPoint, setting: Setting) -> str:
    """What to try when Newton's method did not give a fixed point."""
    if fp.reason.startswith("no convergence"):
        return (f"try {_accuracy(setting)}, whose noise floors the residual; or other gains "
                f"`kp`/`kd`")
    if "singular" in fp.reason:
        return "try other gains `kp`/`kd` or another thrust setting (a multiplier is at 1)"
    return ("the closed loop cannot complete the step from there: try another setting "
            "(`thrust`, the thruster's dynamics, gains `kp`/`kd`)")


def analyse(zd: ZeroDynamics, setting: Setting, *, newton_tol: float = 1e-9,
            agreement_tol: float | None = None, margin: float = MARGIN) -> Floquet:
    """Fixed point, Jacobians, multipliers and verdict of one setting (SPEC 13; module
    docstring). ``agreement_tol`` [1]: the largest accepted difference between matched
    multipliers of the two methods (default None: ``max(1e-6, 10 e_j, E)`` per multiplier,
    from the finite-difference error estimates); ``margin`` [1]: the least error bar of the spectral
    radius. Raises :class:`InputError` for bad gains, tolerances or ``agreement_tol``; a
    failed step, a Newton that does not converge or methods that disagree come back in the
    verdict, whose reason then says what to try."""
    check_setting(zd, setting)
    check_agreement_tol(agreement_tol)
    names = state_names(zd, setting.thrust)
    nz = setting.thrust.n_states
    d2 = zd.delta_zero_sq
    x0, lc = predicted_state(zd, setting.thrust)
    base = dict(setting=setting, names=tuple(names), delta_zero_sq=d2,
                predicted_zeta_star=lc.zeta_star if lc.exists else None,
                predicted_step_time=lc.step_time if lc.exists else None,
                agreement_tol=None if agreement_tol is None else float(agreement_tol))
    if x0 is None:
        return Floquet(exists=False, verdict="no orbit", reason=f"no predicted orbit to start "
                       f"from: {lc.reason}", **base)
    P = PoincareMap(zd, setting)
    fp = newton(P, x0, tol=newton_tol)
    if not fp.converged:
        return Floquet(exists=True, verdict="undetermined",
                       reason=f"no full-order fixed point: Newton's method from the "
                              f"zero-dynamics prediction failed: {fp.reason}; "
                              f"{_newton_advice(fp, setting)}",
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
        return Floquet(exists=True, verdict="undetermined",
                       reason="; ".join(problems) + f"; try {_accuracy(setting)}, or another "
                       f"setting (`thrust`, gains `kp`/`kd`) if the orbit is at the edge of "
                       f"what the closed loop can walk",
                       fixed_point=fp, fd=fd, variational=var, basis=B,
                       simulations=P.calls, **base)
    J = B.T @ var.DP @ B
    scale = max(1.0, float(np.max(np.abs(J))))
    agreement = float(np.max(np.abs(J - fd.J))) / scale
    mults, zi = multipliers(zd, J, fd.J, B, names, nz, J_nb=fd.neighbour,
                            agreement_tol=agreement_tol)
    source = ("given" if agreement_tol is not None
              else "scaled" if fd.neighbour is not None else "floor")
    mult_agree = max(m.difference for m in mults)
    agree = all(m.agrees for m in mults)
    rho = max(m.modulus for m in mults)
    u = max([margin] + [m.difference + SAFETY * (m.fd_error or 0.0) for m in mults])
    zdm = mults[zi].value if zi >= 0 else None
    T = var.T
    ref = output_reference(setting.kp, setting.kd, T)
    worst = max(mults, key=lambda m: m.difference / m.tolerance)
    tol_text = (f"tolerance {worst.tolerance:.2g}, " + (
        "given" if source == "given" else
        f"max(1e-6, 10 x its finite-difference error estimate {worst.fd_error:.2g}, the "
        f"finite-difference entries' error estimate {fd.error:.2g})"
        if source == "scaled" else "1e-6: no finite-difference error estimate"))
    if not agree:
        verdict = "undetermined"
        dist = abs(rho - 1.0)
        wider = (f"or, if a disagreement of {mult_agree:.2g} is acceptable for a radius "
                 f"{dist:.2g} from 1, an `agreement_tol` of at least {mult_agree:.2g}"
                 if dist > mult_agree else
                 "a larger `agreement_tol` cannot help: the radius is within the "
                 "disagreement of 1")
        reason = (f"the two methods disagree: the {worst.kind} multiplier is "
                  f"{_c(worst.value, 10)} by the variational equations and "
                  f"{_c(worst.finite_difference, 10)} by finite "
                  f"differences, {worst.difference:.2g} apart ({tol_text}); Jacobian entries "
                  f"differ by {agreement:.2g} (relative); spectral radius {rho:.6g}: try "
                  f"{_accuracy(setting)}; {wider}")
    elif abs(rho - 1.0) <= u:
        verdict = "undetermined"
        reason = (f"spectral radius {rho:.9g} is within its error bar {u:.2g} of 1 (marginal; "
                  f"the error bar is max({margin:g}, multiplier disagreement + 10 x "
                  f"finite-difference error)): try {_accuracy(setting)} to shrink the error "
                  f"bar; if the radius stays at 1 the orbit is at a bifurcation, which other "
                  f"gains `kp`/`kd` or another thrust setting move")
    elif rho < 1.0:
        verdict = "stable"
        reason = (f"spectral radius {rho:.6g} < 1 (clear of 1 by {1 - rho:.3g}, error bar "
                  f"{u:.2g}): the full-order orbit is exponentially stable")
    else:
        verdict = "unstable"
        top = mults[0]
        reason = (f"spectral radius {rho:.6g} > 1 (the {top.kind} multiplier "
                  f"{_c(top.value)}; error bar {u:.2g})")
    return Floquet(exists=True, verdict=verdict, reason=reason, fixed_point=fp, fd=fd,
                   variational=var, J=J, J_fd=fd.J, basis=B, multipliers=tuple(mults),
                   agreement=agreement, multiplier_agreement=mult_agree, agree=agree,
                   tolerance_source=source, radius_error=u,
                   spectral_radius=rho, zero_dynamics_multiplier=zdm, output_reference=ref,
                   simulations=P.calls, **base)


def _c(z: complex, digits: int = 6) -> str:
    return (f"{z.real:.{digits}g}" if z.imag == 0
            else f"{z.real:.{digits}g}{z.imag:+.{digits}g}i")
