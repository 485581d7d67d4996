"""The ``thrustwalk`` command line. Thin: each command parses, calls the core, renders.

Start-up is kept light (no NumPy, SymPy or matplotlib until a command runs).
"""

from __future__ import annotations

import importlib
import pkgutil

import typer

from . import __version__, commands

# Help lists commands in this order; any other module in commands/ with ``register`` follows.
ORDER = ["compile", "inspect", "limit_cycle", "shape", "feasibility", "optimize", "simulate",
         "design_gait", "report"]

app = typer.Typer(
    name="thrustwalk",
    help=(
        "Thruster-assisted bipedal walking with hybrid zero dynamics.\n\n"
        "Robots and gaits are YAML files (bundled names such as 'three_link' work from any "
        "folder). Results go to an output folder as JSON, CSV and figures."
    ),
    no_args_is_help=True,
    add_completion=False,
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


def _command_modules() -> list[str]:
    found = [m.name for m in pkgutil.iter_modules(commands.__path__) if m.name != "common"]
    return sorted(found, key=lambda n: (ORDER.index(n) if n in ORDER else len(ORDER), n))


for _name in _command_modules():
    _module = importlib.import_module(f"{commands.__name__}.{_name}")
    if hasattr(_module, "register"):
        _module.register(app)


def main() -> None:
    app()
