"""``thrustwalk rough-ground``: the mean first passage time on rough ground against the
roughness sigma per thrust strategy (SPEC 14), by Monte-Carlo on the sweep engine (resumable)
and by the mesh Markov chain, with their agreement."""

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
from .robustness import parse_strategies

HELP = """How much rough ground does thrust buy? The mean first passage time (MFPT: expected
steps attempted up to and including the one that fails) against the roughness sigma [m], the
standard deviation of i.i.d. step heights (--distribution normal, or uniform on
+-sqrt(3) sigma), one thrust strategy beside the other (--strategy, comma list: none,
constant:F [N], control: the step-to-step controller, schedule:FILE).

Two estimates. Monte-Carlo: --trials full-order runs per (strategy, sigma) from the strategy's
fixed point, each on its own seeded terrain (--seed; trial t's standard draws are the same for
every sigma and strategy), until a failure (fell, stopped, scuffed, lifted, slipped,
missed_footing past s_max) or --cap steps (censored, counted with its steps): MFPT = steps
attempted / failures (geometric MLE) with its exact 95 % interval (Clopper-Pearson). Mesh
chain: the pre-impact state reduced to (zeta^-, height of its ground), one-step full-order
simulations from --mesh + 1 values of zeta^- times the impact heights, onto --terrain-samples + 1
heights (failure edges found by bisection), integrated over the
height's density per sigma: MFPT = 1/(1 - lambda_2), the expected steps from the fixed point,
and an uncertainty from half the mesh or half the samples. Agreement: the mesh's value inside
the Monte-Carlo interval. Headline: the sigma each strategy tolerates at an MFPT of --target
steps against none.

With --slope GAMMA [rad, positive uphill] every run and the mesh chain walk the slope (as
simulate --slope: the slope frame, gravity and world-frame thrusters turned); the step heights
are on top of it, normal to the slope. The JSON gains the slope block.

Every trial is a point of the sweep engine: --workers local processes (default: one per core)
or the Dask cluster of --scheduler. DIR is written incrementally (each trial's record in
DIR/trials/); run the same command again to resume. Writes DIR/rough_ground.json, mfpt.csv,
trials.csv and the figure mfpt (PNG/PDF).
"""

EPILOG = ("Example: thrustwalk rough-ground three_link three_link_walk --sigma "
          "0.002:0.005:0.0005 --strategy none,constant:-20 --trials 50 --cap 2000 "
          "--out out/rough")


def run_rough_ground_command(
        robot: str | None, gait: str | None, *, sigma: str, strategy: str | None, trials: int,
        cap: int, seed: int, distribution: str, mesh: int, terrain_samples: int,
        s_max: float, target: float, mu: float | None, min_vertical_force: float,
        thruster: str | None, knots: str, max_thrust: float | None, rtol: float, atol: float,
        workers: int | None, scheduler: str | None, out: Path, quiet: bool,
        json: str | None = None, formats: set[str] | None = None, titles: bool = False,
        slope: float = 0.0) -> dict:
    """Plain function behind the command; returns the ``rough_ground.json`` document."""
    from ..files import output
    from ..studies.rough_ground import mesh_chain, plan_rough_ground, run_rough_ground
    from ..studies.sweep import check_executor, task_executor
    from ..studies.sweep_studies import STUDIES

    kinds = {"csv", "png", "pdf"} if formats is None else formats
    sigmas = parse_values(sigma, "--sigma", "m")
    strategies = parse_strategies(strategy) if strategy is not None else None
    kn = parse_knots(knots)
    if any(k is None for k in kn):
        raise InputError("option --knots: the controller takes fixed knots (no ?)")
    check_executor(workers, scheduler)  # every option before the folder exists
    check_out(out, whole=False, json=json)
    if scheduler is not None:
        from ..sweep.executors import quiet_dask_logs

        quiet_dask_logs()
    walker = load_walker(robot, gait)
    plan = plan_rough_ground(
        walker, sigma=sigmas, strategy=strategies, trials=trials, cap=cap, seed=seed,
        distribution=distribution, mesh=mesh, terrain_samples=terrain_samples, s_max=s_max,
        mu=mu, min_vertical_force=min_vertical_force, thruster=thruster, knots=kn,
        max_thrust=max_thrust, target=target, rtol=rtol, atol=atol, slope=slope)
    warn(plan.warnings)
    folder = output.SweepFolder(out, {"identity": plan.identity, "sweep": "rough-ground",
                                      "file": f"{walker.robot.name} / {walker.gait.name}",
                                      "study": "rough-ground", "points": len(plan.tasks)},
                                records="trials")
    try:
        finished = folder.finished((t.key for t in plan.tasks), label="trial")
        warn(folder.notes)
        todo = len(plan.tasks) - len(finished)
        ensure_kernel(quiet)
        executor = task_executor(plan.tasks, STUDIES["rough-trial"], {}, workers, scheduler,
                                 todo) if todo else None
        tally = {"failed": 0}
        try:
            n_mesh = len(plan.strategies) * plan.settings["mesh"]["points"]
            with progress("mesh chain", n_mesh, quiet) as mesh_advance:
                meshes = [mesh_chain(plan, k, lambda n: mesh_advance(n))
                          for k in range(len(plan.strategies))]
            with progress(f"rough ground ({len(finished)} of {len(plan.tasks)} trials done "
                          "before)", todo, quiet) as advance:
                def on_record(rec: dict) -> None:
                    folder.write_point(rec)
                    tally["failed"] += bool(rec["status"] == "ok" and rec["fields"]["failed"])
                    advance(1, note=f"{tally['failed']} failed before the cap")

                result = run_rough_ground(plan, executor=executor, finished=finished,
                                          on_record=on_record, meshes=meshes)
        finally:
            if executor is not None:
                executor.close()
        prov = output.provenance(walker.robot, walker.gait)
        doc = write_result(result, out, prov, json=json, formats=kinds, titles=titles,
                           into=folder)
    finally:
        folder.close()
    warn(doc["warnings"])
    if not quiet and json != "-":
        _table(doc)
        for line in doc["headline"]["text"]:
            console().print(line, markup=False)
        console().print(wrote_line(out), markup=False)
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    rows = []
    for s in doc["strategies"]:
        for r in s["sigmas"]:
            mc, m = r["monte_carlo"], r["mesh"] or {}
            ci = (f"{fmt(mc['ci_lower'], '.3g')}..{fmt(mc['ci_upper'], '.3g')}"
                  if mc["ci_lower"] is not None else "—")
            rows.append([s["label"], f"{1e3 * r['sigma']:.3g}", fmt(mc["mfpt"], ".3g"), ci,
                         f"{mc['failures']}/{mc['trials']}", fmt(m.get("mfpt"), ".3g"),
                         fmt(m.get("uncertainty"), ".2g"), r["agreement"]])
    show_table(f"rough ground: {doc['robot']['name']} / {doc['gait']['name']}",
               [("strategy", False), ("sigma\n[mm]", True), ("MC MFPT\n[steps]", True),
                ("MC 95 %\n[steps]", False), ("failed/\ntrials", True),
                ("mesh MFPT\n[steps]", True), ("mesh\n+-", True), ("agreement", False)], rows)


def register(app: typer.Typer) -> None:
    @app.command("rough-ground", help=HELP, epilog=EPILOG)
    def rough_ground_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        sigma: Annotated[str, typer.Option(
            "--sigma", help="Roughness sigma [m], the standard deviation of the step heights: "
                            "start:stop:step or a list.")] = "0.002:0.005:0.0005",
        strategy: Annotated[str | None, typer.Option(
            "--strategy", help="Comma list of none, constant:F [N] (constant: the gait's "
                               "thrust: section), control, schedule:FILE (default: "
                               "none,control; none without thrusters).")] = None,
        trials: Annotated[int, typer.Option(
            "--trials", help="Monte-Carlo runs per strategy and sigma.")] = 50,
        cap: Annotated[int, typer.Option(
            "--cap", help="Steps per run at most (a run reaching it is censored).")] = 2000,
        seed: Annotated[int, typer.Option("--seed", help="Seed of the terrains.")] = 0,
        distribution: Annotated[str, typer.Option(
            "--distribution", help="normal, or uniform on +-sqrt(3) sigma.")] = "normal",
        mesh: Annotated[int, typer.Option(
            "--mesh", help="Mesh intervals in zeta^- (even; its half is the refinement "
                           "check).")] = 20,
        terrain_samples: Annotated[int, typer.Option(
            "--terrain-samples", help="Height intervals of the mesh's one-step map (even; "
                                      "over the heights a step completes on, within "
                                      "+-6 sigma_max).")] = 24,
        s_max: Annotated[float, typer.Option(
            "--s-max", help="Missed footing past this phase s without a touchdown.")] = 1.3,
        target: Annotated[float, typer.Option(
            "--target", help="The headline's MFPT [steps].")] = 1000.0,
        mu: MuOpt = None,
        min_vertical_force: MinVerticalForceOpt = 0.0,
        slope: SlopeOpt = 0.0,
        thruster: ThrusterOpt = None,
        knots: Annotated[str, typer.Option(
            "--knots", help="Control: knots as fractions of the step, 0 first, 1 last.")
                         ] = "0,0.5,1",
        max_thrust: Annotated[float | None, typer.Option(
            "--max-thrust", help="Control: |thrust| bound [N] within the thruster's "
                                 "limits.")] = None,
        rtol: Annotated[float, typer.Option("--rtol", help="Relative integration tolerance.")
                        ] = 1e-9,
        atol: Annotated[float, typer.Option("--atol", help="Absolute integration tolerance.")
                        ] = 1e-9,
        workers: Annotated[int | None, typer.Option(
            "--workers", help="Local worker processes (default: one per core; 1 runs in "
                              "this process).")] = None,
        scheduler: Annotated[str | None, typer.Option(
            "--scheduler", help="Run on an existing Dask cluster: tcp://HOST:PORT (or "
                                "tls://HOST:PORT).")] = None,
        out: Annotated[Path, typer.Option(
            "--out", "-o", help="The run's folder: written trial by trial and resumed, never "
                                "replaced as a whole.")] = Path("out/rough_ground"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            doc = run_rough_ground_command(
                robot, gait, sigma=sigma, strategy=strategy, trials=trials, cap=cap,
                seed=seed, distribution=distribution, mesh=mesh,
                terrain_samples=terrain_samples, s_max=s_max, target=target, mu=mu,
                min_vertical_force=min_vertical_force, thruster=thruster, knots=knots,
                max_thrust=max_thrust, rtol=rtol, atol=atol, workers=workers,
                scheduler=scheduler, out=out, quiet=quiet, json=json,
                formats=parse_formats(formats), titles=titles, slope=slope)
            if doc["counts"]["not_run"]:
                raise typer.Exit(1)
