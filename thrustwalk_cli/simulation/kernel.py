"""The compiled closed loop of SPEC 7: source that numba compiles once per machine.

This module is plain Python written in the subset numba compiles. It is never jit-compiled
where it stands: :mod:`thrustwalk_cli.simulation.compiled` concatenates this source with the
tape interpreter of :mod:`thrustwalk_cli.model.tape` (whose definition comes later in the
file and so replaces the placeholder below) and the DOP853 coefficients of
:class:`scipy.integrate.DOP853`, and caches the compiled result in the thrustwalk cache
folder (:mod:`thrustwalk_cli.model.jit`). No robot appears in the code: the model (D, h,
B_F, the ground-force rows, swing-foot kinematics, impact terms) is the robot's *tape*,
appended to the integer settings ``ip`` and run by the interpreter, so one compiled kernel
serves every robot.

What it computes is, equation for equation, the SciPy reference path of
:mod:`thrustwalk_cli.simulation.full_order` and :class:`~thrustwalk_cli.simulation.
closed_loop.ClosedLoop`:

* right-hand side: the input-output linearising controller ``y'' = -K_p y - K_d y'`` reduced
  to a 2 x 2 system in ``(alpha'', q_N'')``, torque saturation with ``D q'' = -h + B_tau u +
  B_F F_T`` (+ ``e_N T``), the thruster states of any linear model of
  :mod:`thrustwalk_cli.thrust.dynamics` (its servo form's matrices in ``par``) under a command
  constant over the run or piecewise in alpha (force or generalised mode);
* integrator: DOP853 with SciPy's error norm, step-size control and initial step, and its
  7th-order dense output (Hairer, Norsett, Wanner, *Solving ODEs I*, II.4-II.6);
* events located on the dense output by Brent's method as ``solve_ivp`` does (same
  directions, same terminal rules, the integration restarted at every event), the guard,
  the dip of the swing foot between two integrator steps, every failure condition;
* the impact map (SPEC 5) and relabelling (SPEC 1), and the step's statistics on the
  integrator's nodes plus a uniform grid, as ``_impact_and_record`` does.

Arrays are flat and row-major (parameters in `par`, scratch in `w`, offsets in `ip`: few
arguments per call keep both the compile time and the call overhead low); units SI. Status
codes and record layouts are the constants below, read by :mod:`.compiled`.

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

import math

import numpy as np

# ------------------------------------------------------------------ placeholder (replaced)
# the tape interpreter (model/tape.py), defined again (for real) later in the compiled file


def tape_run(code, p, x, r, o):  # noqa: D103
    raise NotImplementedError


def tape_batch(code, p, consts, c0, nreg, X, out, chunk):  # noqa: D103
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
# float settings fs[...]
F_AI, F_SPAN, F_DIR, F_KP, F_KD, F_RTOL, F_ATOL, F_TLIM = 0, 1, 2, 3, 4, 5, 6, 7
F_SCUFF, F_MINIMP, F_MAXS, F_GROUND, F_TMAX = 8, 9, 10, 11, 12
F_MU, F_EPS = 13, 14  # the cone a step's first exit is timed against (mu inf: no slip timing)
N_FS = 15
# integer settings ip[...]: sizes, then offsets into par (P_*) and into the work array (W_*)
I_N, I_M, I_NZ, I_CMD, I_ROOT_END, I_GUARD_IDX, I_GRID, I_NLINKS, I_NCOL, I_NBRK = range(10)
# par: gait rows, c, breakpoints, thrust commands (per segment, constant), R, b, and the
# thruster dynamics in the servo form E z' = P z + Q (u - K z), F = C z + D u
# (thrust/dynamics.py: ThrusterDynamics.kernel_data)
(P_ROWS, P_C, P_BRK, P_SEGF, P_SEGT, P_TGT, P_R, P_B, P_DE, P_DP, P_DQ, P_DK, P_DC, P_DD,
 P_SIZE) = range(10, 25)
(W_D, W_H, W_BF, W_GR, W_RHS, W_F, W_GH, W_BY, W_DDQ, W_U, W_A, W_TO, W_P2, W_FV, W_LP,
 W_Y, W_YT, W_K, W_SC, W_Y1, W_F1, W_XS, W_YE, W_FF, W_FN, W_YN, W_X, W_XE, W_DQI, W_ACC,
 W_G, W_GN, W_ROOTS, W_LOWS, W_GRID2, W_OUT, W_CMD, W_ERR, W_SIZE) = range(25, 64)
# the model's tape (appended to ``ip``): offsets of its programs, the number of constants
# (in ``fs`` from N_FS on) and their first register; registers are ``w[:nreg]``
T_ACCEL, T_FORCE, T_HEIGHT, T_FOOTVEL, T_LINKS, T_IMPACT, T_ENERGY, T_PUSH = range(64, 72)
I_NCONST, I_C0, I_NREG = 72, 73, 74
N_IP = 75
# what evaluate() computes (bit flags) and where its scalar results go (w[W_OUT + ...])
E_ACCEL, E_U, E_FORCE, E_HEIGHT, E_FOOTVEL, E_ROOT, E_PRE = 1, 2, 4, 8, 16, 32, 64
V_FH, V_FV, V_HEIGHT, V_FOOTVEL, V_ROOT, V_SAT, V_FNODE = 0, 1, 2, 3, 4, 5, 6
# thrust commands: constant over the run (P_TGT) or piecewise in alpha (P_SEGF, P_SEGT)
CMD_CONSTANT, CMD_PIECEWISE = 0, 1
# events
EV_NONE, EV_BREAK, EV_GUARD, EV_OVERSHOOT, EV_SCUFF = 0, 1, 2, 3, 4
EV_FOOT_MAX, EV_FOOT_MIN, EV_REVERSE, EV_HORIZONTAL, EV_FORCE, EV_PUSH = 5, 6, 7, 8, 9, 10
MAX_EVENTS = 12
MAX_LOWS = 256
# integrate() status
ST_BOUND, ST_EVENT, ST_SMALL, ST_SINGULAR, ST_FULL = 0, 1, -1, -2, -3
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
SAFETY, MIN_FACTOR, MAX_FACTOR, ERR_EXP = 0.9, 0.2, 10.0, -1.0 / 8.0
EPS = 2.220446049250313e-16


def layout(N, m, nz, nlinks, ncol, nbrk, nreg):
    """Sizes and offsets for ``ip`` (plain Python, used to build the kernel's arguments);
    the work array ``w`` starts with the tape's ``nreg`` registers."""
    n = 2 * N + nz
    n2 = N + 2
    mm = max(m, 1)
    nb = N - 1
    ip = [0] * N_IP
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
            (W_A, n2 * (n2 + 2)), (W_TO, to), (W_P2, 2), (W_FV, 1), (W_LP, 4 * nlinks), (W_Y, n),
            (W_YT, n), (W_K, 16 * n), (W_SC, n), (W_Y1, n), (W_F1, n), (W_XS, n), (W_YE, n),
            (W_FF, n), (W_FN, n), (W_YN, n), (W_X, n), (W_XE, n), (W_DQI, n2), (W_ACC, 8),
            (W_G, MAX_EVENTS), (W_GN, MAX_EVENTS), (W_ROOTS, MAX_EVENTS), (W_LOWS, MAX_LOWS),
            (W_GRID2, 65), (W_OUT, 8), (W_CMD, mm), (W_ERR, mm)]
    off = nreg
    for key, size in work:
        ip[key] = off
        off += size
    ip[W_SIZE] = off
    return ip


# ------------------------------------------------------------------ small helpers
def pymax(a, b):
    """Python's ``max(a, b)`` (``a`` unless ``b > a``; NaN-safe the same way)."""
    return b if b > a else a


def pymin(a, b):
    """Python's ``min(a, b)``."""
    return b if b < a else a


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
    ``w[W_OUT + V_FH]``, ``w[W_OUT + V_FV]``; ``E_HEIGHT``/``E_FOOTVEL``: swing-foot height
    [m] and vertical velocity ``E_2,y q'`` [m/s]; ``E_ROOT``: height of the stance link's far
    end [m]. Returns False if the decoupling matrix (or D, when torques saturate) is
    singular."""
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
    thrust_out(x, seg, ip, par, w)
    # D, h, B_F (and with E_FORCE the ground-force rows) from the model's tape (already in
    # place with E_PRE)
    if not what & E_PRE:
        tape_run(ip, ip[T_FORCE] if what & E_FORCE else ip[T_ACCEL], x, w, ip[W_D])
    for i in range(uN):
        w[orhs + i] = -w[oh + i]
    if m > 0:
        for i in range(uN):
            acc = 0.0
            for k in range(um):
                acc += w[oBF + i * um + k] * w[oF + k]
            w[orhs + i] += acc
    if ip[I_CMD] == CMD_PIECEWISE:
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
    if code == EV_GUARD:
        return swing_height(x, fs, ip, par, w)
    if code == EV_OVERSHOOT:
        return d * (alpha_of(x, ip, par) - (fs[F_AI] + fs[F_MAXS] * fs[F_SPAN]))
    if code == EV_SCUFF:
        return swing_height(x, fs, ip, par, w) + fs[F_SCUFF]
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


def event_list(seg, rising, ip, push_here, ev):
    """The events of one segment in ``ClosedLoop.events`` order into ``ev`` (rows: code,
    direction, terminal), with ``push`` first when a push is pending. Returns their
    number."""
    armed = seg > ip[I_GUARD_IDX]
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
    k += 1
    ev[0, k], ev[1, k], ev[2, k] = EV_REVERSE, -1, 1
    ev[0, k + 1], ev[1, k + 1], ev[2, k + 1] = EV_HORIZONTAL, -1, 1
    ev[0, k + 2], ev[1, k + 2], ev[2, k + 2] = EV_FORCE, -1, 1
    return k + 3


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


def brent(code, a, b, fa, fb, buf, first, last, seg, fs, ip, par, w, n, a_next, a_push,
          xtol, rtol):
    """Root in ``[a, b]`` of event ``code`` (or of the swing-foot height, ``code < 0``) on the
    dense solution of steps ``first..last-1``, by Brent's bracketing interpolation (the
    algorithm of ``scipy.optimize.brentq``)."""
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
        if code < 0:
            fcur = swing_height(xs, fs, ip, par, w)
        else:
            fcur = event_value(code, xs, seg, fs, ip, par, w, a_next, a_push)
    return xcur


def integrate(t0, x0, t_bound, seg, ev, nev, fs, ip, par, w, buf, nbuf, a_next, a_push):
    """``solve_ivp(rhs, (t0, t_bound), x0, method="DOP853", events=..., dense_output=True)``
    over one segment: every accepted step goes into ``buf`` from row ``nbuf``.

    ``ev``: rows code, direction, terminal. Returns (status, t_end, fired event code, number
    of ``foot_min`` roots written to ``w[W_LOWS]``, rows used, nfev); the state at ``t_end``
    is in ``w[W_YE]``.
    """
    N, nz = ip[I_N], ip[I_NZ]
    n = 2 * N + nz
    y, f, y_new, K, yend = w[ip[W_Y]:], w[ip[W_FF]:], w[ip[W_YN]:], w[ip[W_K]:], w[ip[W_YE]:]
    g, g_new, roots, lows = w[ip[W_G]:], w[ip[W_GN]:], w[ip[W_ROOTS]:], w[ip[W_LOWS]:]
    for i in range(n):
        y[i] = x0[i]
    nfev = 1
    if not rhs_node(t0, y, seg, fs, ip, par, w, f):
        return ST_SINGULAR, t0, EV_NONE, 0, nbuf, nfev
    vnode = ip[W_OUT] + V_FNODE
    h_abs, ok = initial_step(t0, t_bound, seg, fs, ip, par, w, n)
    nfev += 1
    if not ok:
        return ST_SINGULAR, t0, EV_NONE, 0, nbuf, nfev
    direction = 1.0 if t_bound >= t0 else -1.0
    for e in range(nev):  # (the force at a node is known from its right-hand side)
        if ev[0, e] == EV_FORCE:
            g[e] = w[vnode]
        else:
            g[e] = event_value(ev[0, e], y, seg, fs, ip, par, w, a_next, a_push)
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
            if ev[0, e] == EV_FORCE:
                g_new[e] = w[vnode]
            else:
                g_new[e] = event_value(ev[0, e], y, seg, fs, ip, par, w, a_next, a_push)
        for e in range(nev):
            up = g[e] <= 0 and g_new[e] >= 0
            down = g[e] >= 0 and g_new[e] <= 0
            if (up and ev[1, e] > 0) or (down and ev[1, e] < 0):
                r = brent(ev[0, e], t_old, t, g[e], g_new[e], buf, k, k + 1, seg, fs, ip,
                          par, w, n, a_next, a_push, 4 * EPS, 4 * EPS)
                roots[e] = r
                n_act += 1
                if ev[2, e] == 1 and (first_term < 0 or r < t_term):
                    first_term = e
                    t_term = r
            else:
                roots[e] = np.nan
        if n_act > 0:
            for e in range(nev):
                if roots[e] == roots[e] and ev[0, e] == EV_FOOT_MIN and n_lows < MAX_LOWS:
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


# ------------------------------------------------------------------ one walking step
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
    tape_batch(ip, ip[T_FORCE], fs[N_FS:N_FS + ip[I_NCONST]], ip[I_C0], ip[I_NREG], SX, SO,
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


def note_push(x, t, ip, rec):
    """The push's time [s] and the state just before it into ``rec``."""
    N, nz, m = ip[I_N], ip[I_NZ], ip[I_M]
    rec[R_TPUSH] = t
    off = N_REC0 + 2 * N + 2 * nz + m
    for i in range(2 * N + nz):
        rec[off + i] = x[i]


def sigma_energy(q, dq, ip, w):
    """``sigma_N = e_N^T D q'`` [kg m^2/s] and ``E = 1/2 q'^T D q' + V`` [J]."""
    N = ip[I_N]
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


def sim_step(k, t0, x0, x_next, fs, ip, par, w, buf, calls, push, rec, out):
    """One walking step (``full_order._one_step`` and ``_impact_and_record``): from the
    post-impact state ``x0`` at ``t0`` to the next impact; ``x_next`` gets the relabelled
    post-impact state, ``rec`` the step record, ``out`` the outcome. ``calls`` lists the
    integration calls (restarts), whose steps are rows of ``buf``. ``push``: a push of this
    step when ``push[0] == k``. Returns (status, number of calls, rows of ``buf`` used).

    A step that fails after it started to integrate still gets, in ``rec``, the first times
    its stance force left the cone up to the failure (:func:`step_stats`) and its push's
    time and state: what came first is for the caller to tell."""
    for i in range(R_TLOW, R_TPUSH + 1):
        rec[i] = np.nan
    st, ncalls, nbuf = step_core(k, t0, x0, x_next, fs, ip, par, w, buf, calls, push, rec,
                                 out)
    if st != OK and st != FAIL_BUFFER and ncalls > 0:
        step_stats(calls, ncalls, buf, t0, out[O_T], fs, ip, par, w, rec)
    return st, ncalls, nbuf


def step_core(k, t0, x0, x_next, fs, ip, par, w, buf, calls, push, rec, out):
    """:func:`sim_step` but for the statistics of a failed step."""
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
    h0 = swing_height(x, fs, ip, par, w)
    if h0 < -fs[F_SCUFF]:
        return fail(out, FAIL_START_BELOW, k, t0, s0, h0, EV_NONE), 0, 0
    t = t0
    rising = foot_velocity(x, fs, ip, par, w) >= 0.0
    ev = np.empty((3, MAX_EVENTS), np.int64)
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
        # a dip of the swing foot below the ground between two integrator steps (_dip)
        armed = seg > ip[I_GUARD_IDX]
        limit = -fs[F_GROUND] if armed else -fs[F_SCUFF]
        dip = EV_NONE
        t_dip = 0.0
        for j in range(n_lows):
            tm = lows[j]
            if tm > t1:
                continue
            solution_at(buf, first, nbuf, tm, n, xs)
            if swing_height(xs, fs, ip, par, w) >= limit:
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
                hh = swing_height(xs, fs, ip, par, w)
                if gi > 0 and hprev > 0 and hh <= 0 and found < 0:
                    found = gi - 1
                hprev = hh
            if found < 0:
                dip, t_dip = EV_SCUFF, t
                break
            ga, gb = grid[found], grid[found + 1]
            solution_at(buf, first, nbuf, ga, n, xs)
            fa = swing_height(xs, fs, ip, par, w)
            solution_at(buf, first, nbuf, gb, n, xs)
            fb = swing_height(xs, fs, ip, par, w)
            dip = EV_GUARD
            t_dip = brent(-1, ga, gb, fa, fb, buf, first, nbuf, seg, fs, ip, par, w, n,
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
    sig_m, e_m = sigma_energy(x[:N], x[N:2 * N], ip, w)
    sig_p, e_p = sigma_energy(x_next[:N], x_next[N:2 * N], ip, w)
    sig_0, e_0 = sigma_energy(x0[:N], x0[N:2 * N], ip, w)
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


# ------------------------------------------------------------------ the entry point
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
            st, nc, nbuf = sim_step(k, t, x, x_next, fsr, ip, PAR[r], w, buf, calls, PUSH[r],
                                    recs[r, j], out)
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


# numba signatures (argument types only), callees before callers: each function is compiled
# once, when the generated module is imported (once per machine: no robot appears in the
# code), so a constant argument never makes a second specialisation
_F, _I, _B = "float64", "int64", "boolean"
_A, _A2, _A3 = "float64[::1]", "float64[:, ::1]", "float64[:, :, ::1]"
_IA, _IA2 = "int64[::1]", "int64[:, ::1]"
_CTX = f"{_A}, {_IA}, {_A}, {_A}"  # fs, ip, par, w
SIGNATURES = {
    "pymax": f"({_F}, {_F})",
    "pymin": f"({_F}, {_F})",
    "gauss": f"({_A}, {_I}, {_I})",
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
    "event_list": f"({_I}, {_B}, {_IA}, {_B}, {_IA2})",
    "initial_step": f"({_F}, {_F}, {_I}, {_CTX}, {_I})",
    "rk_step": f"({_F}, {_F}, {_I}, {_CTX}, {_I})",
    "dense_coefficients": f"({_F}, {_F}, {_I}, {_CTX}, {_I}, {_A})",
    "dense_at": f"({_A2}, {_I}, {_F}, {_I}, {_A})",
    "solution_at": f"({_A2}, {_I}, {_I}, {_F}, {_I}, {_A})",
    "brent": f"({_I}, {_F}, {_F}, {_F}, {_F}, {_A2}, {_I}, {_I}, {_I}, {_CTX}, {_I}, {_F}, "
             f"{_F}, {_F}, {_F})",
    "integrate": f"({_F}, {_A}, {_F}, {_I}, {_IA2}, {_I}, {_CTX}, {_A2}, {_I}, {_F}, {_F})",
    "stat_times": f"({_A2}, {_I}, {_A2}, {_I}, {_F}, {_F}, {_B}, {_I}, {_A2}, {_A}, {_I})",
    "details_at": f"({_A}, {_I}, {_CTX}, {_I})",
    "cone_violated": f"({_A}, {_I}, {_CTX}, {_I})",
    "first_violation": f"({_A2}, {_A2}, {_I}, {_F}, {_F}, {_CTX}, {_I}, {_I})",
    "step_stats": f"({_A2}, {_I}, {_A2}, {_F}, {_F}, {_CTX}, {_A})",
    "note_push": f"({_A}, {_F}, {_IA}, {_A})",
    "sigma_energy": f"({_A}, {_A}, {_IA}, {_A})",
    "impact": f"({_A}, {_A}, {_IA}, {_A}, {_A}, {_A}, {_A})",
    "apply_push": f"({_A}, {_A}, {_IA}, {_A})",
    "fail": f"({_A}, {_I}, {_I}, {_F}, {_F}, {_F}, {_I})",
    "push_or_fail": f"({_A}, {_A}, {_IA}, {_A}, {_A}, {_I}, {_F}, {_F})",
    "add_call": f"({_A2}, {_I}, {_I}, {_I}, {_I}, {_F}, {_F})",
    "step_core": f"({_I}, {_F}, {_A}, {_A}, {_CTX}, {_A2}, {_A2}, {_A}, {_A}, {_A})",
    "sim_step": f"({_I}, {_F}, {_A}, {_A}, {_CTX}, {_A2}, {_A2}, {_A}, {_A}, {_A})",
    "run": f"({_A2}, {_A}, {_IA}, {_I}, {_A}, {_IA}, {_A2}, {_A2}, {_A2}, {_A3}, {_A2}, "
           f"{_IA}, {_A2}, {_IA2}, {_I}, {_I}, {_A2}, {_A2})",
}
# compiled without reference counting (model/jit.py): everything but the functions that
# allocate arrays (``run``: the work array; ``step_core``: the events; ``step_stats``: a
# step's statistics) or call them (``sim_step``), and the interpreter's allocation-free
# functions; the work array and every buffer belong to ``run`` and its caller
NRT_FREE = frozenset(SIGNATURES) - {"run", "sim_step", "step_core", "step_stats"} | {
    "tape_run", "tape_chunks"}
