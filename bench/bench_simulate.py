"""Full-order simulation benchmark (SPEC 7): compiled vs SciPy per step, the right-hand side
per call (vs Pinocchio's ABA), the 1,000-run batch, the fixed point by simulation vs the
zero-dynamics route.

Baselines measured in the same run (medians):
* one simulated step: the SciPy reference (``solve_ivp`` DOP853 with Python events, the same
  steps and records) over the same 10 steps from the same start, rtol = atol = 1e-9;
* right-hand side per call: Pinocchio's ABA from Python on the same robot (links, masses,
  inertias, joints; ``pip install -e '.[bench]'``), printed as "skipped" when missing;
* 1,000 runs of 10 steps: threads (the batch API, ``workers=2``) vs a pool of 2 processes,
  each loading the compiled kernel from the cache;
* the fixed point: the zero-dynamics route (the formula and one whole limit cycle, the
  gait's precomputation excluded and included) vs the SciPy reference simulation until
  ``zeta^-`` is within 1e-6 of ``zeta*``;
* simulate as a whole (issue 26; first, alone with ``python bench/bench_simulate.py
  --whole``): ``tw.simulate(walker, steps=20, thrust_model=..., thrust=[0, -10],
  start="nominal")`` (two runs of 20 steps, each with its zero-dynamics prediction and the
  reduced cascade beside it), warm, against the same call with ``method="scipy"``: CPU times
  of this process (the machine is shared), medians of pairs measured side by side. Targets:
  compiled >= 30x the SciPy method with ideal thrust on both bundled robots, and RABBIT's 20
  steps x 2 runs <= 60 ms; the second-order thruster for information.
"""

from __future__ import annotations

import os
import statistics
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from timing import median_cpu, median_time, report

REPO = Path(__file__).resolve().parents[1]
STEPS = 10
WHOLE_STEPS = 20
WHOLE_THRUST = [0.0, -10.0]


def _gaits() -> list[str]:
    return [g for g in ("three_link_walk", "rabbit_walk")
            if (REPO / "gaits" / f"{g}.yaml").is_file()]


def _pinocchio(robot):
    """The robot as a Pinocchio model (planar: revolute joints about z in the link frames,
    the root at the stance foot), or None without Pinocchio."""
    try:
        import pinocchio as pin
    except ImportError:
        return None
    model = pin.Model()
    ids = {}
    for lk in robot.links:  # parents come first
        parent = 0 if lk.parent is None else ids[lk.parent]
        at = robot.stance_foot.point if lk.parent is None else lk.joint
        place = pin.SE3(np.eye(3), np.array([at[0], at[1], 0.0]))
        jid = model.addJoint(parent, pin.JointModelRZ(), place, lk.name)
        inertia = pin.Inertia(lk.mass, np.array([lk.com[0], lk.com[1], 0.0]),
                              np.diag([1e-6, 1e-6, max(lk.inertia, 1e-9)]))
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        ids[lk.name] = jid
    model.gravity.linear = np.array([0.0, -robot.gravity, 0.0])
    return pin, model, model.createData()


def _batch_part(args):
    """One process's share of the 1,000 runs (the kernel comes from the cache)."""
    gait, X0, steps = args
    from thrustwalk_cli.simulation.batch import simulate_batch
    from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
    from thrustwalk_cli.walker import load_walker

    w = load_walker(None, gait)
    th = ThrustModel("constant", np.zeros(w.model.n_thrusters))
    res = simulate_batch(w.zd, th, X0, SimConfig(steps=steps), workers=1)
    return int(res.success.sum())


def whole() -> None:
    """simulate as a whole (issue 26; see the module docstring), both bundled robots."""
    import thrustwalk_cli as tw

    for robot in ("three_link", "rabbit"):
        walker = tw.load_walker(None, f"{robot}_walk")
        for model in ("ideal", "second-order"):
            kw = dict(steps=WHOLE_STEPS, thrust_model=model, thrust=WHOLE_THRUST, start="nominal")
            tw.simulate(walker, **kw)  # warm: the kernel, the walker's caches
            tw.simulate(walker, method="scipy", **dict(kw, steps=1))
            pairs = []
            for _ in range(3 if model == "ideal" else 1):
                ref = median_cpu(lambda: tw.simulate(walker, method="scipy", **kw), 1)
                cmp = median_cpu(lambda: tw.simulate(walker, **kw), 7 if model == "ideal" else 3)
                pairs.append((ref, cmp))
            ref = statistics.median(p[0] for p in pairs)
            cmp = statistics.median(p[1] for p in pairs)
            ratio = statistics.median(p[0] / p[1] for p in pairs)
            tag = f"{robot} {model}: simulate {WHOLE_STEPS} steps x 2 runs"
            print(f"{tag + ', SciPy method (baseline)':<64s} {ref * 1e3:10.1f} ms", flush=True)
            target = ""
            if model == "ideal":
                target = "; target >= 30 x" + (", <= 60 ms" if robot == "rabbit" else "")
            print(f"{tag + ', compiled':<64s} {cmp * 1e3:10.1f} ms  {ratio:6.1f} x"
                  f"{target}", flush=True)
            if model != "ideal":
                continue

            def sampled(**more):  # the call and its samples read (what the command writes)
                res = tw.simulate(walker, **kw, **more)
                for oc in res.outcomes:
                    dict(oc.full.trajectory)
            ref_s = median_cpu(lambda: sampled(method="scipy"), 1)
            cmp_s = median_cpu(sampled, 7)
            print(f"{tag + ', samples read: SciPy method (baseline)':<64s} {ref_s * 1e3:10.1f} ms",
                  flush=True)
            print(f"{tag + ', samples read: compiled':<64s} {cmp_s * 1e3:10.1f} ms  "
                  f"{ref_s / cmp_s:6.1f} x", flush=True)


def main() -> None:
    whole()
    import simulate_energy  # energy along a run (issue 28): its cost, printed as ratios

    simulate_energy.main()
    import numba

    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles, zero_dynamics
    from thrustwalk_cli.simulation import kernel as K
    from thrustwalk_cli.simulation.batch import simulate_batch, start_states
    from thrustwalk_cli.simulation.closed_loop import (
        ClosedLoop,
        SimConfig,
        ThrustModel,
        predicted_cycle,
    )
    from thrustwalk_cli.simulation.full_order import Start, _one_step, initial_state, simulate
    from thrustwalk_cli.simulation.stepper import Stepper, kernel, run_steps
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    jm = kernel()
    rhs_eval = jm.module.rhs_eval

    @numba.njit(nogil=True)
    def rhs_loop(x, fs, ip, par, w, dx, n):  # the kernel's right-hand side, n calls
        for _ in range(n):
            x[0] += 1e-12
            rhs_eval(0.0, x, 0, fs, ip, par, w, dx)
        return dx[0]

    for gait in _gaits():
        walker = load_walker(None, gait)
        model, g, zd = walker.model, walker.gait, walker.zd
        N, m = model.n, model.n_thrusters
        th = ThrustModel("constant", np.zeros(m))
        cfg = SimConfig(steps=STEPS, rtol=1e-9, atol=1e-9)
        cl = ClosedLoop(zd, th, cfg)
        t_max = 10.0 * predicted_cycle(zd, th).step_time
        x0 = initial_state(zd, th, Start(perturb=0.1))

        def scipy_steps():
            x, t, segs = x0, 0.0, []
            for k in range(1, STEPS + 1):
                _, x, t = _one_step(cl, k, t, x, t_max, segs)

        run_steps(cl, x0, t_max, STEPS)
        # side by side: each SciPy run next to compiled runs (the machine's load drifts)
        refs, cmps, ratios = [], [], []
        for _ in range(5):
            t_r = median_time(scipy_steps, repeat=1) / STEPS
            t_c = median_time(lambda: run_steps(cl, x0, t_max, STEPS), repeat=5) / STEPS
            refs.append(t_r)
            cmps.append(t_c)
            ratios.append(t_r / t_c)
        t_ref, t_cmp = float(np.median(refs)), float(np.median(cmps))
        report(f"{gait}: one step, SciPy reference, rtol 1e-9 (baseline)", t_ref, unit="ms")
        report(f"{gait}: one step, compiled kernel (ratio; target <= 1/40)", t_cmp, t_ref,
               unit="ms")
        print(f"{gait + ': compiled vs SciPy per step (median of 5 pairs)':<58s} "
              f"{float(np.median(ratios)):10.1f} x  (pairs {min(ratios):.1f}-{max(ratios):.1f}"
              "; target >= 40 x)", flush=True)

        # -- right-hand side per call
        st = Stepper(cl, t_max, dense=False)
        p = st.packed
        w = np.zeros(p.ip[K.W_SIZE])
        w[p.ip[K.I_C0]:p.ip[K.I_C0] + p.ip[K.I_NCONST]] = p.fs[K.N_FS:]
        x = np.ascontiguousarray(np.concatenate([zd.maps.q_plus, np.ones(N)]))
        dx = np.zeros(2 * N)
        rhs_loop(x.copy(), p.fs, p.ip, p.par, w, dx, 10)
        n = 20000
        t_rhs = median_time(lambda: rhs_loop(x.copy(), p.fs, p.ip, p.par, w, dx, n),
                            repeat=7) / n
        t_py = median_time(lambda: cl.rhs(0.0, x, 0), repeat=7, number=2000)
        pin_model = _pinocchio(model.robot)
        if pin_model is None:
            print(f"{gait + ': Pinocchio ABA from Python':<58s} {'skipped':>12s} (pip install "
                  "-e '.[bench]')", flush=True)
            report(f"{gait}: closed-loop RHS, SciPy path (Python)", t_py, unit="us")
            report(f"{gait}: closed-loop RHS, compiled kernel (ratio to Python)", t_rhs, t_py,
                   unit="us")
        else:
            pin, pm, pdata = pin_model
            qv, vv, tau = np.zeros(pm.nq), np.ones(pm.nv), np.zeros(pm.nv)
            t_aba = median_time(lambda: pin.aba(pm, pdata, qv, vv, tau), repeat=7,
                                number=2000)
            report(f"{gait}: Pinocchio ABA from Python (baseline)", t_aba, unit="us")
            report(f"{gait}: closed-loop RHS, SciPy path (Python)", t_py, t_aba, unit="us")
            report(f"{gait}: closed-loop RHS, compiled kernel (target ratio <= 1)", t_rhs,
                   t_aba, unit="us")

        # -- the fixed point: zero-dynamics route vs the SciPy reference simulation to 1e-6
        sched = Schedule.constant(zd, np.zeros((1, m)))
        zs = limit_cycles(zd, sched)[0].zeta_star
        start = Start(perturb=0.3)
        probe = simulate(zd, th, SimConfig(steps=80, rtol=1e-9, atol=1e-9), start)
        z = np.array([s.zeta_minus for s in probe.steps])
        done = np.nonzero(np.abs(z / zs - 1) < 1e-6)[0]
        if not probe.success or done.size == 0:
            print(f"{gait}: simulation did not settle: {probe.reason}")
            continue
        n_steps = int(done[0]) + 1
        conv = SimConfig(steps=n_steps, rtol=1e-9, atol=1e-9)
        t_sim = median_time(lambda: simulate(zd, th, replace(conv, method="scipy"), start),
                            repeat=3)
        t_csim = median_time(lambda: simulate(zd, th, conv, start), repeat=3)
        af = np.array(zd.alpha_f)
        t_formula = median_time(
            lambda: zd.V_Z(af, sched) / (1.0 - zd.delta_zero_sq), repeat=7, number=200)
        t_cycle = median_time(lambda: limit_cycles(zd, sched), repeat=7)
        t_full = median_time(lambda: limit_cycles(zero_dynamics(model, g), sched), repeat=5)
        print(f"{gait + ': steps to zeta* within 1e-6 by simulation':<58s} {n_steps:12d}",
              flush=True)
        report(f"{gait}: zeta* by the SciPy reference simulation (baseline)", t_sim,
               unit="ms")
        report(f"{gait}: zeta* by the compiled simulation (ratio)", t_csim, t_sim, unit="ms")
        report(f"{gait}: zeta* = V_Z(af)/(1-d0^2) (ratio; target <= 1/1000)", t_formula,
               t_sim, unit="us")
        report(f"{gait}: one whole limit cycle (orbit, T, extrema) (ratio)", t_cycle, t_sim,
               unit="ms")
        report(f"{gait}: ... incl. the gait's precomputation (ratio)", t_full, t_sim,
               unit="ms")

        # -- 1,000 runs of 10 steps from perturbed starts (3-link): threads vs processes
        if gait != "three_link_walk":
            continue
        rng = np.random.default_rng(0)
        starts = [Start(perturb=float(v)) for v in rng.uniform(-0.2, 0.2, 1000)]
        X0 = start_states(zd, th, starts)
        bcfg = SimConfig(steps=STEPS)
        t0 = time.perf_counter()
        res = simulate_batch(zd, th, X0, bcfg, workers=2)
        t_thr = time.perf_counter() - t0
        t0 = time.perf_counter()
        halves = [(gait, X0[:500], STEPS), (gait, X0[500:], STEPS)]
        with ProcessPoolExecutor(max_workers=2) as pool:
            ok = sum(pool.map(_batch_part, halves))
        t_proc = time.perf_counter() - t0
        report(f"{gait}: 1,000 runs x {STEPS} steps, 2 processes (baseline)", t_proc)
        report(f"{gait}: 1,000 runs x {STEPS} steps, 2 threads (target < 15 s)", t_thr,
               t_proc)
        print(f"{'  completed runs (threads / processes)':<58s} "
              f"{int(res.success.sum()):5d} / {ok:d}", flush=True)


if __name__ == "__main__":
    import sys

    sys.path.insert(0, os.path.dirname(__file__))
    whole() if "--whole" in sys.argv[1:] else main()
