"""Integrals of ``|f|`` and ``max(0, f)`` over an interval from samples of ``f`` at Chebyshev-
Lobatto nodes (SPEC 15: the kinks of positive and absolute work and of clipped electrical
power, :mod:`.orbit`): piecewise between the roots of the samples' Chebyshev interpolant,
each root isolated between the nodes with a proof (no root, or exactly one, on each gap,
from bounds of the interpolant's second derivative; gaps without a proof halved) and
polished (:func:`abs_and_positive`). Everything is vectorised over the rows (the orbits of a
batch, their joints and thrusters) with NumPy.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.polynomial import chebyshev as C

from ..hzd.quadrature import _dct_matrix

SPLITS = 12  # halvings of a gap of the nodes to isolate the roots in it
SMALL = 256  # at most this many points: Chebyshev series evaluated without a recurrence


def _closed_form_tables(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``T_k'(x_i)`` (nodes, k < n) and ``T_j(x_i)`` (j < n - 2, nodes) at the ``n`` ascending
    Lobatto nodes ``x_i = cos(theta_i)``, ``theta_i = pi (n - 1 - i) / (n - 1)``:
    ``T_j = cos(j theta)``, ``T_k' = k sin(k theta) / sin(theta)``, at the ends ``T_k'(1) =
    k^2``, ``T_k'(-1) = (-1)^(k+1) k^2``; the angles ``k theta_i`` reduced exactly, in integers
    (``pi (k (n - 1 - i) mod 2 (n - 1)) / (n - 1)``), so that each value is good to rounding."""
    m = n - 1
    k = np.arange(n, dtype=float)
    kt = np.pi * (np.outer(np.arange(m, -1, -1), np.arange(n)) % (2 * m)) / m
    sin = np.sin(np.pi * np.arange(m, -1, -1) / m)
    dT = np.empty((n, n))
    dT[1:-1] = k * np.sin(kt[1:-1]) / sin[1:-1, None]
    dT[0] = (-1.0) ** (k + 1.0) * k * k  # x = -1
    dT[-1] = k * k  # x = 1
    T2 = np.cos(kt[:, :n - 2]).T
    return dT, T2


def derivative_matrix(n: int) -> np.ndarray:
    """``D`` (n, n) with ``T_k' = sum_j D[k, j] T_j``: ``2 k`` for ``j < k`` with ``k - j``
    odd, ``k`` at ``j = 0`` (odd ``k``), else 0."""
    k = np.arange(n)[:, None]
    j = np.arange(n)[None, :]
    D = np.where((j < k) & ((k - j) % 2 == 1), 2.0 * k, 0.0)
    D[:, 0] *= 0.5
    return D


@lru_cache(maxsize=16)
def node_tables(n: int) -> tuple[np.ndarray, ...]:
    """For ``n`` ascending Lobatto nodes ``x_i`` of [-1, 1]: the nodes, the gaps ``h_i =
    x_{i+1} - x_i``, the least ``sin(theta)`` on each gap (``x = cos(theta)``), the columns
    ``(k^2, k, k^2 (k^2 - 1) / 3)`` of :func:`second_derivative_bound` as rows (3, n), the
    matrix (3n+1, n) taking node values to the Chebyshev coefficients, the derivatives at
    the nodes and the antiderivative's coefficients (``F(-1) = 0``), the matrix (n, n-2)
    taking coefficients to those of the second derivative, the rows ``T_j(x_i)`` (n, n-2)
    and ``min(j^2, j / s_i)`` (n-1, n-2) of :func:`node_bound`, ``int_{-1}^1 T_k`` (n,)
    and the factors (3, n-1) ``(h_i^2 / s_i^2, h_i^2 / s_i^3, h_i^2) / 8`` of the gaps'
    no-root test (with the bound's rounding, ``1 + 1e-12``)."""
    x = -np.cos(np.pi * np.arange(n) / (n - 1))
    k = np.arange(n, dtype=float)
    sn = np.sqrt(np.maximum(1.0 - x * x, 0.0))
    s = np.minimum(sn[:-1], sn[1:])
    K = np.stack([k * k, k, k * k * (k * k - 1.0) / 3.0], axis=1)
    dct = _dct_matrix(n)
    dT, T2 = _closed_form_tables(n)  # (nodes, k) T_k'(x_i) and (j, nodes) T_j(x_i)
    D = derivative_matrix(n)
    d2 = (D @ D)[:, :n - 2]  # (k, j): T_k'' = sum_j d2[k, j] T_j (integers: exact)
    k2 = k[:n - 2, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        kd = np.where(s[None, :] > 0, np.minimum(k2 * k2, k2 / s[None, :]), k2 * k2)
    integral = C.chebint(np.eye(n), lbnd=-1.0)  # (n+1, k): int_{-1}^x T_k's coefficients
    F1 = integral.sum(axis=0)  # (k,) int_{-1}^{1} T_k
    h = np.diff(x)
    with np.errstate(divide="ignore"):
        e_abc = np.stack([h * h / (s * s), h * h / (s * s * s), h * h]) * (0.125 * (1.0 + 1e-12))
    anti = integral @ dct  # values -> F's coefficients (n+1, n)
    tables = (x, h, s, K.T.copy(), np.concatenate([dct, dT @ dct, anti]), d2, T2.T.copy(),
              kd.T.copy(), F1, e_abc)
    for t in tables:
        t.setflags(write=False)
    return tables


def second_derivative_bound(abs_coef_sums: np.ndarray, s: np.ndarray) -> np.ndarray:
    """A bound of ``|p''|`` on each gap of the nodes for ``p = sum_k c_k T_k``, from the rows
    ``(sum |c_k| k^2, sum |c_k| k, sum |c_k| k^2 (k^2 - 1) / 3)`` (..., 3) and each gap's
    least ``sin(theta) = s`` (...): with ``x = cos(theta)``, ``T_k'' = (k cos(theta)
    sin(k theta) - k^2 sin(theta) cos(k theta)) / sin(theta)^3``, so ``|T_k''| <= k^2 / s^2
    + k / s^3``, and everywhere ``|T_k''| <= T_k''(1) = k^2 (k^2 - 1) / 3``."""
    A, B, G = (abs_coef_sums[..., i] for i in range(3))
    with np.errstate(divide="ignore", invalid="ignore"):
        loc = A / (s * s) + B / (s * s * s)
    return np.where(s > 0, np.minimum(G, loc), G) * (1.0 + 1e-12)  # and its own rounding


def node_bound(d: np.ndarray, gap: np.ndarray, h: np.ndarray, T2: np.ndarray,
               kd: np.ndarray) -> np.ndarray:
    """A second bound of ``|p''|`` on gaps ``[x_i, x_{i+1}]`` of the nodes (``i = gap``,
    (G,)), for the Chebyshev coefficients ``d`` (G, n-2) of each one's ``p'' = sum_j d_j
    T_j``: :func:`row_node_bounds` of each row, at its gap."""
    return row_node_bounds(d, h, T2, kd)[np.arange(gap.size), gap]


def row_node_bounds(d: np.ndarray, h: np.ndarray, T2: np.ndarray, kd: np.ndarray
                    ) -> np.ndarray:
    """A bound of ``|p''|`` on every gap ``[x_i, x_{i+1}]`` of the nodes (R, n-1) for rows of
    Chebyshev coefficients ``d`` (R, n-2) of ``p'' = sum_j d_j T_j``, tight where the
    coefficients decay: with ``|T_j'| = |j sin(j theta) / sin(theta)| <= min(j^2, j / s_i)``
    on the gap (``s_i`` its least ``sin(theta)``; the rows ``kd`` (n-1, n-2)),

        max |p''| <= max(|p''(x_i)|, |p''(x_{i+1})|) + (h_i / 2) sum_j |d_j| min(j^2, j / s_i)

    (every point of the gap is within ``h_i / 2`` of one end); ``p''(x_i) = sum_j d_j
    T_j(x_i)`` (the rows ``T2`` (n, n-2)) with ``|T_j| <= 1``, so its rounding is below
    ``1e-13 sum_j |d_j|``, added. All the gaps of a row at once, by matrix products."""
    ad = np.abs(d)
    va = np.abs(d @ T2.T)  # |p''| at the nodes (R, n)
    t = ad @ kd.T  # (R, n-1)
    t *= 0.5 * h
    t += np.maximum(va[:, :-1], va[:, 1:])
    t += 1e-13 * ad.sum(axis=1)[:, None]
    t *= 1.0 + 1e-12
    return t


def clenshaw(c: np.ndarray, x: np.ndarray, derivative: bool = False):
    """``sum_k c[k, r] T_k(x_r)`` for coefficient columns ``c`` (n, r, ...) at points ``x``
    (r, ...) by Clenshaw's recurrence; with ``derivative`` also its derivative in ``x``."""
    b1 = np.zeros(np.broadcast_shapes(c.shape[1:], x.shape))
    b2 = np.zeros_like(b1)
    d1 = np.zeros_like(b1)
    d2 = np.zeros_like(b1)
    x2 = 2.0 * x
    for ck in c[:0:-1]:
        if derivative:
            d1, d2 = 2.0 * b1 + x2 * d1 - d2, d1
        b1, b2 = ck + x2 * b1 - b2, b1
    val = c[0] + x * b1 - b2
    return (val, b1 + x * d1 - d2) if derivative else val


def chebyshev_at(cT: np.ndarray, x: np.ndarray, derivative: bool = False):
    """``p(x_r) = sum_k cT[k, r] T_k(x_r)`` for coefficient columns ``cT`` (n, r) at points
    ``x`` (r,) in [-1, 1]; with ``derivative`` also ``p'(x_r)``. Many points: Clenshaw's
    recurrence (:func:`clenshaw`, n vector steps); a few (at most ``SMALL``): with ``x =
    cos(theta)``, ``T_k(x) + i sin(k theta) = e^(i k theta)`` (the powers of ``e^(i theta)``,
    one cumulative product), ``T_k' = k sin(k theta) / sin(theta)``, and at ``x = +-1``
    (``sin(theta) = 0``) its limit ``T_k'(+-1) = (+-1)^(k+1) k^2``."""
    if x.size > SMALL:
        return clenshaw(cT, x, derivative)
    n = cT.shape[0]
    theta = np.arccos(np.clip(x, -1.0, 1.0))
    Z = np.empty((n, x.size), complex)
    Z[0] = 1.0
    Z[1:] = np.exp(1j * theta)
    Z = np.cumprod(Z, axis=0)
    val = np.einsum("kr,kr->r", cT, Z.real)
    if not derivative:
        return val
    k = np.arange(n, dtype=float)[:, None]
    sn = np.sin(theta)
    end = sn == 0.0
    d = np.einsum("kr,kr->r", cT * k, Z.imag) / np.where(end, 1.0, sn)
    if np.any(end):  # T_k'(+-1) = (+-1)^(k+1) k^2
        sgn = np.where(x[end] > 0, 1.0, -1.0)
        d[end] = np.einsum("kr,kr->r", cT[:, end] * (k * k), sgn[None] ** (k + 1))
    return val, d


TABLE_LEVELS = 4  # halvings whose middles take T_k, T_k' from a table (64 2^level points)


@lru_cache(maxsize=16)
def midpoint_table(n: int, level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points ``x_g + j h_g / 2^level`` (odd ``j < 2^level``, every gap ``g`` of the ``n``
    Lobatto nodes; index ``g 2^(level-1) + (j - 1) / 2``) and ``T_k``, ``T_k'`` there (n,
    points): with ``x = cos(theta)``, ``T_k = cos(k theta)``, ``T_k' = k sin(k theta) /
    sin(theta)`` (inner points: ``sin(theta) > 0``)."""
    xn, h = node_tables(n)[:2]
    half = 2 ** (level - 1)
    g = np.repeat(np.arange(n - 1), half)
    j = 2 * np.tile(np.arange(half), n - 1) + 1
    x = _middles(xn, h, g, j, level)
    theta = np.arccos(x)
    kt = np.arange(n, dtype=float)[:, None] * theta[None, :]
    T = np.cos(kt)
    dT = np.arange(n, dtype=float)[:, None] * np.sin(kt) / np.sin(theta)[None, :]
    for t in (x, T, dT):
        t.setflags(write=False)
    return x, T, dT


def _middles(xn: np.ndarray, h: np.ndarray, g: np.ndarray, j: np.ndarray, level: int
             ) -> np.ndarray:
    """``x_g + j h_g / 2^level``: one rounding of ``j (h_g / 2^level)`` and one of the sum."""
    return xn[g] + j * (h[g] * 0.5 ** level)


def midpoint_values(cT: np.ndarray, r: np.ndarray, n: int, level: int, g: np.ndarray,
                    j: np.ndarray, xn: np.ndarray, h: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``p``, ``p'`` of rows ``r`` (coefficient columns ``cT`` (n, P)) at the points
    ``x_g + j h_g / 2^level`` (odd ``j``) and the points: from :func:`midpoint_table` up to
    ``TABLE_LEVELS`` halvings (a dot product per point), else :func:`chebyshev_at`."""
    c = np.take(cT, r, axis=1)
    if level > TABLE_LEVELS:
        x = _middles(xn, h, g, j, level)
        p, d = chebyshev_at(c, x, derivative=True)
        return p, d, x
    x, T, dT = midpoint_table(n, level)
    idx = g * 2 ** (level - 1) + (j - 1) // 2
    p = np.einsum("kr,kr->r", c, np.take(T, idx, axis=1))
    d = np.einsum("kr,kr->r", c, np.take(dT, idx, axis=1))
    return p, d, x[idx]


def hermite_root(fa: np.ndarray, fb: np.ndarray, da: np.ndarray, db: np.ndarray
                  ) -> np.ndarray:
    """A root ``t`` in [0, 1] of each cubic Hermite interpolant ``H`` with end values ``fa``,
    ``fb`` of opposite signs (``fa >= 0`` and ``fb < 0`` or the reverse) and end slopes
    ``da``, ``db`` (d/dt): Newton's method kept inside a bracket of ``H``'s sign change,
    bisecting where a step would leave it, to ``1e-15``. ``H(t) = fa + da t + c_2 t^2 +
    c_3 t^3`` with ``c_2 = 3 (fb - fa) - 2 da - db``, ``c_3 = 2 (fa - fb) + da + db``; every
    root iterated at once, each left where it converged."""
    lo, hi = np.zeros_like(fa), np.ones_like(fa)
    up = fa < 0.0  # H(lo) < 0 <= H(hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.nan_to_num(fa / (fa - fb), nan=0.5), 0.0, 1.0)
    c2 = 3.0 * (fb - fa) - 2.0 * da - db
    c3 = 2.0 * (fa - fb) + da + db
    c2d, c3d = 2.0 * c2, 3.0 * c3
    done = np.zeros(fa.shape, bool)
    for _ in range(60):
        H = ((c3 * t + c2) * t + da) * t + fa
        dH = (c3d * t + c2d) * t + da
        below = (H < 0.0) == up  # the root is above t
        lo = np.where(below, t, lo)
        hi = np.where(below, hi, t)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = t - H / dH
        new = np.where(np.isfinite(new) & (new >= lo) & (new <= hi), new, 0.5 * (lo + hi))
        zero = H == 0.0
        new = np.where(zero | done, t, new)
        done |= (np.abs(new - t) <= 1e-15) | (hi - lo <= 1e-15) | zero
        t = new
        if done.all():
            break
    return t


def abs_and_positive(values: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """``int |f|`` and ``int max(0, f)`` over an interval of half-length ``half`` for rows of
    samples ``values`` (P, n) at ascending Lobatto nodes, piecewise between the roots of each
    row's Chebyshev interpolant ``p`` (module docstring): with ``F`` its antiderivative
    (``F(-1) = 0``), ``s_0`` its sign at the start and ``r_1 < ... < r_p`` its roots,
    ``int |f| = s_0 (sum_i 2 (-1)^(i-1) F(r_i) + (-1)^p F(1))``.

    Each gap ``[x_i, x_{i+1}]`` of the nodes is shown to hold no root (its end values keep
    their sign and ``min(|p(x_i)|, |p(x_{i+1})|) > h_i^2 max|p''| / 8``, the linear
    interpolant's error bound) or exactly one (they change sign and ``p'`` keeps its sign:
    ``p'(x_i) p'(x_{i+1}) > 0`` and ``|p'(x_i)| + |p'(x_{i+1})| > h_i max|p''|``), with
    ``max|p''|`` bounded from the coefficients (:func:`second_derivative_bound`; on a gap
    that this leaves without a proof, the smaller of it and :func:`node_bound`); a gap
    still without a proof is halved (``p`` and ``p'`` at its middle,
    :func:`midpoint_values`) and the test repeated on the halves with the gap's bound, up to
    ``SPLITS`` times (a piece where ``|p|`` stays below ``1e-15`` of the row's largest node
    value is negligible and left unsplit). Each root starts at the root of the cubic
    Hermite interpolant of its bracket's end values and slopes (:func:`hermite_root`) and
    takes one Newton step on ``p``, kept in the bracket (the root's error enters the
    integrals squared). Only roots closer than the last halving's width (``2^-SPLITS`` of a
    gap) and double roots are not separated."""
    P, n = values.shape
    if P == 0:
        return np.zeros(0), np.zeros(0)
    xn, h, sg, K, to_cd, d2, T2, kd, F1_m, e_abc = node_tables(n)
    cd = to_cd @ values.T  # (3n+1, P), rows contiguous: what the recurrences gather
    cT = cd[:n]  # Chebyshev coefficients (n, P)
    coef, dv = cT.T, cd[n:2 * n].T  # (P, n): the coefficients, p' at the nodes
    S = (K @ np.abs(cT)).T  # (P, 3): the sums of second_derivative_bound
    pos = values >= 0.0
    change = pos[:, 1:] != pos[:, :-1]
    av = np.abs(values)
    amin = np.minimum(av[:, :-1], av[:, 1:])
    # every gap at once: h_i^2 max|p''| / 8 <= min(G h_i^2, A h_i^2 / s_i^2 + B h_i^2 / s_i^3)
    # / 8 (the factors e_abc, with the bound's own rounding); the gaps with a sign change and
    # those this does not prove root-free are tested one by one below, with the bound itself
    with np.errstate(invalid="ignore"):  # 0 inf at the end gaps: NaN, which fmin drops
        e = S[:, 0:1] * e_abc[0]
        tmp = S[:, 1:2] * e_abc[1]
        e += tmp
    np.multiply(S[:, 2:3], e_abc[2], out=tmp)
    np.fmin(e, tmp, out=e)
    test = np.less_equal(amin, e)
    test |= change
    r, gap = np.nonzero(test)
    ch = change[r, gap]
    m2 = second_derivative_bound(S[r], sg[gap])
    ga, gb = dv[r, gap], dv[r, gap + 1]
    mono = ga * gb > 0.0
    sdv = np.abs(ga) + np.abs(gb)
    hg, am = h[gap], amin[r, gap]
    one = ch & mono & (sdv > hg * m2)
    open_ = ch & ~one | ~ch & ~((am > 0.125 * hg * hg * m2) | (m2 == 0.0))
    if np.any(open_):  # the node bound too, where it is smaller
        rows_o, inv = np.unique(r[open_], return_inverse=True)
        d = np.take(cT, rows_o, axis=1).T @ d2  # p'''s coefficients, per row
        m2[open_] = np.minimum(m2[open_], row_node_bounds(d, h, T2, kd)[inv, gap[open_]])
        one = ch & mono & (sdv > hg * m2)
        open_ = ch & ~one | ~ch & ~((am > 0.125 * hg * hg * m2) | (m2 == 0.0))
    ro, go = r[one], gap[one]
    brackets = [(ro, xn[go], h[go], values[ro, go], values[ro, go + 1], ga[one], gb[one])]
    # the other gaps: halved until each piece provably holds no root or one
    r, gap = r[open_], gap[open_]
    # a piece: its row, start, width, end values and slopes, bound, and its place: the gap
    # ``g`` of the nodes and ``j``, the start being x_g + j h_g / 2^level
    piece = (r, xn[gap], h[gap], values[r, gap], values[r, gap + 1], ga[open_], gb[open_],
             m2[open_], gap, np.zeros(gap.size, np.int64))
    tiny = 1e-15 * np.max(av, axis=1)  # a piece below it is negligible in the integrals
    for level in range(SPLITS + 1):
        r = piece[0]
        if not r.size:
            break
        if level == SPLITS:  # unresolved (a double root or roots closer than the width)
            ch = (piece[3] >= 0.0) != (piece[4] >= 0.0)
            brackets.append(tuple(v[ch] for v in piece[:7]))
            break
        r, a, w, fa, fb, ga, gb, m2, g, j = piece
        w = 0.5 * w
        j = 2 * j + 1  # the middle: x_g + j h_g / 2^(level + 1)
        pm, dm, xm = midpoint_values(cT, r, n, level + 1, g, j, xn, h)
        r, a, fa, fb, ga, gb, m2, g, j = (np.concatenate(v) for v in (
            (r, r), (a, xm), (fa, pm), (pm, fb), (ga, dm), (dm, gb), (m2, m2), (g, g),
            (j - 1, j)))
        w = np.concatenate([w, w])
        ch = (fa >= 0.0) != (fb >= 0.0)
        e2 = 0.125 * w * w * m2
        afa, afb = np.abs(fa), np.abs(fb)
        small = np.maximum(afa, afb) + e2 <= tiny[r]
        none = ~ch & ((np.minimum(afa, afb) > e2) | small)
        one = ch & (((ga * gb > 0.0) & (np.abs(ga) + np.abs(gb) > w * m2)) | small)
        brackets.append((r[one], a[one], w[one], fa[one], fb[one], ga[one], gb[one]))
        keep = ~(none | one)
        piece = (r[keep], a[keep], w[keep], fa[keep], fb[keep], ga[keep], gb[keep], m2[keep],
                 g[keep], j[keep])
    rows, xa, hb, fa, fb, da, db = (np.concatenate(v) for v in zip(*brackets))
    F1 = coef @ F1_m  # F(1): T_k(1) = 1
    s0 = np.where(pos[:, 0], 1.0, -1.0)
    total_abs = s0 * F1  # no root
    if rows.size:
        order = np.lexsort((xa, rows))
        rows, xa, hb, fa, fb, da, db = (v[order] for v in (rows, xa, hb, fa, fb, da, db))
        t = hermite_root(fa, fb, da * hb, db * hb)
        x = xa + t * hb
        # one Newton step on p itself
        c = np.take(cT, rows, axis=1)  # (n, roots), contiguous rows
        f, df = chebyshev_at(c, x, derivative=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.clip(x - np.nan_to_num(np.where(df != 0, f / df, 0.0)), xa, xa + hb)
        Fr = chebyshev_at(np.take(cd[2 * n:], rows, axis=1), x)  # F's coefficients
        rank = np.arange(rows.size) - np.searchsorted(rows, rows, side="left")
        count = np.bincount(rows, minlength=P)
        inner = np.bincount(rows, 2.0 * np.where(rank % 2 == 0, 1.0, -1.0) * Fr, minlength=P)
        total_abs = s0 * (inner + np.where(count % 2 == 0, 1.0, -1.0) * F1)
    return total_abs * half, 0.5 * (total_abs + F1) * half
