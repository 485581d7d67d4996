"""``thrustwalk compile``: compile (or load from the cache) a robot model and summarise it."""

from __future__ import annotations

from typing import Annotated

import typer

from .common import cli_errors, console
from .options import QuietOpt, RobotArg

HELP = """Compile a robot file with SymPy into cached numeric dynamics.

Derives D, C, G, B_F, the unpinned model, swing-foot kinematics and the impact map, generates
vectorised code with common-subexpression elimination and caches it by content hash.
Prints links, coordinates, total mass [kg], thrusters, time [s] and the cache entry.
"""
EPILOG = "Example: thrustwalk compile rabbit --rebuild"


def run_compile(robot: str, rebuild: bool = False) -> dict:
    from .common import load_model

    return load_model(robot, rebuild).summary()


def register(app: typer.Typer) -> None:
    @app.command("compile", help=HELP, epilog=EPILOG)
    def compile_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        rebuild: Annotated[bool, typer.Option(
            "--rebuild", help="Ignore the cache and compile again.")] = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            s = run_compile(robot, rebuild)
            if quiet:
                return
            from rich.table import Table

            t = Table(title=f"robot {s['name']}", show_header=False)
            t.add_row("links", str(s["links"]))
            t.add_row("coordinates", ", ".join(s["coordinates"]))
            t.add_row("actuated (q_b)", ", ".join(s["actuated"]))
            t.add_row("unactuated (q_N)", s["unactuated"])
            t.add_row("total mass", f"{s['total_mass']:.4g} kg")
            t.add_row("gravity", f"{s['gravity']:.4g} m/s^2")
            t.add_row("thrusters", ", ".join(s["thrusters"]) or "none")
            how = "cache hit" if s["cache_hit"] else "compiled"
            t.add_row("time", f"{s['seconds']:.3f} s ({how})")
            t.add_row("cache entry", s["cache_entry"])
            console().print(t)
