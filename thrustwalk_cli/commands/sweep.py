"""``thrustwalk sweep``: run a sweep file's study at every point, resumably, on local worker
processes or an existing Dask cluster."""

from __future__ import annotations

import hashlib
import sys
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError, Problem
from .common import (
    check_out,
    cli_errors,
    console,
    ensure_kernel,
    parse_formats,
    progress,
    show_table,
    warn,
    write_result,
)
from .options import FormatsOpt, QuietOpt, TitlesOpt

HELP = """Run one study at every point of a sweep file, resumably.

The sweep file (YAML) names the study (limit-cycle, feasibility, simulate, design-gait), the
base robot and gait, fixed settings, the axes (grid: a product; zip: lists varying together;
random: seeded uniform, normal or log-uniform samples) over study parameters (thrust [N],
target_speed [m/s], kp [1/s^2], schedule.j, ...), robot parameters (robot.NAME) and gait
parameters (gait.NAME), and the result fields to collect. Everything is checked before any
point runs. The robot and gait a sweep file names are bundled ones or files inside its folder;
--robot and --gait name files elsewhere.

Each point is a task keyed by a content hash (robot and gait contents, settings, the point,
tool version); its JSON is written to DIR/points/ atomically as it finishes. Running the same
command again skips the finished points, so a sweep killed at any moment resumes with no point
lost or duplicated; a point that fails is recorded with its reason and the sweep goes on.

Writes DIR/results.csv (one row per point: axes and collected fields, SI units in the column
names), DIR/points/KEY.json (each point's full result), DIR/sweep.json (provenance, axes,
counts, wall time, executor) and a heat map of the first collected field per pair of numeric
axes (heatmap_X_Y.png/.pdf); a design-gait sweep also writes its gait library:
DIR/gaits/NAME.yaml, DIR/library.csv and DIR/atlas.png/.pdf. Points run on --workers local
processes (default: one per core) or on the Dask cluster of --scheduler.
"""

EPILOG = "Example: thrustwalk sweep sweeps/thrust_torso_mass.yaml --out out/thrust_torso_mass"


def run_sweep_command(file: Path, out: Path | None, *, workers: int | None = None,
                      scheduler: str | None = None, quiet: bool = False,
                      formats: set[str] | None = None, titles: bool = False,
                      robot: str | None = None, gait: str | None = None) -> dict:
    """Plain function behind the command; returns the ``sweep.json`` document it wrote."""
    from ..files import output
    from ..studies.sweep import check_executor, load_sweep, run_sweep, sweep_executor

    kinds = {"csv", "png", "pdf"} if formats is None else formats
    check_executor(workers, scheduler)  # every option before the folder exists
    if out is not None:
        check_out(out, whole=False)
    if scheduler is not None:
        from ..sweep.executors import quiet_dask_logs

        quiet_dask_logs()
    try:
        sweep = load_sweep(file, robot=robot, gait=gait)
    except InputError as exc:
        raise InputError([_explicit_option(p) for p in exc.problems]) from None
    spec = sweep.spec
    out = Path("out") / spec.name if out is None else out
    check_out(out, whole=False)
    folder = output.SweepFolder(out, {"identity": sweep.identity, "sweep": spec.name,
                                      "file": str(file), "study": spec.study,
                                      "points": len(sweep.tasks)})
    try:
        finished = folder.finished(t.key for t in sweep.tasks)
        warn(folder.notes)
        todo = len(sweep.tasks) - len(finished)
        if todo and sweep.study.prepare is not None and \
                dict(spec.settings).get("method") != "scipy":
            ensure_kernel(quiet)  # the study simulates: compile once here, with a word
        executor = sweep_executor(sweep, workers, scheduler, todo) if todo else None
        counts = {"ok": 0, "failed": 0}

        try:
            with progress(f"sweep {spec.name} ({len(finished)} of {len(sweep.tasks)} done "
                          "before)", todo, quiet) as advance:
                def on_point(record: dict) -> None:
                    folder.write_point(record)
                    counts["ok" if record["status"] == "ok" else "failed"] += 1
                    advance(1, note=f"{counts['ok']} ok, {counts['failed']} failed")

                result = run_sweep(sweep, executor=executor, finished=finished,
                                   on_point=on_point, library=out / "gaits")
        finally:
            if executor is not None:
                executor.close()
        doc = _write_summary(result, folder, kinds, titles)
    finally:
        folder.close()
    if not quiet:
        _summary(doc, out)
    bad = doc["failures"]
    if bad:
        more = f" (and {len(bad) - 1} more: sweep.json)" if len(bad) > 1 else ""
        warn([f"{len(bad)} point(s) failed; point {bad[0]['point']}: {bad[0]['reason']}{more}"])
    lost = result.counts.lost
    if lost:
        more = f" (and {len(lost) - 1} more)" if len(lost) > 1 else ""
        sys.stderr.write(f"error: {len(lost)} point(s) not run: point {sorted(lost)[0]}{more}: "
                         f"{result.counts.lost_reason}; run the sweep again to retry\n")
    return doc


def _explicit_option(p: Problem) -> Problem:
    """A file the sweep file may not name (outside its folder): the message ends with the
    parameter that takes it explicitly, in backquotes; here it becomes the option."""
    from ..files.bundled import EXPLICITLY

    head, sep, tail = p.message.partition(EXPLICITLY)
    if not sep:
        return p
    tail = tail.replace("`robot`", "--robot PATH").replace("`gait`", "--gait PATH")
    return replace(p, message=head + sep + tail)


def _write_summary(result, folder, kinds: set[str], titles: bool) -> dict:
    """sweep.json, results.csv (and library.csv, the gait files) and the figures, each file
    written atomically into the sweep's folder (:func:`write_result`)."""
    from ..files import output

    spec = result.sweep.spec

    def ref(path: str | None, text: str | None) -> dict | None:
        return None if path is None else output.file_ref(
            path, hashlib.sha256((text or "").encode()).hexdigest())

    prov = output.provenance(sweep=output.file_ref(spec.source_file, spec.source_sha256))
    prov.update(robot=ref(spec.robot, spec.robot_text), gait=ref(spec.gait, spec.gait_text))
    return write_result(result, folder.target, prov, formats=kinds, titles=titles, into=folder)


def _summary(doc: dict, out: Path) -> None:
    c, ex = doc["counts"], doc["executor"]
    where = ex.get("scheduler") or (f"{ex.get('workers')} {ex.get('kind')} worker(s)"
                                    if ex.get("kind") != "none" else "none (all done before)")
    show_table(f"sweep {doc['sweep']['name']} ({doc['sweep']['study']})",
               [("points", True), ("ok", True), ("failed", True), ("skipped\n(done before)",
                                                                   True),
                ("computed\nnow", True), ("wall time\n[s]", True), ("executor", False)],
               [[c["points"], c["done"], c["failed"], c["skipped"], c["computed"],
                 f"{doc['wall_time']:.1f}", where]])
    console().print(f"wrote {out}/results.csv, {out}/sweep.json, {out}/points/ and "
                    f"{len(doc['figures'])} figure(s)", markup=False)


def register(app: typer.Typer) -> None:
    @app.command("sweep", help=HELP, epilog=EPILOG)
    def sweep_cli(
        ctx: typer.Context,
        file: Annotated[Path, typer.Argument(help="The sweep file (YAML).")],
        out: Annotated[Path | None, typer.Option(
            "--out", "-o", help="The sweep's folder (default: out/NAME); written point by "
                                "point and resumed, never replaced as a whole.")] = None,
        workers: Annotated[int | None, typer.Option(
            "--workers", help="Local worker processes (default: one per core; 1 runs in "
                              "this process).")] = None,
        scheduler: Annotated[str | None, typer.Option(
            "--scheduler", help="Run on an existing Dask distributed cluster: its scheduler's "
                                "address tcp://HOST:PORT (or tls://HOST:PORT: certificates "
                                "from Dask's configuration); needs 'thrustwalk[cluster]' "
                                "here and on every worker.")] = None,
        robot: Annotated[str | None, typer.Option(
            "--robot", help="The base robot (file or bundled name) instead of the sweep "
                            "file's robot: (which must be a bundled name or a file inside "
                            "the sweep file's folder).")] = None,
        gait: Annotated[str | None, typer.Option(
            "--gait", help="The base gait (file or bundled name) instead of the sweep file's "
                           "gait: (same rule as --robot).")] = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            doc = run_sweep_command(file, out, workers=workers, scheduler=scheduler,
                                    quiet=quiet, formats=parse_formats(formats),
                                    titles=titles, robot=robot, gait=gait)
            if not doc["success"]:
                raise typer.Exit(1)

