"""What every command shares: error rendering (parameters become flags), writing a result
object, progress bars, value-list parsing."""

from __future__ import annotations

import contextlib
import re
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import typer

from ..errors import ComputationError, InputError, Problem

_MENTION = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*)`")


def console(stderr: bool = False):  # -> rich.console.Console
    from rich.console import Console

    return Console(stderr=stderr, highlight=False)


def flags(ctx: typer.Context | None) -> dict[str, str]:
    """Parameter name -> its long flag, for the command of ``ctx`` (empty without one)."""
    out: dict[str, str] = {}
    for p in ctx.command.params if ctx is not None else ():
        longs = [o for o in getattr(p, "opts", ()) if o.startswith("--")]
        if p.name and longs:
            out[p.name] = longs[0]
    return out


def render_problem(p: Problem, flags: dict[str, str]) -> str:
    """One line for a problem: a parameter problem names the command's flag(s)
    (``option --mu: ...``); parameters mentioned in backquotes become flags too."""
    if p.file:
        return str(p)
    msg = _MENTION.sub(lambda m: flags.get(m.group(1), m.group(0)), p.message)
    if p.params:
        names = [flags.get(x, "--" + x.replace("_", "-")) for x in p.params]
        return f"option{'s' if len(names) > 1 else ''} {'/'.join(names)}: {msg}"
    return str(replace(p, message=msg))


@contextlib.contextmanager
def cli_errors(ctx: typer.Context | None = None) -> Iterator[None]:
    """Bad input -> one line per problem on stderr, exit 2; tool failure -> exit 1.
    ``ctx``: the running command, whose flags name the parameters in messages."""
    try:
        yield
    except InputError as exc:
        names = flags(ctx)
        for p in exc.problems:
            sys.stderr.write(f"error: {render_problem(p, names)}\n")
        raise typer.Exit(2) from None
    except ComputationError as exc:
        sys.stderr.write(f"error: computation failed: {exc}\n")
        raise typer.Exit(1) from None


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
    """A rich progress bar with an ETA on stderr (silent with --quiet); yields
    ``advance(n=1)``."""
    if quiet:
        yield lambda n=1: None
        return
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    with Progress(TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                  TextColumn("eta"), TimeRemainingColumn(),
                  console=console(stderr=True), transient=True) as prog:
        task = prog.add_task(description, total=total)
        yield lambda n=1: prog.advance(task, n)


FIGURE_FORMATS = ("png", "pdf", "svg")


def figure_formats(text: str) -> tuple[str, ...]:
    """``--formats``: ``"png,pdf"`` -> ``("png", "pdf")``; ``"none"`` -> ``()``."""
    items = [t.strip().lower() for t in text.split(",") if t.strip()]
    if items == ["none"]:
        return ()
    bad = [t for t in items if t not in FIGURE_FORMATS]
    if bad or not items:
        raise InputError(f"option --formats: unknown format {', '.join(bad) or repr(text)} "
                         f"(choose from {', '.join(FIGURE_FORMATS)}, or none)")
    return tuple(dict.fromkeys(items))


def write_result(result, out: Path, provenance: dict,
                 formats: tuple[str, ...] = ("png", "pdf")) -> dict:
    """Write a study result into the folder ``out``: ``<name>.json`` (provenance first), its
    CSV tables, its attachments and its figures (in ``formats``; none: the figures are not
    drawn and matplotlib is not imported), every file atomically. Returns the JSON document
    written."""
    from ..files import output

    doc = {"provenance": provenance, **result.document()}
    out.mkdir(parents=True, exist_ok=True)
    output.write_json(out / f"{result.name}.json", doc)
    for name, t in result.tables().items():
        output.write_csv(out / f"{name}.csv", t.header, t.rows, comments=t.comments,
                         provenance=provenance)
    attach = getattr(result, "attachments", None)
    for name, data in (attach(doc) if attach else {}).items():
        if isinstance(data, bytes):
            output.write_bytes_atomic(out / name, data)
        else:
            output.write_text_atomic(out / name, data)
    if formats:
        save_figures(result.figures(), out, formats)
    return doc


def save_figures(figures: dict, out: Path, formats: tuple[str, ...] = ("png", "pdf")) -> None:
    """Save each figure as ``out/<name>.<format>`` for every format and close it."""
    if not figures:
        return
    from ..files import output
    from ..plots.style import close

    for name, fig in figures.items():
        output.save_figure(fig, out / name, formats)
        close(fig)
