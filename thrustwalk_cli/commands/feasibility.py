"""``thrustwalk feasibility``: ground-contact feasibility of thrust-assisted walking."""

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
    parse_values,
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
    QuietOpt,
    RobotArg,
    SlopeOpt,
    ThrusterOpt,
    ThrustOpt,
    TitlesOpt,
)

HELP = """Is this gait, with this thrust, physically walkable?

For each constant thrust value [N] (or one piecewise schedule from a gait-format YAML file, or
the gait's own thrust: section when neither is given): the exact ground reaction force
F_1(alpha) = Lambda_2 F + Lambda_1 zeta + Lambda_0 [N] along the periodic orbit, joint torques
[N m], swing-foot height [m], and the impact impulse [N s] with the trailing foot's lift-off
velocity [m/s] and the swing foot's touchdown velocity [m/s]. Feasible when a periodic orbit
exists, F_1^v >= the minimum vertical force, |F_1^h| <= mu F_1^v (the exact planar cone; an
inscribed pyramid mu/sqrt(2) is about 29 % too strict), the impact impulse lies in the cone,
the trailing foot lifts off, the swing foot stays above the ground and moves down at touchdown
(a strike, not a grazing contact). For a robot without thrusters the only thrust is 0 (the
default). Polynomial fits L_0, L_1, L_2 of the Lambdas give a second verdict
beside the exact one. An infeasible gait is a valid answer (exit 0); bad input exits 2, a tool
failure 1. With --slope GAMMA [rad, positive uphill] the walker is on a slope:
F^h and F^v are tangential and normal to the slope, the friction cone is the slope's, and
the cases give the climb rate speed*sin(GAMMA) beside the speed along the ground.

Writes DIR/feasibility.json, DIR/feasibility.md, DIR/grf.png/.pdf and
DIR/feasible_region.png/.pdf.
"""

EPILOG = ("Example: thrustwalk feasibility three_link three_link_walk --thrust 0:-50:-10 "
          "--mu 0.7 --out out/feasibility")


def run_feasibility(robot: str | None, gait: str | None, *, thrust: list[float] | None,
                    schedule: str | None, mu: float | None, min_vertical_force: float,
                    thruster: str | None, degree: int | None, fit_tol: float, out: Path,
                    quiet: bool, json: str | None = None, formats: set[str] | None = None,
                    titles: bool = False, slope: float = 0.0) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files.output import provenance
    from ..studies.feasibility import feasibility

    check_out(out, json=json)
    walker = load_walker(robot, gait)
    result = feasibility(walker, thrust, schedule=schedule, thruster=thruster, mu=mu,
                         min_vertical_force=min_vertical_force, degree=degree, fit_tol=fit_tol,
                         slope=slope)
    if thrust is None and schedule is None and result.schedule is not None and not quiet:
        warn(["no --thrust or --schedule given: the gait's own thrust: schedule is evaluated"])
    doc = write_result(result, out, provenance(walker.robot, walker.gait, schedule=schedule),
                       json=json, formats=formats, titles=titles)
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out, f"verdict: {doc['verdict']}; "), markup=False)
    warn([w for w in doc["warnings"] if w not in walker.warnings])  # the gait's: printed
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt
    from ..studies.feasibility import thrust_text

    rows = [[thrust_text(c["thrust"]), "feasible" if c["feasible"] else "INFEASIBLE",
             fmt(c["min_vertical_force"]), fmt(c["max_friction_ratio"]),
             fmt(c["liftoff_velocity"]), fmt(c["touchdown_velocity"])] for c in doc["cases"]]
    on = f", on the slope {doc['slope']['angle']:.4g} rad" if doc.get("slope") else ""
    show_table(f"feasibility: {doc['robot']['name']} / {doc['gait']['name']} "
               f"(mu = {doc['mu']:g}{on}, verdict: {doc['verdict']})",
               [("thrust [N]", False), ("verdict", False), ("min F^v\n[N]", True),
                ("max |F^h|/F^v\n[-]", True), ("lift-off\n[m/s]", True),
                ("touchdown\n[m/s]", True)], rows)
    con = console()
    for c in doc["cases"]:
        if not c["feasible"]:
            con.print(f"{thrust_text(c['thrust'])}: {c['reason']}", markup=False)


def register(app: typer.Typer) -> None:
    @app.command("feasibility", help=HELP, epilog=EPILOG)
    def feasibility_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        thrust: ThrustOpt = None,
        schedule: Annotated[str | None, typer.Option(
            "--schedule", help="Gait-format YAML file whose `thrust:` section (piecewise in "
                               "alpha, per thruster [N] or generalised [N m]) is evaluated "
                               "instead of --thrust.")] = None,
        mu: MuOpt = None,
        min_vertical_force: MinVerticalForceOpt = 0.0,
        thruster: ThrusterOpt = None,
        slope: SlopeOpt = 0.0,
        degree: Annotated[int | None, typer.Option(
            "--degree", help="Degree of the polynomial fits L_k (default: from --fit-tol).")
        ] = None,
        fit_tol: Annotated[float, typer.Option(
            "--fit-tol", help="Relative max error target of the fits L_k [-].")] = 1e-3,
        out: OutOpt = Path("out/feasibility"),
        json: JsonOpt = None,
        formats: FormatsOpt = "png,pdf,md",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            values = None if thrust is None else parse_values(thrust, "--thrust", "N")
            run_feasibility(robot, gait, thrust=values, schedule=schedule, mu=mu,
                            min_vertical_force=min_vertical_force, thruster=thruster,
                            degree=degree, fit_tol=fit_tol, out=out, quiet=quiet, json=json,
                            formats=parse_formats(formats, ("png", "pdf", "md")),
                            titles=titles, slope=slope)
