"""The walker's closed loop of SPEC 7 in the compiled simulation: numba source, compiled once
per machine.

This module is plain Python written in the subset numba compiles. It is never jit-compiled
where it stands: :mod:`thrustwalk_cli.simulation.stepper` concatenates the generic integrator
(:mod:`.integrator`: DOP853, dense output, event location), this source (the walker's
right-hand side and events, the problem the integrator solves), the walker's step
(:mod:`.step_stats`, :mod:`.step`), the tape interpreter of :mod:`thrustwalk_cli.model.tape`
(whose definitions come later in the file and so replace the placeholders below) and the
DOP853 coefficients of :class:`scipy.integrate.DOP853`, and caches the compiled result in the
thrustwalk cache folder (:mod:`thrustwalk_cli.model.jit`). No robot appears in the code: the
model (D, h, B_F, the ground-force rows, swing-foot kinematics, impact terms) is the robot's
*tape*, appended to the integer settings ``ip`` and run by the interpreter, so one compiled
kernel serves every robot. The block marked *Python only* gives the names the other sources
define to this module as Python sees it (and to ruff); the compiled module leaves it out.

What it computes is, equation for equation, the SciPy reference path of
:mod:`thrustwalk_cli.simulation.full_order` and :class:`~thrustwalk_cli.simulation.
closed_loop.ClosedLoop`:

* right-hand side: the input-output linearising controller ``y'' = -K_p y - K_d y'`` reduced
  to a 2 x 2 system in ``(alpha'', q_N'')``, torque saturation with ``D q'' = -h + B_tau u +
  B_F F_T`` (+ ``e_N T``), the thruster states of any linear model of
  :mod:`thrustwalk_cli.thrust.dynamics` (its servo form's matrices in ``par``) under a command
  constant over the run or piecewise in alpha (force or generalised mode);
* events (``ClosedLoop.events``): the breakpoints in alpha, the guard, the scuff, the
  overshoot, the swing foot's extrema, alpha reversing, the stance link horizontal, the
  vertical ground force; the push of a step (SPEC 12);
* the layout of every array the simulation passes (settings, parameters, work array, step
  records and outcomes), read by :mod:`.stepper`.

Arrays are flat and row-major (parameters in `par`, scratch in `w`, offsets in `ip`: few
arguments per call keep both the compile time and the call overhead low); units SI.

Speed (issue 13's target of 40 times the SciPy path per step; measured, none of it changes a
value: the same operations in the same order): every function that allocates nothing is
compiled without numba's reference counting (:data:`NRT_FREE`, see
:mod:`thrustwalk_cli.model.jit`: an array argument or a view would otherwise cost two atomic
updates); the vertical ground force at an integrator node, the event ``force``, comes with
the right-hand side of the step's last stage (:func:`rhs_node`: the force program is a
superset of the acceleration program) instead of a second evaluation; the controller's
loops and the dense output index with unsigned offsets (numba then skips its negative-index
correction), and the gait's rows are evaluated two at a time; the Runge-Kutta stage sums run
column by column.
"""

import numpy as np

# ---- Python only: names of the sources before this one in the compiled module
from .integrator import (
    I_DIM,
    MAX_EVENTS,
    N_FS_INTEGRATOR,
    N_IP_INTEGRATOR,
    scratch,
)

# ---- end Python only

# ------------------------------------------------------------------ placeholder (replaced)
# the tape interpreter (model/tape.py), defined again (for real) later in the compiled file


def tape_run(code, p, x, r, o):  # noqa: D103
    raise NotImplementedError


def tape_batch(code, p, consts, c0, nreg, X, out, chunk):  # noqa: D103
    raise NotImplementedError


# ------------------------------------------------------------------ layout
# float settings fs[...] (after the integrator's rtol, atol)
(F_AI, F_SPAN, F_DIR, F_KP, F_KD, F_TLIM, F_SCUFF, F_MINIMP, F_MAXS, F_GROUND, F_TMAX, F_MU,
 F_EPS, F_SLOPE, F_COSG, F_SING, F_TERRAIN, F_BEHIND) = range(N_FS_INTEGRATOR,
                                                               N_FS_INTEGRATOR + 18)
# F_MU, F_EPS: the cone a step's first exit is timed against (mu inf: no slip timing);
# F_SLOPE, F_COSG, F_SING: the ground angle gamma [rad] (SPEC 14; 0: level ground) and its
# cosine and sine; F_TERRAIN: the height [m] of the ground where this step's swing foot lands,
# above the stance foot and normal to the slope (SPEC 14; 0: level ground): the guard;
# F_BEHIND: the ground the scuff checks measure from before the guard is armed [m]: the lower
# of the stance foot's level (0) and the level the swing foot left (the previous step's
# height below the stance foot)
N_FS = N_FS_INTEGRATOR + 18
# integer settings ip[...] (after the integrator's): sizes, then offsets into par (P_*) and
# into the work array (W_*)
(I_N, I_M, I_NZ, I_CMD, I_ROOT_END, I_GUARD_IDX, I_GRID, I_NLINKS, I_NCOL,
 I_NBRK) = range(N_IP_INTEGRATOR, N_IP_INTEGRATOR + 10)
# par: gait rows, c, breakpoints, thrust commands (per segment, constant), R, b, and the
# thruster dynamics in the servo form E z' = P z + Q (u - K z), F = C z + D u
# (thrust/dynamics.py: ThrusterDynamics.kernel_data)
(P_ROWS, P_C, P_BRK, P_SEGF, P_SEGT, P_TGT, P_R, P_B, P_DE, P_DP, P_DQ, P_DK, P_DC, P_DD,
 P_SIZE) = range(I_NBRK + 1, I_NBRK + 16)
(W_D, W_H, W_BF, W_GR, W_RHS, W_F, W_GH, W_BY, W_DDQ, W_U, W_A, W_TO, W_P2, W_FV, W_LP,
 W_X, W_XE, W_DQI, W_ACC, W_GRID2, W_OUT, W_CMD, W_ERR, W_XT, W_SIZE) = range(P_SIZE + 1,
                                                                             P_SIZE + 26)
# the model's tape (appended to ``ip``): offsets of its programs, the number of constants
# (in ``fs`` from N_FS on) and their first register; registers are ``w[:nreg]``
T_ACCEL, T_FORCE, T_HEIGHT, T_FOOTVEL, T_LINKS, T_IMPACT, T_ENERGY, T_PUSH = range(
    W_SIZE + 1, W_SIZE + 9)
I_NCONST, I_C0, I_NREG = T_PUSH + 1, T_PUSH + 2, T_PUSH + 3
N_IP = T_PUSH + 4
# what evaluate() computes (bit flags) and where its scalar results go (w[W_OUT + ...])
E_ACCEL, E_U, E_FORCE, E_HEIGHT, E_FOOTVEL, E_ROOT, E_PRE = 1, 2, 4, 8, 16, 32, 64
E_FIXF = 128  # the thrust given in w[W_F] (no generalised force): energies (step_stats)
V_FH, V_FV, V_HEIGHT, V_FOOTVEL, V_ROOT, V_SAT, V_FNODE = 0, 1, 2, 3, 4, 5, 6
# thrust commands: constant over the run (P_TGT) or piecewise in alpha (P_SEGF, P_SEGT)
CMD_CONSTANT, CMD_PIECEWISE = 0, 1
# events (0: none, integrator.EV_NONE)
EV_BREAK, EV_GUARD, EV_OVERSHOOT, EV_SCUFF = 1, 2, 3, 4
EV_FOOT_MAX, EV_FOOT_MIN, EV_REVERSE, EV_HORIZONTAL, EV_FORCE, EV_PUSH = 5, 6, 7, 8, 9, 10
# outcome of a step / run
OK, FAIL_START_FORCE, FAIL_START_BELOW, FAIL_INTEGRATOR, FAIL_CONTROLLER = 0, 1, 2, 3, 4
FAIL_NO_IMPACT, FAIL_EVENT, FAIL_EARLY, FAIL_IMPACT_FY, FAIL_IMPACT_LIFT = 5, 6, 7, 8, 9
FAIL_BUFFER = 10
# step record rec[...] (then q^- (N), q'^- (N), z_start (nz), z^- (nz), F at impact (m), the
# state just before the push (2 N + nz)). R_TLOW/R_SLOW: time [s] and phase of the first
# F_1^v <= eps, R_TSLIP/R_SSLIP of the first |F_1^h| > mu F_1^v (F_1^v > 0), R_TPUSH the
# push's time (NaN: none); these five are written for a failed step too (up to its failure)
R_STEP, R_T0, R_T1, R_ALPHA0, R_ALPHAM, R_SM, R_SIG0, R_SIGM, R_SIGP = range(9)
R_FX, R_FY, R_LIFT, R_MINFV, R_MAXFR, R_MAXY, R_MAXDY, R_MAXU, R_SAT = range(9, 18)
R_EM, R_EP, R_NFEV, R_PUSHED = range(18, 22)
R_TLOW, R_SLOW, R_TSLIP, R_SSLIP, R_TPUSH = range(22, 27)
N_REC0 = 27
# outcome out[...]: status, step, t, s, value, event
O_STATUS, O_STEP, O_T, O_S, O_VALUE, O_EVENT = range(6)
N_OUT = 6
# dense buffer rows: [t_old, t_new, y_old (n), F (7 n)]; calls: [seg, first, last, t0, t1]
N_CALL = 5


def layout(N, m, nz, nlinks, ncol, nbrk, nreg):
    """Sizes and offsets for ``ip`` (plain Python, used to build the kernel's arguments);
    the work array ``w`` starts with the tape's ``nreg`` registers, the integrator's scratch
    (:func:`~thrustwalk_cli.simulation.integrator.scratch`) after the walker's arrays."""
    n = 2 * N + nz
    n2 = N + 2
    mm = max(m, 1)
    nb = N - 1
    ip = [0] * N_IP
    ip[I_DIM] = n
    ip[I_N], ip[I_M], ip[I_NZ], ip[I_NLINKS], ip[I_NCOL], ip[I_NBRK] = N, m, nz, nlinks, ncol, nbrk
    nzz = max(nz, 1)
    par = [(P_ROWS, 3 * nb * ncol), (P_C, N), (P_BRK, max(nbrk, 1)),
           (P_SEGF, (nbrk + 1) * mm), (P_SEGT, nbrk + 1), (P_TGT, mm), (P_R, N * N),
           (P_B, N), (P_DE, nzz), (P_DP, nzz * nzz), (P_DQ, nzz * mm), (P_DK, mm * nzz),
           (P_DC, mm * nzz), (P_DD, mm * mm)]
    off = 0
    for key, size in par:
        ip[key] = off
        off += size
    ip[P_SIZE] = off
    # D, h, B_F and the ground-force rows are contiguous: the tape's accel/force outputs
    to = max(N * N + 1, n2 * n2 + 2 * n2, N * N + 4 * nlinks * N)
    work = [(W_D, N * N), (W_H, N), (W_BF, N * m), (W_GR, 2 * N + 2 + 2 * m + 1), (W_RHS, N),
            (W_F, mm), (W_GH, 3 * nb), (W_BY, nb), (W_DDQ, N), (W_U, nb),
            (W_A, n2 * (n2 + 2)), (W_TO, to), (W_P2, 2), (W_FV, 1), (W_LP, 4 * nlinks),
            (W_X, n), (W_XE, n), (W_DQI, n2), (W_ACC, 8), (W_GRID2, 65), (W_OUT, 8),
            (W_CMD, mm), (W_ERR, mm), (W_XT, 2 * N)] + scratch(n)
    off = nreg
    for key, size in work:
        ip[key] = off
        off += size
    ip[W_SIZE] = off
    return ip


# ------------------------------------------------------------------ small helpers
def gauss(A, n, nrhs):
    """Solve in place: ``A`` is (n, n + nrhs) flat row-major; partial pivoting. Returns
    False if singular; the solution overwrites the last ``nrhs`` columns."""
    w = n + nrhs
    for k in range(n):
        p, big = k, abs(A[k * w + k])
        for i in range(k + 1, n):
            if abs(A[i * w + k]) > big:
                p, big = i, abs(A[i * w + k])
        if big == 0.0:
            return False
        if p != k:
            for j in range(w):
                tmp = A[k * w + j]
                A[k * w + j] = A[p * w + j]
                A[p * w + j] = tmp
        pk = A[k * w + k]
        for i in range(k + 1, n):
            f = A[i * w + k] / pk
            if f != 0.0:
                for j in range(k + 1, w):
                    A[i * w + j] -= f * A[k * w + j]
    for r in range(nrhs):
        col = n + r
        for i in range(n - 1, -1, -1):
            acc = A[i * w + col]
            for j in range(i + 1, n):
                acc -= A[i * w + j] * A[j * w + col]
            A[i * w + col] = acc / A[i * w + i]
    return True


def tilted(x, n, fs, ip, w):
    """The first ``n`` values of the state ``x`` with the whole robot turned by the slope
    into ``w[W_XT]``: ``q_N + gamma``, the posture in the world frame
    (SPEC 14; ``q_N`` the absolute angle, counter-clockwise, the actuated ones relative). The
    level-ground model at the turned posture is the slope-frame model: ``D`` and ``C`` do not
    change, ``G``, ``V`` and the world thrusters' ``B_F`` are those of gravity ``g (-sin,
    -cos)`` and directions turned by ``-gamma``; the ground-force rows come out in world
    components (turned back in :func:`evaluate`). Heights above the ground, the swing foot,
    the impact and the pushes stay in the slope frame (the untilted state)."""
    o = ip[W_XT]
    for i in range(n):
        w[o + i] = x[i]
    w[o + ip[I_N] - 1] += fs[F_SLOPE]


def alpha_of(x, ip, par):
    """``alpha = c q`` [rad]."""
    c0 = ip[P_C]
    acc = 0.0
    for i in range(ip[I_N]):
        acc += par[c0 + i] * x[i]
    return acc


def alpha_rate(x, ip, par):
    """``alpha' = c q'`` [rad/s]."""
    c0, N = ip[P_C], ip[I_N]
    acc = 0.0
    for i in range(N):
        acc += par[c0 + i] * x[N + i]
    return acc


# ------------------------------------------------------------------ closed loop
def evaluate(x, seg, fs, ip, par, w, what):
    """Everything the closed loop needs at one state, the only caller of the model's
    right-hand-side functions (one compiled copy of them). ``what``: flags ``E_*``.

    ``E_ACCEL``: thrust into ``w[W_F]``, ``q''`` into ``w[W_DDQ]`` by the equations of
    ``ClosedLoop._accel`` (and ``u`` into ``w[W_U]`` with ``E_U`` or torque limits, the
    saturation flag into ``w[W_OUT + V_SAT]``); ``E_FORCE``: the ground force
    ``F_1 = rows N+1..N+2 of (D_u [q''; 0] + h_u(q, [q'; 0]) - B_Fu F_T)`` [N] (SPEC 5) into
    ``w[W_OUT + V_FH]``, ``w[W_OUT + V_FV]`` (on a slope: tangential and normal to it, the
    dynamics at the turned posture of :func:`tilted`); ``E_HEIGHT``/``E_FOOTVEL``: swing-foot height
    [m] and vertical velocity ``E_2,y q'`` [m/s]; ``E_ROOT``: height of the stance link's far
    end [m]. ``E_FIXF``: the thrust is the one already in ``w[W_F]`` (the command and the
    thruster states not read) and no generalised force (``ClosedLoop.law`` with ``force``).
    Returns False if the decoupling matrix (or D, when torques saturate) is singular."""
    N, m = ip[I_N], ip[I_M]
    vo = ip[W_OUT]
    if what & E_HEIGHT:
        tape_run(ip, ip[T_HEIGHT], x, w, ip[W_P2])
        w[vo + V_HEIGHT] = w[ip[W_P2] + 1]
    if what & E_FOOTVEL:
        tape_run(ip, ip[T_FOOTVEL], x, w, ip[W_FV])
        w[vo + V_FOOTVEL] = w[ip[W_FV]]
    if what & E_ROOT:
        tape_run(ip, ip[T_LINKS], x, w, ip[W_LP])
        w[vo + V_ROOT] = w[ip[W_LP] + ip[I_ROOT_END]]
    if not what & (E_ACCEL | E_U | E_FORCE):
        return True
    # offsets into w, not views of it: a view costs two atomic reference-count updates
    # (measured: this function 25 % faster); unsigned, so that numba skips its
    # negative-index correction (measured: another 20-25 %)
    u = np.uint64
    uN, um = u(N), u(m)
    unb = uN - u(1)
    oD, oh, oBF, orhs, oF = u(ip[W_D]), u(ip[W_H]), u(ip[W_BF]), u(ip[W_RHS]), u(ip[W_F])
    oH, oby, oddq, ou = u(ip[W_GH]), u(ip[W_BY]), u(ip[W_DDQ]), u(ip[W_U])
    c0 = u(ip[P_C])
    if not what & E_FIXF:
        thrust_out(x, seg, ip, par, w)
    # D, h, B_F (and with E_FORCE the ground-force rows) from the model's tape (already in
    # place with E_PRE)
    if not what & E_PRE:
        prog = ip[T_FORCE] if what & E_FORCE else ip[T_ACCEL]
        if fs[F_SLOPE] != 0.0:  # on a slope: the turned posture (:func:`tilted`)
            tilted(x, 2 * N, fs, ip, w)
            tape_run(ip, prog, w[ip[W_XT]:], w, ip[W_D])
        else:
            tape_run(ip, prog, x, w, ip[W_D])
    for i in range(uN):
        w[orhs + i] = -w[oh + i]
    if m > 0:
        for i in range(uN):
            acc = 0.0
            for k in range(um):
                acc += w[oBF + i * um + k] * w[oF + k]
            w[orhs + i] += acc
    if ip[I_CMD] == CMD_PIECEWISE and not what & E_FIXF:
        w[orhs + unb] += par[ip[P_SEGT] + seg]
    alpha = 0.0
    adot = 0.0
    for i in range(uN):
        alpha += par[c0 + i] * x[i]
        adot += par[c0 + i] * x[uN + i]
    # gait values [h_d; h_d'; h_d''] from power-basis rows (ScalarGait)
    s = (alpha - fs[F_AI]) / fs[F_SPAN]
    ucol = u(ip[I_NCOL])
    r0 = u(ip[P_ROWS])
    nrow = u(3) * unb
    one = u(1)
    ri = u(0)
    while ri < nrow:  # two rows at a time: two independent chains of additions
        ri2 = ri + one if ri + one < nrow else ri
        o1 = r0 + ri * ucol
        o2 = r0 + ri2 * ucol
        a0 = 0.0
        a1 = 0.0
        pw = 1.0
        for k in range(ucol):
            a0 += par[o1 + k] * pw
            a1 += par[o2 + k] * pw
            pw *= s
        w[oH + ri] = a0
        w[oH + ri2] = a1
        ri += u(2)
    kp, kd = fs[F_KP], fs[F_KD]
    ad2 = adot * adot
    oH1, oH2 = oH + unb, oH + u(2) * unb
    for i in range(unb):
        w[oby + i] = (-kp * (x[i] - w[oH + i]) - kd * (x[uN + i] - w[oH1 + i] * adot)
                      + w[oH2 + i] * ad2)
    # the 2 x 2 system in (alpha'', q_N'') of ClosedLoop._accel
    a11 = 1.0
    a21 = 0.0
    r1 = 0.0
    r2 = w[orhs + unb]
    oDN = oD + unb * uN  # the last row of D
    for i in range(unb):
        a11 -= par[c0 + i] * w[oH1 + i]
        a21 += w[oDN + i] * w[oH1 + i]
        r1 += par[c0 + i] * w[oby + i]
        r2 -= w[oDN + i] * w[oby + i]
    DNN = w[oDN + unb]
    cN = par[c0 + unb]
    det = a11 * DNN + cN * a21
    if det == 0.0:
        return False
    a = (r1 * DNN + cN * r2) / det
    for i in range(unb):
        w[oddq + i] = w[oby + i] + w[oH1 + i] * a
    w[oddq + unb] = (a11 * r2 - a21 * r1) / det
    lim = fs[F_TLIM]
    w[vo + V_SAT] = 0.0
    if what & E_U or lim < np.inf:
        big = 0.0
        for i in range(unb):
            acc = 0.0
            oDi = oD + i * uN
            for j in range(uN):
                acc += w[oDi + j] * w[oddq + j]
            w[ou + i] = acc - w[orhs + i]
            if abs(w[ou + i]) > big:
                big = abs(w[ou + i])
        if lim < np.inf and big > lim:
            w[vo + V_SAT] = 1.0
            for i in range(unb):
                w[ou + i] = min(max(w[ou + i], -lim), lim)
            oA = u(ip[W_A])
            uN1 = uN + u(1)
            for i in range(uN):
                for j in range(uN):
                    w[oA + i * uN1 + j] = w[oD + i * uN + j]
                w[oA + i * uN1 + uN] = w[orhs + i] + (w[ou + i] if i < unb else 0.0)
            if not gauss(w[ip[W_A]:], N, 1):
                return False
            for i in range(uN):
                w[oddq + i] = w[oA + i * uN1 + uN]
    if what & E_FORCE:
        # rows N, N+1 of D_u (first N columns), of h_u(q, [q'; 0; 0]) and of B_Fu
        ogr = u(ip[W_GR])
        ohg, obg = ogr + u(2) * uN, ogr + u(2) * uN + u(2)
        for r in range(u(2)):
            acc = 0.0
            ogn = ogr + r * uN
            for j in range(uN):
                acc += w[ogn + j] * w[oddq + j]
            acc += w[ohg + r]
            for k in range(um):
                acc -= w[obg + r * um + k] * w[oF + k]
            w[u(vo + V_FH) + r] = acc
        if fs[F_SLOPE] != 0.0:  # world components -> tangential and normal to the slope
            cg, sg = fs[F_COSG], fs[F_SING]
            fx, fy = w[vo + V_FH], w[vo + V_FV]
            w[vo + V_FH] = cg * fx + sg * fy
            w[vo + V_FV] = cg * fy - sg * fx
    return True


def thrust_out(x, seg, ip, par, w):
    """The thrusters' commands ``u`` into ``w[W_CMD]`` (the segment's value of a piecewise
    command, else ``F_ss``) and their thrust ``F = C z + D u`` [N] into ``w[W_F]``
    (thrust/dynamics.py: the servo form's output)."""
    N, m, nz = ip[I_N], ip[I_M], ip[I_NZ]
    oU, oF = ip[W_CMD], ip[W_F]
    o = ip[P_SEGF] + seg * m if ip[I_CMD] == CMD_PIECEWISE else ip[P_TGT]
    for k in range(m):
        w[oU + k] = par[o + k]
    oC, oD, oz = ip[P_DC], ip[P_DD], 2 * N
    for k in range(m):
        acc = 0.0
        for j in range(nz):
            acc += par[oC + k * nz + j] * x[oz + j]
        for j in range(m):
            acc += par[oD + k * m + j] * w[oU + j]
        w[oF + k] = acc


def rhs_eval(t, x, seg, fs, ip, par, w, dx):
    """``x' = [q'; q''; z']`` (SPEC 7) into ``dx``; False if the controller is singular."""
    if not evaluate(x, seg, fs, ip, par, w, E_ACCEL):
        return False
    state_rate(x, fs, ip, par, w, dx)
    return True


def rhs_node(t, x, seg, fs, ip, par, w, dx):
    """:func:`rhs_eval` at a state that may become an integrator node (the last stage of a
    step, the start of an integration): the force program in place of the acceleration
    program (a superset, the same ``q''``) also gives the vertical ground force, kept in
    ``w[W_OUT + V_FNODE]`` for the event ``force`` at that node."""
    if not evaluate(x, seg, fs, ip, par, w, E_FORCE):
        return False
    state_rate(x, fs, ip, par, w, dx)
    w[ip[W_OUT] + V_FNODE] = w[ip[W_OUT] + V_FV]
    return True


def state_rate(x, fs, ip, par, w, dx):
    """``dx = [q'; q''; z']`` with ``q''`` in ``w[W_DDQ]`` and the commands in ``w[W_CMD]``
    (just computed): the thruster states by the servo form ``E z' = P z + Q (u - K z)``, the
    command error first, then per state ``(sum Q e + sum P z) / E`` (thrust/dynamics.py)."""
    N, m, nz = ip[I_N], ip[I_M], ip[I_NZ]
    d0 = ip[W_DDQ]
    for i in range(N):
        dx[i] = x[N + i]
        dx[N + i] = w[d0 + i]
    if nz == 0:
        return
    oU, oE, oz = ip[W_CMD], ip[W_ERR], 2 * N
    oK, oQ, oP, oT = ip[P_DK], ip[P_DQ], ip[P_DP], ip[P_DE]
    for k in range(m):
        acc = 0.0
        for j in range(nz):
            acc += par[oK + k * nz + j] * x[oz + j]
        w[oE + k] = w[oU + k] - acc
    for i in range(nz):
        acc = 0.0
        for k in range(m):
            acc += par[oQ + i * m + k] * w[oE + k]
        for j in range(nz):
            acc += par[oP + i * nz + j] * x[oz + j]
        dx[oz + i] = acc / par[oT + i]


def vertical_force(x, seg, fs, ip, par, w):
    """``F_1^v`` [N] at one state (event ``force``); NaN if the controller is singular."""
    if not evaluate(x, seg, fs, ip, par, w, E_FORCE):
        return np.nan
    return w[ip[W_OUT] + V_FV]


def swing_height(x, fs, ip, par, w):
    """Swing-foot height [m]."""
    evaluate(x, 0, fs, ip, par, w, E_HEIGHT)
    return w[ip[W_OUT] + V_HEIGHT]


def foot_velocity(x, fs, ip, par, w):
    """Vertical swing-foot velocity [m/s]."""
    evaluate(x, 0, fs, ip, par, w, E_FOOTVEL)
    return w[ip[W_OUT] + V_FOOTVEL]


def event_value(code, x, seg, fs, ip, par, w, a_next, a_push):
    """Value of event ``code`` at state ``x`` (``ClosedLoop.events``)."""
    d = fs[F_DIR]
    if code == EV_BREAK:
        return d * (alpha_of(x, ip, par) - a_next)
    if code == EV_PUSH:
        return d * (alpha_of(x, ip, par) - a_push)
    if code == EV_GUARD:  # the swing foot reaches the ground of this step (F_TERRAIN)
        return swing_height(x, fs, ip, par, w) - fs[F_TERRAIN]
    if code == EV_OVERSHOOT:
        return d * (alpha_of(x, ip, par) - (fs[F_AI] + fs[F_MAXS] * fs[F_SPAN]))
    if code == EV_SCUFF:
        return swing_height(x, fs, ip, par, w) - fs[F_BEHIND] + fs[F_SCUFF]
    if code == EV_FOOT_MAX or code == EV_FOOT_MIN:
        return foot_velocity(x, fs, ip, par, w)
    if code == EV_REVERSE:
        return d * alpha_rate(x, ip, par)
    if code == EV_HORIZONTAL:
        evaluate(x, 0, fs, ip, par, w, E_ROOT)
        return w[ip[W_OUT] + V_ROOT]
    if code == EV_FORCE:
        return vertical_force(x, seg, fs, ip, par, w)
    return 0.0


def node_event_value(code, x, seg, fs, ip, par, w, a_next, a_push):
    """Value of event ``code`` at an integrator node, just after :func:`rhs_node` there: the
    event ``force`` is the vertical ground force that came with the right-hand side."""
    if code == EV_FORCE:
        return w[ip[W_OUT] + V_FNODE]
    return event_value(code, x, seg, fs, ip, par, w, a_next, a_push)


def event_list(seg, rising, ip, push_here, ev):
    """The events of one segment in ``ClosedLoop.events`` order into ``ev`` (rows: code,
    direction, terminal, recorded: the roots of ``foot_min``, the swing foot's lowest points,
    are kept for the dip check), with ``push`` first when a push is pending. Returns their
    number."""
    armed = seg > ip[I_GUARD_IDX]
    for e in range(MAX_EVENTS):
        ev[3, e] = 0
    k = 0
    if push_here:
        ev[0, k], ev[1, k], ev[2, k] = EV_PUSH, 1, 1
        k += 1
    if seg < ip[I_NBRK]:
        ev[0, k], ev[1, k], ev[2, k] = EV_BREAK, 1, 1
        k += 1
    if armed:
        ev[0, k], ev[1, k], ev[2, k] = EV_GUARD, -1, 1
        ev[0, k + 1], ev[1, k + 1], ev[2, k + 1] = EV_OVERSHOOT, 1, 1
        k += 2
    else:
        ev[0, k], ev[1, k], ev[2, k] = EV_SCUFF, -1, 1
        k += 1
    if armed and rising:
        ev[0, k], ev[1, k], ev[2, k] = EV_FOOT_MAX, -1, 1
    else:
        ev[0, k], ev[1, k], ev[2, k] = EV_FOOT_MIN, 1, 1 if armed else 0
        ev[3, k] = 1
    k += 1
    ev[0, k], ev[1, k], ev[2, k] = EV_REVERSE, -1, 1
    ev[0, k + 1], ev[1, k + 1], ev[2, k + 1] = EV_HORIZONTAL, -1, 1
    ev[0, k + 2], ev[1, k + 2], ev[2, k + 2] = EV_FORCE, -1, 1
    return k + 3


# numba signatures (argument types only), callees before callers: each function is compiled
# once, when the generated module is imported (once per machine: no robot appears in the
# code), so a constant argument never makes a second specialisation
_F, _I, _B = "float64", "int64", "boolean"
_A, _A2, _A3 = "float64[::1]", "float64[:, ::1]", "float64[:, :, ::1]"
_IA, _IA2 = "int64[::1]", "int64[:, ::1]"
_CTX = f"{_A}, {_IA}, {_A}, {_A}"  # fs, ip, par, w
SIGNATURES = {
    "gauss": f"({_A}, {_I}, {_I})",
    "tilted": f"({_A}, {_I}, {_A}, {_IA}, {_A})",
    "alpha_of": f"({_A}, {_IA}, {_A})",
    "alpha_rate": f"({_A}, {_IA}, {_A})",
    "thrust_out": f"({_A}, {_I}, {_IA}, {_A}, {_A})",
    "evaluate": f"({_A}, {_I}, {_CTX}, {_I})",
    "state_rate": f"({_A}, {_CTX}, {_A})",
    "rhs_eval": f"({_F}, {_A}, {_I}, {_CTX}, {_A})",
    "rhs_node": f"({_F}, {_A}, {_I}, {_CTX}, {_A})",
    "vertical_force": f"({_A}, {_I}, {_CTX})",
    "swing_height": f"({_A}, {_CTX})",
    "foot_velocity": f"({_A}, {_CTX})",
    "event_value": f"({_I}, {_A}, {_I}, {_CTX}, {_F}, {_F})",
    "node_event_value": f"({_I}, {_A}, {_I}, {_CTX}, {_F}, {_F})",
    "event_list": f"({_I}, {_B}, {_IA}, {_B}, {_IA2})",
}
# every one allocation-free: compiled without reference counting (model/jit.py)
NRT_FREE = frozenset(SIGNATURES)
# compiled into their callers only (numba's IR inlining, see ``model/jit.py``): small wrappers
# of :func:`evaluate` and ``event_list`` (one caller); each would otherwise be a library of its
# own whose compile optimizes and translates ``evaluate`` and the interpreter once more. Their
# callers are allocation-free too, but for the step (``step_core``), where they take no view.
INLINED = frozenset({"rhs_eval", "rhs_node", "node_event_value", "vertical_force",
                     "swing_height", "foot_velocity", "event_list"})
