"""The compiled full-order simulation (SPEC 7): the numba kernel, its parameters, and results
in the same form as the SciPy reference path.

One kernel serves every robot: the sources of the generic integrator (:mod:`.integrator`:
DOP853, dense output, event location), of the walker's closed loop (:mod:`.kernel`) and step
(:mod:`.step_stats`, :mod:`.step`) and the tape interpreter, concatenated into one module
(:func:`kernel_source`), compiled by numba once per machine and cached in the thrustwalk cache
folder (:mod:`thrustwalk_cli.model.jit`); the robot enters as data, its tape
(:mod:`thrustwalk_cli.model.tape`) appended to the integer settings. It integrates with DOP853
(same tolerance semantics, step-size control and events as ``solve_ivp``), so its steps agree
with the SciPy path (``method="scipy"``) to the integration tolerance. numba is imported only
here, when a compiled run is asked for. (Named for :class:`Stepper`, which runs the compiled
closed loop step by step; :mod:`thrustwalk_cli.model.compiled` is the compiled *model*.)
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..model import jit
from ..model.tape import SIGNATURES as TAPE_SIGNATURES
from ..model.tape import interpreter_source
from . import integrator as I
from . import kernel as K
from . import step as S
from . import step_stats as SS
from .records import EVENT_REASONS, Segment, StepRecord, behind_level, missed_footing

if TYPE_CHECKING:  # the closed loop (and the zero dynamics under it) load when a run needs them
    from .closed_loop import ClosedLoop, SimConfig

TAG = "sim"
BUF_ROWS = 512  # integrator steps per walking step kept for dense output (grows on demand)
GRID = 201  # uniform samples of a step for its statistics (as the SciPy path)


def _coefficients() -> str:
    """The DOP853 tableau of :class:`scipy.integrate.DOP853` as source (exact reprs)."""
    from scipy.integrate import DOP853

    def arr(a) -> str:
        return "np.array(" + repr(np.asarray(a, float).tolist()) + ")"

    parts = {"DOP_A": DOP853.A, "DOP_B": DOP853.B, "DOP_C": DOP853.C, "DOP_E3": DOP853.E3,
             "DOP_E5": DOP853.E5, "DOP_D": DOP853.D, "DOP_AX": DOP853.A_EXTRA,
             "DOP_CX": DOP853.C_EXTRA}
    return "\n".join(f"{k} = {arr(v)}" for k, v in parts.items())


SOURCES = (I, K, SS, S)  # in this order: each source uses the names of those before it
PYTHON_ONLY = ("# ---- Python only", "# ---- end Python only")


def numba_source(module) -> str:
    """A kernel module's source without its block marked *Python only* (the imports that give
    Python the names of the sources before it; in the compiled module they are defined
    there)."""
    out, skip = [], False
    for line in inspect.getsource(module).splitlines(keepends=True):
        if line.startswith(PYTHON_ONLY[0]):
            skip = True
        if not skip:
            out.append(line)
        if line.startswith(PYTHON_ONLY[1]):
            skip = False
    return "".join(out)


@functools.cache
def kernel_source() -> str:
    """The sources of the integrator, the walker's closed loop and step, the tape interpreter
    and the DOP853 coefficients (the last two replace the placeholders)."""
    return ("\n\n".join(numba_source(m) for m in SOURCES)
            + "\n\n# ---- the tape interpreter (model/tape.py)\n"
            + interpreter_source() + "\n\n# ---- DOP853 tableau (scipy.integrate.DOP853)\n"
            + _coefficients() + "\n")


@functools.cache
def _names() -> dict[str, str]:
    """Every function to compile with its numba signature, callees first: the interpreter,
    the integrator's helpers, the closed loop (the integrator's problem), the integrator, the
    step's statistics, the step."""
    sigs = {**TAPE_SIGNATURES, **I.HELPERS, **K.SIGNATURES, **I.SIGNATURES, **SS.SIGNATURES,
            **S.SIGNATURES}
    return {k: jit.INLINE if k in INLINED else v for k, v in sigs.items()}


# compiled into their callers only (``jit.INLINE``): numba compiles every other function as a
# library of its own, into which it links the code of all its callees and optimizes and
# translates the whole again, so a deep call chain pays for the code below it at every level
# (issue 26: 54-60 s for the kernel). Functions with one call site and small wrappers are
# inlined (``tape_batch``: into ``step_stats``, under reference counting as it allocates);
# what Python calls (``run``; ``tape_run`` in the tests) keeps its signature, as does every
# allocation-free function with an allocating caller where it is hot (``integrate``).
INLINED = I.INLINED | K.INLINED | SS.INLINED | S.INLINED | {"tape_batch"}


# compiled without reference counting (model/jit.py): the allocation-free functions of every
# source and of the tape interpreter
NRT_FREE = I.NRT_FREE | K.NRT_FREE | SS.NRT_FREE | S.NRT_FREE | {"tape_run", "tape_chunks"}


@functools.cache
def _fingerprint() -> str:
    """What the kernel's module is made of, cheaply (no SciPy import, no source assembly):
    the files of its source and SciPy's file of the DOP853 tableau."""
    from pathlib import Path

    from ..model import cache

    here = Path(__file__).parent
    return cache.files_digest(
        [here / f"{m.__name__.rsplit('.', 1)[1]}.py" for m in SOURCES]
        + [Path(__file__), here.parent / "model" / "tape.py"],
        cache.package_file("scipy", "integrate/_ivp/dop853_coefficients.py"))


def kernel(rebuild: bool = False, on_wait: Callable[[str], None] | None = None
           ) -> jit.JitModule:
    """The compiled kernel (every robot): compiled once per machine (numba) or loaded from
    the cache; while another process compiles it, this one waits (``on_wait`` is told, see
    :func:`thrustwalk_cli.model.jit.load`) and then loads it."""
    return jit.load(TAG, kernel_source, _names(), rebuild=rebuild, fingerprint=_fingerprint(),
                    nrt_free=NRT_FREE, what="the simulation kernel", on_wait=on_wait)


def loop_context(cl: ClosedLoop) -> tuple:
    """The compiled kernel's module and its parameters ``(fs, ip, par)`` for the closed loop
    ``cl`` (:func:`pack`: the settings of a compiled run of ``cl``, its thrust before any
    ``Stepper.set_thrust``; a compiled run's own when it has one), made once per closed loop:
    for evaluating ``cl`` in the kernel after or outside a run (the energies' nodes, the
    variational equations' right-hand side)."""
    ctx = cl.__dict__.get("_kernel_context")
    if ctx is None:
        p = cl.__dict__.get("_packed")  # a compiled run's (Stepper), else made now
        if p is None:
            p = pack(cl, 1.0)
        ctx = (kernel().module, p.fs, p.ip, p.par)
        cl.__dict__["_kernel_context"] = ctx
    return ctx


def work_array(fs: np.ndarray, ip: np.ndarray) -> np.ndarray:
    """A kernel work array for ``(fs, ip)`` with the tape's constants in their registers."""
    w = np.zeros(int(ip[K.W_SIZE]))
    c0, nc = int(ip[K.I_C0]), int(ip[K.I_NCONST])
    w[c0:c0 + nc] = fs[K.N_FS:K.N_FS + nc]
    return w


def kernel_status() -> dict:
    """Whether the compiled kernel is cached, without importing numba or SciPy."""
    return jit.status(TAG, _fingerprint(), _names(), NRT_FREE)


# ----------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class Packed:
    """The kernel's parameters for one gait, thrust model and configuration: float settings
    ``fs``, sizes and offsets ``ip``, the flat parameter vector ``par`` (gait rows, c,
    breakpoints, thrust per segment, F_ss, R, b, the thruster dynamics' matrices)."""

    fs: np.ndarray
    ip: np.ndarray
    par: np.ndarray
    t_max: float
    nz: int

    def part(self, key: int, size: int) -> np.ndarray:
        """A view of one block of ``par`` (``key`` a ``kernel.P_*`` offset)."""
        o = int(self.ip[key])
        return self.par[o:o + size]


def pack(cl: ClosedLoop, t_max: float, grid: int = GRID) -> Packed:
    """Arrays for the kernel from a :class:`ClosedLoop` (the SciPy path's own setup, so both
    methods see the same breakpoints, thrust pieces and settings). On a slope (the closed
    loop's model a slope-frame model, SPEC 14) the kernel runs the level-ground tape at the
    turned posture (``kernel.tilted``) with the slope in ``fs``."""
    th, cfg, model = cl.thrust, cl.config, cl.model
    N, m = model.n, model.n_thrusters
    rows = np.array(cl.gait_s.rows, float)
    nbrk = len(cl.breaks)
    gamma = float(getattr(model, "slope", 0.0))
    flat = getattr(model, "flat", model) if gamma != 0.0 else model
    if gamma != 0.0:
        check_turn(flat)
    tape = flat.tape
    ip = np.array(K.layout(N, m, th.n_states, len(model.robot.links), rows.shape[1], nbrk,
                           tape.nreg), np.int64)
    for slot, name in ((K.T_ACCEL, "accel"), (K.T_FORCE, "force"), (K.T_HEIGHT, "height"),
                       (K.T_FOOTVEL, "footvel"), (K.T_LINKS, "links"),
                       (K.T_IMPACT, "impact"), (K.T_ENERGY, "energy"), (K.T_PUSH, "push")):
        ip[slot] = K.N_IP + tape.programs[name]
    ip[K.I_NCONST], ip[K.I_C0], ip[K.I_NREG] = tape.consts.size, tape.n_inputs, tape.nreg
    ip = np.concatenate([ip, tape.code])
    ip[K.I_CMD] = K.CMD_PIECEWISE if th.piecewise else K.CMD_CONSTANT
    ip[K.I_ROOT_END] = cl.root_end
    ip[K.I_GUARD_IDX] = cl.breaks.index(cl.arm_s)
    ip[K.I_GRID] = grid
    fs = np.zeros(K.N_FS + tape.consts.size)
    fs[K.N_FS:] = tape.consts
    fs[K.F_AI], fs[K.F_SPAN], fs[K.F_DIR] = cl.ai, cl.span, cl.direction
    fs[K.F_KP], fs[K.F_KD] = cl.kp, cl.kd
    fs[I.F_RTOL], fs[I.F_ATOL] = cfg.rtol, cfg.atol
    fs[K.F_TLIM] = np.inf if cfg.torque_limit is None else cfg.torque_limit
    fs[K.F_SCUFF], fs[K.F_MINIMP], fs[K.F_MAXS] = cfg.scuff_tol, cfg.min_impact_s, cfg.max_s
    fs[K.F_GROUND], fs[K.F_TMAX] = cfg.ground_tol, t_max
    fs[K.F_MU] = np.inf if cfg.cone_mu is None else cfg.cone_mu
    fs[K.F_EPS] = cfg.cone_eps
    fs[K.F_SLOPE], fs[K.F_COSG], fs[K.F_SING] = gamma, np.cos(gamma), np.sin(gamma)
    par = np.zeros(ip[K.P_SIZE])
    p = Packed(fs, ip, par, t_max, th.n_states)
    p.part(K.P_ROWS, rows.size)[:] = rows.ravel()
    p.part(K.P_C, N)[:] = cl.c
    p.part(K.P_BRK, nbrk)[:] = cl.breaks
    p.part(K.P_SEGF, (nbrk + 1) * m)[:] = np.array(cl._piece_force, float).ravel()
    p.part(K.P_SEGT, nbrk + 1)[:] = cl._piece_T
    p.part(K.P_TGT, m)[:] = np.asarray(th.target, float)
    p.part(K.P_R, N * N)[:] = np.asarray(model.R, float).ravel()
    p.part(K.P_B, N)[:] = model.b
    nz = th.n_states
    dyn = th.dynamics.kernel_data()  # the servo form (thrust/dynamics.py)
    for key, slot, size in (("E", K.P_DE, nz), ("P", K.P_DP, nz * nz), ("Q", K.P_DQ, nz * m),
                            ("K", K.P_DK, m * nz), ("C", K.P_DC, m * nz),
                            ("D", K.P_DD, m * m)):
        p.part(slot, size)[:] = dyn[key].ravel()
    return p


def check_turn(model) -> None:
    """That turning the posture by ``delta`` (``q_N + delta``, ``kernel.tilted``) turns the
    robot rigidly about its stance foot, counter-clockwise (the swing foot and the centre of
    mass move by the rotation ``Rot(delta)``): what the compiled simulation on a slope rests
    on (SPEC 1: ``q_N`` the one absolute angle). ``ComputationError`` otherwise."""
    from ..errors import ComputationError

    N = model.n
    q = 0.3 + 0.17 * np.arange(N)
    d = 0.4
    qt = q.copy()
    qt[N - 1] += d
    rot = np.array([[np.cos(d), -np.sin(d)], [np.sin(d), np.cos(d)]])
    for f in (model.p_swing, model.p_com):
        a, b = np.asarray(f(qt), float)[:2], rot @ np.asarray(f(q), float)[:2]
        if not np.allclose(a, b, rtol=1e-10, atol=1e-12):
            raise ComputationError("the robot's unactuated coordinate does not turn it rigidly "
                                   "about the stance foot: the compiled simulation cannot put "
                                   "it on a slope")


def with_thrust(p: Packed, target=None, seg_force=None, seg_T=None) -> np.ndarray:
    """A copy of ``p.par`` with other thrust values: ``F_ss`` per thruster [N], the
    piecewise force per segment and thruster [N] (segments: ``len(breaks) + 1``), or the
    generalised force per segment [N m]."""
    m, nbrk = int(p.ip[K.I_M]), int(p.ip[K.I_NBRK])
    q = Packed(p.fs, p.ip, p.par.copy(), p.t_max, p.nz)
    if target is not None:
        q.part(K.P_TGT, m)[:] = np.asarray(target, float).ravel()
    if seg_force is not None:
        q.part(K.P_SEGF, (nbrk + 1) * m)[:] = np.asarray(seg_force, float).ravel()
    if seg_T is not None:
        q.part(K.P_SEGT, nbrk + 1)[:] = np.asarray(seg_T, float).ravel()
    return q.par


def record_width(N: int, nz: int, m: int) -> int:
    """Columns of a kernel step record: ``kernel.N_REC0`` scalars, ``q^-``, ``q'^-``,
    ``z_start``, ``z^-``, the thrust at impact and the state before the step's push."""
    return K.N_REC0 + 2 * N + 2 * nz + m + 2 * N + nz


def push_state(rec: np.ndarray, N: int, nz: int, m: int) -> tuple[float, np.ndarray] | None:
    """``(t, x)`` of the push of a kernel step record: its time [s] and the state
    ``[q; q'; z]`` just before it; None when the step had no push (or failed before it)."""
    t = float(rec[K.R_TPUSH])
    if t != t:
        return None
    o = K.N_REC0 + 2 * N + 2 * nz + m
    return t, np.array(rec[o:o + 2 * N + nz], float)


def first_times(rec: np.ndarray) -> dict[str, tuple[float, float] | None]:
    """The first times the stance force of a kernel step record left the cone it was timed
    against (``SimConfig.cone_mu``, ``cone_eps``): ``{"low_force": (t [s], s [1]) or None,
    "cone_exit": ...}`` (written for a failed step too, up to its failure)."""
    out = {}
    for name, (it, js) in (("low_force", (K.R_TLOW, K.R_SLOW)),
                           ("cone_exit", (K.R_TSLIP, K.R_SSLIP))):
        t = float(rec[it])
        out[name] = None if t != t else (t, float(rec[js]))
    return out


# ----------------------------------------------------------------------------- dense output
class DenseSolution:
    """The dense DOP853 solution of one integration call, evaluated like SciPy's
    ``OdeSolution`` (a time on a node belongs to the step that ends there). ``ts``: nodes.
    Made for every piece of every step, evaluated for few: it keeps one copy of the rows and
    takes its parts from it when first asked."""

    def __init__(self, rows: np.ndarray, t0: float, t1: float, n: int, copy: bool = True):
        self.rows = rows[:, :2 + 8 * n].copy() if copy else rows[:, :2 + 8 * n]
        self.t0, self.t1, self.n = t0, t1, n

    @functools.cached_property
    def t_old(self) -> np.ndarray:
        return self.rows[:, 0]

    @functools.cached_property
    def t_new(self) -> np.ndarray:
        return self.rows[:, 1]

    @functools.cached_property
    def y_old(self) -> np.ndarray:
        return self.rows[:, 2:2 + self.n]

    @functools.cached_property
    def F(self) -> np.ndarray:
        return self.rows[:, 2 + self.n:].reshape(-1, 7, self.n)

    @functools.cached_property
    def ts(self) -> np.ndarray:
        return np.concatenate([[self.t0], self.t_new[:-1], [self.t1]])

    def __call__(self, t):
        t = np.asarray(t, float)
        scalar = t.ndim == 0
        tt = np.atleast_1d(t)
        k = np.searchsorted(self.ts, tt, side="left") - 1
        k = np.clip(k, 0, self.t_old.size - 1)
        h = self.t_new[k] - self.t_old[k]
        x = ((tt - self.t_old[k]) / h)[:, None]
        y = np.zeros((tt.size, self.n))
        for i, j in enumerate(range(6, -1, -1)):
            y += self.F[k, j]
            y *= x if i % 2 == 0 else 1.0 - x
        y += self.y_old[k]
        return y[0] if scalar else y.T


# ----------------------------------------------------------------------------- one run
@dataclass
class StepOutcome:
    """One walking step of the kernel: status (``kernel.OK`` or a failure code), the raw
    record, the outcome row, the post-impact state, the dense pieces ``(t0, t1, seg, sol)``."""

    status: int
    record: np.ndarray
    outcome: np.ndarray
    x_next: np.ndarray
    pieces: list


class Stepper:
    """Run the compiled closed loop one walking step at a time (for callers that change the
    thrust between steps, e.g. step-to-step control): ``step`` returns a
    :class:`StepOutcome`; ``set_thrust`` changes the thrust values of the following steps."""

    def __init__(self, cl: ClosedLoop, t_max: float, dense: bool = True):
        self.cl = cl
        self.model = cl.model
        self.packed = pack(cl, t_max)
        self.jm = kernel()
        # kept with the closed loop: the energies of its runs evaluate it at their quadrature
        # nodes through the kernel with these settings (energetics/nodes.py)
        cl.__dict__.setdefault("_packed", self.packed)
        self.dense = dense
        N, m = self.model.n, self.model.n_thrusters
        self.n = 2 * N + self.packed.nz
        self.width = record_width(N, self.packed.nz, m)
        self.par = self.packed.par.copy()
        # (rows are read only after the kernel wrote them: no need to zero 300 kB per run)
        self._buf = np.empty((BUF_ROWS, 2 + 8 * self.n))
        self._calls = np.zeros((256, K.N_CALL))
        # the kernel's one-run arguments, reused from step to step
        p = self.packed
        self._X0 = np.zeros((1, self.n))
        self._T0 = np.zeros(1)
        self._K0 = np.zeros(1, np.int64)
        self._recs = np.zeros((1, 1, self.width))
        self._outs = np.zeros((1, K.N_OUT))
        self._XN = np.zeros((1, self.n))
        self._info = np.zeros((1, 2), np.int64)
        self._done = np.zeros(1, np.int64)
        self._gains = np.array([[p.fs[K.F_KP], p.fs[K.F_KD]]])
        self._nopush = np.full((1, 6), -1.0)
        self._fs = p.fs.copy()  # with this step's ground height (kernel.F_TERRAIN)

    def set_thrust(self, target=None, seg_force=None, seg_T=None) -> None:
        """Thrust values for the following steps (see :func:`with_thrust`)."""
        self.par = with_thrust(Packed(self.packed.fs, self.packed.ip, self.par,
                                      self.packed.t_max, self.packed.nz),
                               target, seg_force, seg_T)

    def step(self, k: int, t0: float, x0: np.ndarray, push=None, ground: float = 0.0,
             behind: float = 0.0) -> StepOutcome:
        """Step ``k`` (1-based) from the post-impact state ``x0`` at time ``t0`` [s];
        ``push``: ``[k, s, link index, lambda, P_x, P_y]`` (see ``kernel.apply_push``);
        ``ground``: the height [m] above the stance foot (normal to the slope) of the ground
        where the swing foot lands (SPEC 14: the guard is the swing foot at that height);
        ``behind``: the ground [m] the scuff checks measure from before the guard is armed
        (the lower of the stance level and the level the swing foot left)."""
        p = self.packed
        fs = self._fs
        fs[K.F_TERRAIN], fs[K.F_BEHIND] = ground, behind
        X0, recs, outs, XN, info = self._X0, self._recs, self._outs, self._XN, self._info
        X0[0] = np.asarray(x0, float).reshape(self.n)
        self._T0[0] = t0
        self._K0[0] = k
        pu = self._nopush if push is None else np.ascontiguousarray(
            np.asarray(push, float).reshape(1, 6))
        while True:
            self.jm.module.run(X0, self._T0, self._K0, 1, fs, p.ip, self.par[None, :],
                               self._gains, pu, recs, outs, self._done, XN, info, 0, 1,
                               self._buf, self._calls)
            if int(outs[0, K.O_STATUS]) != K.FAIL_BUFFER or self._buf.shape[0] >= 1 << 18:
                break
            self._buf = np.empty((4 * self._buf.shape[0], self._buf.shape[1]))
            self._calls = np.zeros((4 * self._calls.shape[0], K.N_CALL))
        status, ncalls = int(outs[0, K.O_STATUS]), int(info[0, 0])
        pieces = []
        if self.dense and ncalls:
            calls = self._calls[:ncalls].tolist()
            # one copy of the step's rows (the buffer is reused), each piece a view of it
            block = self._buf[:int(max(c[2] for c in calls)), :2 + 8 * self.n].copy()
            for seg, first, last, ta, tb in calls:
                pieces.append((ta, tb, int(seg), DenseSolution(block[int(first):int(last)], ta,
                                                               tb, self.n, copy=False)))
        return StepOutcome(status, recs[0, 0].copy(), outs[0].copy(), XN[0].copy(), pieces)


def failure_text(out: np.ndarray, cfg: SimConfig, t_max: float) -> tuple[str, str]:
    """``(failure kind, reason)`` of a failed step, worded as the SciPy path words them."""
    code, t, s, v = int(out[K.O_STATUS]), out[K.O_T], out[K.O_S], out[K.O_VALUE]
    if code == K.FAIL_START_FORCE:
        return "fall", (f"the vertical ground force is negative at the start of the step "
                        f"({v:.4g} N)")
    if code == K.FAIL_START_BELOW:
        return "scuff", f"the swing foot starts the step {-v:.4g} m below the ground (s = {s:.4g})"
    if code == K.FAIL_INTEGRATOR:
        if v > 0 and s > 1.0:  # the guard was armed and the step ran past the gait's end
            return "no-impact", (f"the swing foot did not strike the ground by the end of the "
                                 f"step (s = 1; a grazing or missed touchdown): on the "
                                 f"extrapolated constraints the integrator DOP853 (compiled) "
                                 f"failed at s = {s:.4g}, t = {t:.6g} s (Required step size is "
                                 f"less than spacing between numbers.)")
        return "integrator", (f"integrator DOP853 (compiled) failed at t = {t:.6g} s: "
                              "Required step size is less than spacing between numbers.")
    if code == K.FAIL_CONTROLLER:
        return "controller", (f"the decoupling matrix is singular near t = {t:.6g} s "
                              "(input-output linearisation undefined)")
    if code == K.FAIL_NO_IMPACT:
        return "no-impact", f"no impact within {t_max:.4g} s (alpha = {v:.6g} rad)"
    if code == K.FAIL_EVENT:
        name = {K.EV_SCUFF: "scuff", K.EV_OVERSHOOT: "overshoot", K.EV_REVERSE: "reverse",
                K.EV_HORIZONTAL: "horizontal", K.EV_FORCE: "force"}[int(out[K.O_EVENT])]
        failure, text = EVENT_REASONS[name]
        return failure, f"{text} at t = {t:.6g} s, s = {s:.4g}"
    if code == K.FAIL_EARLY:
        return "scuff", (f"the swing foot strikes the ground at s = {s:.4g}, before "
                         f"s = {cfg.min_impact_s:g} (a scuff, not the end of the step; "
                         "threshold `min_impact_s`)")
    if code == K.FAIL_IMPACT_FY:
        return "impact", f"impact infeasible: vertical impulse {v:.4g} N s <= 0 at t = {t:.6g} s"
    if code == K.FAIL_IMPACT_LIFT:
        return "impact", (f"impact infeasible: the trailing foot does not lift off (vertical "
                          f"velocity {v:.4g} m/s) at t = {t:.6g} s")
    return "integrator", "the integration needed more steps than the kernel's buffers hold"


def step_record(rec: np.ndarray, N: int, nz: int, m: int):
    """A :class:`~thrustwalk_cli.simulation.full_order.StepRecord` from a kernel record."""
    r = rec.tolist()  # Python floats, converted at once
    o = K.N_REC0
    q, dq = r[o:o + N], r[o + N:o + 2 * N]
    z0 = r[o + 2 * N:o + 2 * N + nz]
    F = r[o + 2 * N + 2 * nz:o + 2 * N + 2 * nz + m]
    fr = r[K.R_MAXFR]
    sm, sp, s0 = r[K.R_SIGM], r[K.R_SIGP], r[K.R_SIG0]
    Fx, Fy = r[K.R_FX], r[K.R_FY]
    return StepRecord(
        step=int(r[K.R_STEP]), t_start=r[K.R_T0], t_impact=r[K.R_T1],
        step_time=float(rec[K.R_T1] - rec[K.R_T0]), alpha_start=r[K.R_ALPHA0],
        z_start=tuple(z0), alpha_minus=r[K.R_ALPHAM],
        s_minus=r[K.R_SM], sigma_start=s0, zeta_start=0.5 * s0 ** 2,
        sigma_minus=sm, zeta_minus=0.5 * sm ** 2, sigma_plus=sp,
        zeta_plus=0.5 * sp ** 2, impulse=(Fx, Fy), impulse_friction_ratio=abs(Fx) / Fy,
        trailing_foot_lift_velocity=r[K.R_LIFT],
        thrust_at_impact=tuple(F), min_vertical_force=r[K.R_MINFV],
        max_friction_ratio=None if fr != fr else fr,
        low_force_at=None if r[K.R_TLOW] != r[K.R_TLOW] else (r[K.R_TLOW], r[K.R_SLOW]),
        cone_exit_at=None if r[K.R_TSLIP] != r[K.R_TSLIP] else (r[K.R_TSLIP], r[K.R_SSLIP]),
        max_abs_output=r[K.R_MAXY], max_abs_output_rate=r[K.R_MAXDY],
        max_abs_torque=r[K.R_MAXU], torque_saturated=bool(r[K.R_SAT]),
        energy_minus=r[K.R_EM], energy_plus=r[K.R_EP],
        q_minus=tuple(q), dq_minus=tuple(dq), nfev=int(r[K.R_NFEV]))


def run_steps(cl: ClosedLoop, x0: np.ndarray, t_max: float, steps: int,
              progress: Callable[[int], None] | None = None, heights=None):
    """The compiled counterpart of ``full_order.simulate``'s loop: (records, segments,
    failure, reason, nfev) with segments ``full_order.Segment`` holding dense solutions.
    ``heights``: the terrain, step ``k`` landing ``heights[k - 1]`` [m] above its stance foot
    (SPEC 14; None: level ground); each record carries its height (``terrain_height``)."""
    st = Stepper(cl, t_max, dense=True)
    N, m, nz = cl.N, cl.m, st.packed.nz
    records, segments = [], []
    failure, reason, nfev = "", "", 0
    t, x = 0.0, np.asarray(x0, float)
    for k in range(1, steps + 1):
        h = 0.0 if heights is None else float(heights[k - 1])
        res = st.step(k, t, x, ground=h, behind=behind_level(heights, k))
        for ta, tb, seg, sol in res.pieces:
            segments.append(Segment(k, ta, tb, seg, sol))
        if res.status != K.OK:
            failure, text = failure_text(res.outcome, cl.config, t_max)
            if (heights is not None and int(res.outcome[K.O_STATUS]) == K.FAIL_EVENT
                    and int(res.outcome[K.O_EVENT]) == K.EV_OVERSHOOT):
                failure, text = missed_footing(cl.config.max_s, h, res.outcome[K.O_T])
            reason = f"step {k}: {text}"
            break
        rec = step_record(res.record, N, nz, m)
        if h != 0.0:
            rec = replace(rec, terrain_height=h)
        nfev += rec.nfev
        records.append(rec)
        t, x = rec.t_impact, res.x_next
        if progress is not None:
            progress(1)
    return records, segments, failure, reason, nfev
