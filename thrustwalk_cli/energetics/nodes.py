"""The closed loop at the quadrature nodes of a full-order run's dense output (SPEC 15, 7),
for the energies along the run (:mod:`.run`): the run's integrator steps as one table
(:class:`Dense`: every integration piece's DOP853 interpolant, the compiled kernel's rows or
SciPy's), their ``NODES``-point Gauss-Lobatto nodes (:func:`lobatto_rule`), and the closed
loop's torques ``u`` [N m], ``q'``, thrust ``F`` [N], generalised force ``T`` [N m] and ``d_k
. p_k' = (B_F^T q')_k`` [m/s] at the interpolated states: for a compiled run through the
compiled kernel (:func:`evaluate_compiled`, ``step_stats.energy_nodes``: interpolation and
closed loop in one compiled loop, a step's first node shared with the end of the step before
it in its piece), else through ``ClosedLoop.law`` in NumPy (:func:`evaluate`); the same
equations (SPEC 7), the same values to rounding.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

NODES = 6  # Gauss-Lobatto nodes per integrator step (exact to degree 11)


@lru_cache(maxsize=4)
def lobatto_rule(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Lobatto nodes (ascending) and weights of ``[-1, 1]``, ``n`` points: the ends and
    the roots of ``P'_{n-1}``, weights ``2 / (n (n - 1) P_{n-1}(x)^2)``."""
    L = np.polynomial.legendre.Legendre.basis(n - 1)
    x = np.concatenate([[-1.0], np.sort(L.deriv().roots().real), [1.0]])
    w = 2.0 / (n * (n - 1) * L(x) ** 2)
    return x, w


# ----------------------------------------------------------------------------- dense output
class Dense:
    """The integrator steps of several integration pieces as one table: ``lo``, ``hi`` (the
    step clipped to its piece), ``seg`` and ``owner`` (the walking step's index) per row, and
    the interpolant's evaluation at ``(row, t)`` for many points at once."""

    def __init__(self, steps: list[tuple]):
        from ..simulation.stepper import DenseSolution

        pieces = [(i, piece) for i, ps in enumerate(steps) for piece in ps]
        # the compiled kernel's solutions: their rows as they are (no parts asked for)
        self.compiled = all(type(piece[3]) is DenseSolution for _, piece in pieces)
        got = ([(None, None, piece[3].rows) for _, piece in pieces] if self.compiled
               else [rows_of(piece[3]) for _, piece in pieces])
        self.piece_owner: list[int] = [i for i, _ in pieces]
        self.generic = any(R is None for _, _, R in got)
        if self.generic:
            self._generic(pieces, got)
            return
        # every piece has its rows: one table, the rows outside their piece dropped
        count = np.array([R.shape[0] for _, _, R in got], int)
        R = (np.concatenate([R for _, _, R in got]) if got
             else np.zeros((0, 2)))
        ta = np.repeat(np.array([pc[0] for _, pc in pieces], float), count)
        tb = np.repeat(np.array([pc[1] for _, pc in pieces], float), count)
        a = np.maximum(R[:, 0], ta)
        b = np.minimum(R[:, 1], tb)
        keep = b > a
        self.lo, self.hi = a[keep], b[keep]
        self.seg = np.repeat(np.array([pc[2] for _, pc in pieces], int), count)[keep]
        self.owner = np.repeat(np.array(self.piece_owner, int), count)[keep]
        bounds = np.r_[0, np.cumsum(count)]
        cum = np.r_[0, np.cumsum(keep)]
        kept = cum[bounds[1:]] - cum[bounds[:-1]]  # rows kept per piece
        first = np.r_[0, np.cumsum(kept)[:-1]]
        self.piece_rows = list(zip(first.tolist(), (first + kept - 1).tolist()))
        self.call = []
        R = R[keep]
        self.R = R
        self.start = np.zeros(R.shape[0], np.int64)  # 1 on a piece's first row
        self.start[first[kept > 0]] = 1
        n = (R.shape[1] - 2) // 8
        self.n = n
        self.t_old = R[:, 0]
        self.h = R[:, 1] - R[:, 0]
        self.y_old = R[:, 2:2 + n]
        self.F = R[:, 2 + n:].reshape(-1, 7, n)

    def _generic(self, pieces: list, got: list) -> None:
        """The table of pieces of which some are evaluated through their solution."""
        lo, hi, seg, owner, call = [], [], [], [], []
        self.piece_rows = []
        for (i, (ta, tb, sg, sol)), (t_old, t_new, _) in zip(pieces, got):
            a = np.maximum(t_old, ta)
            b = np.minimum(t_new, tb)
            keep = b > a
            first = len(lo)
            lo.extend(a[keep].tolist())
            hi.extend(b[keep].tolist())
            seg.extend([sg] * int(keep.sum()))
            owner.extend([i] * int(keep.sum()))
            call.extend([sol] * int(keep.sum()))
            self.piece_rows.append((first, len(lo) - 1))
        self.lo, self.hi = np.array(lo), np.array(hi)
        self.seg = np.array(seg, int)
        self.owner = np.array(owner, int)
        self.call = call

    def at(self, row: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The states (K, n) at times ``t`` on rows ``row`` (DOP853 dense output)."""
        if self.generic:
            out = None
            for j in np.unique(row):
                sel = row == j
                y = np.asarray(self.call[j](t[sel]), float).T
                if out is None:
                    out = np.empty((t.size, y.shape[1]))
                out[sel] = y
            return out if out is not None else np.zeros((0, 0))
        x = ((t - self.t_old[row]) / self.h[row])[:, None]
        y = np.zeros((t.size, self.n))
        F = self.F[row]
        for i, j in enumerate(range(6, -1, -1)):
            y += F[:, j]
            y *= x if i % 2 == 0 else 1.0 - x
        return y + self.y_old[row]

    def at_nodes(self, t: np.ndarray) -> np.ndarray:
        """:meth:`at` for times ``t`` (rows, K) on every row, K each: the states (rows * K,
        n), row by row (the same arithmetic, without gathering the rows K times)."""
        if self.generic:
            return self.at(np.repeat(np.arange(t.shape[0]), t.shape[1]), t.ravel())
        x = ((t - self.t_old[:, None]) / self.h[:, None])[..., None]
        y = np.zeros(t.shape + (self.n,))
        F = self.F
        for i, j in enumerate(range(6, -1, -1)):
            y += F[:, None, j]
            y *= x if i % 2 == 0 else 1.0 - x
        return (y + self.y_old[:, None]).reshape(-1, self.n)


def rows_of(sol) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(t_old, t_new, rows [t_old, t_new, y_old, F (7 n)])`` of a dense solution: the
    compiled kernel's ``DenseSolution`` or SciPy's ``OdeSolution`` of DOP853; rows None for
    another SciPy method (then evaluated through the solution itself)."""
    if hasattr(sol, "rows") and hasattr(sol, "t_old"):
        return sol.t_old, sol.t_new, sol.rows
    interps = getattr(sol, "interpolants", None)
    ts = np.asarray(sol.ts, float)
    t_old = np.minimum(ts[:-1], ts[1:])
    t_new = np.maximum(ts[:-1], ts[1:])
    if interps and all(getattr(i, "F", None) is not None and np.ndim(i.F) == 2
                       and np.shape(i.F)[0] == 7 for i in interps):
        R = np.array([np.concatenate([[i.t_old, i.t_old + i.h], i.y_old, np.ravel(i.F)])
                      for i in interps])
        return R[:, 0], R[:, 1], R
    return t_old, t_new, None


# ----------------------------------------------------------------------------- the closed loop
def evaluate(cl, X: np.ndarray, seg: np.ndarray, force: np.ndarray | None = None) -> dict:
    """The closed loop's torques ``u`` (K, N-1), ``q'``, thrust ``F`` (K, m), generalised force
    ``T`` (K,) and ``d_k . p_k' = (B_F^T q')_k`` (K, m) at states ``X`` in segments ``seg``
    (``ClosedLoop.law``, torque limits included; ``force``: the thrust per row instead)."""
    w = cl.law(X, seg) if force is None else cl.law(X, seg, force)
    dq, BF = w["dq"], w["B_F"]
    bt = np.einsum("kn,knm->km", dq, BF) if BF is not None else np.zeros((len(dq), 0))
    return {"u": w["u"], "dq": dq, "F": w["F"], "T": w["T"], "bt": bt}


def kernel_context(cl) -> tuple:
    """The compiled kernel and its parameters ``(fs, ip, par)`` for the closed loop ``cl``
    (``stepper.loop_context``)."""
    from ..simulation import stepper

    return stepper.loop_context(cl)


def evaluate_compiled(cl, dense: Dense, force: np.ndarray | None) -> dict | None:
    """:func:`evaluate` at every Gauss-Lobatto node of every row of ``dense`` (rows *
    NODES, row by row) through the compiled kernel (``step_stats.energy_nodes``: the dense
    output interpolated and the closed loop evaluated as :meth:`Dense.at_nodes` and
    ``ClosedLoop.law`` do, the equations of SPEC 7, to rounding; a row's first node shared
    with the end of the row before it in its piece). ``force``: the thrust per row (rows, m).
    None if the controller is singular at a node (then the NumPy path says how)."""
    from ..simulation import stepper

    mod, fs, ip, par = kernel_context(cl)
    N, nb, m = cl.N, cl.nb, cl.m
    w = stepper.work_array(fs, ip)
    R = dense.R.shape[0]
    cols = nb + N + 2 * m + 1
    V = np.empty((R, NODES, cols))
    F = (np.zeros((0, m)) if force is None
         else np.ascontiguousarray(force, float).reshape(R, m))
    x, _ = lobatto_rule(NODES)
    bad = mod.energy_nodes(dense.R, dense.lo, dense.hi, dense.seg.astype(np.int64),
                           dense.start, F, x, fs, ip, par, w, V)
    if bad >= 0:
        return None
    V = V.reshape(R * NODES, cols)
    o = nb + N + m
    return {"u": V[:, :nb], "dq": V[:, nb:nb + N], "F": V[:, nb + N:o], "T": V[:, o],
            "bt": V[:, o + 1:]}
