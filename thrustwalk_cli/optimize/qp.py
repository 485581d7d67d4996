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


# ----------------------------------------------------------------- general strictly convex QP
class ConvexQP:
    """``min 1/2 x^T H x + c^T x`` s.t. ``A x <= b`` (and optionally ``a_eq x = b_eq``) for a
    fixed positive definite ``H``, fixed ``A`` and ``a_eq``, solved many times for new ``c``,
    ``b``, ``b_eq`` (a controller's per-step QP, SPEC 11). Exact and finite.

    With ``H = L L^T`` and ``y = L^T x + L^-1 c`` the objective is ``1/2 |y|^2`` up to a
    constant and ``A x <= b`` becomes ``G y <= b + G L^-1 c`` with ``G = A L^-T``; the equality
    ``g_e y = h_e`` is eliminated on its null space (``y = y_p + N z``, ``y_p`` its minimum-norm
    solution, so ``|y|^2 = |y_p|^2 + |z|^2``). What remains is a least-distance problem
    ``min |z|`` s.t. ``M z <= m``, solved exactly by Lawson-Hanson NNLS as in :func:`ldp_qp`.
    Rows are generated: the LDP is solved on a working set (the rows active at the previous
    solve, then the most violated rows of all), and rows violated by its solution are added
    until none is; the solution of the working set then satisfies every row, so it is the
    optimum of the whole problem (the working set's feasible set contains the whole one).
    An incompatible working set proves the whole problem infeasible; a working set whose
    NNLS solution violates one of its own rows (round-off at an almost empty feasible set,
    where NNLS no longer tells incompatible rows apart) is reported the same way: never a
    point that violates a row.
    """

    def __init__(self, H: np.ndarray, A: np.ndarray, a_eq: np.ndarray | None = None):
        H = np.asarray(H, float)
        self.n = H.shape[0]
        self.L = np.linalg.cholesky(H)
        A = np.asarray(A, float).reshape(-1, self.n)
        self.A = A
        G = np.linalg.solve(self.L, A.T).T  # A L^-T
        self.G = G
        self.eq = a_eq is not None
        if self.eq:
            ge = np.linalg.solve(self.L, np.asarray(a_eq, float).ravel())  # (L^-1 a_eq^T)^T
            self.ge = ge
            self.ge2 = float(ge @ ge)
            self.N = null_space(ge[None, :])
        else:
            self.N = np.eye(self.n)
        M = G @ self.N
        norms = np.linalg.norm(M, axis=1)
        self.const = norms <= 1e-12 * max(1.0, float(norms.max(initial=0.0)))
        self.any_const = bool(self.const.any())
        self.scale = np.where(self.const, 1.0, norms)
        self.rows = np.flatnonzero(~self.const)
        self.Mr = np.ascontiguousarray((M / self.scale[:, None])[self.rows])
        self.Linv = np.linalg.inv(self.L)
        self.LTinv = self.Linv.T.copy()
        self.working: np.ndarray = np.zeros(0, int)  # positions in ``rows``

    def solve(self, c: np.ndarray, b: np.ndarray, b_eq: float | None = None,
              tol: float = 1e-10) -> tuple[np.ndarray | None, np.ndarray]:
        """The optimum ``x`` (None when the constraints are incompatible) and the indices of
        the rows of ``A`` active at it (slack within 1e-9 of the row's scale)."""
        Lc = self.Linv @ np.asarray(c, float)
        h = np.asarray(b, float) + self.G @ Lc
        if self.eq:
            he = float(b_eq) + float(self.ge @ Lc)
            yp = self.ge * (he / self.ge2)
            m = (h - self.G @ yp) / self.scale  # rows: M z <= m (unit-norm rows of M)
        else:
            yp = None
            m = h / self.scale
        if self.any_const and np.any(m[self.const] < -tol * (1.0 + np.abs(m[self.const]))):
            return None, np.zeros(0, int)
        mr = m[self.rows]
        thr = tol * (1.0 + np.abs(mr))
        work = self.working
        z = self._ldp(work, mr) if work.size else np.zeros(self.N.shape[1])
        if z is None:  # the previous active set no longer fits: start afresh
            work, z = np.zeros(0, int), np.zeros(self.N.shape[1])
        for _ in range(len(mr) + 1):
            viol = self.Mr @ z - mr
            bad = np.flatnonzero(viol > thr)
            if bad.size == 0:
                break
            bad = bad[~np.isin(bad, work)]
            if bad.size == 0:  # the working set's solution violates its own rows
                self.working = np.zeros(0, int)
                return None, np.zeros(0, int)
            if bad.size > 8:
                bad = bad[np.argpartition(-viol[bad], 8)[:8]]
            work = np.concatenate([work, bad])
            z = self._ldp(work, mr)
            if z is None:
                self.working = np.zeros(0, int)
                return None, np.zeros(0, int)
        else:  # every row added and still violated: no optimum found
            self.working = np.zeros(0, int)
            return None, np.zeros(0, int)
        y = self.N @ z if yp is None else yp + self.N @ z
        x = self.LTinv @ (y - Lc)
        slack = mr - self.Mr @ z
        act = np.flatnonzero(slack <= 1e-9 * (1.0 + np.abs(mr)))
        self.working = act
        return x, self.rows[act]

    def _ldp(self, work: np.ndarray, m: np.ndarray) -> np.ndarray | None:
        """``min |z|`` s.t. ``M[work] z <= m[work]`` (positions in the non-constant rows) by
        NNLS (Lawson & Hanson, ch. 23); None when the rows are incompatible."""
        Mw, mw = self.Mr[work], m[work]
        if self.N.shape[1] == 0:
            return np.zeros(0) if np.all(mw >= -1e-12) else None
        E = np.vstack([-Mw.T, -mw[None, :]])  # rows of "-M z >= -m" as columns
        f = np.zeros(E.shape[0])
        f[-1] = 1.0
        u, _ = nnls(E, f, maxiter=50 * E.shape[1] + 50)
        r = E @ u - f
        if abs(r[-1]) < 1e-12:
            return None
        return -r[:-1] / r[-1]
