"""Energy along a run from the integrator's own stages? (SPEC 15, 7; issue 28: "energy along a
run adds < 10 % to simulate"). A measurement, not a feature: what the idea of integrating the
step energies with DOP853's weights at its accepted stages (the augmented-ODE quadrature
``int g dt ~ h sum_i b_i g(Y_i)`` over the stages with ``b_i != 0``, no new closed-loop
evaluation) would give and cost, against today's 6-point Gauss-Lobatto on the dense output
(``energetics.run``). Tried and not kept: see docs/performance.md, issue 28.

For RABBIT and the 3-link walker (``bench/simulate_energy.py``'s runs: 2 runs x 20 steps,
ideal thrust 0 / -10 N, the nominal start) and walker5 (-20 N on its torso thruster):

* accuracy, on the first run of 6 steps: every accepted integrator step's 12 stages
  rebuilt from its dense row (``y_old``, ``t_old``, ``h``) with SciPy's DOP853 tableau and
  ``ClosedLoop.rhs`` (the compiled kernel's stages to rounding: the rebuilt ``y_new`` is
  printed against the row's end), the closed loop at the 8 stages with ``b_i != 0`` and at
  ``y_new`` by ``ClosedLoop.law``, every integrand of ``run_energy`` there; per walking step
  the stage quadrature on the rows not clipped by an event (Lobatto on the clipped ones)
  against Lobatto on every row, over the step's absolute work (joints and thrusters), and
  the work-energy identity's residual of both;
* the rows that would still need the Lobatto path and the root finding: a kinked integrand
  (``u_j q_j'``, ``F_k d_k.p_k'``, the clipped electrical power) changing sign among the 9
  stage samples, or a row clipped by an event (its stages span the whole step);
* CPU (medians, this process): ``tw.simulate``, its step energies
  (``simulation_energy``), and the compiled kernel's closed loop at the Lobatto nodes
  (``step_stats.energy_nodes``) on every row against on the rows a stage quadrature would
  leave to it (here: a kinked integrand changing sign among the Lobatto nodes, which the
  stage samples find on about as many rows, see the accuracy line, or clipped), each such row
  evaluated on its own (6 nodes).

What the stage data would cost the simulation itself (the kernel keeping ``u``, ``q'``,
``F``, ``T``, ``B_F^T q'`` at every stage and copying the 9 kept stages of each accepted
step next to its dense row) needs a modified kernel: measured with a prototype, reported in
docs/performance.md, not here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.integrate import DOP853
from timing import median_cpu

import thrustwalk_cli as tw
from thrustwalk_cli.energetics import nodes as NODES
from thrustwalk_cli.energetics import run as RUN
from thrustwalk_cli.simulation import kernel as K

REPO = Path(__file__).resolve().parents[1]
CASES = {"RABBIT": ("robots/rabbit.yaml", "gaits/rabbit_walk.yaml", [0.0, -10.0]),
         "3-link": ("robots/three_link.yaml", "gaits/three_link_walk.yaml", [0.0, -10.0]),
         "walker5": ("tests/data/walker5.yaml", "tests/data/walker5_thrust.yaml", [-20.0])}
B_STAGES = np.nonzero(DOP853.B)[0]  # 0, 5, ..., 11


def _cpu(fn, repeat: int = 9) -> float:
    return median_cpu(fn, repeat)


def _steps(full) -> list[tuple]:
    by: dict[int, list] = {}
    for s in full.segments:
        by.setdefault(s.step, []).append((s.t0, s.t1, s.interval, s.sol))
    return [(r.step, by[r.step], r.q_minus, r.dq_minus) for r in full.steps]


def _stages(cl, t: float, y: np.ndarray, h: float, seg: int) -> tuple[np.ndarray, np.ndarray]:
    """DOP853's 12 stage states of one step (SciPy's tableau) and its 8th-order ``y_new``."""
    A, B, C = DOP853.A, DOP853.B, DOP853.C
    Kx = np.zeros((12, y.size))
    X = np.zeros((12, y.size))
    X[0] = y
    Kx[0] = cl.rhs(t, y, seg)
    for s in range(1, 12):
        X[s] = y + h * (Kx[:s].T @ A[s, :s])
        Kx[s] = cl.rhs(t + C[s] * h, X[s], seg)
    return X, y + h * (Kx.T @ B)


def _integrands(ig, d: dict, rows: int, k: int) -> tuple[np.ndarray, int]:
    """``run_energy``'s integrand table (rows, k, columns) and its number of kinked ones."""
    kv = ig.kinked(d)
    gen, pin, fuel = ig.smooth(d)
    cols = [kv, gen[:, None]]
    if ig.m:
        cols += [np.nan_to_num(pin, nan=0.0), fuel]
    if ig.el:
        cols.append(ig.joule(d))
    return np.concatenate(cols, axis=1).reshape(rows, k, -1), kv.shape[1]


def accuracy(label: str, w, thrust: list[float]) -> None:
    """The stage quadrature against Lobatto, per walking step (module docstring)."""
    full = tw.simulate(w, steps=6, thrust_model="ideal", thrust=thrust[-1:],
                       start="nominal").outcomes[0].full
    cl = full.sim
    steps = _steps(full)
    dense = NODES.Dense([s[1] for s in steps])
    ig = RUN._Integrands(cl, False)
    R = dense.lo.size
    whole = (dense.lo == dense.t_old) & (dense.hi == dense.t_old + dense.h)
    X, gap = [], 0.0
    for r in range(R):
        S, y_new = _stages(cl, dense.t_old[r], dense.y_old[r], dense.h[r], int(dense.seg[r]))
        X.append(np.vstack([S[B_STAGES], y_new]))
        end = dense.at(np.array([r]), np.array([dense.t_old[r] + dense.h[r]]))[0]
        gap = max(gap, float(np.abs(y_new - end).max()))
    X = np.array(X)
    ks = B_STAGES.size + 1
    sv, nk = _integrands(ig, NODES.evaluate(cl, X.reshape(R * ks, -1), np.repeat(dense.seg, ks)),
                         R, ks)
    stage = np.einsum("rkc,k->rc", sv[:, :-1], DOP853.B[B_STAGES]) * dense.h[:, None]
    x, wl = NODES.lobatto_rule(NODES.NODES)
    half = 0.5 * (dense.hi - dense.lo)
    t = (0.5 * (dense.lo + dense.hi))[:, None] + half[:, None] * x[None]
    lv, _ = _integrands(ig, NODES.evaluate(cl, dense.at_nodes(t),
                                           np.repeat(dense.seg, NODES.NODES)), R, NODES.NODES)
    lob = np.einsum("rkc,k->rc", lv, wl) * half[:, None]
    sg = sv[..., :nk] >= 0.0
    kinked = np.any(sg != sg[:, :1], axis=1).any(axis=1)
    ps, pl = (np.zeros((len(steps), lob.shape[1])) for _ in range(2))
    np.add.at(ps, dense.owner, np.where(whole[:, None], stage, lob))
    np.add.at(pl, dense.owner, lob)
    en = RUN.run_energy(cl, steps)
    absw = np.array([sum(e.joint_absolute_work) + sum(map(abs, e.thrust_work)) for e in en])
    dE = np.array([e.kinetic_end + e.potential_end - e.kinetic_start - e.potential_start
                   for e in en])
    nb, m = cl.nb, cl.m
    work = np.r_[np.arange(nb + m), nk]  # joints' and thrusters' net work, generalised work
    print(f"{label}: {len(steps)} steps, {R} integrator steps ({(~whole).sum()} clipped by an "
          f"event); rebuilt y_new vs the row's end {gap:.1e}; stage vs Lobatto, per step, "
          f"every integrand, / the step's absolute work: max "
          f"{(np.abs(ps - pl).max(1) / absw).max():.1e}; work-energy residual / absolute work: "
          f"stages {(np.abs(ps[:, work].sum(1) - dE) / absw).max():.1e}, Lobatto "
          f"{(np.abs(pl[:, work].sum(1) - dE) / absw).max():.1e}; rows still needing "
          f"Lobatto: {(kinked | ~whole).sum()} of {R} ({100 * (kinked | ~whole).mean():.0f} %)")


def cost(label: str, w, thrust: list[float]) -> None:
    """CPU of simulate, its step energies, and the kernel's nodes on all rows / fallback rows."""
    def sim():
        return tw.simulate(w, steps=20, thrust_model="ideal", thrust=thrust, start="nominal")

    sim()
    t_sim = _cpu(sim)
    results = [sim() for _ in range(9)]
    it = iter(results)

    def energy():
        for oc in next(it).outcomes:
            RUN.simulation_energy(oc.full)
    t_energy = _cpu(energy)
    t_all = t_sub = 0.0
    n_all = n_sub = 0
    for oc in results[0].outcomes:
        full = oc.full
        cl = full.sim
        dense = NODES.Dense([s[1] for s in _steps(full)])
        ig = RUN._Integrands(cl, False)
        kv = ig.kinked(NODES.evaluate_compiled(cl, dense, None))
        sg = kv.reshape(dense.lo.size, NODES.NODES, -1) >= 0.0
        sel = np.nonzero(np.any(sg != sg[:, :1], axis=(1, 2))
                         | (dense.lo > dense.t_old) | (dense.hi < dense.t_old + dense.h))[0]
        mod, fs, ip, par = NODES.kernel_context(cl)
        wk = np.zeros(int(ip[K.W_SIZE]))
        c0, nc = int(ip[K.I_C0]), int(ip[K.I_NCONST])
        wk[c0:c0 + nc] = fs[K.N_FS:K.N_FS + nc]
        x, _ = NODES.lobatto_rule(NODES.NODES)
        width = cl.nb + cl.N + 2 * cl.m + 1

        def nodes(idx, start):
            args = (np.ascontiguousarray(dense.R[idx]), np.ascontiguousarray(dense.lo[idx]),
                    np.ascontiguousarray(dense.hi[idx]), dense.seg[idx].astype(np.int64),
                    start, np.zeros((0, cl.m)), x, fs, ip, par, wk,
                    np.empty((idx.size, NODES.NODES, width)))
            return lambda: mod.energy_nodes(*args)
        every = np.arange(dense.lo.size)
        t_all += _cpu(nodes(every, dense.start.copy()))
        t_sub += _cpu(nodes(sel, np.ones(sel.size, np.int64)))  # each row on its own
        n_all += every.size
        n_sub += sel.size
    print(f"{label} 2 runs x 20 steps: simulate {1e3 * t_sim:.1f} ms, step energies "
          f"{1e3 * t_energy:.1f} ms ({100 * t_energy / t_sim:.0f} %); the kernel's closed loop "
          f"at the Lobatto nodes, every row ({n_all}) {1e3 * t_all:.2f} ms "
          f"({100 * t_all / t_sim:.1f} %), only the rows a stage quadrature would leave to it "
          f"({n_sub}, {100 * n_sub / n_all:.0f} %) {1e3 * t_sub:.2f} ms "
          f"({100 * t_sub / t_sim:.1f} %)")


def main() -> None:
    for label, (robot, gait, thrust) in CASES.items():
        w = tw.load_walker(str(REPO / robot), str(REPO / gait))
        accuracy(label, w, thrust)
        if label != "walker5":
            cost(label, w, thrust)


if __name__ == "__main__":
    main()
