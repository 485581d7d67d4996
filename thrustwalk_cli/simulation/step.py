"""One walking step of the compiled simulation (SPEC 1, 5, 7, 12) and the entry point ``run``:
numba source, part of the compiled module that :mod:`thrustwalk_cli.simulation.stepper`
assembles (see :mod:`.kernel`).

A step (``full_order._one_step`` and ``_impact_and_record``): from the post-impact state,
integration calls of :mod:`.integrator` segment by segment (the breakpoints in alpha, the
push of the step), the dip of the swing foot below the ground between two integrator steps
(found from the recorded lowest points and located on the dense output), every failure
condition, the strike, the impact map (SPEC 5) with the relabelling (SPEC 1) and the step's
record with its statistics (:mod:`.step_stats`). ``run`` walks a batch of runs, each with its
own parameters, gains and push. Units SI.
"""

import numpy as np

# ---- Python only: names of the sources before this one in the compiled module
from .integrator import (
    EPS,
    EV_NONE,
    MAX_EVENTS,
    ST_FULL,
    ST_SINGULAR,
    ST_SMALL,
    W_LOWS,
    W_XS,
    W_YE,
    brent,
    integrate,
    solution_at,
)
from .kernel import (
    EV_BREAK,
    EV_FOOT_MAX,
    EV_FOOT_MIN,
    EV_GUARD,
    EV_PUSH,
    EV_SCUFF,
    F_AI,
    F_BEHIND,
    F_DIR,
    F_GROUND,
    F_KD,
    F_KP,
    F_MINIMP,
    F_SCUFF,
    F_SLOPE,
    F_SPAN,
    F_TERRAIN,
    F_TMAX,
    FAIL_BUFFER,
    FAIL_CONTROLLER,
    FAIL_EARLY,
    FAIL_EVENT,
    FAIL_IMPACT_FY,
    FAIL_IMPACT_LIFT,
    FAIL_INTEGRATOR,
    FAIL_NO_IMPACT,
    FAIL_START_BELOW,
    FAIL_START_FORCE,
    I_C0,
    I_GUARD_IDX,
    I_M,
    I_N,
    I_NBRK,
    I_NCONST,
    I_NZ,
    N_FS,
    N_REC0,
    O_EVENT,
    O_S,
    O_STATUS,
    O_STEP,
    O_T,
    O_VALUE,
    OK,
    P_B,
    P_BRK,
    P_R,
    R_ALPHA0,
    R_ALPHAM,
    R_EM,
    R_EP,
    R_FX,
    R_FY,
    R_LIFT,
    R_MAXDY,
    R_MAXFR,
    R_MAXU,
    R_MAXY,
    R_MINFV,
    R_NFEV,
    R_PUSHED,
    R_SAT,
    R_SIG0,
    R_SIGM,
    R_SIGP,
    R_SM,
    R_STEP,
    R_T0,
    R_T1,
    R_TLOW,
    R_TPUSH,
    T_ENERGY,
    T_IMPACT,
    T_PUSH,
    W_A,
    W_ACC,
    W_DQI,
    W_F,
    W_GRID2,
    W_SIZE,
    W_TO,
    W_X,
    W_XE,
    W_XT,
    alpha_of,
    event_list,
    foot_velocity,
    gauss,
    swing_height,
    tape_run,
    thrust_out,
    tilted,
    vertical_force,
)
from .step_stats import step_stats

# ---- end Python only


def sigma_energy(q, dq, fs, ip, w):
    """``sigma_N = e_N^T D q'`` [kg m^2/s] and ``E = 1/2 q'^T D q' + V`` [J] (on a slope ``V``
    of the slope frame: the turned posture of :func:`tilted`)."""
    N = ip[I_N]
    if fs[F_SLOPE] != 0.0:
        tilted(q, N, fs, ip, w)
        tape_run(ip, ip[T_ENERGY], w[ip[W_XT]:], w, ip[W_TO])
    else:
        tape_run(ip, ip[T_ENERGY], q, w, ip[W_TO])
    D = w[ip[W_TO]:]
    sig = 0.0
    kin = 0.0
    for i in range(N):
        row = 0.0
        for j in range(N):
            row += D[i * N + j] * dq[j]
        kin += dq[i] * row
        if i == N - 1:
            sig = row
    return sig, 0.5 * kin + D[N * N]


def impact(q, dq, ip, par, w, q_plus, dq_plus):
    """Impact map and relabelling (SPEC 5, 1):
    ``[D_u, -E_2^T; E_2, 0][q_u'^+; F_2] = [D_u [q'^-; 0]; 0]``, ``q^+ = R q^- + b``,
    ``q'^+ = R q_u'^+[:N]``. Returns (ok, F_2x, F_2y, vertical velocity of the old stance
    foot)."""
    N = ip[I_N]
    n2 = N + 2
    Du, A, dqu = w[ip[W_TO]:], w[ip[W_A]:], w[ip[W_DQI]:]
    r0, b0 = ip[P_R], ip[P_B]
    tape_run(ip, ip[T_IMPACT], q, w, ip[W_TO])
    Eu = Du[n2 * n2:]
    wd = n2 + 2  # [D_u | E^T] -> D_u^-1 E^T  (n2 x 2)
    for i in range(n2):
        for j in range(n2):
            A[i * wd + j] = Du[i * n2 + j]
        A[i * wd + n2] = Eu[i]
        A[i * wd + n2 + 1] = Eu[n2 + i]
    if not gauss(A, n2, 2):
        return False, 0.0, 0.0, 0.0
    s00 = 0.0
    s01 = 0.0
    s10 = 0.0
    s11 = 0.0
    for i in range(n2):
        s00 += Eu[i] * A[i * wd + n2]
        s01 += Eu[i] * A[i * wd + n2 + 1]
        s10 += Eu[n2 + i] * A[i * wd + n2]
        s11 += Eu[n2 + i] * A[i * wd + n2 + 1]
    v0 = 0.0
    v1 = 0.0
    for j in range(N):
        v0 += Eu[j] * dq[j]
        v1 += Eu[n2 + j] * dq[j]
    det = s00 * s11 - s01 * s10
    if det == 0.0:
        return False, 0.0, 0.0, 0.0
    F0 = -(s11 * v0 - s01 * v1) / det  # F_2 = -(E D_u^-1 E^T)^-1 E [I; 0] q'
    F1 = -(-s10 * v0 + s00 * v1) / det
    for i in range(n2):
        dqu[i] = (dq[i] if i < N else 0.0) + A[i * wd + n2] * F0 + A[i * wd + n2 + 1] * F1
    for i in range(N):
        acc_q = 0.0
        acc_v = 0.0
        for j in range(N):
            acc_q += par[r0 + i * N + j] * q[j]
            acc_v += par[r0 + i * N + j] * dqu[j]
        q_plus[i] = acc_q + par[b0 + i]
        dq_plus[i] = acc_v
    return True, F0, F1, dqu[N + 1]


def apply_push(x, push, ip, w):
    """``q' += D(q)^-1 J_p(q)^T P`` (SPEC 12) for ``push = [step, s, link, lambda, P_x, P_y]``
    at the point ``(1 - lambda) origin + lambda end`` of the link [N s]. False if D is
    singular."""
    N = ip[I_N]
    D, A = w[ip[W_TO]:], w[ip[W_A]:]
    q = x[:N]
    tape_run(ip, ip[T_PUSH], q, w, ip[W_TO])
    lpJ = D[N * N:]
    li = int(push[2])
    lam = push[3]
    for i in range(N):
        for j in range(N):
            A[i * (N + 1) + j] = D[i * N + j]
        jx = (1.0 - lam) * lpJ[(4 * li) * N + i] + lam * lpJ[(4 * li + 2) * N + i]
        jy = (1.0 - lam) * lpJ[(4 * li + 1) * N + i] + lam * lpJ[(4 * li + 3) * N + i]
        A[i * (N + 1) + N] = jx * push[4] + jy * push[5]
    if not gauss(A, N, 1):
        return False
    for i in range(N):
        x[N + i] += A[i * (N + 1) + N]
    return True


def note_push(x, t, ip, rec):
    """The push's time [s] and the state just before it into ``rec``."""
    N, nz, m = ip[I_N], ip[I_NZ], ip[I_M]
    rec[R_TPUSH] = t
    off = N_REC0 + 2 * N + 2 * nz + m
    for i in range(2 * N + nz):
        rec[off + i] = x[i]


def push_or_fail(x, push, ip, w, out, k, t, s):
    """Apply the push of this step (:func:`apply_push`); if D is singular, record the failure
    (``controller`` at ``t``, ``s``) in ``out``. Returns whether the push was applied."""
    if apply_push(x, push, ip, w):
        return True
    fail(out, FAIL_CONTROLLER, k, t, s, 0.0, EV_PUSH)
    return False


def fail(out, code, k, t, s, value, event):
    out[O_STATUS] = code
    out[O_STEP] = k
    out[O_T] = t
    out[O_S] = s
    out[O_VALUE] = value
    out[O_EVENT] = event
    return code


def add_call(calls, j, seg, first, last, t0, t1):
    calls[j, 0] = seg
    calls[j, 1] = first
    calls[j, 2] = last
    calls[j, 3] = t0
    calls[j, 4] = t1
    return j + 1


def step_core(k, t0, x0, x_next, fs, ip, par, w, buf, calls, push, rec, out):
    """One walking step (``full_order._one_step`` and ``_impact_and_record``): from the
    post-impact state ``x0`` at ``t0`` to the next impact; ``x_next`` gets the relabelled
    post-impact state, ``rec`` the step record, ``out`` the outcome. ``calls`` lists the
    integration calls (restarts), whose steps are rows of ``buf``. ``push``: a push of this
    step when ``push[0] == k``. Returns (status, number of calls, rows of ``buf`` used).
    The statistics of a failed step are left to the caller (:func:`run`)."""
    N, m, nz, nbk = ip[I_N], ip[I_M], ip[I_NZ], ip[I_NBRK]
    n = 2 * N + nz
    x, xs, yend, xe = w[ip[W_X]:], w[ip[W_XS]:], w[ip[W_YE]:], w[ip[W_XE]:]
    grid, lows = w[ip[W_GRID2]:], w[ip[W_LOWS]:]
    for i in range(n):
        x[i] = x0[i]
    ai, span, d = fs[F_AI], fs[F_SPAN], fs[F_DIR]
    brk = ip[P_BRK]
    s0 = (alpha_of(x, ip, par) - ai) / span
    seg = 0
    for j in range(nbk):
        if par[brk + j] <= s0:
            seg = j + 1
    pushed = 0.0
    push_pending = push[0] == k
    a_push = ai + push[1] * span
    if push_pending and d * a_push <= d * alpha_of(x, ip, par):
        note_push(x, t0, ip, rec)
        if not push_or_fail(x, push, ip, w, out, k, t0, s0):
            return FAIL_CONTROLLER, 0, 0
        push_pending = False
        pushed = 1.0
    fv0 = vertical_force(x, seg, fs, ip, par, w)
    if fv0 < 0:
        return fail(out, FAIL_START_FORCE, k, t0, s0, fv0, EV_NONE), 0, 0
    h0 = swing_height(x, fs, ip, par, w) - fs[F_BEHIND]
    if h0 < -fs[F_SCUFF]:
        return fail(out, FAIL_START_BELOW, k, t0, s0, h0, EV_NONE), 0, 0
    t = t0
    rising = foot_velocity(x, fs, ip, par, w) >= 0.0
    ev = np.empty((4, MAX_EVENTS), np.int64)
    ncalls = 0
    nbuf = 0
    nfev = 0
    while True:
        nev = event_list(seg, rising, ip, push_pending, ev)
        a_next = ai + par[brk + seg] * span if seg < nbk else 0.0
        if ncalls >= calls.shape[0]:
            return fail(out, FAIL_BUFFER, k, t, 0.0, 0.0, EV_NONE), ncalls, nbuf
        first = nbuf
        status, t1, name, n_lows, nbuf, nf = integrate(
            t, x, t0 + fs[F_TMAX], seg, ev, nev, fs, ip, par, w, buf, nbuf, a_next, a_push)
        nfev += nf
        if status == ST_FULL:
            return fail(out, FAIL_BUFFER, k, t, 0.0, 0.0, EV_NONE), ncalls, nbuf
        if status == ST_SINGULAR:
            s = (alpha_of(x, ip, par) - ai) / span
            return fail(out, FAIL_CONTROLLER, k, t, s, 0.0, EV_NONE), ncalls, nbuf
        for i in range(n):
            xe[i] = yend[i]
        # a dip of the swing foot below the ground between two integrator steps (_dip): once
        # the guard is armed, below the ground where it lands (F_TERRAIN), before below the
        # ground it left or stands on (F_BEHIND)
        armed = seg > ip[I_GUARD_IDX]
        limit = -fs[F_GROUND] if armed else -fs[F_SCUFF]
        ground = fs[F_TERRAIN] if armed else fs[F_BEHIND]
        dip = EV_NONE
        t_dip = 0.0
        for j in range(n_lows):
            tm = lows[j]
            if tm > t1:
                continue
            solution_at(buf, first, nbuf, tm, n, xs)
            if swing_height(xs, fs, ip, par, w) - ground >= limit:
                continue
            if not armed:
                dip, t_dip = EV_SCUFF, tm
                break
            # the downward crossing before the lowest point, on a 65-point grid
            hprev = 0.0
            found = -1
            for gi in range(65):
                tt = t + gi * ((tm - t) / 64.0) if gi < 64 else tm
                grid[gi] = tt
                solution_at(buf, first, nbuf, tt, n, xs)
                hh = swing_height(xs, fs, ip, par, w) - ground
                if gi > 0 and hprev > 0 and hh <= 0 and found < 0:
                    found = gi - 1
                hprev = hh
            if found < 0:
                dip, t_dip = EV_SCUFF, t
                break
            ga, gb = grid[found], grid[found + 1]
            solution_at(buf, first, nbuf, ga, n, xs)
            fa = swing_height(xs, fs, ip, par, w) - ground
            solution_at(buf, first, nbuf, gb, n, xs)
            fb = swing_height(xs, fs, ip, par, w) - ground
            dip = EV_GUARD
            t_dip = brent(EV_GUARD, ga, gb, fa, fb, buf, first, nbuf, seg, fs, ip, par, w, n,
                          a_next, a_push, 1e-14, 4 * EPS)
            break
        if dip != EV_NONE:
            name = dip
            t1 = t_dip
            solution_at(buf, first, nbuf, t1, n, xe)
        elif status == ST_SMALL:
            if t1 > t:
                ncalls = add_call(calls, ncalls, seg, first, nbuf, t, t1)
            # past the gait's end with the guard armed: a missed touchdown (physics), which
            # the caller words as such; value 1 flags the armed guard
            s1 = (alpha_of(xe, ip, par) - ai) / span
            return (fail(out, FAIL_INTEGRATOR, k, t1, s1, 1.0 if armed else 0.0, EV_NONE),
                    ncalls, nbuf)
        if t1 > t:
            ncalls = add_call(calls, ncalls, seg, first, nbuf, t, t1)
        t = t1
        for i in range(n):
            x[i] = xe[i]
        if name == EV_FOOT_MIN or name == EV_FOOT_MAX:
            rising = name == EV_FOOT_MIN
            continue
        if name == EV_NONE:
            return (fail(out, FAIL_NO_IMPACT, k, t, 0.0, alpha_of(x, ip, par), EV_NONE),
                    ncalls, nbuf)
        if name == EV_BREAK or name == EV_PUSH:
            if name == EV_BREAK:
                seg += 1
                # watch the swing foot's next extremum from here: a foot already moving down
                # when the guard is armed must be watched for its lowest point (a shallow dip
                # below the ground at a slow touchdown lies between two integrator steps),
                # not for an apex
                rising = foot_velocity(x, fs, ip, par, w) >= 0.0
            else:
                note_push(x, t, ip, rec)
                if not push_or_fail(x, push, ip, w, out, k, t, push[1]):
                    return FAIL_CONTROLLER, ncalls, nbuf
                push_pending = False
                pushed = 1.0
                # ``rising`` is kept, as at a breakpoint: a zero push changes nothing
            # events due at the same alpha (a push at a breakpoint's phase, e.g. at
            # min_impact_s): the one located first leaves the others at a value >= 0, where
            # the next call would see no crossing and miss them (the guard never armed)
            a_here = d * alpha_of(x, ip, par)
            while seg < nbk and a_here >= d * (ai + par[brk + seg] * span):
                seg += 1
                rising = foot_velocity(x, fs, ip, par, w) >= 0.0
            if push_pending and a_here >= d * a_push:
                note_push(x, t, ip, rec)
                if not push_or_fail(x, push, ip, w, out, k, t, push[1]):
                    return FAIL_CONTROLLER, ncalls, nbuf
                push_pending = False
                pushed = 1.0
            continue
        if name == EV_GUARD:
            break
        s = (alpha_of(x, ip, par) - ai) / span
        return fail(out, FAIL_EVENT, k, t, s, 0.0, name), ncalls, nbuf
    # -- the strike
    alpha_m = alpha_of(x, ip, par)
    s_minus = (alpha_m - ai) / span
    if s_minus < fs[F_MINIMP]:
        return fail(out, FAIL_EARLY, k, t, s_minus, 0.0, EV_NONE), ncalls, nbuf
    ok, Fx, Fy, lift = impact(x[:N], x[N:2 * N], ip, par, w, x_next[:N], x_next[N:2 * N])
    if not ok:
        return fail(out, FAIL_CONTROLLER, k, t, s_minus, 0.0, EV_NONE), ncalls, nbuf
    if Fy <= 0:
        return fail(out, FAIL_IMPACT_FY, k, t, s_minus, Fy, EV_NONE), ncalls, nbuf
    if lift <= 0:
        return fail(out, FAIL_IMPACT_LIFT, k, t, s_minus, lift, EV_NONE), ncalls, nbuf
    for i in range(nz):
        x_next[2 * N + i] = x[2 * N + i]
    # -- statistics on the integrator's nodes and a uniform grid of the step
    acc = w[ip[W_ACC]:]
    step_stats(calls, ncalls, buf, t0, t, fs, ip, par, w, rec)
    sig_m, e_m = sigma_energy(x[:N], x[N:2 * N], fs, ip, w)
    sig_p, e_p = sigma_energy(x_next[:N], x_next[N:2 * N], fs, ip, w)
    sig_0, e_0 = sigma_energy(x0[:N], x0[N:2 * N], fs, ip, w)
    rec[R_STEP] = k
    rec[R_T0] = t0
    rec[R_T1] = t
    rec[R_ALPHA0] = alpha_of(x0, ip, par)
    rec[R_ALPHAM] = alpha_m
    rec[R_SM] = s_minus
    rec[R_SIG0] = sig_0
    rec[R_SIGM] = sig_m
    rec[R_SIGP] = sig_p
    rec[R_FX] = Fx
    rec[R_FY] = Fy
    rec[R_LIFT] = lift
    rec[R_MINFV] = acc[0]
    rec[R_MAXFR] = acc[1] if acc[2] > 0 else np.nan
    rec[R_MAXY] = acc[3]
    rec[R_MAXDY] = acc[4]
    rec[R_MAXU] = acc[5]
    rec[R_SAT] = acc[6]
    rec[R_EM] = e_m
    rec[R_EP] = e_p
    rec[R_NFEV] = nfev
    rec[R_PUSHED] = pushed
    off = N_REC0
    for i in range(N):
        rec[off + i] = x[i]
        rec[off + N + i] = x[N + i]
    off += 2 * N
    for i in range(nz):
        rec[off + i] = x0[2 * N + i]
        rec[off + nz + i] = x[2 * N + i]
    off += 2 * nz
    thrust_out(x, seg, ip, par, w)  # the thrust at impact (of the last segment)
    for i in range(m):
        rec[off + i] = w[ip[W_F] + i]
    out[O_STATUS] = OK
    out[O_STEP] = k
    out[O_T] = t
    out[O_S] = s_minus
    return OK, ncalls, nbuf


def run(X0, T0, K0, n_steps, fs, ip, PAR, GAINS, PUSH, recs, outs, done, XN, info, lo, hi,
        buf, calls):
    """Runs ``lo..hi-1`` of a batch (one thread's share), ``n_steps`` walking steps each:
    run ``r`` starts at the post-impact state ``X0[r]`` at time ``T0[r]`` [s] with step
    number ``K0[r]``, with its own parameters ``PAR[r]`` (thrust values), gains ``GAINS[r] =
    (kp, kd)`` and push ``PUSH[r]``. Outputs: one record per completed step in ``recs[r]``,
    the outcome in ``outs[r]``, the number of completed steps in ``done[r]``, the last
    post-impact state in ``XN[r]``, and ``info[r] = (calls, rows of buf)`` of its last step
    (whose dense output stays in ``buf`` and ``calls``). A step that outgrows ``buf`` or
    ``calls`` ends its run with ``FAIL_BUFFER`` (the caller retries with larger ones)."""
    N, nz = ip[I_N], ip[I_NZ]
    n = 2 * N + nz
    w = np.zeros(ip[W_SIZE])
    for i in range(ip[I_NCONST]):  # the tape's constants into their registers
        w[ip[I_C0] + i] = fs[N_FS + i]
    fsr = fs.copy()
    x = np.empty(n)
    x_next = np.empty(n)
    for r in range(lo, hi):
        fsr[F_KP] = GAINS[r, 0]
        fsr[F_KD] = GAINS[r, 1]
        out = outs[r]
        for i in range(n):
            x[i] = X0[r, i]
        t = T0[r]
        out[O_STATUS] = OK
        out[O_STEP] = K0[r] - 1
        completed = 0
        for j in range(n_steps):
            k = K0[r] + j
            rec = recs[r, j]
            for i in range(R_TLOW, R_TPUSH + 1):
                rec[i] = np.nan
            st, nc, nbuf = step_core(k, t, x, x_next, fsr, ip, PAR[r], w, buf, calls, PUSH[r],
                                     rec, out)
            if st != OK and st != FAIL_BUFFER and nc > 0:
                # a step that failed after it started to integrate still gets, in its
                # record, the first times its stance force left the cone up to the failure
                # (step_stats; its push's time and state are written by step_core): what
                # came first is for the caller to tell
                step_stats(calls, nc, buf, t, out[O_T], fsr, ip, PAR[r], w, rec)
            info[r, 0] = nc
            info[r, 1] = nbuf
            if st != OK:
                break
            completed = j + 1
            t = out[O_T]
            for i in range(n):
                x[i] = x_next[i]
        for i in range(n):
            XN[r, i] = x[i]
        done[r] = completed
    return 0


_F, _I = "float64", "int64"
_A, _A2, _A3 = "float64[::1]", "float64[:, ::1]", "float64[:, :, ::1]"
_IA, _IA2 = "int64[::1]", "int64[:, ::1]"
_CTX = f"{_A}, {_IA}, {_A}, {_A}"  # fs, ip, par, w
SIGNATURES = {
    "note_push": f"({_A}, {_F}, {_IA}, {_A})",
    "sigma_energy": f"({_A}, {_A}, {_A}, {_IA}, {_A})",
    "impact": f"({_A}, {_A}, {_IA}, {_A}, {_A}, {_A}, {_A})",
    "apply_push": f"({_A}, {_A}, {_IA}, {_A})",
    "fail": f"({_A}, {_I}, {_I}, {_F}, {_F}, {_F}, {_I})",
    "push_or_fail": f"({_A}, {_A}, {_IA}, {_A}, {_A}, {_I}, {_F}, {_F})",
    "add_call": f"({_A2}, {_I}, {_I}, {_I}, {_I}, {_F}, {_F})",
    "step_core": f"({_I}, {_F}, {_A}, {_A}, {_CTX}, {_A2}, {_A2}, {_A}, {_A}, {_A})",
    "run": f"({_A2}, {_A}, {_IA}, {_I}, {_A}, {_IA}, {_A2}, {_A2}, {_A2}, {_A3}, {_A2}, "
           f"{_IA}, {_A2}, {_IA2}, {_I}, {_I}, {_A2}, {_A2})",
}
# compiled without reference counting (model/jit.py): everything but the functions that
# allocate arrays (``run``: the work array; ``step_core``: the events); the work array and
# every buffer belong to ``run`` and its caller
NRT_FREE = frozenset(SIGNATURES) - {"run", "step_core"}
# compiled into their one caller only (numba's IR inlining, see ``model/jit.py``): the step
# into ``run``, so that the whole closed loop below it is optimized and translated to machine
# code once, in ``run``'s library, not once more for the step; ``apply_push`` into
# ``push_or_fail``; ``impact`` into the step (under its reference counting: three views, once
# a step)
INLINED = frozenset({"step_core", "apply_push", "impact"})
