"""MuJoCo second opinion benchmark (SPEC 16): 20 steps of the 3-link walker on MuJoCo with the
controller evaluated every MuJoCo step (default contact: timestep 0.5 ms), target < 5 s on one
core (the run's CPU time is printed beside its wall time: the machine may be shared), against
the compiled full-order simulation (the numba kernel, rigid impacts) of the same 20 steps from
the same start, measured in the same run (medians). The stiff preset (timestep 0.1 ms) is
timed too. Printed as "skipped" without MuJoCo (pip install -e '.[mujoco]')."""

from __future__ import annotations

import time

import numpy as np
from timing import median_time, report

STEPS = 20


def main() -> None:
    try:
        import mujoco
    except ImportError:
        print(f"{'MuJoCo runs':<58s} {'skipped':>12s} (pip install -e '.[mujoco]')",
              flush=True)
        return
    from thrustwalk_cli.interchange.mjcf import CONTACT_PRESETS
    from thrustwalk_cli.interchange.mujoco_run import run_mujoco, thrust_runs
    from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
    from thrustwalk_cli.simulation.full_order import Start, simulate
    from thrustwalk_cli.walker import load_walker

    w = load_walker("three_link", "three_link_walk")
    zd = w.zd
    th = ThrustModel("constant", np.zeros(w.model.n_thrusters))
    cfg = SimConfig(steps=STEPS)
    simulate(zd, th, cfg, Start())  # the kernel compiled and loaded
    t_sim = median_time(lambda: simulate(zd, th, cfg, Start()), repeat=5)
    report(f"3-link, {STEPS} steps, compiled simulation (baseline)", t_sim)
    (_, thm), = thrust_runs(zd, "constant", [0.0], None)
    for preset in ("default", "stiff"):
        ct = CONTACT_PRESETS[preset]
        runs = []

        def go(ct=ct):
            runs.append(run_mujoco(zd, thm, 0.0, steps=STEPS, contact=ct, mu=w.gait.mu))

        cpu = time.process_time()
        t_mj = median_time(go, repeat=3 if preset == "default" else 1)
        cpu = (time.process_time() - cpu) / len(runs)
        run = runs[-1]
        target = " (target < 5 s)" if preset == "default" else ""
        report(f"3-link, {STEPS} steps, MuJoCo {mujoco.__version__} {preset} "
               f"(dt {ct.timestep:g} s){target}", t_mj, t_sim)
        report("  ... CPU time of one run (one core)", cpu)
        print(f"{'  ... per MuJoCo step (physics + controller)':<58s} "
              f"{run.wall_time / max(run.mj_steps, 1) * 1e6:12.4g} us "
              f"({run.mj_steps} steps, {'ok' if run.success else run.reason})", flush=True)
