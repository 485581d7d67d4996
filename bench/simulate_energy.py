"""Energy along a full-order run (SPEC 15, issue 28: "energy along a run adds < 10 % to
simulate"): ``tw.simulate`` of RABBIT and of the 3-link walker, two runs of 20 steps each
(ideal thrust 0 and -10 N, from the nominal start), warm, against the same results' step
energies (``energetics.run.simulation_energy``: 6-point Gauss-Lobatto on every integrator step
of the dense output, the closed loop at the nodes evaluated by the compiled kernel, computed
when first read) and against the whole document (which includes them). CPU times of this
process, medians. Prints the ratios energy / simulate and document / simulate.

Measured 2026-11-26 (load 1-2): the step energies 35-38 % of simulate for RABBIT (34-35 ms),
38-39 % for the 3-link (18-21 ms). ``bench/stage_quadrature.py`` measures the idea of
integrating them with the integrator's own stages instead (accurate to 6e-11 of a step's
absolute work, but at best about 24-27 %: docs/performance.md, issue 28).
"""

from __future__ import annotations

from pathlib import Path

from timing import median_cpu

import thrustwalk_cli as tw
from thrustwalk_cli.energetics.run import simulation_energy

REPO = Path(__file__).resolve().parents[1]


def _cpu(fn, repeat: int = 7) -> float:
    return median_cpu(fn, repeat)


def bench(robot: str, label: str) -> None:
    """One robot's line: simulate, its step energies, its document."""
    w = tw.load_walker(str(REPO / "robots" / f"{robot}.yaml"),
                       str(REPO / "gaits" / f"{robot}_walk.yaml"))

    def sim():
        return tw.simulate(w, steps=20, thrust_model="ideal", thrust=[0.0, -10.0],
                           start="nominal")

    sim()
    t_sim = _cpu(sim)
    results = [sim() for _ in range(7)]
    it = iter(results)

    def energy():
        r = next(it)
        for oc in r.outcomes:
            simulation_energy(oc.full)
    t_energy = _cpu(energy)
    t_doc = _cpu(lambda: sim().document()) - t_sim
    print(f"{label} 2 runs x 20 steps: simulate {1e3 * t_sim:.1f} ms, step energies "
          f"{1e3 * t_energy:.1f} ms ({100 * t_energy / t_sim:.0f} % of simulate), "
          f"document with energies {1e3 * t_doc:.1f} ms ({100 * t_doc / t_sim:.0f} %)")


def main() -> None:
    bench("rabbit", "RABBIT")
    bench("three_link", "3-link")


if __name__ == "__main__":
    main()
