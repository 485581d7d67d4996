"""``thrustwalk robustness``: push maps, survivable pushes, basins of attraction and parameter
uncertainty per thrust strategy (SPEC 12), every trial a resumable point of the sweep engine."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from .common import (
    check_out,
    cli_errors,
    console,
    ensure_kernel,
    load_walker,
    parse_formats,
    parse_knots,
    parse_values,
    progress,
    show_table,
    warn,
    write_result,
    wrote_line,
)
from .options import (
    FormatsOpt,
    GaitArg,
    JsonOpt,
    MinVerticalForceOpt,
    MuOpt,
    QuietOpt,
    RobotArg,
    SlopeOpt,
    ThrusterOpt,
    TitlesOpt,
)

HELP = """How much do thrusters buy? Push trials, basins of attraction and parameter
uncertainty of the full-order closed loop, one thrust strategy beside the other.

Push trials: a push of --push-impulse [N s] (signed along --push-direction; default forward) at
the end of the stance link (the hip of a one-link stance leg, a kneed walker's stance knee;
--push-link, --push-at move it) at phase s of the first step (--push-phase, 0..1), started on
the strategy's orbit; the closed loop walks --steps steps in all. Outcome: recovered (the last
zeta^- within --recovery-tol of the orbit, outputs settled), unsettled (walking, not yet back),
fell, slipped (friction cone), lifted (vertical force <= 0; also the push's impulsive ground
reaction), scuffed, stopped (alpha reverses), or error (could not be computed): the first of
them in time. A direction in which one outcome covers every push (e.g. every forward push
lifts the stance foot of a knee walker) is a warning: try --push-duration. Strategies
(--strategy, comma list): none, constant:F [N] (constant: the gait's thrust: section), control
(the step-to-step controller of thrustwalk control, regulating to the zero-thrust orbit),
schedule:FILE (the thrust: section of a gait file).

Per strategy: the outcome map over (phase, impulse); the largest survivable push forward and
backward per phase (a lower bound within one grid step) and its mean over phases [N s]; the
exact basin of the reduced walker (in closed form) and a full-order slice over sigma_N^+
and one output rate (--basin-grid, --basin-sigma, --basin-rate); with --uncertainty FILE,
--samples robots drawn from the file's distributions (reduced model): the fraction that walks
and the spread of the converged speed.

With --slope GAMMA [rad, positive uphill] everything is on a slope: each strategy's
orbit, reduced basin and controller, the trials (pushes given in the world frame, turned into
the slope frame as simulate --slope turns them; ground forces tangential and normal to the
slope) and the uncertainty samples; the JSON gains the slope block and each orbit its climb
rate beside its speed along the ground. With --terrain FILE (docs/files.md, as simulate
--terrain) every push and basin trial walks the file's step heights (the same ground for each;
past its s_max without a touchdown a trial fell: missed footing), measured against the plane
ground's orbit; the uncertainty samples (reduced model) do not walk it.

Every trial is a point of the sweep engine (consecutive trials share a task): --workers local
processes (default: one per core) or the Dask cluster of --scheduler. DIR is written
incrementally like a sweep's folder: each trial's record in DIR/trials/ as it finishes; run
the same command again to resume. Writes DIR/robustness.json, DIR/trials.csv (and
uncertainty.csv) and the figures push_map, survivable_push, push_energy, basin (and
uncertainty), PNG/PDF.
"""

EPILOG = ("Example: thrustwalk robustness three_link three_link_walk --push-impulse -30:30:2 "
          "--push-phase 0:1:0.05 --strategy none,constant:-20,control --steps 10 "
          "--out out/robustness")


def parse_pair(text: str, option: str, what: str) -> tuple[float, float]:
    """``"A,B"`` or ``"A:B"`` -> two finite numbers."""
    parts = text.replace(":", ",").split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        a, b = (float(p) for p in parts)
        if not (abs(a) <= 1e9 and abs(b) <= 1e9):
            raise ValueError
    except ValueError:
        raise InputError(f"option {option}: {text!r} is not {what}") from None
    return a, b


def parse_strategies(text: str) -> list[str]:
    items = [t.strip() for t in text.split(",") if t.strip()]
    if not items:
        raise InputError("option --strategy: no strategy (e.g. none,constant:-20,control)")
    return items


def run_robustness_command(
        robot: str | None, gait: str | None, *, push_impulse: str, push_phase: str,
        strategy: str | None, steps: int, push_direction: str, push_link: str | None,
        push_at: float, push_duration: float, recovery_tol: float, output_tol: float,
        mu: float | None, min_vertical_force: float, thruster: str | None, knots: str,
        max_thrust: float | None, basin_grid: int, basin_sigma: str, basin_rate: float,
        basin_joint: str | None, uncertainty: Path | None, samples: int, rtol: float,
        atol: float, workers: int | None, scheduler: str | None, out: Path, quiet: bool,
        json: str | None = None, formats: set[str] | None = None, titles: bool = False,
        slope: float = 0.0, terrain: Path | None = None) -> dict:
    """Plain function behind the command; returns the ``robustness.json`` document."""
    from ..files import output
    from ..studies.robustness import plan_robustness, run_robustness
    from ..studies.sweep import check_executor, task_executor
    from ..studies.sweep_studies import STUDIES

    kinds = {"csv", "png", "pdf"} if formats is None else formats
    impulses = parse_values(push_impulse, "--push-impulse", "N s")
    phases = parse_values(push_phase, "--push-phase")
    strategies = parse_strategies(strategy) if strategy is not None else None
    direction = parse_pair(push_direction, "--push-direction", "a direction DX,DY (e.g. 1,0)")
    sigma = parse_pair(basin_sigma, "--basin-sigma", "a range LO:HI (e.g. -0.8:1.6)")
    kn = parse_knots(knots)
    if any(k is None for k in kn):
        raise InputError("option --knots: the controller takes fixed knots (no ?)")
    check_executor(workers, scheduler)  # every option before the folder exists
    check_out(out, whole=False, json=json)
    if scheduler is not None:
        from ..sweep.executors import quiet_dask_logs

        quiet_dask_logs()
    walker = load_walker(robot, gait)
    plan = plan_robustness(
        walker, push_impulse=impulses, push_phase=phases, strategy=strategies, steps=steps,
        push_direction=direction, push_link=push_link, push_at=push_at,
        push_duration=push_duration, recovery_tol=recovery_tol, output_tol=output_tol, mu=mu,
        min_vertical_force=min_vertical_force, thruster=thruster, knots=kn,
        max_thrust=max_thrust, basin_grid=basin_grid, basin_sigma=sigma,
        basin_rate=basin_rate, basin_joint=basin_joint,
        uncertainty=str(uncertainty) if uncertainty is not None else None, samples=samples,
        rtol=rtol, atol=atol, slope=slope,
        terrain=None if terrain is None else str(terrain))
    warn(plan.warnings)
    folder = output.SweepFolder(out, {"identity": plan.identity, "sweep": "robustness",
                                      "file": f"{walker.robot.name} / {walker.gait.name}",
                                      "study": "robustness", "points": len(plan.tasks)},
                                records="trials")
    try:
        finished = folder.finished((t.key for t in plan.tasks), label="trial")
        warn(folder.notes)
        todo = len(plan.tasks) - len(finished)
        if todo:
            ensure_kernel(quiet)
        executor = task_executor(plan.tasks, STUDIES["push-trial"], {}, workers, scheduler,
                                 todo) if todo else None
        tally = {"recovered": 0, "other": 0}
        try:
            with progress(f"robustness ({len(finished)} of {len(plan.tasks)} done before)",
                          todo, quiet) as advance:
                def on_record(rec: dict) -> None:
                    folder.write_point(rec)
                    ok = rec["status"] == "ok" and rec["fields"].get("outcome") == "recovered"
                    tally["recovered" if ok else "other"] += 1
                    advance(1, note=f"{tally['recovered']} recovered")

                result = run_robustness(plan, executor=executor, finished=finished,
                                        on_record=on_record)
        finally:
            if executor is not None:
                executor.close()
        prov = output.provenance(walker.robot, walker.gait)
        if plan.uncertainty is not None:
            prov["uncertainty"] = output.file_ref(plan.uncertainty.source_file,
                                                  plan.uncertainty.source_sha256)
        doc = write_result(result, out, prov, json=json, formats=kinds, titles=titles,
                           into=folder)
    finally:
        folder.close()
    warn(doc["warnings"])
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out), markup=False)
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    rows = []
    for s in doc["strategies"]:
        b = s["reduced_basin"]
        rel = b["relative_to_zeta_star"]
        basin = (f"{fmt(rel['lower'], '.3g')}..{fmt(rel['upper'], '.3g')}" if b["exists"]
                 else "none")
        push = s["push"]
        sl = s.get("basin_slice")
        un = s.get("uncertainty")
        speed = (un or {}).get("speed")
        rows.append([s["label"], basin, fmt(push["recovered_fraction"], ".0%"),
                     fmt(push["mean_forward"], ".3g"), fmt(push["mean_backward"], ".3g"),
                     fmt(push["summary"], ".3g"),
                     fmt(sl["converging_fraction"], ".0%") if sl else "—",
                     fmt(un["success_rate"], ".0%") if un else "—",
                     f"{speed['mean']:.3f} ± {speed['std']:.3f}" if speed else "—"])
    on = f", on the slope {doc['slope']['angle']:.4g} rad" if doc.get("slope") else ""
    show_table(f"robustness: {doc['robot']['name']} / {doc['gait']['name']}{on}",
               [("strategy", False), ("reduced basin\n[zeta*]", False), ("pushes\nrecovered",
                                                                          True),
                ("forward\n[N s]", True), ("backward\n[N s]", True), ("summary\n[N s]", True),
                ("slice\nconverging", True), ("samples\nwalking", True),
                ("speed\n[m/s]", False)], rows)


def register(app: typer.Typer) -> None:
    @app.command("robustness", help=HELP, epilog=EPILOG)
    def robustness_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        push_impulse: Annotated[str, typer.Option(
            "--push-impulse", help="Push impulses [N s], signed along --push-direction: "
                                   "start:stop:step or a list.")] = "-30:30:2",
        push_phase: Annotated[str, typer.Option(
            "--push-phase", help="Phases s [1] of the first step at which the push acts, in "
                                 "[0, 1] (1: just before the impact).")] = "0:1:0.05",
        strategy: Annotated[str | None, typer.Option(
            "--strategy", help="Comma list of none, constant:F [N] (constant: the gait's "
                               "thrust: section), control, schedule:FILE (default: "
                               "none,control; none without thrusters).")] = None,
        steps: Annotated[int, typer.Option(
            "--steps", help="Steps per trial, the pushed one included.")] = 10,
        push_direction: Annotated[str, typer.Option(
            "--push-direction", metavar="DX,DY",
            help="Direction of a positive impulse in the world frame (normalised).")] = "1,0",
        push_link: Annotated[str | None, typer.Option(
            "--push-link", help="Link pushed (default: the stance link; its end is the "
                                "hip of a one-link stance leg, a kneed walker's stance "
                                "knee).")] = None,
        push_at: Annotated[float, typer.Option(
            "--push-at", help="Point of the link: (1 - at) joint + at end [1].")] = 1.0,
        push_duration: Annotated[float, typer.Option(
            "--push-duration", help="Duration [s] for the stance foot's check of the push: "
                                    "0 = impulsive (lifts or slips whatever its size); "
                                    "> 0 adds the stance force at the push over it "
                                    "(the simulated push stays impulsive).")] = 0.0,
        recovery_tol: Annotated[float, typer.Option(
            "--recovery-tol", help="Recovered: the last zeta^- within this fraction of the "
                                   "orbit's [1].")] = 0.05,
        output_tol: Annotated[float, typer.Option(
            "--output-tol", help="Recovered: max |y| over the last step at most this "
                                 "[rad].")] = 1e-3,
        mu: MuOpt = None,
        min_vertical_force: MinVerticalForceOpt = 0.0,
        thruster: ThrusterOpt = None,
        knots: Annotated[str, typer.Option(
            "--knots", help="Control: knots as fractions of the step, 0 first, 1 last.")
                         ] = "0,0.5,1",
        max_thrust: Annotated[float | None, typer.Option(
            "--max-thrust", help="Control: |thrust| bound [N] within the thruster's "
                                 "limits.")] = None,
        basin_grid: Annotated[int, typer.Option(
            "--basin-grid", help="Points per axis of the full-order basin slice (0: "
                                 "none).")] = 11,
        basin_sigma: Annotated[str, typer.Option(
            "--basin-sigma", metavar="LO:HI",
            help="Range of the relative change of sigma_N^+ in the slice [1].")] = "-0.8:1.6",
        basin_rate: Annotated[float, typer.Option(
            "--basin-rate", help="The slice's output rate runs over +-this [rad/s].")] = 0.5,
        basin_joint: Annotated[str | None, typer.Option(
            "--basin-joint", help="Actuated coordinate whose output rate the slice perturbs "
                                  "(default: the first).")] = None,
        uncertainty: Annotated[Path | None, typer.Option(
            "--uncertainty", metavar="FILE",
            help="Robot parameters as distributions (YAML): Monte-Carlo of the reduced "
                 "model.")] = None,
        samples: Annotated[int, typer.Option(
            "--samples", help="Robots drawn from --uncertainty (seeded by the file).")] = 100,
        rtol: Annotated[float, typer.Option("--rtol", help="Relative integration tolerance.")
                        ] = 1e-9,
        atol: Annotated[float, typer.Option("--atol", help="Absolute integration tolerance.")
                        ] = 1e-9,
        slope: SlopeOpt = 0.0,
        terrain: Annotated[Path | None, typer.Option(
            "--terrain", help="Terrain file (YAML, docs/files.md) every trial walks: a slope "
                              "and step heights (explicit or rough, seeded).")] = None,
        workers: Annotated[int | None, typer.Option(
            "--workers", help="Local worker processes (default: one per core; 1 runs in "
                              "this process).")] = None,
        scheduler: Annotated[str | None, typer.Option(
            "--scheduler", help="Run on an existing Dask cluster: tcp://HOST:PORT (or "
                                "tls://HOST:PORT).")] = None,
        out: Annotated[Path, typer.Option(
            "--out", "-o", help="The run's folder: written trial by trial and resumed, never "
                                "replaced as a whole.")] = Path("out/robustness"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            doc = run_robustness_command(
                robot, gait, push_impulse=push_impulse, push_phase=push_phase,
                strategy=strategy, steps=steps, push_direction=push_direction,
                push_link=push_link, push_at=push_at, push_duration=push_duration,
                recovery_tol=recovery_tol, output_tol=output_tol, mu=mu,
                min_vertical_force=min_vertical_force, thruster=thruster, knots=knots,
                max_thrust=max_thrust, basin_grid=basin_grid, basin_sigma=basin_sigma,
                basin_rate=basin_rate, basin_joint=basin_joint, uncertainty=uncertainty,
                samples=samples, rtol=rtol, atol=atol, workers=workers, scheduler=scheduler,
                out=out, quiet=quiet, json=json, formats=parse_formats(formats),
                titles=titles, slope=slope, terrain=terrain)
            if doc["counts"]["not_run"]:
                raise typer.Exit(1)
