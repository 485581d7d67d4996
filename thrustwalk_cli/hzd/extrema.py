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
