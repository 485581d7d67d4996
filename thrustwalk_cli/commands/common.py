"""What every command shares: error rendering (parameters become flags), writing a result
object, progress bars, value-list parsing."""

from __future__ import annotations

import contextlib
import contextvars
import re
import sys
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import typer

from ..description.sweep import range_count, range_values
from ..errors import ComputationError, InputError, Problem

_MENTION = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*)`")


def number_column(table, header: str) -> None:
    """A numeric column: never wrapped (a number is never split across lines), right-aligned,
    at least as wide as its header's longest line (the unit stays visible)."""
    from rich.markup import escape

    table.add_column(escape(header), no_wrap=True, justify="right",
                     min_width=max(len(line) for line in header.split("\n")))


def show_table(title: str, columns: list[tuple[str, bool]], rows: list[list]) -> None:
    """Print a summary table (``columns``: (header with its unit, numeric?)). Numeric columns
    never wrap; text columns fold. When the terminal is too narrow for the numeric columns,
    the rows are printed as ``header: value`` lines instead, so no number is ever split. A
    None cell is shown as the missing mark of every table (``studies.documents.MISSING``)."""
    from rich.markup import escape
    from rich.table import Table

    from ..studies.documents import MISSING

    rows = [[MISSING if v is None else v for v in row] for row in rows]
    con = console()
    t = Table(title=escape(title))
    for header, numeric in columns:
        if numeric:
            number_column(t, header)
        else:
            t.add_column(escape(header), overflow="fold")
    for row in rows:
        t.add_row(*(escape(str(v)) for v in row))
    def least(j: int, numeric: bool) -> int:  # narrowest the column can be without a split
        cells = [str(r[j]) for r in rows] + columns[j][0].split("\n")
        if not numeric:
            cells = [w for c in cells for w in c.split()] or [""]
        return max(len(c) for c in cells)

    need = sum(least(j, num) + 3 for j, (_, num) in enumerate(columns)) + 1
    if need <= con.width:
        con.print(t)
        return
    con.print(title, markup=False)
    for row in rows:
        con.print("; ".join(f"{h.replace(chr(10), ' ')}: {v}" for (h, _), v in zip(columns, row)),
                  markup=False)


_CTX: contextvars.ContextVar[typer.Context | None] = contextvars.ContextVar("ctx",
                                                                          default=None)


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


def render_mentions(text: str, ctx: typer.Context | None) -> str:
    """``text`` with parameters mentioned in backquotes (`` `max_iter` ``) written as the
    running command's flags (``--max-iter``); unknown names stay as they are."""
    names = flags(ctx)
    return _MENTION.sub(lambda m: names.get(m.group(1), m.group(0)), text)


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


LARGEST = 1e9  # a number option beyond this (in SI units) is a typo, not a request


def check_numbers(ctx: typer.Context | None) -> None:
    """Every number option of the command is finite and sane: ``nan``, ``inf`` and values
    beyond ``LARGEST`` are refused with the option's name before any work."""
    if ctx is None:
        return
    names = flags(ctx)
    for name, value in ctx.params.items():
        if isinstance(value, float) and not (abs(value) <= LARGEST):
            raise InputError(f"option {names.get(name, name)}: {value:g} is not a usable "
                             f"number (finite, at most {LARGEST:g} in size)")


@contextlib.contextmanager
def cli_errors(ctx: typer.Context | None = None) -> Iterator[None]:
    """Bad input -> one line per problem on stderr, exit 2; a failed computation or an
    environment problem (a file that cannot be written) -> one line, exit 1; never a traceback
    (set THRUSTWALK_DEBUG=1 to see one for an unexpected error). ``ctx``: the running command,
    whose flags name the parameters in messages."""
    import os
    import warnings

    from ..model import cache

    token = _CTX.set(ctx)
    quiet = bool(ctx is not None and ctx.params.get("quiet"))
    reporter = cache.set_wait_reporter(None if quiet else _say)  # waits for another build
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # overflow etc. are checked
            check_numbers(ctx)
            yield
    except InputError as exc:
        names = flags(ctx)
        for p in exc.problems:
            sys.stderr.write(f"error: {render_problem(p, names)}\n")
        raise typer.Exit(2) from None
    except ComputationError as exc:
        sys.stderr.write(f"error: computation failed: {exc}\n")
        raise typer.Exit(1) from None
    except (typer.Exit, typer.Abort):
        raise
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        raise typer.Exit(130) from None
    except OSError as exc:
        what = exc.filename if exc.filename else ""
        sys.stderr.write(f"error: {what + ': ' if what else ''}{exc.strerror or exc}\n")
        raise typer.Exit(1) from None
    except Exception as exc:
        if os.environ.get("THRUSTWALK_DEBUG"):
            raise
        sys.stderr.write(f"error: internal error ({type(exc).__name__}: {exc}); please report "
                         "it with the command line (THRUSTWALK_DEBUG=1 shows the traceback)\n")
        raise typer.Exit(1) from None
    finally:
        _CTX.reset(token)
        cache.set_wait_reporter(reporter)


def _say(line: str) -> None:
    """One line on standard error (what a command says while it waits or compiles)."""
    sys.stderr.write(line + "\n")


MAX_VALUES = 10_000  # values in one sweep option


def parse_values(text: str, option: str, unit: str = "") -> list[float]:
    """``"0:-50:-10"`` (start:stop:step, stop included when reached), ``"0,-10,-25"`` or ``"5"``.

    Raises :class:`InputError` naming the option on malformed input.
    """
    def bad(msg: str) -> InputError:
        shown = text if len(text) <= 60 else text[:40] + " ... " + text[-12:]
        return InputError(f"option {option}: {msg} (got {shown!r}; use e.g. 0:-50:-10 or "
                          "0,-10)")

    text = text.strip()
    try:
        if ":" in text:
            parts = [float(p) for p in text.split(":")]
            if len(parts) == 2:  # a silent step of 1 would be a guess
                raise bad("a range needs its step, start:stop:step")
            if len(parts) != 3:
                raise bad("a range has the form start:stop:step")
            start, stop, step = parts
            if not all(abs(v) <= LARGEST for v in parts):
                raise bad(f"values must be finite and at most {LARGEST:g} in size")
            count = range_count(start, stop, step, MAX_VALUES)
            if isinstance(count, str):
                raise bad(count)
            return range_values(start, step, count)
        values = [float(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise bad("not a number, list or range") from None
    if not values:
        raise bad("no values")
    if len(values) > MAX_VALUES:
        raise bad(f"{len(values)} values: the limit is {MAX_VALUES}")
    if not all(abs(v) <= LARGEST for v in values):
        raise bad(f"values must be finite and at most {LARGEST:g} in size")
    return values


def parse_knots(text: str, option: str = "--knots") -> list[float | None]:
    """Knots in one syntax for every command: a comma list whose entries are numbers or ``?``
    (a knot to solve for), or a range ``start:stop:step`` (stop included)."""
    text = text.strip()
    if ":" in text:
        return [float(v) for v in parse_values(text, option)]
    out: list[float | None] = []
    for item in text.split(","):
        item = item.strip()
        if item == "?":
            out.append(None)
            continue
        try:
            v = float(item)
        except ValueError:
            raise InputError(f"option {option}: {item!r} is not a number or ? (a free knot); "
                             "use e.g. 0,?,?,1, 0,0.3,0.6,1 or 0:1:0.25") from None
        if not abs(v) <= LARGEST:
            raise InputError(f"option {option}: knots must be finite and at most {LARGEST:g} "
                             f"in size, got {item!r}")
        out.append(v)
    return out


def parse_push(items: list[str] | None, option: str = "--push"
               ) -> list[tuple[float, float, float, float]]:
    """``STEP:PHASE:PX[:PY]`` (an impulse [N s] at phase s [1] of a step, P_y 0 when not
    given) -> ``(step, phase, P_x, P_y)``, for every command with ``--push``. Raises
    :class:`InputError` naming the option on malformed input; the study checks the values
    (the step in range, the phase in [0, 1), the impulse's size)."""
    out = []
    for item in items or []:
        parts = item.split(":")
        try:
            if len(parts) not in (3, 4):
                raise ValueError
            v = [float(p) for p in parts]
        except ValueError:
            raise InputError(f"option {option}: {item!r} is not STEP:PHASE:PX[:PY] (e.g. "
                             "3:0.5:20 for 20 N s forward at phase 0.5 of step 3)") from None
        out.append((v[0], v[1], v[2], v[3] if len(v) == 4 else 0.0))
    return out


def parse_formats(text: str, allowed: tuple[str, ...] = ("csv", "png", "pdf", "svg")
                  ) -> set[str]:
    """``--formats csv,png`` -> the set of file kinds to write besides the JSON; ``none``:
    only the JSON (no figure is drawn and matplotlib is not imported). A kind that another
    command writes but this one does not (``csv`` for feasibility) is refused saying what
    this command writes instead; an unknown word is refused as unknown."""
    kinds = {k.strip().lower() for k in text.split(",") if k.strip()}
    if kinds == {"none"}:
        return set()
    bad = sorted(kinds - set(allowed))
    if not bad:
        return kinds
    choose = f"choose from {', '.join(allowed)}, or none: only the JSON"
    unknown = [k for k in bad if k not in FORMAT_KINDS]
    if unknown:
        raise InputError(f"option --formats: unknown {', '.join(unknown)} ({choose})")
    ctx = _CTX.get()
    who = ctx.info_name if ctx is not None and ctx.info_name else "this command"
    raise InputError(f"option --formats: {who} writes no {', '.join(bad)} file (its JSON "
                     f"document holds every number; {choose})")


#: every kind of file ``--formats`` names in some command (each command accepts a subset)
FORMAT_KINDS = ("csv", "png", "pdf", "svg", "md")


def warn(lines) -> None:
    """Warnings on standard error, one line each (also with --quiet); parameters mentioned in
    backquotes are written as the running command's flags."""
    ctx = _CTX.get()
    for line in lines:
        sys.stderr.write(f"warning: {render_mentions(line, ctx)}\n")


def load_walker(robot: str | None, gait: str | None, quiet: bool | None = None):
    """:func:`thrustwalk_cli.walker.load_walker`, with the gait's warnings printed and the
    progress of a long compile shown (:func:`compile_progress`)."""
    from ..walker import load_walker as _load

    with compile_progress(quiet) as report:
        walker = _load(robot, gait, progress=report)
    warn(walker.model.notes)
    warn(walker.warnings)
    return walker


def load_model(robot: str, rebuild: bool = False, quiet: bool | None = None):
    """:func:`thrustwalk_cli.studies.compile.compile_robot`, with cache notes printed and
    the progress of a long compile shown (:func:`compile_progress`)."""
    from ..studies.compile import compile_robot

    with compile_progress(quiet) as report:
        model = compile_robot(robot, rebuild, progress=report)
    warn(model.notes)
    return model


#: a compile shows its progress once it has run this long [s] (most robots take less)
COMPILE_QUIET_SECONDS = 2.0


@contextlib.contextmanager
def compile_progress(quiet: bool | None = None) -> Iterator:
    """A progress callback for :func:`thrustwalk_cli.model.compiler.load_model` (``done,
    total, phase``; None with ``quiet``, which defaults to the running command's
    ``--quiet``). Silent for the first :data:`COMPILE_QUIET_SECONDS` of a compile, then a
    :func:`progress` bar on standard error with the phase (derivation, code generation,
    tape, checks), and one line when it is done."""
    if quiet is None:
        ctx = _CTX.get()
        quiet = bool(ctx is not None and ctx.params.get("quiet"))
    if quiet:
        yield None
        return
    t0 = time.monotonic()
    shown = [0]
    with contextlib.ExitStack() as stack:
        bar: list = []

        def report(done: int, total: int, phase: str) -> None:
            if not bar:
                if time.monotonic() - t0 < COMPILE_QUIET_SECONDS:
                    return
                bar.append(stack.enter_context(progress(
                    "compiling the robot model (once per robot structure)", total, False)))
            bar[0](done - shown[0], note=phase)
            shown[0] = done
        yield report
    if shown[0]:
        sys.stderr.write(f"compiled the robot model in {time.monotonic() - t0:.1f} s "
                         "(cached: later runs load it)\n")


def check_out(out: Path, *, whole: bool = True, json: str | None = None) -> None:
    """Check the output folder (and the ``--json`` file, unless ``-``) before any work
    (:func:`thrustwalk_cli.files.output.check_target`; ``whole``: the command replaces the
    folder as a whole)."""
    from ..files.output import check_file_target, check_target

    check_target(out, whole=whole)
    if json and json != "-":
        check_file_target(Path(json))


#: the longest interval [s] between two progress lines written to a log (not a terminal)
LOG_SECONDS = 5.0


@contextlib.contextmanager
def progress(description: str, total: int, quiet: bool) -> Iterator:
    """A rich progress bar with an ETA on stderr (silent with --quiet); yields
    ``advance(n=1, note=None)`` (``note``: a short status shown after the counts, e.g.
    ``3 failed``)."""
    if quiet:
        yield lambda n=1, note=None: None
        return
    con = console(stderr=True)
    if not con.is_terminal:
        # a log, not a terminal: a line for the first and the last unit, at every tenth of
        # the total and at least every LOG_SECONDS in between (not one per unit: a sweep of
        # 10,000 trials would write 10,000 lines)
        t0 = time.monotonic()
        done, shown, last = 0, -1, t0

        def line(n: int = 1, note: str | None = None) -> None:
            nonlocal done, shown, last
            before = done
            done += n
            now = time.monotonic()
            tenth = 10 * done // max(total, 1)
            if not (before == 0 or done >= total or tenth > 10 * before // max(total, 1)
                    or now - last >= LOG_SECONDS) or done == shown:
                return
            shown, last = done, now
            el = now - t0
            eta = el / done * (total - done) if done else 0.0
            extra = f", {note}" if note else ""
            sys.stderr.write(f"{description}: {done}/{total}{extra} ({el:.1f} s, eta "
                             f"{eta:.1f} s)\n")
        yield line
        return
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    with Progress(TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total}"), TextColumn("{task.fields[note]}"),
                  TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(),
                  console=con, transient=True) as prog:
        task = prog.add_task(description, total=total, note="")

        def advance(n: int = 1, note: str | None = None) -> None:
            if note is None:
                prog.advance(task, n)
            else:
                prog.update(task, advance=n, note=note)
        yield advance


KERNEL_SECONDS = 30.0  # [s] the one-time numba compile on an idle 2-core machine (bench)


def ensure_kernel(quiet: bool) -> dict | None:
    """Before a command that simulates: compile the numba simulation kernel now if this
    machine has not (once per machine, for every robot), saying so on standard error with an
    elapsed-time bar against the expected time (silent with ``--quiet``), so that the first
    run is not a minute of silence. Returns :func:`compile_kernel`'s record when it compiled,
    None when the kernel was cached."""
    from ..simulation.stepper import kernel_status
    from ..studies.compile import compile_kernel

    if kernel_status()["cached"]:
        return None
    if quiet:
        return compile_kernel()  # (cli_errors installs no wait reporter with --quiet)
    import threading

    sys.stderr.write(f"compiling the simulation kernel once for this machine (~"
                     f"{KERNEL_SECONDS:.0f} s; every later run loads it)\n")
    done = threading.Event()
    steps = 100
    with progress("compiling the simulation kernel", steps, False) as advance:
        def tick() -> None:  # the bar follows the clock against the expected time
            shown, t0 = 0, time.monotonic()
            while not done.wait(0.5):
                due = min(steps - 1, int(steps * (time.monotonic() - t0) / KERNEL_SECONDS))
                if due > shown:
                    advance(due - shown)
                    shown = due
            advance(steps - shown)
        ticker = threading.Thread(target=tick, daemon=True)
        ticker.start()
        try:  # another process compiling it: this one says so (the cache's wait reporter
            rec = compile_kernel()  # of cli_errors: standard error), waits, and loads it
        finally:
            done.set()
            ticker.join()
    secs = rec["seconds"]
    if rec["cache_hit"]:
        _say("loaded the simulation kernel another process compiled")
        return rec
    sys.stderr.write("compiled the simulation kernel" + (f" in {secs:.1f} s" if secs else "")
                     + (f" ({rec['note']})" if rec["note"] else "") + "\n")
    return rec


def write_result(result, out: Path, provenance: dict, *, json: str | None = None,
                 formats: set[str] | None = None, titles: bool = False,
                 extra: dict[str, bytes] | None = None, into=None) -> dict:
    """Write a study result as the folder ``out``, as a whole (a killed run leaves the previous
    folder or none, never a mix): ``<name>.json`` (provenance first), its CSV tables, its
    attachments, ``extra`` files and its figures (PNG and PDF), each kind only when in
    ``formats`` (default: all); with ``json`` also the document to that path, or to standard
    output for ``-``. Returns the JSON document written.

    ``into``: the open resumable folder (``output.SweepFolder``) of a command whose records
    were written one by one (sweep, robustness): the same files are written into it, each
    atomically, the JSON document last (it marks the folder complete) and listing the
    figures."""
    import json as _json

    from ..files import output

    kinds = {"csv", "png", "pdf", "md", "yaml", "npz", "gif"} if formats is None else formats
    figure_kinds = [k for k in ("png", "pdf", "svg") if k in kinds]
    folder = output.ResultFolder(out) if into is None else into
    try:
        tables = result.tables() if "csv" in kinds else {}
        doc = {"provenance": provenance, **result.document()}
        if tables or into is not None:
            doc["tables"] = {f"{name}.csv": {"columns": t.header, "notes": t.comments}
                             for name, t in tables.items()}
        figures = result.figures(titles=titles) if figure_kinds else {}
        if isinstance(doc.get("files"), list):
            # a document that lists its files (optimize) names the figures of the kinds
            # written, never one that --formats left out
            doc["files"] = ([f for f in doc["files"] if f.rsplit(".", 1)[-1] not in FIGURE_KINDS]
                            + [f"{n}.{k}" for n in figures for k in figure_kinds])
        if into is not None:
            doc["figures"] = sorted(figures)
        else:
            output.write_json(folder.path(f"{result.name}.json"), doc)
        for name, t in tables.items():
            output.write_csv(folder.path(f"{name}.csv"), t.header, t.rows)
        attach = getattr(result, "attachments", None)
        files = {**(attach(doc) if attach else {}), **(extra or {})}
        for name, data in files.items():
            needs = {"md": "md", "npz": "csv"}.get(name.rsplit(".", 1)[-1])
            if needs and needs not in kinds:
                continue
            if isinstance(data, bytes):
                output.write_bytes_atomic(folder.path(name), data)
            else:
                output.write_text_atomic(folder.path(name), data)
        if figure_kinds:
            save_figures(figures, folder.tmp if into is None else folder.target, figure_kinds)
        if into is None:
            folder.commit(provenance)
        else:
            output.write_json(folder.path(f"{result.name}.json"), doc)
    except BaseException:
        if into is None:
            folder.abort()
        raise
    if json == "-":
        sys.stdout.write(_json.dumps(output.jsonable(doc), indent=2) + "\n")
    elif json:
        output.write_json(Path(json), doc)
    return doc


FIGURE_KINDS = ("png", "pdf", "svg")


def wrote_line(out: Path, head: str = "") -> str:
    """``wrote DIR: a.json, a.csv, trials/; figures x, y (png, pdf)``: what the result folder
    ``out`` holds now (written by :func:`write_result`), so that the line never names a file
    that ``--formats`` left out."""
    files = sorted(p for p in Path(out).iterdir() if not p.name.startswith("."))
    figs: dict[str, list[str]] = {}
    plain = []
    for p in files:
        if p.is_file() and p.suffix[1:] in FIGURE_KINDS:
            figs.setdefault(p.stem, []).append(p.suffix[1:])
        else:
            plain.append(p.name + ("/" if p.is_dir() else ""))
    text = f"{head}wrote {out}: " + ", ".join(plain)
    if figs:
        kinds = sorted({k for v in figs.values() for k in v}, key=FIGURE_KINDS.index)
        text += f"; figures {', '.join(figs)} ({', '.join(kinds)})"
    else:
        text += " (no figures)"
    return text


def save_figures(figures: dict, out: Path, kinds=("png", "pdf")) -> None:
    """Save each figure as ``out/<name>.<kind>`` (PNG, PDF, SVG) and close it."""
    from .._version import __version__
    from ..files import output
    from ..plots.style import close, render

    for name, fig in figures.items():
        for kind in kinds:
            output.write_bytes_atomic(out / f"{name}.{kind}",
                                      render(fig, kind, f"thrustwalk {__version__}"))
        close(fig)
