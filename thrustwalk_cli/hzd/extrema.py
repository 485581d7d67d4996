"""Exact extrema of functions sampled on a grid: the grid locates the extremum, a vectorised
golden-section search polishes it between the neighbouring grid points, so that a reported
minimum or maximum is not limited by the grid spacing (SPEC 3, 5).

Every search works on a batch: one bracket ``[lo_i, hi_i]`` per entry, ``f`` maps an array of
abscissae (one per entry) to an array of values. Golden section needs no derivative and
converges for any function that is unimodal in the bracket (kinks allowed, e.g. at the knots
of a piecewise thrust schedule); the bracket shrinks by 0.618 per evaluation.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
ITERATIONS = 40  # bracket shrinks by 0.618^40 ~ 4e-9 of two grid spacings (~1e-11 rad)


def golden_min(f: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray,
               iters: int = ITERATIONS) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised golden-section minimisation of ``f`` on ``[lo_i, hi_i]`` (one bracket per
    entry); returns (argmin, min) of the last bracket's interior points."""
    a, b = np.asarray(lo, float).copy(), np.asarray(hi, float).copy()
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        left = fc <= fd
        na, nb = np.where(left, a, c), np.where(left, d, b)
        kx, kf = np.where(left, c, d), np.where(left, fc, fd)
        x = np.where(left, nb - GOLDEN * (nb - na), na + GOLDEN * (nb - na))
        fx = f(x)
        c, fc = np.where(left, x, kx), np.where(left, fx, kf)
        d, fd = np.where(left, kx, x), np.where(left, kf, fx)
        a, b = na, nb
    best = fc <= fd
    return np.where(best, c, d), np.where(best, fc, fd)


LOCAL_NODES = 9  # Chebyshev-Lobatto samples per bracket for golden_min_smooth


def golden_min_smooth(sample: Callable[[np.ndarray], np.ndarray],
                      objective: Callable[[np.ndarray], np.ndarray], lo: np.ndarray,
                      hi: np.ndarray, nodes: int = LOCAL_NODES, iters: int = ITERATIONS
                      ) -> np.ndarray:
    """Argmin of ``objective(g(x))`` on ``[lo_i, hi_i]`` for a quantity ``g`` that is smooth
    (analytic) on each bracket, such as the stance force between two grid points of one knot
    interval (SPEC 5). ``g`` is sampled once, at ``nodes`` Chebyshev-Lobatto points of every
    bracket (``sample(X)``, ``X`` of shape (k, nodes) -> (k, nodes, c)); the golden-section
    search (:func:`golden_min`) then runs on its barycentric polynomial interpolant. A bracket
    spans two grid spacings (~1e-3 of the step), so the interpolant of degree ``nodes - 1``
    agrees with ``g`` to rounding: the search costs one batch of ``nodes`` evaluations instead
    of one per iteration. ``objective`` may have kinks (``|F^h|/F^v``): it is applied to the
    interpolated components. Returns the argmin (k,); evaluate the exact quantity there."""
    a, b = np.asarray(lo, float), np.asarray(hi, float)
    j = np.arange(nodes)
    t = -np.cos(np.pi * j / (nodes - 1))  # ascending Lobatto nodes on [-1, 1]
    w = (-1.0) ** j
    w[0] *= 0.5
    w[-1] *= 0.5
    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    G = sample(mid[:, None] + half[:, None] * t)  # (k, nodes, c)
    scale = np.where(half > 0, half, 1.0)

    def interpolant(x: np.ndarray) -> np.ndarray:
        d = (x - mid)[:, None] / scale[:, None] - t
        hit = d == 0.0
        c = w / np.where(hit, 1.0, d)
        c = np.where(hit.any(axis=1)[:, None], hit.astype(float), c)
        return np.einsum("kn,kn...->k...", c, G) / c.sum(axis=1).reshape(
            (-1,) + (1,) * (G.ndim - 2))

    return golden_min(lambda x: objective(interpolant(x)), a, b, iters)[0]


def neighbours(x: np.ndarray, j: np.ndarray, segment: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """Bracket ``[lo, hi]`` around grid index ``j`` (an array): the neighbouring grid points,
    not crossing into another ``segment`` (e.g. a knot interval whose thrust differs; the
    grid then holds each knot once per side). ``x`` may be ascending or descending."""
    x = np.asarray(x, float)
    j = np.asarray(j, int)
    n = x.size
    seg = np.zeros(n, int) if segment is None else np.asarray(segment)
    jm, jp = np.clip(j - 1, 0, n - 1), np.clip(j + 1, 0, n - 1)
    lo = np.where((j > 0) & (seg[jm] == seg[j]), x[jm], x[j])
    hi = np.where((j < n - 1) & (seg[jp] == seg[j]), x[jp], x[j])
    return np.minimum(lo, hi), np.maximum(lo, hi)


def polish_min(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, values: np.ndarray,
               segment: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Minimum of ``f`` per batch entry: ``values`` (k, g) are ``f`` on the grid ``x`` (g,);
    the grid minimum of each row is refined by :func:`golden_min` between its neighbours.
    ``f`` takes one abscissa per entry (shape (k,)). Returns (argmin, min), each (k,); the
    result is never worse than the grid minimum."""
    values = np.atleast_2d(values)
    k = values.shape[0]
    j = np.argmin(values, axis=1)
    gx, gv = x[j], values[np.arange(k), j]
    lo, hi = neighbours(x, j, segment)
    xa, fa = golden_min(f, lo, hi)
    better = np.isfinite(fa) & (fa < gv)
    return np.where(better, xa, gx), np.where(better, fa, gv)


def polish_max(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, values: np.ndarray,
               segment: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Maximum counterpart of :func:`polish_min`: (argmax, max), each (k,)."""
    xa, fa = polish_min(lambda a: -f(a), x, -np.atleast_2d(values), segment)
    return xa, -fa


def peaks(values: np.ndarray, segment: np.ndarray | None = None, floor: float = -np.inf,
          most: int = 16) -> np.ndarray:
    """Indices of the local maxima of ``values`` (g,) sampled on a grid: the points not below
    a neighbour of the same ``segment`` (a segment's end has one neighbour; ties count, so a
    maximum between two equal samples is found from either), with value ``>= floor``; at most
    ``most``, the largest first. The grid maximum is always among them (it is the global
    maximum's best bracket when the peaks are unimodal between samples), so polishing every
    returned index by :func:`golden_min` between its :func:`neighbours` finds every peak that
    can exceed ``floor`` when ``floor`` is below the limit by more than the grid can miss."""
    v = np.asarray(values, float)
    n = v.size
    if n == 0:
        return np.zeros(0, int)
    seg = np.zeros(n, int) if segment is None else np.asarray(segment)
    w = np.where(np.isnan(v), -np.inf, v)
    same_l = np.r_[False, seg[1:] == seg[:-1]]
    same_r = np.r_[seg[:-1] == seg[1:], False]
    ok_l = ~same_l | (w >= np.r_[-np.inf, w[:-1]])
    ok_r = ~same_r | (w >= np.r_[w[1:], -np.inf])
    cand = np.flatnonzero(ok_l & ok_r & (w >= floor) & (w > -np.inf))
    top = int(np.argmax(w))
    if top not in cand:
        cand = np.r_[cand, top]
    return cand[np.argsort(-w[cand], kind="stable")][:most]


def grid_miss(values: np.ndarray, segment: np.ndarray | None = None) -> float:
    """How far a smooth function sampled on a grid can exceed its samples between them: the
    largest second difference within a segment (``h^2 |f''|``, eight times the parabola's
    overshoot ``h^2 |f''| / 8``; non-finite samples ignored). A peak whose sample lies lower
    than the limit by more than this cannot reach the limit between samples."""
    v = np.asarray(values, float)
    if v.size < 3:
        return 0.0
    seg = np.zeros(v.size, int) if segment is None else np.asarray(segment)
    d2 = np.abs(v[2:] - 2.0 * v[1:-1] + v[:-2])
    ok = (seg[2:] == seg[1:-1]) & (seg[1:-1] == seg[:-2]) & np.isfinite(d2)
    return float(d2[ok].max(initial=0.0))
