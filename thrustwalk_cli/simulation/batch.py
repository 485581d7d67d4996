"""Many full-order simulations in one call (SPEC 7, 12, 13): the compiled kernel over a batch
of runs that differ in their start, thrust values, controller gains and pushes, on every core.

This is the entry point for studies that need thousands of closed-loop runs: push-recovery
maps (a push per run), Floquet multipliers by finite differences (perturbed starts, one step
each, pre-impact states in the records), Monte-Carlo starts, thrust sweeps. A controller that
changes the thrust between steps uses :class:`thrustwalk_cli.simulation.stepper.Stepper`
(one step per call) instead.

Runs are split into chunks that threads hand to the kernel, which releases the GIL (numba
``nogil``); on 2 cores threads beat a process pool (no start-up, no pickling, the compiled
kernel loaded once), see ``bench/bench_simulate.py``. Units SI.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..hzd.zero_dynamics import ZeroDynamics
from . import kernel as K
from . import stepper as C
from .closed_loop import ClosedLoop, SimConfig, ThrustModel, predicted_cycle
from .full_order import Start, initial_state
from .records import StepRecord

# per-step fields of BatchResult.field(name): kernel record column
FIELDS = {
    "t_start": K.R_T0, "t_impact": K.R_T1, "alpha_start": K.R_ALPHA0,
    "alpha_minus": K.R_ALPHAM, "s_minus": K.R_SM, "sigma_start": K.R_SIG0,
    "sigma_minus": K.R_SIGM, "sigma_plus": K.R_SIGP, "impulse_x": K.R_FX,
    "impulse_y": K.R_FY, "trailing_foot_lift_velocity": K.R_LIFT,
    "min_vertical_force": K.R_MINFV, "max_friction_ratio": K.R_MAXFR,
    "max_abs_output": K.R_MAXY, "max_abs_output_rate": K.R_MAXDY,
    "max_abs_torque": K.R_MAXU, "torque_saturated": K.R_SAT, "energy_minus": K.R_EM,
    "energy_plus": K.R_EP, "nfev": K.R_NFEV, "pushed": K.R_PUSHED,
}


def push_row(model, step: int, s: float, impulse: Sequence[float], link: str | None = None,
             at: float = 1.0) -> np.ndarray:
    """A push for :func:`simulate_batch`: impulse ``(P_x, P_y)`` [N s] at phase ``s`` of step
    ``step`` (1-based), applied at the point ``(1 - at) * origin + at * end`` of ``link``
    (default: the stance link's end: the hip of a one-link stance leg, the stance knee of a
    kneed walker): ``q' += D^-1 J_p^T P``
    with the stance foot pinned (SPEC 12). The impulse is in the world frame: on a slope
    (``model`` a slope-frame model, SPEC 14) it is turned into the slope frame by ``-gamma``."""
    names = model.robot.link_names
    li = 0 if link is None else names.index(link) if link in names else -1
    if li < 0:
        raise InputError.param("link", f"unknown link {link!r} (choose from "
                                       f"{', '.join(names)})")
    P = np.asarray(impulse, float).ravel()
    if P.size != 2 or step < 1:
        raise InputError.param("push", "a push needs step >= 1 and an impulse (P_x, P_y)")
    gamma = float(getattr(model, "slope", 0.0))
    if gamma != 0.0:  # world -> slope frame
        c, sn = np.cos(gamma), np.sin(gamma)
        P = np.array([c * P[0] + sn * P[1], c * P[1] - sn * P[0]])
    return np.array([float(step), float(s), float(li), float(at), P[0], P[1]])


@dataclass(frozen=True)
class BatchResult:
    """Outcomes of a batch: per run ``success``, ``failure`` (kind, as
    :class:`~thrustwalk_cli.simulation.full_order.SimResult`), ``reason``, ``failed_step``
    (0 when it completed), ``steps_completed``; per step the raw kernel records (read them
    with :meth:`field` or :meth:`step_records`); ``final_state`` the last post-impact state
    of each run. ``wall_time`` [s], ``workers`` threads."""

    success: np.ndarray
    failure: tuple[str, ...]
    reason: tuple[str, ...]
    failed_step: np.ndarray
    steps_completed: np.ndarray
    records: np.ndarray = field(repr=False)
    final_state: np.ndarray = field(repr=False)
    N: int
    nz: int
    m: int
    wall_time: float
    workers: int

    def field(self, name: str) -> np.ndarray:
        """(runs, steps) array of one per-step quantity (NaN where the step was not
        completed): any key of ``FIELDS``, or ``zeta_minus``/``zeta_plus``/``zeta_start``/
        ``step_time``."""
        done = np.arange(self.records.shape[1])[None, :] < self.steps_completed[:, None]
        if name in ("zeta_minus", "zeta_plus", "zeta_start"):
            base = {"zeta_minus": "sigma_minus", "zeta_plus": "sigma_plus",
                    "zeta_start": "sigma_start"}[name]
            v = 0.5 * self.records[:, :, FIELDS[base]] ** 2
        elif name == "step_time":
            v = self.records[:, :, K.R_T1] - self.records[:, :, K.R_T0]
        else:
            v = self.records[:, :, FIELDS[name]].astype(float)
        return np.where(done, v, np.nan)

    def state_minus(self) -> np.ndarray:
        """(runs, steps, 2N + nz) pre-impact states ``[q^-; q'^-; z^-]`` (NaN where not
        completed): what a Poincare map on the impact surface needs (SPEC 13)."""
        o, N, nz = K.N_REC0, self.N, self.nz
        x = np.concatenate([self.records[:, :, o:o + 2 * N],
                            self.records[:, :, o + 2 * N + nz:o + 2 * N + 2 * nz]], axis=2)
        done = np.arange(self.records.shape[1])[None, :] < self.steps_completed[:, None]
        return np.where(done[:, :, None], x, np.nan)

    def step_records(self, run: int) -> list[StepRecord]:
        """The completed steps of one run as :class:`StepRecord` objects."""
        return [C.step_record(self.records[run, j], self.N, self.nz, self.m)
                for j in range(int(self.steps_completed[run]))]


def start_states(zd: ZeroDynamics, thrust: ThrustModel, starts: Sequence[Start]) -> np.ndarray:
    """(runs, 2N + nz) post-impact start states for :func:`simulate_batch` (SPEC 5, 7)."""
    return np.array([initial_state(zd, thrust, st) for st in starts], float)


def simulate_batch(zd: ZeroDynamics, thrust: ThrustModel, x0: np.ndarray,
                   config: SimConfig = SimConfig(), *, targets: np.ndarray | None = None,
                   seg_force: np.ndarray | None = None, seg_T: np.ndarray | None = None,
                   gains: np.ndarray | None = None, pushes: np.ndarray | None = None,
                   workers: int = 2, chunk: int | None = None) -> BatchResult:
    """Run ``len(x0)`` full-order simulations of ``config.steps`` steps with the compiled
    kernel (SPEC 7). Every run starts at t = 0 from its post-impact state ``x0[r]`` =
    ``[q; q'; z]`` (:func:`start_states`) with the thrust model ``thrust``, except where a
    per-run array overrides it: ``targets`` (runs, m) F_ss [N]; ``seg_force`` (runs, segments,
    m) [N] / ``seg_T`` (runs, segments) [N m], the piecewise thrust per alpha segment;
    ``gains`` (runs, 2) ``(K_p, K_d)``; ``pushes`` (runs, 6), rows from :func:`push_row`
    (``-1`` rows: none). ``workers`` threads share the runs. A failure ends its run only."""
    config.validate()
    t_wall = time.perf_counter()
    cl = ClosedLoop(zd, thrust, config)
    pred = predicted_cycle(zd, thrust)
    t_max = config.max_step_time or (10.0 * pred.step_time if pred.exists else 10.0)
    p = C.pack(cl, t_max)
    jm = C.kernel()
    N, m, nz = cl.N, cl.m, p.nz
    n = 2 * N + nz
    X0 = np.ascontiguousarray(np.asarray(x0, float).reshape(-1, n))
    R = X0.shape[0]
    nseg = int(p.ip[K.I_NBRK]) + 1
    PAR = np.repeat(p.par[None, :], R, axis=0)
    for r in range(R):
        if targets is not None or seg_force is not None or seg_T is not None:
            PAR[r] = C.with_thrust(
                p, None if targets is None else np.asarray(targets, float).reshape(R, m)[r],
                None if seg_force is None else np.asarray(seg_force, float).reshape(
                    R, nseg, m)[r],
                None if seg_T is None else np.asarray(seg_T, float).reshape(R, nseg)[r])
    G = np.tile([p.fs[K.F_KP], p.fs[K.F_KD]], (R, 1)) if gains is None else \
        np.ascontiguousarray(np.asarray(gains, float).reshape(R, 2))
    PU = np.full((R, 6), -1.0) if pushes is None else \
        np.ascontiguousarray(np.asarray(pushes, float).reshape(R, 6))
    width = C.record_width(N, nz, m)
    S = config.steps
    recs = np.zeros((R, S, width))
    outs = np.zeros((R, K.N_OUT))
    done = np.zeros(R, np.int64)
    XN = np.zeros((R, n))
    info = np.zeros((R, 2), np.int64)
    T0 = np.zeros(R)
    K0 = np.ones(R, np.int64)
    workers = max(1, int(workers))
    chunk = chunk or max(1, min(64, -(-R // (4 * workers))))

    def work(lo: int, hi: int, rows: int = C.BUF_ROWS) -> None:
        buf = np.zeros((rows, 2 + 8 * n))
        calls = np.zeros((256 if rows == C.BUF_ROWS else 4096, K.N_CALL))
        jm.module.run(X0, T0, K0, S, p.fs, p.ip, PAR, G, PU, recs, outs, done, XN, info, lo,
                      hi, buf, calls)

    bounds = [(lo, min(R, lo + chunk)) for lo in range(0, R, chunk)]
    if workers == 1 or len(bounds) == 1:
        for lo, hi in bounds:
            work(lo, hi)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(lambda b: work(*b), bounds))
    for r in np.nonzero(outs[:, K.O_STATUS] == K.FAIL_BUFFER)[0]:  # rare: a long step
        work(int(r), int(r) + 1, rows=64 * C.BUF_ROWS)
    success = outs[:, K.O_STATUS] == K.OK
    failure, reason = [], []
    for r in range(R):
        if success[r]:
            failure.append("")
            reason.append(f"completed {S} steps")
        else:
            kind, text = C.failure_text(outs[r], config, t_max)
            failure.append(kind)
            reason.append(f"step {int(outs[r, K.O_STEP])}: {text}")
    failed_step = np.where(success, 0, outs[:, K.O_STEP]).astype(int)
    return BatchResult(success, tuple(failure), tuple(reason), failed_step, done.copy(), recs,
                       XN, N, nz, m, time.perf_counter() - t_wall, workers)
