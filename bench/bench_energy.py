"""Energy benchmark (SPEC 15): the ``energy`` study on 200 constant thrust values against
``limit-cycle`` without energy on the same values (the orbits and their contact verdicts
alone), on the bundled 3-link walker (motors and rotors: every energy computed) and the test
robot walker5 (no motor or power model: mechanical energies only).

The study is ``limit_cycle`` with its energy (one vectorised quadrature for all the orbits,
kinks located), plus the power along the step of two orbits for the figure; the ratio is
what the energies and the study's bookkeeping cost on top of the orbits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from timing import median_time, report

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"


def main() -> None:
    from thrustwalk_cli.studies.energy import energy
    from thrustwalk_cli.studies.limit_cycle import limit_cycle
    from thrustwalk_cli.walker import load_walker

    cases = (("three_link", None, "three_link", np.linspace(0.0, -50.0, 200)),
             (str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"), "walker5",
              np.linspace(0.0, -40.0, 200)))
    for robot, gait, name, thrust in cases:
        walker = load_walker(robot, gait)
        energy(walker, thrust)  # the process's one-time quadrature tables
        t_lc = median_time(lambda: limit_cycle(walker, thrust, energy=False), repeat=5)
        t_en = median_time(lambda: energy(walker, thrust), repeat=5)
        report(f"{name}: limit-cycle without energy, 200 thrust values (baseline)", t_lc)
        report(f"{name}: energy study, 200 thrust values (ratio)", t_en, t_lc)


if __name__ == "__main__":
    main()
