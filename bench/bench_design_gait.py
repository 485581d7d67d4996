"""Gait-design benchmark (issue 26): RABBIT from the default start, the command's defaults
(``thrustwalk design-gait rabbit --target-speed 0.53 --starts 1``: one SLSQP run).

Baselines measured in the same run (medians where repeated):
* one objective + constraints evaluation (the unit of work);
* one forward-difference Jacobian: all perturbed points in one vectorised call
  (``Problem.evaluate_many``) vs one evaluation per point (the column-by-column reference,
  ``_Cache.differences(x, batched=False)``);
* the whole design: batched Jacobians vs column-by-column ones (target >= 2x). SLSQP follows
  the same path, so the gaits must agree (printed: the largest difference of the Bezier
  coefficients, alpha_f and zeta*, target <= 1e-9), with the share of the Jacobians in each.

BLAS runs single-threaded, as under the command line (``thrustwalk_cli.cli``): the benchmark
runs itself in a child process when the environment does not say so (numpy reads it at import).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
from timing import median_time, report


def _design(model, spec, batched: bool):
    """solve_design with the batched or the column-by-column Jacobian: (result, seconds,
    seconds in Jacobians)."""
    from thrustwalk_cli.design import solver

    spent = [0.0]
    real = solver._Cache.jacobian

    def timed(self, x):
        t = time.perf_counter()
        try:
            if batched:
                return real(self, x)
            x = np.asarray(x, float)
            if self.jx is None or not np.array_equal(x, self.jx):
                self.jx, self.jac = x.copy(), self.differences(x, batched=False)
            return self.jac
        finally:
            spent[0] += time.perf_counter() - t

    solver._Cache.jacobian = timed
    try:
        t0 = time.perf_counter()
        res = solver.solve_design(model, spec)
        return res, time.perf_counter() - t0, spent[0]
    finally:
        solver._Cache.jacobian = real


def main() -> None:
    if os.environ.get("OPENBLAS_NUM_THREADS") != "1":
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        subprocess.run([sys.executable, __file__], env=env, check=True)
        return
    from thrustwalk_cli.design.problem import Problem
    from thrustwalk_cli.design.solver import _Cache
    from thrustwalk_cli.design.spec import DesignSpec
    from thrustwalk_cli.studies.compile import compile_robot

    model = compile_robot("rabbit")
    spec = DesignSpec(speed=0.53, starts=1, seed=0)
    prob = Problem(model, spec)
    x0 = prob.start(None)
    prob.fix_shapes(prob.evaluate(x0))
    t_eval = median_time(lambda: prob.evaluate(x0), repeat=21)
    t_cols = median_time(lambda: _Cache(prob).differences(x0, batched=False), repeat=5)
    t_batch = median_time(lambda: _Cache(prob).differences(x0), repeat=11)
    report("rabbit: one objective + constraints evaluation", t_eval, unit="ms")
    report(f"rabbit: Jacobian column by column ({x0.size} evaluations)", t_cols, t_eval,
           unit="ms")
    report("rabbit: Jacobian batched (ratio vs column by column)", t_batch, t_cols, unit="ms")
    new, t_new, j_new = _design(model, spec, batched=True)
    old, t_old, j_old = _design(model, spec, batched=False)
    report(f"rabbit: design, column-by-column Jacobians ({100 * j_old / t_old:.0f} % in them)",
           t_old)
    report(f"rabbit: design, batched Jacobians ({100 * j_new / t_new:.0f} %; ratio vs column)",
           t_new, t_old)
    dA = float(np.abs(np.array(new.gait.A) - np.array(old.gait.A)).max())
    daf = abs(new.gait.alpha_f - old.gait.alpha_f)
    zn, zo = new.check["orbit"]["zeta_star"], old.check["orbit"]["zeta_star"]
    dz = f"{abs(zn - zo) / abs(zo):.1e}" if zn is not None and zo else "n/a (no orbit)"
    print(f"{'':<58s} same gait: max |dA| {dA:.1e} rad, |d alpha_f| {daf:.1e} rad, "
          f"zeta* {dz} relative (target <= 1e-9); target ratio <= 0.5", flush=True)
    print(f"{'':<58s} {new.evaluations} evaluations, {new.starts[0].iterations} iterations, "
          f"feasible {new.feasible}, effort {new.objective:.5g} N^2 m s", flush=True)


if __name__ == "__main__":
    main()
