"""The ``thrustwalk`` command line. Thin: each command parses, calls a study, writes, renders.

Start-up is kept light (no NumPy, SymPy or matplotlib until a command runs): command modules
import only typer at module level.
"""

from __future__ import annotations

import os

import typer

from ._version import __version__
from .commands import (
    compile,
    design_gait,
    feasibility,
    inspect,
    limit_cycle,
    optimize,
    report,
    shape,
    simulate,
    sweep,
)

# Help lists the commands in this order.
COMMANDS = (compile, inspect, limit_cycle, shape, feasibility, optimize, simulate, design_gait,
            sweep, report)

app = typer.Typer(
    name="thrustwalk",
    help=(
        "Thruster-assisted bipedal walking with hybrid zero dynamics.\n\n"
        "Robots and gaits are YAML files (bundled names such as 'three_link' work from any "
        "folder). Results go to an output folder as JSON, CSV and figures."
    ),
    no_args_is_help=True,
    add_completion=True,
    rich_markup_mode=None,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"thrustwalk {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="Show the version and exit."),
) -> None:
    """Thruster-assisted bipedal walking with hybrid zero dynamics."""


for _module in COMMANDS:
    _module.register(app)


def main() -> None:
    os.environ.setdefault("MPLBACKEND", "Agg")  # figures only go to files: no screen needed
    app()
