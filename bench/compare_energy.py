"""Compare every OrbitEnergy field (and two power profiles) between two checkouts (issue 28's
speed-up must not move an energy by more than 1e-12 relative plus 1e-15 J): ``dump FILE``
writes this checkout's numbers (run it with PYTHONPATH at each checkout), ``compare A B``
prints the largest relative difference per case and every field outside the tolerance.
Cases: three_link, RABBIT, walker5 (both test gaits) and kneed4, 200 constant thrust values
each, clipped and regenerated electrical power, a second call on warm caches, a 3-orbit
sub-batch after the full one."""

from __future__ import annotations

import dataclasses
import pickle
import sys
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"
CASES = {"three_link": ("three_link", None, (0.0, -50.0)),
         "rabbit": ("rabbit", "rabbit_walk", (0.0, -50.0)),
         "walker5": (str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"), (0.0, -40.0)),
         "walker5_walk": (str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"),
                          (0.0, -40.0)),
         "kneed4": (str(DATA / "kneed4.yaml"), str(DATA / "kneed4_walk.yaml"), (40.0, -40.0))}


def dump(path: str) -> None:
    from thrustwalk_cli.energetics.orbit import orbit_energy, power_profile
    from thrustwalk_cli.studies.limit_cycle import limit_cycle
    from thrustwalk_cli.walker import load_walker

    out = {}
    for name, (robot, gait, (a, b)) in CASES.items():
        w = load_walker(robot, gait)
        res = limit_cycle(w, np.linspace(a, b, 200), energy=False)
        for key, kw in ((False, {}), (True, {"regenerate": True}), ("again", {})):
            out[(name, key)] = [dataclasses.asdict(e) for e in
                                orbit_energy(w.zd, res.schedule, res.cycles, **kw)]
        idx = np.array([0, 57, 199])
        out[(name, "sub")] = [dataclasses.asdict(e) for e in orbit_energy(
            w.zd, res.schedule.take(idx), [res.cycles[i] for i in idx])]
        for i in (3, 150):
            out[(name, "profile", i)] = power_profile(w.zd, res.schedule.take(np.array([i])),
                                                      res.cycles[i])
    with open(path, "wb") as f:
        pickle.dump(out, f)


def compare(path_a: str, path_b: str) -> None:
    with open(path_a, "rb") as f:
        a = pickle.load(f)
    with open(path_b, "rb") as f:
        b = pickle.load(f)
    worst: dict = {}

    def walk(x, y, where):
        if isinstance(x, dict):
            for k in x:
                walk(x[k], y[k], where + (k,))
        elif isinstance(x, (list, tuple)):
            for i, (u, v) in enumerate(zip(x, y)):
                walk(u, v, where + (i,))
        elif isinstance(x, (float, np.ndarray)):
            x, y = np.asarray(x, float), np.asarray(y, float)
            d = np.abs(x - y)
            if d.size:
                rel = float(np.max(d / np.maximum(np.abs(x), 1e-300)))
                worst[where[0]] = max(worst.get(where[0], 0.0), rel)
            if np.any(d > 1e-12 * np.abs(x) + 1e-15):
                print("outside 1e-12 + 1e-15 J:", where, x, y)
        elif x != y:
            print("differs:", where, x, y)
    for key in a:
        walk(a[key], b[key], (key,))
    for key, v in worst.items():
        print(key, f"largest relative difference {v:.3g}")


if __name__ == "__main__":
    if sys.argv[1] == "dump":
        dump(sys.argv[2])
    else:
        compare(sys.argv[2], sys.argv[3])
