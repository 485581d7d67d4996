"""Slope-map benchmark (SPEC 14): a 200 x 200 slope x thrust walkability map vs one
limit-cycle call (the issue's target: the map well under a second).

The map is explicit in (cos, sin) of the slope and affine in the thrust: the level-ground
and along-the-ground series are computed once per gait, each pair then costs a few
multiply-adds per grid point, its step time a nested quadrature and, near a contact limit,
a golden-section polish (contact/slope_map.py, called by studies/slope.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from timing import median_time, report

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"


def main() -> None:
    from thrustwalk_cli.studies.limit_cycle import limit_cycle
    from thrustwalk_cli.studies.slope import slope_map
    from thrustwalk_cli.walker import load_walker

    cases = (("three_link", None, "three_link"),
             (str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"), "walker5"))
    slopes, thrust = np.linspace(-0.3, 0.3, 200), np.linspace(0.0, -60.0, 200)
    for robot, gait, name in cases:
        walker = load_walker(robot, gait)
        slope_map(walker, slopes, thrust)  # the process's one-time quadrature tables
        t_one = median_time(lambda: limit_cycle(walker, [-20.0], slope=0.05), repeat=5)
        t_map = median_time(lambda: slope_map(walker, slopes, thrust), repeat=3)
        report(f"{name}: one limit-cycle call on a slope (baseline)", t_one)
        report(f"{name}: 200 x 200 slope x thrust map (ratio; target well under 1 s)", t_map,
               t_one)


if __name__ == "__main__":
    main()
