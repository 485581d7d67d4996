"""Energy benchmark (SPEC 15, issue 28: energy on the orbit adds < 10 % to limit-cycle): the
``energy`` study on 200 constant thrust values against ``limit-cycle`` without energy on the
same values (the orbits and their contact verdicts alone), on the bundled 3-link walker
(motors and rotors: every energy computed) and the test robot walker5 (no motor or power
model: mechanical energies only); and on RABBIT (motors and a rotor) ``limit_cycle`` with its
energies against without.

The study is ``limit_cycle`` with its energy (one vectorised quadrature for all the orbits,
kinks located), plus the power along the step of two orbits for the figure; the ratio is
what the energies and the study's bookkeeping cost on top of the orbits. The first call per
walker (timed apart) also computes what is kept on the walker (the alpha-only terms at the
quadrature nodes and along the figure's samples).
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
        t_first = median_time(lambda: energy(walker, thrust), repeat=1)  # tables, kept terms
        t_lc = median_time(lambda: limit_cycle(walker, thrust, energy=False), repeat=5)
        t_en = median_time(lambda: energy(walker, thrust), repeat=5)
        report(f"{name}: limit-cycle without energy, 200 thrust values (baseline)", t_lc)
        report(f"{name}: energy study, 200 thrust values (ratio)", t_en, t_lc)
        report(f"{name}: the walker's first energy study (ratio)", t_first, t_lc)
    walker = load_walker("rabbit", "rabbit_walk")
    thrust = np.linspace(0.0, -50.0, 200)
    limit_cycle(walker, thrust, energy=True)
    t_lc = median_time(lambda: limit_cycle(walker, thrust, energy=False), repeat=5)
    t_en = median_time(lambda: limit_cycle(walker, thrust, energy=True), repeat=5)
    report("rabbit: limit-cycle without energy, 200 thrust values (baseline)", t_lc)
    report("rabbit: limit-cycle with energy, 200 thrust values (ratio)", t_en, t_lc)
    import command_energy  # the energies' share of whole commands, in the same run

    command_energy.main()


if __name__ == "__main__":
    main()
