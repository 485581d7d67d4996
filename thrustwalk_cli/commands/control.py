"""``thrustwalk control``: step-to-step thrust control with certified contact (SPEC 11)."""

from __future__ import annotations

import sys
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
    parse_push,
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
    OutOpt,
    PushOpt,
    QuietOpt,
    RobotArg,
    SlopeOpt,
    TauOpt,
    TitlesOpt,
    WnOpt,
    XiOpt,
    thrust_model_opt,
    thrusters_opt,
)

HELP = """Step-to-step thrust control with certified contact, in closed loop with the
full-order simulation.

At every impact the controller measures zeta^- [kg^2 m^4/s^2] and solves one small convex QP:
the next step's thrust on the knots (force mode) so that the next zeta^- meets the
reference, with least effort (and change from the previous step), subject to the friction cone
|F_1^h| <= mu F_1^v and F_1^v >= the minimum vertical force [N] on an alpha grid and between its
points (the plan's worst points polished, cutting planes added until they hold to 1e-9; exact
Lambda terms, or --terms fitted: the polynomials L_k with their error bound added to the
margin), zeta(alpha) >= --zeta-min, the thrust limits of the robot file [N] and --rate-limit [N
per step]. A reference beyond the limits is met as closely as the constraints allow and
reported as saturated; a step whose constraints cannot hold is reported infeasible. With
--objective energy each plan, tracking first, minimises the driven thrusters' input energy
[J] over the predicted step (their power: models) under the same constraints instead.

References: --reference speed [m/s] or zeta [kg^2 m^4/s^2] with --profile step:value,... (held,
or --ramp), or nominal (the zero-thrust orbit). A speed is tracked as a speed: its zeta^-
reference is the controller's own steady state that walks at it, and the tracking error is the
speed's. Disturbances: --push STEP:PHASE:PX[:PY] [N s] at
the end of the stance link (the hip of a one-link stance leg, a kneed walker's stance knee),
--plant-scale NAME=FACTOR (robot parameters of the plant), --noise R (uniform relative
error of the measured zeta^-, --seed). Slow thrusters (--thrust-model first-order/second-order):
the controller uses the thruster's linear response; the same plant under a controller that
ignores the lag is run for comparison. Certificate: per step the predicted and realised margins;
a step outside the prediction's error bound is flagged.

With --terrain FILE (docs/files.md, as simulate --terrain) the plant walks steps or rough
ground: step k's swing foot lands h_k above its stance foot; the controller's step model stays
that of the plane ground and meets the steps through the measured zeta^-. Each step records its
terrain_height.

Writes DIR/control.json, DIR/control_steps.csv and the figures speed_tracking, thrust_schedule,
contact_margin (PNG/PDF); --export FILE the controller's data (JSON with units).
"""

EPILOG = ("Example: thrustwalk control three_link three_link_walk --reference speed --profile "
          "0:0.8,10:1.4,25:1.0 --knots 0,0.5,1 --steps 40 --mu 0.7 --out out/control")


def parse_profile(text: str | None) -> list[tuple[float, float]]:
    """``"0:0.8,10:1.4"`` -> ``[(0, 0.8), (10, 1.4)]``."""
    if text is None:
        return []
    out = []
    for item in text.split(","):
        parts = item.strip().split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            out.append((float(parts[0]), float(parts[1])))
        except ValueError:
            raise InputError(f"option --profile: {item.strip()!r} is not step:value (use e.g. "
                             "0:0.8,10:1.4,25:1.0)") from None
    return out


def parse_scale(items: list[str] | None) -> dict[str, float]:
    """``NAME=FACTOR`` -> {name: factor}."""
    out = {}
    for item in items or []:
        name, sep, val = item.partition("=")
        try:
            if not sep or not name.strip():
                raise ValueError
            out[name.strip()] = float(val)
        except ValueError:
            raise InputError(f"option --plant-scale: {item!r} is not NAME=FACTOR (e.g. "
                             "MT=1.1)") from None
    return out


def run_control(robot: str | None, gait: str | None, *, reference: str, profile: str | None,
                ramp: bool, knots: str, steps: int, thrust_model: str, wn: float, xi: float,
                tau: float, thrusters: list[str] | None, push: list[str] | None,
                plant_scale: list[str] | None, noise: float, seed: int, mu: float | None,
                min_vertical_force: float, zeta_min: float | None, max_thrust: float | None,
                rate_limit: float | None, tracking_weight: float | None, effort_weight: float,
                rate_weight: float, terms: str, fit_tol: float, points: int, out: Path,
                quiet: bool, export: Path | None = None, json: str | None = None,
                formats: set[str] | None = None, titles: bool = False,
                slope: float = 0.0, terrain: Path | None = None,
                objective: str = "effort") -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files import output
    from ..studies.control import control

    prof = parse_profile(profile)
    pushes = parse_push(push)
    scale = parse_scale(plant_scale)
    kn = parse_knots(knots)
    if any(k is None for k in kn):
        raise InputError("option --knots: control takes fixed knots (no ?)")
    check_out(out)
    if export is not None and (export.is_dir() or (export.parent.exists()
                                                    and not export.parent.is_dir())):
        raise InputError(f"option --export: {export} is not a file path")
    walker = load_walker(robot, gait)
    runs = 2 + (thrust_model != "ideal")
    args = dict(reference=reference, profile=prof, ramp=ramp, knots=kn, steps=steps,
                thrust_model=thrust_model, wn=wn, xi=xi, tau=tau, thruster=thrusters,
                push=pushes, plant_scale=scale, noise=noise, seed=seed, mu=mu,
                min_vertical_force=min_vertical_force, zeta_min=zeta_min,
                max_thrust=max_thrust, rate_limit=rate_limit, tracking_weight=tracking_weight,
                effort_weight=effort_weight, rate_weight=rate_weight, terms=terms,
                fit_tol=fit_tol, points=points, slope=slope,
                terrain=None if terrain is None else str(terrain), objective=objective)
    control(walker, **args, check_only=True)  # every option before the kernel is compiled
    ensure_kernel(quiet)
    with progress("controlled steps", runs * steps, quiet) as advance:
        result = control(walker, **args, progress=advance)
    prov = output.provenance(walker.robot, walker.gait)
    doc = write_result(result, out, prov, json=json, formats=formats, titles=titles)
    if export is not None:
        output.write_json(export, {"provenance": prov, **result.export_document()})
    if doc["status"] == "warning":
        warn([f"control: {doc['reason']}"])
    elif doc["status"] != "ok":
        warn([f"control: {doc['status']}: {doc['reason']}"])
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out) + (f"; {export}" if export is not None else ""),
                        markup=False)
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    s = doc["summary"]
    un = doc["uncontrolled"]
    lag = doc["lag_ignored"]
    rows = [["controlled", str(s["steps_completed"]), fmt(s["final_tracking_error"], ".2e"),
             fmt(doc["steps"][-1]["speed"] if doc["steps"] else None),
             f"{1e6 * s['qp_time_median']:.0f}" if s["qp_time_median"] else "—",
             doc["status"]]]
    if un is not None:
        rows.append(["uncontrolled", str(un["steps_completed"]), "—",
                     fmt(un["speed"][-1] if un["speed"] else None), "—",
                     "ok" if un["success"] else un["failure"]])
    if lag is not None:
        err = abs(lag["mismatch"][-1]["relative_mismatch"]) if lag["mismatch"] else None
        rows.append(["lag ignored", str(lag["steps_completed"]), fmt(err, ".2e"),
                     fmt(lag["speed"][-1] if lag["speed"] else None), "—",
                     "ok" if lag["success"] else lag["failure"]])
    on = f", on the slope {doc['slope']['angle']:.4g} rad" if doc.get("slope") else ""
    obj = ""
    if doc["settings"].get("objective") == "energy":
        e = s["planned_input_energy"]
        unit = s.get("planned_input_energy_unit", "J")
        obj = ", least input energy" + (f": {e:.4g} {unit} planned" if e is not None else "")
    show_table(f"control: {doc['robot']['name']} / {doc['gait']['name']}{on} "
               f"({doc['settings']['reference']}, {doc['settings']['thrust_model']} thrust"
               f"{obj})",
               [("walker", False), ("steps", True), ("final error\n[-]", True),
                ("final speed\n[m/s]", True), ("QP median\n[us]", True), ("status", False)],
               rows)


def register(app: typer.Typer) -> None:
    @app.command("control", help=HELP, epilog=EPILOG)
    def control_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        reference: Annotated[str, typer.Option(
            "--reference", help="speed [m/s] or zeta [kg^2 m^4/s^2] (with --profile), or "
                                "nominal (the zero-thrust orbit).")] = "speed",
        profile: Annotated[str | None, typer.Option(
            "--profile", help="Reference over steps, step:value,... with steps increasing "
                              "(e.g. 0:0.8,10:1.4,25:1.0).")] = None,
        ramp: Annotated[bool, typer.Option(
            "--ramp", help="Ramp linearly between profile points (default: hold).")] = False,
        knots: Annotated[str, typer.Option(
            "--knots", help="Knots as fractions of the step, 0 first, 1 last (0,1 for a "
                            "thruster with dynamics).")] = "0,0.5,1",
        steps: Annotated[int, typer.Option("--steps", help="Steps to walk.")] = 40,
        thrust_model: Annotated[str, thrust_model_opt(
            "ideal: the thrust is the command; first-order uses --tau, second-order --wn "
            "and --xi", piecewise=False)] = "ideal",
        wn: WnOpt = 20.0,
        xi: XiOpt = 1.0,
        tau: TauOpt = 0.05,
        thruster: Annotated[list[str] | None, thrusters_opt("the controller drives")
                            ] = None,
        push: PushOpt = None,
        plant_scale: Annotated[list[str] | None, typer.Option(
            "--plant-scale", metavar="NAME=FACTOR",
            help="Scale a robot-file parameter of the plant (e.g. MT=1.1; repeatable): the "
                 "controller keeps the model.")] = None,
        noise: Annotated[float, typer.Option(
            "--noise", help="Relative bound of the uniform error of the measured zeta^- "
                            "[1].")] = 0.0,
        seed: Annotated[int, typer.Option("--seed", help="Seed of the measurement noise.")
                        ] = 0,
        mu: MuOpt = None,
        min_vertical_force: MinVerticalForceOpt = 0.0,
        zeta_min: Annotated[float | None, typer.Option(
            "--zeta-min", help="Least zeta along a step [kg^2 m^4/s^2] (default 1 % of the "
                               "nominal zeta*).")] = None,
        max_thrust: Annotated[float | None, typer.Option(
            "--max-thrust", help="|thrust| bound [N] within the thruster's limits.")] = None,
        rate_limit: Annotated[float | None, typer.Option(
            "--rate-limit", help="Largest change of a thrust value from one step to the next "
                                 "[N].")] = None,
        tracking_weight: Annotated[float | None, typer.Option(
            "--tracking-weight", help="Weight w of the tracking term [1] (default: tracking "
                                      "first, deadbeat when reachable).")] = None,
        effort_weight: Annotated[float, typer.Option(
            "--effort-weight", help="Weight of the thrust effort [1].")] = 1.0,
        rate_weight: Annotated[float, typer.Option(
            "--rate-weight", help="Weight of the change from the previous step [1].")] = 0.0,
        terms: Annotated[str, typer.Option(
            "--terms", help="exact Lambda terms, or fitted polynomials L_k with their error "
                            "bound added to the margins.")] = "exact",
        fit_tol: Annotated[float, typer.Option(
            "--fit-tol", help="Relative max error of the fitted L_k [1].")] = 1e-3,
        points: Annotated[int, typer.Option(
            "--points", help="Alpha grid points of the contact constraints.")] = 401,
        objective: Annotated[str, typer.Option(
            "--objective", help="effort: least thrust effort (the QP); energy: least input "
                                "energy of the driven thrusters over the predicted step "
                                "(their power: models), tracking first.")] = "effort",
        export: Annotated[Path | None, typer.Option(
            "--export", metavar="FILE", help="Also write the controller's data (knots, "
                                             "delta_zero^2, V_0(alpha_f), Gamma_j, L_k fits, "
                                             "QP rows) as JSON with units.")] = None,
        slope: SlopeOpt = 0.0,
        terrain: Annotated[Path | None, typer.Option(
            "--terrain", help="Terrain file (YAML, docs/files.md) the plant walks: a slope "
                              "and step heights (explicit or rough, seeded).")] = None,
        out: OutOpt = Path("out/control"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            doc = run_control(
                robot, gait, reference=reference, profile=profile, ramp=ramp, knots=knots,
                steps=steps, thrust_model=thrust_model, wn=wn, xi=xi, tau=tau,
                thrusters=thruster, push=push, plant_scale=plant_scale, noise=noise,
                seed=seed, mu=mu, min_vertical_force=min_vertical_force, zeta_min=zeta_min,
                max_thrust=max_thrust, rate_limit=rate_limit,
                tracking_weight=tracking_weight, effort_weight=effort_weight,
                rate_weight=rate_weight, terms=terms, fit_tol=fit_tol, points=points,
                out=out, quiet=quiet, export=export, json=json,
                formats=parse_formats(formats), titles=titles, slope=slope,
                terrain=terrain, objective=objective)
        if doc["failure"] in ("integrator", "controller"):
            sys.stderr.write(f"error: an integrator or controller failure ended the run (see "
                             f"{out}/control.json)\n")
            raise typer.Exit(1)
