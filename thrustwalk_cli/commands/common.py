"""Options shared by every command, error handling, progress and value-list parsing."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer

from ..errors import ComputationError, InputError

RobotArg = Annotated[
    str,
    typer.Argument(help="Robot: a bundled name (three_link, rabbit) or a path to a YAML file."),
]
GaitArg = Annotated[
    str,
    typer.Argument(help="Gait: a bundled name (three_link_walk, rabbit_walk) or a YAML path."),
]
OutOpt = Annotated[
    Path, typer.Option("--out", "-o", help="Output folder (created if missing).")
]
QuietOpt = Annotated[
    bool, typer.Option("--quiet", "-q", help="No progress bar and no summary table.")
]


def console(stderr: bool = False):  # -> rich.console.Console
    from rich.console import Console

    return Console(stderr=stderr, highlight=False)


@contextlib.contextmanager
def cli_errors() -> Iterator[None]:
    """Bad input -> one line per problem on stderr, exit 2; tool failure -> exit 1."""
    try:
        yield
    except InputError as exc:
        for p in exc.problems:
            sys.stderr.write(f"error: {p}\n")
        raise typer.Exit(2) from None
    except ComputationError as exc:
        sys.stderr.write(f"error: computation failed: {exc}\n")
        raise typer.Exit(1) from None


def fmt(v, spec: str = ".4g") -> str:
    """A number for a summary table or markdown: ``format(v, spec)``, or an em dash for None."""
    return "—" if v is None else format(v, spec)


def parse_values(text: str, option: str, unit: str = "") -> list[float]:
    """``"0:-50:-10"`` (start:stop:step, stop included when reached), ``"0,-10,-25"`` or ``"5"``.

    Raises :class:`InputError` naming the option on malformed input.
    """
    def bad(msg: str) -> InputError:
        return InputError(f"option {option}: {msg} (got {text!r}; use e.g. 0:-50:-10 or 0,-10)")

    text = text.strip()
    try:
        if ":" in text:
            parts = [float(p) for p in text.split(":")]
            if len(parts) == 2:
                parts.append(1.0 if parts[1] >= parts[0] else -1.0)
            if len(parts) != 3:
                raise bad("a range has the form start:stop:step")
            start, stop, step = parts
            if step == 0 or (stop - start) * step < 0:
                raise bad("the step must be non-zero and point from start to stop")
            count = int(abs((stop - start) / step) + 1e-9) + 1
            if count > 100000:
                raise bad("more than 100000 values")
            return [start + i * step for i in range(count)]
        values = [float(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise bad("not a number, list or range") from None
    if not values:
        raise bad("no values")
    if any(v != v or v in (float("inf"), float("-inf")) for v in values):
        raise bad("values must be finite")
    return values


@contextlib.contextmanager
def progress(description: str, total: int, quiet: bool) -> Iterator:
    """A rich progress bar (silent with --quiet); yields ``advance(n=1)``."""
    if quiet:
        yield lambda n=1: None
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                  console=console(stderr=True), transient=True) as prog:
        task = prog.add_task(description, total=total)
        yield lambda n=1: prog.advance(task, n)
