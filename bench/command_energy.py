"""Energy's share of whole commands (SPEC 15, issue 28): the CPU time a command spends in its
energies (on the orbit: ``energetics.orbit.orbit_energy`` as limit-cycle calls it; along a
run: ``energetics.run.run_energy``), against the whole command's CPU time, both measured in
the same call: the command runs in this process (Typer's test runner, after one warm-up
call), its energy function wrapped by a timer, nothing else changed. The figures are drawn
(``--formats png``: one format) as a user's command draws them.

This is the share a user sees at the command line. ``bench_energy.py`` and
``simulate_energy.py`` measure the library calls alone (``tw.limit_cycle``, ``tw.simulate``),
where the energies' share is larger.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from typer.testing import CliRunner

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"


def _share(args: list[str], module, name: str, repeat: int = 5) -> tuple[float, float]:
    """(median CPU seconds of the command, median share of it inside ``module.name``)."""
    from thrustwalk_cli.cli import app

    inner = getattr(module, name)
    spent = [0.0]

    def timed(*a, **k):
        t0 = time.process_time()
        try:
            return inner(*a, **k)
        finally:
            spent[0] += time.process_time() - t0

    runner = CliRunner()
    setattr(module, name, timed)
    try:
        totals, shares = [], []
        with tempfile.TemporaryDirectory() as tmp:
            for i in range(repeat + 1):
                spent[0] = 0.0
                t0 = time.process_time()
                res = runner.invoke(app, [*args, "--out", str(Path(tmp) / f"r{i}"), "-q"])
                total = time.process_time() - t0
                if res.exit_code != 0:
                    raise RuntimeError(f"{args}: exit {res.exit_code}: {res.output[-500:]}")
                if i:  # the first call loads the walker and warms the caches
                    totals.append(total)
                    shares.append(spent[0] / total)
        return statistics.median(totals), statistics.median(shares)
    finally:
        setattr(module, name, inner)


def main() -> None:
    import thrustwalk_cli.energetics.run as run_mod
    import thrustwalk_cli.studies.limit_cycle as lc_mod

    cases = (
        ("limit-cycle rabbit, 200 thrust values",
         ["limit-cycle", "rabbit", "rabbit_walk", "--thrust", "0:-50:-0.25"], lc_mod,
         "orbit_energy"),
        ("limit-cycle walker5, 200 thrust values",
         ["limit-cycle", str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"),
          "--thrust", "0:-40:-0.2"], lc_mod, "orbit_energy"),
        ("simulate rabbit, 2 runs x 20 steps",
         ["simulate", "rabbit", "rabbit_walk", "--steps", "20", "--thrust", "0,-10"], run_mod,
         "run_energy"),
        ("simulate three_link, 2 runs x 20 steps",
         ["simulate", "three_link", "three_link_walk", "--steps", "20", "--thrust", "0,-10"],
         run_mod, "run_energy"),
    )
    for label, args, module, name in cases:
        for formats in ("png", "none"):
            total, share = _share([*args, "--formats", formats], module, name)
            print(f"{label + ', --formats ' + formats + ': energies in the command':<72s} "
                  f"{100 * share:5.1f} %  (command {total:.2f} s CPU; target < 10 %)",
                  flush=True)


if __name__ == "__main__":
    main()
