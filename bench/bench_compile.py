"""Model benchmarks (robot-model issue, issue 13; big robots, issue 26): compile/load times,
the one-time numba kernel, D and bias evaluation, start-up, warm commands, and the cold
compile of planar chain bipeds of 3 to 20 links (``bench/chains.py``).

Baselines measured in the same run: a bare ``python -c pass`` start (for start-up and warm
load), a SymPy ``lambdify`` of the same expressions (per call), a Python loop over the
generated scalar functions (per state in a batch), the generated NumPy batch (for the
compiled batch D + C q' + G), the 3-link chain's cold compile (for the chain scaling).

``python bench/bench_compile.py --chains [--json FILE]`` runs only the chain scaling (and
writes its CPU times to FILE for ``bench/plot_compile.py``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from chains import write_chain
from timing import median_time, report

ROBOTS = ["three_link", "rabbit"]


def _sub(code: str, env: dict | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, env=env,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def _cpu(cmd: list[str], env: dict) -> float:
    """CPU time (user + system) of a child process [s]."""
    before = os.times()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    after = os.times()
    return (after.children_user - before.children_user
            + after.children_system - before.children_system)


#: chain sizes of the scaling benchmark, and the issue's targets [s of CPU, whole process]
CHAIN_SIZES = tuple(range(3, 21))
CHAIN_TARGETS = {12: 8.0, 16: 20.0, 20: 45.0}


def chain_scaling(sizes=CHAIN_SIZES, repeat: int = 1) -> dict[int, float]:
    """Cold ``thrustwalk compile CHAIN --no-kernel -q`` of the N-link chain biped, whole
    process, in a fresh model cache each time: CPU time (user + system) of the child [s],
    the least of ``repeat`` runs (CPU, not wall time: the machine is shared)."""
    folder = tempfile.mkdtemp(prefix="tw-bench-chains-")
    out = {}
    for n in sizes:
        path = write_chain(n, folder)
        runs = []
        for r in range(repeat):
            env = dict(os.environ, THRUSTWALK_CACHE_DIR=f"{folder}/cache-{n}-{r}")
            runs.append(_cpu([sys.executable, "-m", "thrustwalk_cli", "compile", str(path),
                              "--no-kernel", "-q"], env))
        out[n] = min(runs)
        base = out[min(out)]
        target = CHAIN_TARGETS.get(n)
        report(f"chain {n:2d} links: cold compile, CPU" + (f" (target <= {target:g} s)"
                                                             if target else "")
               + (" (baseline)" if n == min(out) else ""), out[n],
               None if n == min(out) else base)
    ns = sorted(out)
    if len(ns) > 2:
        slope = np.polyfit(np.log(ns), np.log([out[n] for n in ns]), 1)[0]
        print(f"  compile CPU grows as N^{slope:.2f} over N = {ns[0]}..{ns[-1]}", flush=True)
    return out


def main(argv: list[str] | None = None) -> None:
    argv = list(argv or [])
    if "--chains" in argv:
        res = chain_scaling()
        if "--json" in argv:
            import json

            with open(argv[argv.index("--json") + 1], "w") as fh:
                json.dump({str(n): t for n, t in res.items()}, fh, indent=1)
        return
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
    # the numba kernel: compiled once per machine (a fresh cache folder), shared by robots
    cache = tempfile.mkdtemp(prefix="tw-bench-")
    env = dict(os.environ, THRUSTWALK_CACHE_DIR=cache)
    kcode = ("from thrustwalk_cli.simulation.stepper import kernel; "
             "jm = kernel(); assert not jm.cache_hit")
    t_kernel = _sub(kcode, env)
    t_kload = min(_sub("from thrustwalk_cli.simulation.stepper import kernel; "
                       "assert kernel().cache_hit", env) for _ in range(3))
    report("numba kernel: one-time compile (per machine), whole process", t_kernel, base)
    report("numba kernel: load from the cache, whole process", t_kload, base)
    for name in ROBOTS:
        rcache = tempfile.mkdtemp(prefix="tw-bench-")
        # the kernel is shared: copy the compiled one, so the robot's cold compile is measured
        subprocess.run(["cp", "-r", f"{cache}/.", rcache], check=True)
        renv = dict(os.environ, THRUSTWALK_CACHE_DIR=rcache)
        code = ("from thrustwalk_cli.files.robot_file import load_robot;"
                "from thrustwalk_cli.model.compiler import load_model;"
                f"m = load_model(load_robot({name!r}))")
        cold = _sub(code, renv)
        warm = min(_sub(code + "; import sys; assert 'sympy' not in sys.modules", renv)
                   for _ in range(3))
        report(f"{name}: cold compile (SymPy + tape), whole process (target < 5 s)", cold,
               base)
        report(f"{name}: warm load, whole process (target < 0.3 s)", warm, base)
        gait = {"three_link": "three_link_walk", "rabbit": "rabbit_walk"}[name]
        scode = ("import numpy as np\n"
                 "from thrustwalk_cli.walker import load_walker\n"
                 "from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel\n"
                 "from thrustwalk_cli.simulation.full_order import simulate\n"
                 f"w = load_walker({name!r}, {gait!r})\n"
                 "r = simulate(w.zd, ThrustModel('constant', np.zeros(w.model.n_thrusters)),"
                 " SimConfig(steps=1))\n"
                 "assert r.success\n")
        rcache2 = tempfile.mkdtemp(prefix="tw-bench-")
        subprocess.run(["cp", "-r", f"{cache}/.", rcache2], check=True)
        first = _sub(scode, dict(os.environ, THRUSTWALK_CACHE_DIR=rcache2))
        report(f"{name}: new robot to its first compiled step, whole process", first, base)
        # as installed: byte code cached (PYTHONDONTWRITEBYTECODE would recompile every
        # module of every command); the first run writes it
        cenv = {k: v for k, v in renv.items() if k != "PYTHONDONTWRITEBYTECODE"}
        for cmd in (["compile", name, "-q"], ["inspect", name, "--q",
                                              ",".join(["0.1"] * (3 if name == "three_link"
                                                                  else 5))]):
            argv = [sys.executable, "-m", "thrustwalk_cli", *cmd]
            _cpu(argv, cenv)
            cpu = min(_cpu(argv, cenv) for _ in range(3))
            report(f"{name}: warm `thrustwalk {cmd[0]}`, CPU (target < 0.3 s)", cpu)

    from sympy import lambdify

    from thrustwalk_cli.files.robot_file import load_robot
    from thrustwalk_cli.model import derive_reference, jit
    from thrustwalk_cli.model.compiler import load_model

    rng = np.random.default_rng(0)
    for name in ROBOTS:
        robot = load_robot(name)
        m = load_model(robot)
        n = m.n
        q, dq = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
        ql, dql = q.tolist(), dq.tolist()
        der = derive_reference.derive_reference(robot, folded=True)  # numbers written in, as
        # lambdify users do (one expression per entry, no definitions)
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
        report(f"{name}: D+h per state, generated NumPy batch of 10,000", t_batch, t_loop,
               unit="us")
        jit.D_h_batch(m, Q[:10], DQ[:10])
        t_jit = median_time(lambda: jit.D_h_batch(m, Q, DQ), repeat=7) / 10000
        report(f"{name}: D+h per state, compiled tape batch (ratio to NumPy; target "
               "<= 0.3 us)", t_jit, t_batch, unit="us")
    chain_scaling()


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(__file__))
    main(sys.argv[1:])
