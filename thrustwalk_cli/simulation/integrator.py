"""A generic compiled integrator: DOP853 with dense output and event location, the numba
source of the simulation (SPEC 7), knowing nothing of walkers.

``integrate`` is ``scipy.integrate.solve_ivp(f, (t0, t_bound), x0, method="DOP853",
events=..., dense_output=True)`` over one segment of a problem, step for step: SciPy's error
norm, step-size control and initial step (``select_initial_step``, error estimator order 7),
its 7th-order dense output (``Dop853DenseOutput``; Hairer, Norsett, Wanner, *Solving ODEs I*,
II.4-II.6) and its event handling (sign changes in the event's direction between two accepted
steps located on the dense output by Brent's method, ``scipy.optimize.brentq``; the first
terminal root ends the call, the first event in list order among roots at the same time).
Every accepted step is kept (``buf``: rows ``[t_old, t_new, y_old (n), F (7 n)]``), so that
the caller can evaluate the solution anywhere afterwards (:func:`solution_at`, with
``OdeSolution``'s choice of interval).

The problem is source that follows this one in the compiled module and defines what the
placeholders below stand for: ``rhs_eval(t, x, seg, fs, ip, par, w, dx)`` (the right-hand
side into ``dx``; False where it is undefined), ``rhs_node`` (the same at a state that may
become a node: the end of a step, the start of a call), ``event_value(code, x, seg, fs, ip,
par, w, ea, eb)`` and ``node_event_value`` (an event's value at a node, where the problem
may already know it from ``rhs_node``). Its data travels in the flat arrays ``fs`` (float
settings; the integrator reads ``fs[F_RTOL]``, ``fs[F_ATOL]``), ``ip`` (integer settings; the
integrator reads the state dimension ``ip[I_DIM]`` and the offsets of its scratch in ``w``,
``ip[W_*]``, see :func:`scratch`), ``par`` and the work array ``w``; a problem's own settings
follow the integrator's (``fs`` from ``N_FS_INTEGRATOR``, ``ip`` from ``N_IP_INTEGRATOR``).
The DOP853 tableau is that of :class:`scipy.integrate.DOP853`, defined for real after the
sources (:mod:`thrustwalk_cli.simulation.stepper`). Units: those of the problem.
"""

import math

import numpy as np

# ------------------------------------------------------------------ placeholders (replaced)
# the problem's functions, defined for real by the problem's source that follows


def rhs_eval(t, x, seg, fs, ip, par, w, dx):  # noqa: D103
    raise NotImplementedError


def rhs_node(t, x, seg, fs, ip, par, w, dx):  # noqa: D103
    raise NotImplementedError


def event_value(code, x, seg, fs, ip, par, w, ea, eb):  # noqa: D103
    raise NotImplementedError


def node_event_value(code, x, seg, fs, ip, par, w, ea, eb):  # noqa: D103
    raise NotImplementedError


# DOP853 coefficients (scipy.integrate.DOP853), defined for real in the compiled file
DOP_A = np.zeros((12, 12))
DOP_B = np.zeros(12)
DOP_C = np.zeros(12)
DOP_E3 = np.zeros(13)
DOP_E5 = np.zeros(13)
DOP_D = np.zeros((4, 16))
DOP_AX = np.zeros((3, 16))
DOP_CX = np.zeros(3)

# ------------------------------------------------------------------ layout
# float settings fs[...]: the tolerances (rtol, and atol on every component)
F_RTOL, F_ATOL = 0, 1
N_FS_INTEGRATOR = 2
# integer settings ip[...]: the state dimension n, the offsets of the scratch in w: the state
# y, a stage's state, the 16 stages K, the error scale, the initial step's trial state and
# rate, a state for evaluations of the dense output (free between calls), the state at the
# end of a call, the rate at y, the new state, the event values (old, new), the roots of a
# step and the recorded roots
(I_DIM, W_Y, W_YT, W_K, W_SC, W_Y1, W_F1, W_XS, W_YE, W_FF, W_YN, W_G, W_GN, W_ROOTS,
 W_LOWS) = range(15)
N_IP_INTEGRATOR = 15
EV_NONE = 0  # no event fired (problems number their events from 1)
MAX_EVENTS = 12
MAX_LOWS = 256
# integrate() status
ST_BOUND, ST_EVENT, ST_SMALL, ST_SINGULAR, ST_FULL = 0, 1, -1, -2, -3
SAFETY, MIN_FACTOR, MAX_FACTOR, ERR_EXP = 0.9, 0.2, 10.0, -1.0 / 8.0
EPS = 2.220446049250313e-16


def scratch(n):
    """``(ip index, size)`` of every scratch array of the integrator for ``n`` states (plain
    Python, for the problem's layout)."""
    return [(W_Y, n), (W_YT, n), (W_K, 16 * n), (W_SC, n), (W_Y1, n), (W_F1, n), (W_XS, n),
            (W_YE, n), (W_FF, n), (W_YN, n), (W_G, MAX_EVENTS), (W_GN, MAX_EVENTS),
            (W_ROOTS, MAX_EVENTS), (W_LOWS, MAX_LOWS)]


# ------------------------------------------------------------------ helpers
def pymax(a, b):
    """Python's ``max(a, b)`` (``a`` unless ``b > a``; NaN-safe the same way)."""
    return b if b > a else a


def pymin(a, b):
    """Python's ``min(a, b)``."""
    return b if b < a else a


# ------------------------------------------------------------------ DOP853
def initial_step(t0, t_bound, seg, fs, ip, par, w, n):
    """SciPy's ``select_initial_step`` (error estimator order 7) from ``y = w[W_Y]``,
    ``f = w[W_FF]``. Returns (h, ok)."""
    y0, f0, scale = w[ip[W_Y]:], w[ip[W_FF]:], w[ip[W_SC]:]
    y1, f1 = w[ip[W_Y1]:], w[ip[W_F1]:]
    rtol, atol = fs[F_RTOL], fs[F_ATOL]
    length = abs(t_bound - t0)
    if length == 0.0:
        return 0.0, True
    direction = 1.0 if t_bound > t0 else -1.0
    d0 = 0.0
    d1 = 0.0
    for i in range(n):
        scale[i] = atol + abs(y0[i]) * rtol
        d0 += (y0[i] / scale[i]) ** 2
        d1 += (f0[i] / scale[i]) ** 2
    d0 = math.sqrt(d0 / n)
    d1 = math.sqrt(d1 / n)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = pymin(h0, length)
    for i in range(n):
        y1[i] = y0[i] + h0 * direction * f0[i]
    if not rhs_eval(t0 + h0 * direction, y1, seg, fs, ip, par, w, f1):
        return 0.0, False
    d2 = 0.0
    for i in range(n):
        d2 += ((f1[i] - f0[i]) / scale[i]) ** 2
    d2 = math.sqrt(d2 / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = pymax(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / pymax(d1, d2)) ** (1.0 / 8.0)
    return pymin(pymin(100 * h0, h1), length), True


def rk_step(t, h, seg, fs, ip, par, w, n):
    """One DOP853 step from ``y = w[W_Y]``, ``f = w[W_FF]``: stages into ``w[W_K]`` (13 rows
    of n), the 8th-order solution into ``w[W_YN]``, ``K[12] = f(t + h, y_new)`` (by
    :func:`rhs_node`: with the vertical ground force at ``y_new``). Returns the error norm
    (SciPy's DOP853 estimate), or -1 if the controller is singular."""
    y, f, K, ytmp, y_new = w[ip[W_Y]:], w[ip[W_FF]:], w[ip[W_K]:], w[ip[W_YT]:], w[ip[W_YN]:]
    scale = w[ip[W_SC]:]
    for i in range(n):
        K[i] = f[i]
    for s in range(1, 12):
        # sum_j K_j a_sj column by column: each component adds the same terms in the same
        # order as a row-by-row sum, in loops the compiler vectorises
        a = DOP_A[s, 0]
        for i in range(n):
            ytmp[i] = K[i] * a
        for j in range(1, s):
            a = DOP_A[s, j]
            for i in range(n):
                ytmp[i] += K[j * n + i] * a
        for i in range(n):
            ytmp[i] = y[i] + ytmp[i] * h
        if not rhs_eval(t + DOP_C[s] * h, ytmp, seg, fs, ip, par, w, K[s * n:(s + 1) * n]):
            return -1.0
    b = DOP_B[0]
    for i in range(n):
        y_new[i] = K[i] * b
    for j in range(1, 12):
        b = DOP_B[j]
        for i in range(n):
            y_new[i] += K[j * n + i] * b
    for i in range(n):
        y_new[i] = y[i] + h * y_new[i]
    if not rhs_node(t + h, y_new, seg, fs, ip, par, w, K[12 * n:13 * n]):
        return -1.0
    rtol, atol = fs[F_RTOL], fs[F_ATOL]
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        scale[i] = atol + pymax(abs(y[i]), abs(y_new[i])) * rtol
        a5 = 0.0
        a3 = 0.0
        for j in range(13):
            a5 += K[j * n + i] * DOP_E5[j]
            a3 += K[j * n + i] * DOP_E3[j]
        a5 /= scale[i]
        a3 /= scale[i]
        e5 += a5 * a5
        e3 += a3 * a3
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


def dense_coefficients(t_old, h, seg, fs, ip, par, w, n, Fout):
    """DOP853 dense output over the step just taken (3 extra stages) into ``Fout`` (7 rows)
    from ``y_old = w[W_Y]``, ``y = w[W_YN]``, ``f_old = w[W_FF]``, ``f = K[12]``."""
    y_old, y, f_old, K, ytmp = w[ip[W_Y]:], w[ip[W_YN]:], w[ip[W_FF]:], w[ip[W_K]:], w[ip[W_YT]:]
    for s in range(13, 16):
        a = DOP_AX[s - 13, 0]  # column by column, as in rk_step
        for i in range(n):
            ytmp[i] = K[i] * a
        for j in range(1, s):
            a = DOP_AX[s - 13, j]
            for i in range(n):
                ytmp[i] += K[j * n + i] * a
        for i in range(n):
            ytmp[i] = y_old[i] + ytmp[i] * h
        if not rhs_eval(t_old + DOP_CX[s - 13] * h, ytmp, seg, fs, ip, par, w,
                        K[s * n:(s + 1) * n]):
            return False
    for i in range(n):
        dy = y[i] - y_old[i]
        Fout[i] = dy
        Fout[n + i] = h * f_old[i] - dy
        Fout[2 * n + i] = 2 * dy - h * (K[12 * n + i] + f_old[i])
    for r in range(4):
        o = (3 + r) * n
        d = DOP_D[r, 0]
        for i in range(n):
            Fout[o + i] = d * K[i]
        for j in range(1, 16):
            d = DOP_D[r, j]
            for i in range(n):
                Fout[o + i] += d * K[j * n + i]
        for i in range(n):
            Fout[o + i] = h * Fout[o + i]
    return True


def dense_at(buf, k, t, n, out):
    """Evaluate stored step ``k`` of ``buf`` at time ``t`` (SciPy's Dop853DenseOutput).
    Unsigned offsets into the row (numba then skips its negative-index correction)."""
    row = buf[k]
    t_old = row[0]
    x = (t - t_old) / (row[1] - t_old)
    x1 = 1.0 - x
    un = np.uint64(n)
    for i in range(un):
        acc = 0.0
        o = np.uint64(2) + np.uint64(7) * un + i  # coefficient 6, then 5, ..., 0
        for r in range(7):
            acc += row[o]
            if r % 2 == 0:
                acc *= x
            else:
                acc *= x1
            o -= un
        out[i] = acc + row[np.uint64(2) + i]


def solution_at(buf, first, last, t, n, out):
    """The dense solution of one integration call (steps ``first..last-1``) at ``t``, with
    ``OdeSolution``'s choice of interval (a time on a node belongs to the step ending
    there)."""
    k = first
    while k < last - 1 and buf[k, 1] < t:
        k += 1
    dense_at(buf, k, t, n, out)


def brent(code, a, b, fa, fb, buf, first, last, seg, fs, ip, par, w, n, ea, eb, xtol, rtol):
    """Root in ``[a, b]`` of event ``code`` (:func:`event_value`, with the event parameters
    ``ea``, ``eb``) on the dense solution of steps ``first..last-1``, by Brent's bracketing
    interpolation (the algorithm of ``scipy.optimize.brentq``)."""
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    xs = w[ip[W_XS]:]
    xpre, xcur, fpre, fcur = a, b, fa, fb
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    for _ in range(200):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = 0.5 * (xtol + rtol * abs(xcur))
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        solution_at(buf, first, last, xcur, n, xs[:n])
        fcur = event_value(code, xs, seg, fs, ip, par, w, ea, eb)
    return xcur


def integrate(t0, x0, t_bound, seg, ev, nev, fs, ip, par, w, buf, nbuf, ea, eb):
    """``solve_ivp(rhs, (t0, t_bound), x0, method="DOP853", events=..., dense_output=True)``
    over one segment ``seg`` of the problem: every accepted step goes into ``buf`` from row
    ``nbuf``.

    ``ev``: rows code, direction (+1 rising, -1 falling), terminal (1/0) and recorded (1: its
    roots up to the termination time are written to ``w[W_LOWS]``, at most ``MAX_LOWS``) of
    ``nev`` events; ``ea``, ``eb``: two parameters passed to :func:`event_value`. Returns
    (status, t_end, fired event code, number of recorded roots, rows used, nfev); the state at
    ``t_end`` is in ``w[W_YE]``.
    """
    n = ip[I_DIM]
    y, f, y_new, K, yend = w[ip[W_Y]:], w[ip[W_FF]:], w[ip[W_YN]:], w[ip[W_K]:], w[ip[W_YE]:]
    g, g_new, roots, lows = w[ip[W_G]:], w[ip[W_GN]:], w[ip[W_ROOTS]:], w[ip[W_LOWS]:]
    for i in range(n):
        y[i] = x0[i]
    nfev = 1
    if not rhs_node(t0, y, seg, fs, ip, par, w, f):
        return ST_SINGULAR, t0, EV_NONE, 0, nbuf, nfev
    h_abs, ok = initial_step(t0, t_bound, seg, fs, ip, par, w, n)
    nfev += 1
    if not ok:
        return ST_SINGULAR, t0, EV_NONE, 0, nbuf, nfev
    direction = 1.0 if t_bound >= t0 else -1.0
    for e in range(nev):  # (at a node, the problem may know a value from its right-hand side)
        g[e] = node_event_value(ev[0, e], y, seg, fs, ip, par, w, ea, eb)
    n_lows = 0
    t = t0
    while True:
        if nbuf >= buf.shape[0]:
            return ST_FULL, t, EV_NONE, n_lows, nbuf, nfev
        # -- one accepted step (RungeKutta._step_impl)
        min_step = 10.0 * abs(np.nextafter(t, direction * np.inf) - t)
        if h_abs < min_step:
            h_abs = min_step
        accepted = False
        rejected = False
        h = 0.0
        t_new = t
        while not accepted:
            if h_abs < min_step or not (h_abs == h_abs):
                for i in range(n):
                    yend[i] = y[i]
                return ST_SMALL, t, EV_NONE, n_lows, nbuf, nfev
            h = h_abs * direction
            t_new = t + h
            if direction * (t_new - t_bound) > 0:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            err = rk_step(t, h, seg, fs, ip, par, w, n)
            nfev += 12
            if err < 0.0:
                return ST_SINGULAR, t, EV_NONE, n_lows, nbuf, nfev
            if err < 1.0:
                if err == 0.0:
                    factor = MAX_FACTOR
                else:
                    factor = pymin(MAX_FACTOR, SAFETY * err ** ERR_EXP)
                if rejected:
                    factor = pymin(1.0, factor)
                h_abs *= factor
                accepted = True
            else:
                h_abs *= pymax(MIN_FACTOR, SAFETY * err ** ERR_EXP)
                rejected = True
        # -- store the step and its dense output
        buf[nbuf, 0] = t
        buf[nbuf, 1] = t_new
        for i in range(n):
            buf[nbuf, 2 + i] = y[i]
        if not dense_coefficients(t, h, seg, fs, ip, par, w, n, buf[nbuf, 2 + n:]):
            return ST_SINGULAR, t, EV_NONE, n_lows, nbuf, nfev
        nfev += 3
        k = nbuf
        nbuf += 1
        t_old = t
        t = t_new
        for i in range(n):
            y[i] = y_new[i]
            f[i] = K[12 * n + i]
        finished = direction * (t - t_bound) >= 0
        # -- events (find_active_events / handle_events)
        n_act = 0
        first_term = -1
        t_term = 0.0
        for e in range(nev):
            g_new[e] = node_event_value(ev[0, e], y, seg, fs, ip, par, w, ea, eb)
        for e in range(nev):
            up = g[e] <= 0 and g_new[e] >= 0
            down = g[e] >= 0 and g_new[e] <= 0
            if (up and ev[1, e] > 0) or (down and ev[1, e] < 0):
                r = brent(ev[0, e], t_old, t, g[e], g_new[e], buf, k, k + 1, seg, fs, ip,
                          par, w, n, ea, eb, 4 * EPS, 4 * EPS)
                roots[e] = r
                n_act += 1
                if ev[2, e] == 1 and (first_term < 0 or r < t_term):
                    first_term = e
                    t_term = r
            else:
                roots[e] = np.nan
        if n_act > 0:
            for e in range(nev):
                if roots[e] == roots[e] and ev[3, e] == 1 and n_lows < MAX_LOWS:
                    if first_term < 0 or roots[e] <= t_term:
                        lows[n_lows] = roots[e]
                        n_lows += 1
            if first_term >= 0:
                # the first event in list order whose root is the termination time
                fired = ev[0, first_term]
                for e in range(nev):
                    if ev[2, e] == 1 and roots[e] == t_term:
                        fired = ev[0, e]
                        break
                dense_at(buf, k, t_term, n, yend)
                return ST_EVENT, t_term, fired, n_lows, nbuf, nfev
        for e in range(nev):
            g[e] = g_new[e]
        if finished:
            for i in range(n):
                yend[i] = y[i]
            return ST_BOUND, t, EV_NONE, n_lows, nbuf, nfev


# numba signatures (argument types only), callees before callers; the problem's functions
# (rhs_eval, rhs_node, event_value, node_event_value) are compiled before these
_F, _I = "float64", "int64"
_A, _A2 = "float64[::1]", "float64[:, ::1]"
_IA, _IA2 = "int64[::1]", "int64[:, ::1]"
_CTX = f"{_A}, {_IA}, {_A}, {_A}"  # fs, ip, par, w
HELPERS = {
    "pymax": f"({_F}, {_F})",
    "pymin": f"({_F}, {_F})",
}
SIGNATURES = {
    "initial_step": f"({_F}, {_F}, {_I}, {_CTX}, {_I})",
    "rk_step": f"({_F}, {_F}, {_I}, {_CTX}, {_I})",
    "dense_coefficients": f"({_F}, {_F}, {_I}, {_CTX}, {_I}, {_A})",
    "dense_at": f"({_A2}, {_I}, {_F}, {_I}, {_A})",
    "solution_at": f"({_A2}, {_I}, {_I}, {_F}, {_I}, {_A})",
    "brent": f"({_I}, {_F}, {_F}, {_F}, {_F}, {_A2}, {_I}, {_I}, {_I}, {_CTX}, {_I}, {_F}, "
             f"{_F}, {_F}, {_F})",
    "integrate": f"({_F}, {_A}, {_F}, {_I}, {_IA2}, {_I}, {_CTX}, {_A2}, {_I}, {_F}, {_F})",
}
# every one allocation-free: compiled without reference counting (model/jit.py)
NRT_FREE = frozenset(SIGNATURES) | frozenset(HELPERS)
# compiled into their one caller, ``integrate``, only (numba's IR inlining, see
# ``model/jit.py``): no library of their own, whose compile would optimize and translate the
# problem's functions below them once more (the signatures above are the types they are
# called with)
INLINED = frozenset({"initial_step", "rk_step", "dense_coefficients"})
