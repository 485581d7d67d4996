"""The ``thrustwalk`` command line. Thin: each command parses, calls the core, renders.

Start-up is kept light (no NumPy, SymPy or matplotlib until a command runs).
"""

from __future__ import annotations

import typer

from . import __version__
from .commands import compile as compile_cmd
from .commands import inspect as inspect_cmd
from .commands import limit_cycle as limit_cycle_cmd

app = typer.Typer(
    name="thrustwalk",
    help=(
        "Thruster-assisted bipedal walking with hybrid zero dynamics.\n\n"
        "Robots and gaits are YAML files (bundled names such as 'three_link' work from any "
        "folder). Results go to an output folder as JSON, CSV and figures."
    ),
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode="rich",
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


for module in (compile_cmd, inspect_cmd, limit_cycle_cmd):
    module.register(app)


def main() -> None:
    app()
