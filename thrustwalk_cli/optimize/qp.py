"""Exact solvers of the minimum-effort QP of SPEC 6: ``min sum_j w_j x_j^2`` subject to
``A x <= b`` and one equality ``a_eq x = b_eq`` (``w_j > 0``).

- :func:`lp_feasible`: feasibility by a linear programme (HiGHS), with a feasible point;
- :func:`ldp_qp`: the QP as a least-distance problem solved by Lawson-Hanson NNLS (exact, finite);
- :func:`active_set_qp`: a primal active-set method, an independent solver of the same QP;
- :func:`kkt`: KKT residuals and multipliers of a candidate solution.

Rows are scaled to unit norm first (:func:`normalise_rows`); rows with ``A ~ 0`` are constant
conditions ``0 <= b``. The problem assembly is in :mod:`thrustwalk_cli.optimize`.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import null_space
from scipy.optimize import linprog, nnls

from ..errors import ComputationError


def normalise_rows(A: np.ndarray, b: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit-norm rows; returns (A, b, norms, constant-row mask) (constant rows: A ~ 0)."""
    norms = np.linalg.norm(A, axis=1)
    const = norms <= 1e-12 * max(1.0, float(norms.max(initial=0.0)))
    safe = np.where(const, 1.0, norms)
    return A / safe[:, None], b / safe, safe, const


def lp_feasible(A: np.ndarray, b: np.ndarray, a_eq: np.ndarray | None, b_eq: float | None
                ) -> tuple[bool, np.ndarray | None]:
    """Exact feasibility of ``A x <= b, a_eq x = b_eq`` by HiGHS (status 0 or 2)."""
    An, bn, _, const = normalise_rows(A, b)
    if np.any(bn[const] < -1e-9 * (1 + np.abs(b[const]))):
        return False, None
    n = A.shape[1]
    kw = {}
    if a_eq is not None:
        s = np.linalg.norm(a_eq) or 1.0
        kw = {"A_eq": (a_eq / s)[None, :], "b_eq": [b_eq / s]}
    res = linprog(np.zeros(n), A_ub=An[~const], b_ub=bn[~const], bounds=[(None, None)] * n,
                  method="highs", **kw)
    if res.status == 0:
        return True, res.x
    if res.status == 2:
        return False, None
    raise ComputationError(f"linear programme (HiGHS) failed: {res.message}")


def ldp_qp(A: np.ndarray, b: np.ndarray, a_eq: np.ndarray, b_eq: float, w: np.ndarray
           ) -> np.ndarray:
    """``min sum w x^2`` s.t. ``A x <= b``, ``a_eq x = b_eq`` as a least-distance problem.

    ``y = sqrt(w) x``; ``y = y_p + N z`` with ``y_p`` the minimum-norm solution of the equality and
    ``N`` an orthonormal basis of its null space (so ``|y|^2 = |y_p|^2 + |z|^2``); then
    ``min |z|`` s.t. ``G z >= h`` is solved exactly by NNLS (Lawson & Hanson, ch. 23):
    ``u = argmin_{u >= 0} |[G^T; h^T] u - e_last|``, ``r = [G^T; h^T] u - e_last``,
    ``z = -r[:-1] / r[-1]``. Assumes the problem is feasible (checked by :func:`lp_feasible`).
    """
    s = 1.0 / np.sqrt(w)
    As = A * s
    ae = a_eq * s
    nrm2 = float(ae @ ae)
    if nrm2 == 0.0:
        yp, N = np.zeros(len(w)), np.eye(len(w))
    else:
        yp = ae * b_eq / nrm2
        N = null_space(ae[None, :])
    G = -(As @ N)
    h = -(b - As @ yp)
    Gn, hn, _, const = normalise_rows(-G, -h)  # rows of "-G z <= -h"
    Gn, hn = -Gn[~const], -hn[~const]
    if N.shape[1] == 0 or len(hn) == 0:
        return s * yp
    E = np.vstack([Gn.T, hn[None, :]])
    f = np.zeros(E.shape[0])
    f[-1] = 1.0
    u, _ = nnls(E, f, maxiter=50 * E.shape[1])
    r = E @ u - f
    if abs(r[-1]) < 1e-12:
        raise ComputationError("least-distance QP: NNLS reports incompatible constraints "
                               "although the LP found a feasible point")
    zz = -r[:-1] / r[-1]
    return s * (yp + N @ zz)


def active_set_qp(A: np.ndarray, b: np.ndarray, a_eq: np.ndarray, b_eq: float,
                  w: np.ndarray, x0: np.ndarray, max_iter: int = 500) -> np.ndarray:
    """Primal active-set method (Nocedal & Wright, alg. 16.3) for ``min sum w x^2`` from a
    feasible ``x0``; an independent exact solver of the same QP as :func:`ldp_qp`."""
    An, bn, _, const = normalise_rows(A, b)
    An, bn = An[~const], bn[~const]
    H = np.diag(2.0 * w)
    x = np.array(x0, float)
    tol = 1e-10 * (1 + np.abs(bn))
    work: list[int] = []
    for i in np.argsort(bn - An @ x):
        if bn[i] - An[i] @ x > tol[i] or len(work) >= len(w) - 1:
            break
        cand = np.vstack([a_eq[None, :], An[work + [int(i)]]])
        if np.linalg.matrix_rank(cand) == cand.shape[0]:
            work.append(int(i))
    for _ in range(max_iter):
        Aw = np.vstack([a_eq[None, :], An[work]])
        k = Aw.shape[0]
        K = np.block([[H, Aw.T], [Aw, np.zeros((k, k))]])
        rhs = np.concatenate([-H @ x, np.zeros(k)])
        sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
        p, lam = sol[:len(w)], sol[len(w) + 1:]
        if np.linalg.norm(p) <= 1e-12 * (1 + np.linalg.norm(x)):
            if len(lam) == 0 or lam.min() >= -1e-12 * (1 + np.abs(lam).max()):
                return x
            work.pop(int(np.argmin(lam)))
            continue
        Ap = An @ p
        slack = bn - An @ x
        mask = Ap > 1e-14
        mask[work] = False
        steps = np.where(mask, slack / np.where(mask, Ap, 1.0), np.inf)
        j = int(np.argmin(steps))
        t = min(1.0, max(0.0, steps[j]))
        x = x + t * p
        if steps[j] < 1.0:
            work.append(j)
    raise ComputationError(f"active-set QP did not converge in {max_iter} iterations")


def kkt(A: np.ndarray, b: np.ndarray, a_eq: np.ndarray, b_eq: float, w: np.ndarray,
        x: np.ndarray, act_tol: float = 1e-7) -> dict:
    """KKT check of ``x`` for ``min sum w x^2``: multipliers ``lambda >= 0`` on the active rows
    and ``nu`` on the equality from NNLS of ``2 W x + nu a_eq + A_act^T lambda = 0``.

    Returns residuals (stationarity relative to ``|2 W x|``, primal feasibility of the
    normalised rows, complementarity), the active rows and their multipliers in the original
    row scaling (``d objective / d b_i``)."""
    An, bn, norms, const = normalise_rows(A, b)
    slack = bn - An @ x
    slack[const] = bn[const]
    active = np.flatnonzero((~const) & (slack <= act_tol * (1 + np.abs(bn))))
    grad = 2.0 * w * x
    M = np.column_stack([An[active].T, a_eq, -a_eq]) if len(active) else \
        np.column_stack([a_eq, -a_eq])
    mult, _ = nnls(M, -grad, maxiter=50 * M.shape[1])
    res = np.linalg.norm(M @ mult + grad)
    scale = max(np.linalg.norm(grad), 1e-12)
    lam = mult[:len(active)]
    return {
        "stationarity_relative": float(res / scale) if np.linalg.norm(grad) > 1e-12 else
        float(res),
        "primal_infeasibility": float(max(0.0, -slack.min(initial=0.0))),
        "equality_residual": float(abs(a_eq @ x - b_eq) / (np.linalg.norm(a_eq) or 1.0)),
        "complementarity": float(np.max(lam * np.abs(slack[active]), initial=0.0)),
        "min_multiplier": float(lam.min(initial=0.0)),
        "active": active, "multipliers": lam / norms[active],
        "nu": float(mult[-2] - mult[-1]),
    }
