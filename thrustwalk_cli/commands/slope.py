"""``thrustwalk slope``: the walkability map of a gait over slope x constant thrust (SPEC 14)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import (
    check_out,
    cli_errors,
    console,
    load_walker,
    parse_formats,
    parse_values,
    progress,
    show_table,
    write_result,
    wrote_line,
)
from .options import (
    FormatsOpt,
    GaitArg,
    JsonOpt,
    MinVerticalForceOpt,
    MuOpt,
    OutOpt,
    QuietOpt,
    RobotArg,
    ThrusterOpt,
    TitlesOpt,
)

HELP = """Walkability map of a gait over slope x constant thrust (docs/commands.md, `slope`).

For every pair (slope [rad, positive uphill], constant thrust [N] on one thruster): whether the
zero-dynamics orbit exists (zeta* > 0), is stable (delta_zero^2 < 1), completes the step
(alpha reaches its end) and is contact-feasible at --mu (F^v >= --min-vertical-force and
|F^h| <= mu F^v along the step, normal and tangential to the slope; an admissible impact; the
swing foot above the ground), the first condition that fails, zeta* [kg^2 m^4/s^2], the step
time [s], the speed along the ground [m/s] and the climb rate speed*sin(slope) [m/s]. The map
is explicit in cos and sin of the slope and affine in the thrust: a 200 x 200 map takes well
under a second. The summary gives the headline: the slopes the gait walks without thrust and
with the largest thrust of the map. A map without a walkable pair is a valid answer (exit 0).

Writes DIR/slope.json, DIR/slope.csv (one row per pair) and the figures DIR/slope_map
(walkable region with speed contours) and DIR/steepest_slope (highest and lowest walkable
slope against thrust), .png and .pdf.
"""

EPILOG = ("Example: thrustwalk slope three_link three_link_walk --slope -0.2:0.2:0.01 "
          "--thrust 0:-50:-5 --out out/slope")


def run_slope(robot: str | None, gait: str | None, slopes: list[float] | None,
              thrust: list[float] | None, thruster: str | None, out: Path, quiet: bool, *,
              mu: float | None = None, min_vertical_force: float = 0.0,
              json: str | None = None, formats: set[str] | None = None,
              titles: bool = False) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files.output import provenance
    from ..studies.slope import slope_map

    check_out(out, json=json)
    walker = load_walker(robot, gait)
    n = len(slopes) if slopes is not None else 41
    with progress("slope map", n, quiet or json == "-") as advance:
        done = [0]

        def tick(k: int, total: int) -> None:
            advance(k - done[0])
            done[0] = k

        result = slope_map(walker, slopes, thrust, thruster, mu=mu,
                           min_vertical_force=min_vertical_force, progress=tick)
    doc = write_result(result, out, provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles)
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out), markup=False)
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    rows = [[fmt(p["thrust"]), fmt(p["steepest_downhill"]), fmt(p["steepest_uphill"])]
            for p in _few(doc["per_thrust"])]
    show_table(f"slope map: {doc['robot']['name']} / {doc['gait']['name']} (mu = "
               f"{doc['mu']:g}; {doc['walkable_pairs']} of {doc['pairs']} pairs walkable)",
               [("thrust\n[N]", True), ("steepest downhill\n[rad]", True),
                ("steepest uphill\n[rad]", True)], rows)
    con = console()
    counts = ", ".join(f"{k} {v}" for k, v in doc["first_failure_counts"].items() if v)
    con.print(f"first failing condition: {counts}", markup=False)
    con.print(doc["headline"], markup=False)


def _few(per: list, most: int = 11) -> list:
    """At most ``most`` rows of the per-thrust list, evenly spaced, the ends included."""
    if len(per) <= most:
        return per
    idx = sorted({round(i * (len(per) - 1) / (most - 1)) for i in range(most)})
    return [per[i] for i in idx]


def register(app: typer.Typer) -> None:
    @app.command("slope", help=HELP, epilog=EPILOG)
    def slope_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        slopes: Annotated[str | None, typer.Option(
            "--slope", help="Slopes [rad], positive uphill, each |slope| < pi/2: "
                            "start:stop:step or a comma list (default -0.2:0.2:0.01).")] = None,
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help="Constant thrust values [N]: start:stop:step or a comma list "
                             "(default 0:-50:-5; 0 for a robot without thrusters).")] = None,
        thruster: ThrusterOpt = None,
        mu: MuOpt = None,
        min_vertical_force: MinVerticalForceOpt = 0.0,
        out: OutOpt = Path("out/slope"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            g = None if slopes is None else parse_values(slopes, "--slope", "rad")
            f = None if thrust is None else parse_values(thrust, "--thrust", "N")
            run_slope(robot, gait, g, f, thruster, out, quiet, mu=mu,
                      min_vertical_force=min_vertical_force, json=json,
                      formats=parse_formats(formats), titles=titles)
