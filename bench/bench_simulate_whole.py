"""simulate as a whole (issue 26): ``tw.simulate(walker, steps=20, thrust_model=...,
thrust=[0, -10], start="nominal")`` (two runs of 20 steps, each with its zero-dynamics
prediction and the reduced cascade beside it), warm, in one process.

Baseline measured in the same run: the same call with ``method="scipy"`` (the reference:
``solve_ivp`` over the full-order model). Times are CPU times of this process (the machine is
shared), medians of pairs measured side by side. Targets: compiled >= 30x the SciPy method
with ideal thrust on both bundled robots, and the 20 steps x 2 runs of RABBIT <= 60 ms. The
second-order thruster is printed for information (its cascade and per-step predictions are
the spectral solution in alpha, ``simulation/reduced.spectral_steps``).
"""

from __future__ import annotations

import os
import statistics
import time

STEPS = 20
THRUST = [0.0, -10.0]


def _cpu(fn, repeat: int) -> float:
    """Median CPU time of ``fn`` [s]."""
    runs = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        runs.append(time.process_time() - t0)
    return statistics.median(runs)


def main() -> None:
    import thrustwalk_cli as tw

    for robot in ("three_link", "rabbit"):
        walker = tw.load_walker(None, f"{robot}_walk")
        for model in ("ideal", "second-order"):
            kw = dict(steps=STEPS, thrust_model=model, thrust=THRUST, start="nominal")
            tw.simulate(walker, **kw)  # warm: the kernel, the walker's caches
            tw.simulate(walker, method="scipy", **dict(kw, steps=1))
            pairs = []
            for _ in range(3 if model == "ideal" else 1):
                ref = _cpu(lambda: tw.simulate(walker, method="scipy", **kw), 1)
                cmp = _cpu(lambda: tw.simulate(walker, **kw), 7 if model == "ideal" else 3)
                pairs.append((ref, cmp))
            ref = statistics.median(p[0] for p in pairs)
            cmp = statistics.median(p[1] for p in pairs)
            ratio = statistics.median(p[0] / p[1] for p in pairs)
            tag = f"{robot} {model}: simulate {STEPS} steps x 2 runs"
            print(f"{tag + ', SciPy method (baseline)':<64s} {ref * 1e3:10.1f} ms", flush=True)
            target = ""
            if model == "ideal":
                target = "; target >= 30 x" + (", <= 60 ms" if robot == "rabbit" else "")
            print(f"{tag + ', compiled':<64s} {cmp * 1e3:10.1f} ms  {ratio:6.1f} x"
                  f"{target}", flush=True)


if __name__ == "__main__":
    import sys

    sys.path.insert(0, os.path.dirname(__file__))
    main()
