"""``thrustwalk feasibility``: ground-contact feasibility of thrust-assisted walking (SPEC 5)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import cli_errors, console, figure_formats, parse_values, write_result
from .options import EpsOpt, FormatsOpt, GaitArg, MuOpt, OutOpt, QuietOpt, RobotArg

HELP = """Is this gait, with this thrust, physically walkable?

For each constant thrust value [N] (or one piecewise schedule from a gait-format YAML file):
the exact ground reaction force F_1(alpha) = Lambda_2 F + Lambda_1 zeta + Lambda_0 [N] along the
periodic orbit, joint torques [N m], swing-foot height [m], and the impact impulse [N s] with
the trailing foot's lift-off velocity [m/s]. Feasible when a periodic orbit exists,
F_1^v >= eps, |F_1^h| <= mu F_1^v (the exact planar cone; an inscribed pyramid mu/sqrt(2) is
about 29 % too strict), the impact impulse lies in the cone and the trailing foot lifts off.
Polynomial fits L_0, L_1, L_2 of the Lambdas give a second verdict beside the exact one.
An infeasible gait is a valid answer (exit 0); bad input exits 2, a tool failure 1.

Writes DIR/feasibility.json, DIR/feasibility.md, DIR/grf.png/.pdf and
DIR/feasible_region.png/.pdf.
"""

EPILOG = ("Example: thrustwalk feasibility three_link three_link_walk --thrust 0:-50:-10 "
          "--mu 0.7 --out out/feasibility")

DEFAULT_THRUST = "0:-50:-10"  # the study's default values, as the help shows them


def run_feasibility(robot: str, gait: str, *, thrust: list[float] | None, schedule: str | None,
                    mu: float | None, eps: float, thruster: str | None, degree: int | None,
                    fit_tol: float, out: Path, quiet: bool,
                    formats: str = "png,pdf") -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files.output import provenance
    from ..studies.feasibility import feasibility
    from ..walker import load_walker

    walker = load_walker(robot, gait)
    result = feasibility(walker, thrust, schedule=schedule, thruster=thruster, mu=mu, eps=eps,
                         degree=degree, fit_tol=fit_tol)
    doc = write_result(result, out, provenance(walker.robot, walker.gait, schedule=schedule),
                       formats=figure_formats(formats))
    if not quiet:
        _table(doc)
    return doc


def _table(doc: dict) -> None:
    from rich.table import Table

    from ..studies.feasibility import thrust_text
    from ..studies.records import fmt

    t = Table(title=f"feasibility: {doc['robot']['name']} / {doc['gait']['name']} "
                    f"(mu = {doc['mu']:g}, verdict: {doc['verdict']})")
    for col in ("thrust [N]", "verdict", "min F^v [N]", "max |F^h|/F^v", "lift-off [m/s]"):
        t.add_column(col, overflow="fold")
    for c in doc["cases"]:
        t.add_row(thrust_text(c["thrust"]), "feasible" if c["feasible"] else "INFEASIBLE",
                  fmt(c["min_vertical_force"]), fmt(c["max_friction_ratio"]),
                  fmt(c["liftoff_velocity"]))
    con = console()
    con.print(t)
    for c in doc["cases"]:
        if not c["feasible"]:
            con.print(f"{thrust_text(c['thrust'])}: {c['reason']}", markup=False)


def register(app: typer.Typer) -> None:
    @app.command("feasibility", help=HELP, epilog=EPILOG)
    def feasibility_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = "three_link_walk",
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help=f"Constant thrust values [N]: start:stop:step or a comma list "
                             f"(default {DEFAULT_THRUST}).")] = None,
        schedule: Annotated[str | None, typer.Option(
            "--schedule", help="Gait-format YAML file whose `thrust:` section (piecewise in "
                               "alpha, per thruster [N] or generalised [N m]) is evaluated "
                               "instead of --thrust.")] = None,
        mu: MuOpt = None,
        eps: EpsOpt = 0.0,
        thruster: Annotated[str | None, typer.Option(
            "--thruster", help="Thruster that --thrust drives (default: the first).")] = None,
        degree: Annotated[int | None, typer.Option(
            "--degree", help="Degree of the polynomial fits L_k (default: from --fit-tol).")
        ] = None,
        fit_tol: Annotated[float, typer.Option(
            "--fit-tol", help="Relative max error target of the fits L_k [-].")] = 1e-3,
        out: OutOpt = Path("out/feasibility"),
        formats: FormatsOpt = "png,pdf",
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            values = None if thrust is None else parse_values(thrust, "--thrust", "N")
            doc = run_feasibility(robot, gait, thrust=values, schedule=schedule, mu=mu, eps=eps,
                                  thruster=thruster, degree=degree, fit_tol=fit_tol, out=out,
                                  quiet=quiet, formats=formats)
            if not quiet:
                console().print(f"verdict: {doc['verdict']}; wrote {out}/feasibility.json, "
                                f".md, grf.png/.pdf, feasible_region.png/.pdf")
