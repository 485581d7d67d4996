"""``thrustwalk limit-cycle``: fixed points and orbits of the zero dynamics over a thrust sweep."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import cli_errors, console, figure_formats, parse_values, write_result
from .options import FormatsOpt, GaitArg, OutOpt, QuietOpt, RobotArg, ThrusterOpt

HELP = """Limit cycles of the hybrid zero dynamics for constant thrust values.

For every thrust value: Poincare fixed point zeta* [kg^2 m^4/s^2], stability (delta_zero^2),
step time [s], step length [m], speed [m/s], sigma_N^+/- [kg m^2/s], alpha'^+/- [rad/s] and
the point of minimum |alpha'|. Thrust is in newtons; with the bundled robots negative thrust
pushes forward (the paper's convention).

Writes DIR/limit_cycles.json, DIR/limit_cycles.csv, DIR/limit_cycles.png and .pdf, and
DIR/fixed_point_shift.png and .pdf (zeta* and speed versus thrust, with the affine law).
"""

EPILOG = ("Example: thrustwalk limit-cycle three_link three_link_walk --thrust 0:-50:-10 "
          "--out out/lc")


def run_limit_cycle(robot: str, gait: str, thrust: list[float], thruster: str | None,
                    out: Path, quiet: bool, formats: str = "png,pdf") -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files.output import provenance
    from ..studies.limit_cycle import limit_cycle
    from ..walker import load_walker

    walker = load_walker(robot, gait)
    doc = write_result(limit_cycle(walker, thrust, thruster), out,
                       provenance(walker.robot, walker.gait), formats=figure_formats(formats))
    if not quiet:
        _table(doc)
    return doc


def _table(doc: dict) -> None:
    from rich.table import Table

    from ..studies.records import fmt

    zd = doc["zero_dynamics"]
    t = Table(title=f"limit cycles: {doc['robot']['name']} / {doc['gait']['name']} "
                    f"(delta_zero^2 = {zd['delta_zero_sq']:.4f})")
    for col in ("thrust [N]", "zeta*", "stable", "T [s]", "speed [m/s]", "min|α'| [rad/s]",
                "reason"):
        t.add_column(col, overflow="fold")
    for c in doc["cycles"]:
        t.add_row(fmt(c["thrust"]), fmt(c["zeta_star"]),
                  "yes" if c["stable"] else ("no" if c["exists"] else "no orbit"),
                  fmt(c["step_time"]), fmt(c["speed"]), fmt(c["min_abs_alpha_dot"]),
                  "" if c["stable"] else c["reason"])
    console().print(t)


def register(app: typer.Typer) -> None:
    @app.command("limit-cycle", help=HELP, epilog=EPILOG)
    def limit_cycle_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = "three_link_walk",
        thrust: Annotated[str, typer.Option(
            "--thrust", help="Thrust values [N]: start:stop:step or a comma list.")] = "0:-50:-10",
        thruster: ThrusterOpt = None,
        out: OutOpt = Path("out/limit_cycle"),
        formats: FormatsOpt = "png,pdf",
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            values = parse_values(thrust, "--thrust", "N")
            run_limit_cycle(robot, gait, values, thruster, out, quiet, formats)
            if not quiet:
                console().print(f"wrote {out}/limit_cycles.json, .csv, .png, .pdf and "
                                f"{out}/fixed_point_shift.png, .pdf")
