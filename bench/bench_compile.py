"""Model benchmarks (robot-model issue): compile/load times, D and bias evaluation, start-up.

Baselines measured in the same run: a bare ``python -c pass`` start (for start-up and warm
load), a SymPy ``lambdify`` of the same expressions (per call), a Python loop over the
generated scalar functions (per state in a batch).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from timing import median_time, report

ROBOTS = ["three_link", "rabbit"]


def _sub(code: str, env: dict | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, env=env,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    base = min(_sub("pass") for _ in range(3))
    report("python -c pass (baseline)", base)
    ts = []
    for _ in range(3):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "thrustwalk_cli", "--help"], check=True,
                       stdout=subprocess.DEVNULL)
        ts.append(time.perf_counter() - t0)
    help_t = min(ts)
    report("thrustwalk --help start-up (target < 0.3 s)", help_t, base)
    for name in ROBOTS:
        cache = tempfile.mkdtemp(prefix="tw-bench-")
        env = dict(os.environ, THRUSTWALK_CACHE_DIR=cache)
        code = ("from thrustwalk_cli.files.robot_file import load_robot;"
                "from thrustwalk_cli.model.compiler import load_model;"
                f"m = load_model(load_robot({name!r}))")
        cold = _sub(code, env)
        warm = min(_sub(code + "; import sys; assert 'sympy' not in sys.modules", env)
                   for _ in range(3))
        report(f"{name}: cold compile, whole process", cold, base)
        report(f"{name}: warm load, whole process (target < 0.3 s)", warm, base)

    from sympy import lambdify

    from thrustwalk_cli.files.robot_file import load_robot
    from thrustwalk_cli.model import derive
    from thrustwalk_cli.model.compiler import load_model

    rng = np.random.default_rng(0)
    for name in ROBOTS:
        robot = load_robot(name)
        m = load_model(robot)
        n = m.n
        q, dq = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
        ql, dql = q.tolist(), dq.tolist()
        der = derive.derive(robot)
        lam = lambdify([der.q, der.dq], [der.exprs["D"], der.exprs["h"]], "numpy")
        t_lam = median_time(lambda: lam(q, dq), number=200)
        t_s = median_time(lambda: (m.D_s(ql), m.h_s(ql, dql)), number=2000)
        t_np1 = median_time(lambda: (m.D(q), m.h(q, dq)), number=500)
        report(f"{name}: D+h one state, sympy lambdify (baseline)", t_lam, unit="us")
        report(f"{name}: D+h one state, generated scalar", t_s, t_lam, unit="us")
        report(f"{name}: D+h one state, generated NumPy", t_np1, t_lam, unit="us")
        Q, DQ = rng.uniform(-1, 1, (10000, n)), rng.uniform(-1, 1, (10000, n))
        QL, DQL = Q.tolist(), DQ.tolist()
        t_loop = median_time(lambda: [(m.D_s(a), m.h_s(a, b)) for a, b in zip(QL, DQL)],
                             repeat=3) / 10000
        t_batch = median_time(lambda: (m.D(Q), m.h(Q, DQ)), repeat=5) / 10000
        report(f"{name}: D+h per state, loop over scalar (baseline)", t_loop, unit="us")
        report(f"{name}: D+h per state, batch of 10,000 (target < 1 us)", t_batch, t_loop,
               unit="us")


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(__file__))
    main()
