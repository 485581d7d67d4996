"""A walking step's statistics in the compiled simulation (SPEC 5, 7): numba source, part of
the compiled module that :mod:`thrustwalk_cli.simulation.stepper` assembles (see
:mod:`.kernel`).

As ``full_order._impact_and_record`` does: the states at the integrator's nodes, at the ends of
every integration call and on a uniform grid of the step, taken from the dense output; the
force program of the model's tape on all of them at once; per state the vertical ground force,
the friction ratio, the outputs and their rates and the torques (their extremes folded into
``w[W_ACC]``); and the first times the stance force left the contact cone it is timed against
(``F_1^v <= eps``, ``|F_1^h| > mu F_1^v``), located by bisection on the dense output.

Also here, called from Python after a run: :func:`energy_nodes`, the closed loop's torques,
thrust and velocities at the Gauss-Lobatto nodes of every integrator step of a run's dense
output, which the energies along the run integrate, and :func:`kink_integrals`, their
absolute values' integrals where they change sign (SPEC 15,
:mod:`thrustwalk_cli.energetics.nodes`; the same states and equations as its NumPy path, to
rounding). Units SI.
"""

import numpy as np

# ---- Python only: names of the sources before this one in the compiled module
from .integrator import EPS, I_DIM, W_XS, dense_at, solution_at
from .kernel import (
    CMD_PIECEWISE,
    E_ACCEL,
    E_FIXF,
    E_FORCE,
    E_PRE,
    E_U,
    F_AI,
    F_EPS,
    F_MU,
    F_SLOPE,
    F_SPAN,
    I_C0,
    I_CMD,
    I_GRID,
    I_M,
    I_N,
    I_NCONST,
    I_NREG,
    I_NZ,
    N_FS,
    P_SEGT,
    R_SLOW,
    R_TLOW,
    T_FORCE,
    V_FH,
    V_FV,
    V_SAT,
    W_ACC,
    W_BF,
    W_D,
    W_F,
    W_GH,
    W_OUT,
    W_U,
    alpha_of,
    alpha_rate,
    evaluate,
    rhs_eval,
    tape_batch,
)

# ---- end Python only


def stat_times(calls, ci, buf, ng, t0, t1, store, n, SX, ST, k0):
    """The states where a step's statistics are taken within integration call ``ci`` (as
    ``_impact_and_record``): its start, the integrator's nodes inside it, its end, and the
    points of the uniform ``ng``-point grid of the step ``[t0, t1]`` that fall in it. With
    ``store`` they go into the rows ``k0, k0 + 1, ...`` of ``SX`` (their times into ``ST``);
    returns their number."""
    c0, c1 = int(calls[ci, 1]), int(calls[ci, 2])
    ta, tb = calls[ci, 3], calls[ci, 4]
    cnt = 0
    for j in range(c0 - 1, c1 + ng):
        if j == c0 - 1:
            tt = ta
        elif j < c1 - 1:
            tt = buf[j, 1]
            if not (tt >= ta and tt <= tb):
                continue
        elif j == c1 - 1:
            tt = tb
        else:
            gi = j - c1
            tt = t0 + gi * ((t1 - t0) / (ng - 1.0)) if gi < ng - 1 else t1
            if not (tt >= ta and tt <= tb):
                continue
        if store:
            solution_at(buf, c0, c1, tt, n, SX[k0 + cnt])
            ST[k0 + cnt] = tt
        cnt += 1
    return cnt


def details_at(x, seg, fs, ip, par, w, flags):
    """Fold one state's statistics into ``w[W_ACC]`` = [min F_v, max |F_h|/F_v (over
    F_v > 0), all F_v > 0, max |y|, max |y'|, max |u|, any saturated] (as
    ``ClosedLoop.details``). ``flags``: ``E_PRE`` when the force program's outputs are in
    place. Returns False (nothing folded) if the controller is singular there."""
    N = ip[I_N]
    nb = N - 1
    oacc, oH, ou = ip[W_ACC], ip[W_GH], ip[W_U]  # offsets into w (no views)
    if not evaluate(x, seg, fs, ip, par, w, E_U | E_FORCE | flags):
        return False
    vo = ip[W_OUT]
    fh, fv = w[vo + V_FH], w[vo + V_FV]
    if fv < w[oacc + 0]:
        w[oacc + 0] = fv
    if fv > 0:
        r = abs(fh) / fv
        if r > w[oacc + 1]:
            w[oacc + 1] = r
    else:
        w[oacc + 2] = 0.0
    adot = alpha_rate(x, ip, par)
    for i in range(nb):
        y = abs(x[i] - w[oH + i])
        dy = abs(x[N + i] - w[oH + nb + i] * adot)
        if y > w[oacc + 3]:
            w[oacc + 3] = y
        if dy > w[oacc + 4]:
            w[oacc + 4] = dy
        if abs(w[ou + i]) > w[oacc + 5]:
            w[oacc + 5] = abs(w[ou + i])
    if w[vo + V_SAT] > 0:
        w[oacc + 6] = 1.0
    return True


def cone_violated(x, seg, fs, ip, par, w, which):
    """Whether the stance force at ``x`` violates one condition of the cone the step is
    timed against: ``which`` 0: ``F_1^v <= eps``; 1: ``|F_1^h| > mu F_1^v`` with
    ``F_1^v > 0`` (False where the controller is singular)."""
    if not evaluate(x, seg, fs, ip, par, w, E_FORCE):
        return False
    vo = ip[W_OUT]
    fh, fv = w[vo + V_FH], w[vo + V_FV]
    if which == 0:
        return fv <= fs[F_EPS]
    return fv > 0 and abs(fh) > fs[F_MU] * fv


def first_violation(buf, calls, ci, ta, tb, fs, ip, par, w, which, n):
    """The time [s] in ``(ta, tb]`` of integration call ``ci`` where cone condition
    ``which`` (:func:`cone_violated`) starts to be violated, by bisection on the dense
    output: it holds at ``ta`` and is violated at ``tb`` (returns the violated end)."""
    c0, c1 = int(calls[ci, 1]), int(calls[ci, 2])
    seg = int(calls[ci, 0])
    xs = w[ip[W_XS]:]
    a, b = ta, tb
    for _ in range(200):
        if b - a <= 4 * EPS * abs(b) + 1e-15:
            break
        mid = 0.5 * (a + b)
        solution_at(buf, c0, c1, mid, n, xs)
        if cone_violated(xs, seg, fs, ip, par, w, which):
            b = mid
        else:
            a = mid
    return b


def energy_nodes(R, lo, hi, seg, start, force, xn, fs, ip, par, w, V):
    """The closed loop's values that the energies along a run integrate
    (:mod:`thrustwalk_cli.energetics.nodes`, SPEC 15), at the Gauss-Lobatto nodes ``xn`` of
    ``[-1, 1]`` (ascending, both ends included) mapped onto every row ``r`` of a dense output
    ``R`` (rows ``[t_old, t_new, y_old, F]``, :func:`dense_at`) clipped to ``[lo[r],
    hi[r]]``, in segment ``seg[r]``: node ``t = (lo + hi) / 2 + x (hi - lo) / 2`` [s], the
    state interpolated there as ``energetics.nodes.Dense.at_nodes`` does (the same arithmetic),
    then by :func:`evaluate` (``ClosedLoop.law``'s equations, torque limits included) into
    ``V[r, k]``: the torques ``u`` (N - 1) [N m], ``q'`` (N), the thrust ``F`` (m) [N], the
    generalised force ``T`` [N m] and ``B_F^T q'`` (m) [m/s]. ``force`` (rows, m): the thrust
    of each row instead of the closed loop's, T = 0 (no rows: the closed loop's own). A row
    that continues the one before it within an integration piece (``start[r] == 0``: the same
    segment and thrust, its start that row's end) takes that row's last node as its first:
    the same state, to rounding. Returns -1, or the first row whose controller is singular
    at a node (then ``V`` is incomplete)."""
    N, m = ip[I_N], ip[I_M]
    nb = N - 1
    n = ip[I_DIM]
    K = xn.size
    nc = V.shape[2]
    fixed = force.shape[0] > 0
    what = E_ACCEL | E_U
    if fixed:
        what |= E_FIXF
    piecewise = ip[I_CMD] == CMD_PIECEWISE
    xs = w[ip[W_XS]:]  # the state at a node (integrator scratch, free between calls)
    ou, oF, oBF = ip[W_U], ip[W_F], ip[W_BF]
    for r in range(R.shape[0]):
        a, b = lo[r], hi[r]
        mid = 0.5 * (a + b)
        half = 0.5 * (b - a)
        sg = seg[r]
        for k in range(K):
            if k == 0 and r > 0 and start[r] == 0:
                for j in range(nc):
                    V[r, 0, j] = V[r - 1, K - 1, j]
                continue
            dense_at(R, r, mid + half * xn[k], n, xs)
            if fixed:
                for j in range(m):
                    w[oF + j] = force[r, j]
            if not evaluate(xs, sg, fs, ip, par, w, what):
                return r
            for j in range(nb):
                V[r, k, j] = w[ou + j]
            for j in range(N):
                V[r, k, nb + j] = xs[N + j]
            o = nb + N
            for j in range(m):
                V[r, k, o + j] = w[oF + j]
            V[r, k, o + m] = par[ip[P_SEGT] + sg] if piecewise and not fixed else 0.0
            o += m + 1
            for j in range(m):
                acc = 0.0
                for i in range(N):
                    acc += w[oBF + i * m + j] * xs[N + i]
                V[r, k, o + j] = acc
    return -1


def rhs_rows(X, seg, fs, ip, par, w, out):
    """``x' = [q'; q''; z']`` (SPEC 7, :func:`rhs_eval`: the closed loop's equations, torque
    limits and thruster dynamics included, as ``ClosedLoop.details`` and the thrust model
    evaluate them in NumPy, to rounding) at every row of ``X`` (K, n) in segment ``seg``,
    into ``out`` (K, n): the states of ``floquet.variational``'s finite differences (SPEC
    13). Returns -1, or the first row whose controller is singular (then ``out`` is
    incomplete)."""
    for r in range(X.shape[0]):
        if not rhs_eval(0.0, X[r], seg, fs, ip, par, w, out[r]):
            return r
    return -1


def kink_integrals(v, coef, anti, x, iters, out):
    """``int |p| dx`` over ``[-1, 1]`` (into ``out``) of polynomials ``p`` that change sign
    between some of the nodes ``x`` (ascending, with both ends): per row ``v`` its values at
    the nodes, ``coef`` its monomial coefficients in ``x``, ``anti`` those of its
    antiderivative vanishing at 0. Each root between two nodes of opposite sign is located by
    Illinois' regula falsi on ``p`` (at most ``iters`` steps, to rounding), and ``int |p| =
    sum |A(end) - A(start)|`` over the pieces between the roots and the ends (the same
    operations, element by element, as ``energetics.run._abs_integrals`` in NumPy; SPEC 15:
    positive and absolute work)."""
    K = x.size
    nc = coef.shape[1]
    na = anti.shape[1]
    for p in range(v.shape[0]):
        acc = 0.0  # A(-1)
        for j in range(na - 1, -1, -1):
            acc = acc * -1.0 + anti[p, j]
        prev = acc
        total = 0.0
        for g in range(K - 1):
            fa, fb = v[p, g], v[p, g + 1]
            if (fa >= 0.0) == (fb >= 0.0):
                continue
            a, b = x[g], x[g + 1]
            root = a if fa == 0.0 else b
            done = fa == 0.0 or fb == 0.0
            it = 0
            while not done and it < iters:  # bracket [a, b] (either order)
                it += 1
                xn = b - fb * (b - a) / (1.0 if fb == fa else fb - fa)
                lo, hi = min(a, b), max(a, b)
                if not (xn > lo and xn < hi):
                    xn = 0.5 * (a + b)
                fx = 0.0
                for j in range(nc - 1, -1, -1):
                    fx = fx * xn + coef[p, j]
                flip = (fx >= 0.0) != (fb >= 0.0)
                if flip:
                    a = b
                    fa = fb
                else:
                    fa = 0.5 * fa
                b = xn
                fb = fx
                root = xn
                done = fx == 0.0 or abs(b - a) <= 4e-16
            acc = 0.0
            for j in range(na - 1, -1, -1):
                acc = acc * root + anti[p, j]
            total += abs(acc - prev)
            prev = acc
        acc = 0.0  # A(1)
        for j in range(na - 1, -1, -1):
            acc = acc * 1.0 + anti[p, j]
        out[p] = total + abs(acc - prev)


def step_stats(calls, ncalls, buf, t0, t1, fs, ip, par, w, rec):
    """A step's statistics over its integration calls ``0..ncalls-1`` from ``t0`` to ``t1``
    [s] (as ``_impact_and_record``: the states at the integrator's nodes, the calls' ends and a
    uniform grid of the step): the extremes into ``w[W_ACC]`` (:func:`details_at`), and into
    ``rec`` the time and phase of the first ``F_1^v <= eps`` and of the first
    ``|F_1^h| > mu F_1^v`` (NaN: none), located by bisection on the dense output between the
    last sample where the condition held and the first where it did not."""
    N = ip[I_N]
    n = 2 * N + ip[I_NZ]
    xs = w[ip[W_XS]:]
    acc = w[ip[W_ACC]:]
    acc[0] = np.inf
    for i in range(1, 7):
        acc[i] = 0.0
    acc[2] = 1.0
    # the states first (nodes and ends of every integration call, the grid), then the
    # model's force program on all of them at once (the batch interpreter), then each state
    ng = ip[I_GRID]
    cnt = 0
    for ci in range(ncalls):
        cnt += stat_times(calls, ci, buf, ng, t0, t1, False, n, buf, buf[0], 0)
    SX = np.empty((cnt, n))
    ST = np.empty(cnt)
    SC = np.empty(cnt, np.int64)
    cnt = 0
    for ci in range(ncalls):
        k0 = cnt
        cnt += stat_times(calls, ci, buf, ng, t0, t1, True, n, SX, ST, cnt)
        for i in range(k0, cnt):
            SC[i] = ci
    nout = ip[ip[T_FORCE] + 1]
    SO = np.empty((cnt, nout))
    SM = SX
    if fs[F_SLOPE] != 0.0:  # on a slope: the model at the turned postures (kernel.tilted)
        SM = SX.copy()
        for i in range(cnt):
            SM[i, N - 1] += fs[F_SLOPE]
    tape_batch(ip, ip[T_FORCE], fs[N_FS:N_FS + ip[I_NCONST]], ip[I_C0], ip[I_NREG], SM, SO,
               32)
    D = w[ip[W_D]:]
    vo = ip[W_OUT]
    first = np.full(2, np.inf)
    at = np.full(2, -1, np.int64)
    for i in range(cnt):  # (row copies rather than views: a view costs reference counting)
        for j in range(nout):
            D[j] = SO[i, j]
        for j in range(n):
            xs[j] = SX[i, j]
        if not details_at(xs, int(calls[SC[i], 0]), fs, ip, par, w, E_PRE):
            continue
        fh, fv = w[vo + V_FH], w[vo + V_FV]
        if fv <= fs[F_EPS] and ST[i] < first[0]:
            first[0] = ST[i]
            at[0] = i
        if fv > 0 and abs(fh) > fs[F_MU] * fv and ST[i] < first[1]:
            first[1] = ST[i]
            at[1] = i
    ai, span = fs[F_AI], fs[F_SPAN]
    for which in range(2):
        i = at[which]
        if i < 0:
            rec[R_TLOW + 2 * which] = np.nan
            rec[R_SLOW + 2 * which] = np.nan
            continue
        ci = SC[i]
        prev = -np.inf
        for j in range(cnt):  # the last sample of the same call before it (the condition held)
            if SC[j] == ci and ST[j] < ST[i] and ST[j] > prev:
                prev = ST[j]
        te = ST[i]
        if prev > -np.inf:
            te = first_violation(buf, calls, ci, prev, ST[i], fs, ip, par, w, which, n)
        solution_at(buf, int(calls[ci, 1]), int(calls[ci, 2]), te, n, xs)
        rec[R_TLOW + 2 * which] = te
        rec[R_SLOW + 2 * which] = (alpha_of(xs, ip, par) - ai) / span


_F, _I, _B = "float64", "int64", "boolean"
_A, _A2, _A3 = "float64[::1]", "float64[:, ::1]", "float64[:, :, ::1]"
_IA = "int64[::1]"
_CTX = f"{_A}, {_IA}, {_A}, {_A}"  # fs, ip, par, w
SIGNATURES = {
    "stat_times": f"({_A2}, {_I}, {_A2}, {_I}, {_F}, {_F}, {_B}, {_I}, {_A2}, {_A}, {_I})",
    "details_at": f"({_A}, {_I}, {_CTX}, {_I})",
    "cone_violated": f"({_A}, {_I}, {_CTX}, {_I})",
    "first_violation": f"({_A2}, {_A2}, {_I}, {_F}, {_F}, {_CTX}, {_I}, {_I})",
    "step_stats": f"({_A2}, {_I}, {_A2}, {_F}, {_F}, {_CTX}, {_A})",
    "energy_nodes": f"({_A2}, {_A}, {_A}, {_IA}, {_IA}, {_A2}, {_A}, {_CTX}, {_A3})",
    "kink_integrals": f"({_A2}, {_A2}, {_A2}, {_A}, {_I}, {_A})",
    "rhs_rows": f"({_A2}, {_I}, {_CTX}, {_A2})",
}
# compiled without reference counting (model/jit.py): all but step_stats (it allocates the
# arrays of the step's states)
NRT_FREE = frozenset(SIGNATURES) - {"step_stats"}
# compiled into their one caller only (numba's IR inlining, see ``model/jit.py``):
# ``cone_violated`` into ``first_violation``, both into ``step_stats`` with ``details_at``
# (under its reference counting: they take no view per sample, ``first_violation`` one per
# call, at most two calls a step)
INLINED = frozenset({"details_at", "cone_violated", "first_violation"})
