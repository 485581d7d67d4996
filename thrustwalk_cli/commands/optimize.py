"""``thrustwalk optimize``: minimum-effort thrust schedule as an exact convex QP."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import (
    check_out,
    cli_errors,
    console,
    load_walker,
    parse_formats,
    parse_knots,
    show_table,
    write_result,
)
from .options import (
    FormatsOpt,
    GaitArg,
    JsonOpt,
    MinVerticalForceOpt,
    MuOpt,
    OutOpt,
    QuietOpt,
    RobotArg,
    SlopeOpt,
    TargetSpeedOpt,
    TitlesOpt,
)

HELP = """The least thrust that reaches a target while staying walkable.

Chooses one thrust value per knot interval (force mode: newtons on one thruster; generalized
mode: T_j on q_N in N m) minimising sum_j w_j x_j^2 (w_j = alpha-length [rad] or nominal time
[s] of interval j) subject to: the fixed-point equation for the target zeta* [kg^2 m^4/s^2]
(or the zeta* that gives the target speed [m/s]), F_1^v >= the minimum vertical force [N] and
|F_1^h| <= mu F_1^v on an alpha grid, zeta(alpha) >= zeta_min, and |x_j| <= max thrust. All
constraints are linear in the thrust values: the convex QP is solved exactly (LP feasibility by
HiGHS, least-distance QP by NNLS, KKT conditions verified). An infeasible problem is reported
with the violated constraint family (exit 0); bad input exits 2, a tool failure 1.

--objective energy minimises the thruster's input energy per step [J] instead (the
thruster needs a `power:` model in the robot file; a fuel model without heating value: its fuel
mass [kg]) under the same constraints: sequential convex programming on the orbit's time
weights, each convex problem solved exactly; the energy is re-computed on the schedule's orbit
and compared with the minimum-effort schedule's.

--slope GAMMA [rad, positive uphill] solves the problem on a slope: the fixed point
and the contact terms of the slope frame, the target speed along the ground; the JSON gains
the slope block and the climb rate, the gait file's header the slope.

Writes DIR/optimal_schedule.json, DIR/<gait>_optimal.yaml (the gait with the resulting
`thrust:` section) and DIR/optimal_orbit.png/.pdf.
"""

EPILOG = ("Example: thrustwalk optimize three_link three_link_walk --knots 0:1:0.25 "
          "--target-speed 1.0 --max-thrust 30 --mu 0.7 --out out/optimize")


def run_optimize(robot: str | None, gait: str | None, *, knots: list[float | None],
                 target_speed: float | None, target_zeta: float | None,
                 max_thrust: float | None, mu: float | None, min_vertical_force: float,
                 zeta_min: float | None, thruster: str | None, mode: str, weights: str,
                 out: Path, quiet: bool, json: str | None = None,
                 formats: set[str] | None = None, titles: bool = False,
                 objective: str = "effort", slope: float = 0.0) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from dataclasses import replace

    from ..files.gait_file import robot_reference
    from ..files.output import provenance
    from ..studies.optimize import optimize_schedule

    check_out(out, json=json)
    walker = load_walker(robot, gait)
    result = optimize_schedule(
        walker, knots=knots, target_zeta=target_zeta, target_speed=target_speed,
        max_thrust=max_thrust, mu=mu, min_vertical_force=min_vertical_force,
        zeta_min=zeta_min, thruster=thruster, mode=mode, weights=weights, objective=objective,
        slope=slope)
    # the gait file names its robot relative to its own folder (as design-gait's do), so that
    # it loads after the folder moves and from a sweep file beside the robot
    given = robot if robot is not None else robot_reference(walker.robot)
    result = replace(result, robot_ref=robot_reference(walker.robot, given,
                                                       out / result.gait_file))
    doc = write_result(result, out, provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles)
    if not quiet and json != "-":
        _summary(doc)
        console().print(f"wrote {', '.join(f'{out}/{f}' for f in doc['files'])}",
                        markup=False)
    return doc


def _summary(doc: dict) -> None:
    c = console()
    if not doc["feasible"]:
        c.print(f"INFEASIBLE — {doc['reason']}", markup=False)
        return
    en = doc.get("objective_details")
    if en is None:
        c.print(f"optimal schedule ({doc['mode']} mode): objective {doc['objective']:.4g}, "
                f"zeta* = {doc['zeta_star']:.6g} kg^2 m^4/s^2, speed {doc['speed']:.4g} m/s",
                markup=False)
    else:
        word = ("energy-optimal schedule" if doc["status"] == "optimal"
                else f"NOT OPTIMAL ({doc['status']})")
        c.print(f"{word}: {_num(en['orbit_energy'])} {en['unit']} ({en['quantity']}), "
                f"zeta* = {doc['zeta_star']:.6g} kg^2 m^4/s^2, speed {doc['speed']:.4g} m/s; "
                f"fixed point of the time weights: {en['iterations']} iteration(s), last "
                f"change {en['final_change']:.2g}", markup=False)
        if doc["status"] != "optimal":
            c.print(doc["reason"], markup=False)
        eff = en["effort_optimal"]
        key = [k for k in eff if k not in ("feasible", "values", "objective", "method")][0]
        if en["saving_vs_effort_optimal"] is not None:
            c.print(f"the minimum-effort schedule spends {_num(eff[key])} {en['unit']}: "
                    f"{100 * en['saving_vs_effort_optimal']:.3g} % saved", markup=False)
        else:
            c.print(f"the minimum-effort schedule's {key.replace('_', ' ')}: "
                    f"{_num(eff[key])}", markup=False)
    k = doc["knots_fraction"]
    show_table("thrust per knot interval",
               [("interval\n[fraction of step]", False), (f"thrust\n[{doc['unit']}]", True)],
               [[f"{k[i]:g} – {k[i + 1]:g}", f"{v:.4g}"] for i, v in enumerate(doc["values"])])
    act = doc["active_constraints"]
    c.print(f"active constraints: {len(act)}"
            + ("" if not act else " (" + ", ".join(sorted({a['family'] for a in act})) + ")"),
            markup=False)


def _num(v) -> str:
    return "not computed" if v is None else f"{v:.6g}"


def register(app: typer.Typer) -> None:
    @app.command("optimize", help=HELP, epilog=EPILOG)
    def optimize_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        knots: Annotated[str, typer.Option(
            "--knots", help="Knots as fractions of the step [-], 0 first and 1 last: a comma "
                            "list or start:stop:step.")] = "0:1:0.25",
        target_speed: TargetSpeedOpt = None,
        target_zeta: Annotated[float | None, typer.Option(
            "--target-zeta", help="Target fixed point zeta* [kg^2 m^4/s^2].")] = None,
        max_thrust: Annotated[float | None, typer.Option(
            "--max-thrust", help="Bound |x_j| <= this [N] (force mode; default: the thruster's "
                                 "limits) or [N m] (generalized mode, required).")] = None,
        mu: MuOpt = None,
        min_vertical_force: MinVerticalForceOpt = 0.0,
        zeta_min: Annotated[float | None, typer.Option(
            "--zeta-min", help="Lower bound on zeta(alpha) along the step [kg^2 m^4/s^2] "
                               "(default: 1 % of zeta*).")] = None,
        thruster: Annotated[str | None, typer.Option(
            "--thruster", help="Thruster to schedule in force mode (default: the first).")
        ] = None,
        mode: Annotated[str, typer.Option(
            "--mode", help="force (thrust [N]) or generalized (T_j on q_N [N m]).")] = "force",
        weights: Annotated[str, typer.Option(
            "--weights", help="Effort weights w_j: alpha (interval length [rad]) or time "
                              "(nominal time in the interval [s]).")] = "alpha",
        objective: Annotated[str, typer.Option(
            "--objective", help="effort (sum_j w_j x_j^2) or energy (the thruster's input "
                                "energy per step [J], from its `power:` model).")] = "effort",
        slope: SlopeOpt = 0.0,
        out: OutOpt = Path("out/optimize"),
        json: JsonOpt = None,
        formats: FormatsOpt = "png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            run_optimize(robot, gait, knots=parse_knots(knots), target_speed=target_speed,
                         target_zeta=target_zeta, max_thrust=max_thrust, mu=mu,
                         min_vertical_force=min_vertical_force, zeta_min=zeta_min,
                         thruster=thruster, mode=mode, weights=weights, out=out, quiet=quiet,
                         json=json, formats=parse_formats(formats, ("png", "pdf")),
                         titles=titles, objective=objective, slope=slope)
