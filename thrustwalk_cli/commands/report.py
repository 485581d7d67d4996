"""``thrustwalk report``: index a results folder (figures, commands, key numbers)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from .common import cli_errors, console
from .options import QuietOpt

HELP = """Write DIR/index.md: every figure below DIR with the command that made it (from the
provenance of the JSON next to it) and its key numbers in SI units (thrust [N], speed [m/s],
zeta* [kg^2 m^4/s^2]), each followed by the JSON path it comes from; a number of a case or
run that has a verdict (walkable, feasible, completed, stable, ...) is shown beside that
verdict and its path.
"""
EPILOG = "Example: thrustwalk report figures"


def register(app: typer.Typer) -> None:
    @app.command("report", help=HELP, epilog=EPILOG)
    def report_cli(
        ctx: typer.Context,
        folder: Annotated[Path, typer.Argument(help="Results folder, e.g. figures.")],
        title: Annotated[str, typer.Option("--title", help="Heading of the index.")] = (
            "thrustwalk figures"),
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            from ..errors import InputError
            from ..files import output
            from ..studies.report import build_index

            if not folder.is_dir():
                raise InputError(f"{folder}: not a folder")
            problems: list[str] = []
            text = build_index(folder, title, problems)
            for line in problems:
                sys.stderr.write(f"warning: {line}\n")
            output.write_text_atomic(folder / "index.md", text)
            if not quiet:
                console().print(f"wrote {folder / 'index.md'}")
