"""``thrustwalk feasibility``: ground-contact feasibility of thrust-assisted walking (SPEC 5)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import GaitArg, OutOpt, QuietOpt, RobotArg, cli_errors, console, fmt, parse_values

HELP = """Is this gait, with this thrust, physically walkable? (SPEC 5)

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

DEFAULT_THRUST = "0:-50:-10"


def run_feasibility(robot: str, gait: str, *, thrust: list[float] | None, schedule: str | None,
                    mu: float | None, eps: float, thruster: str | None, degree: int | None,
                    fit_tol: float, out: Path, quiet: bool) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from .. import output, plots_contact
    from ..contact_study import feasibility_study
    from ..errors import InputError
    from ..model import load_model
    from ..robot_io import load_gait, load_gait_for
    from ..zero_dynamics import zero_dynamics

    if thrust is not None and schedule is not None:
        raise InputError("options --thrust and --schedule: give one of them, not both")
    rob, g = load_gait_for(robot, gait)
    spec = None
    if schedule is not None:
        sg, _ = load_gait(schedule)
        if sg.thrust is None:
            raise InputError(f"{schedule}: thrust: the file has no `thrust:` section "
                             "(a gait-format YAML with a thrust schedule is expected)")
        spec = sg.thrust
    elif thrust is None:
        thrust = parse_values(DEFAULT_THRUST, "--thrust", "N")
    model = load_model(rob)
    zd = zero_dynamics(model, g)
    mu = g.mu if mu is None else mu
    doc, figs = feasibility_study(model, zd, values=thrust, spec=spec,
                                  spec_source=str(schedule), thruster=thruster, mu=mu, eps=eps,
                                  degree=degree, fit_tol=fit_tol)
    doc = {"provenance": output.provenance(rob, g, schedule=schedule),
           "robot": {"name": rob.name, "file": rob.source_file,
                     "coordinates": rob.coordinate_names, "thrusters": rob.thruster_names,
                     "total_mass": rob.total_mass, "gravity": rob.gravity},
           "gait": {"name": g.name, "file": g.source_file, "alpha_i": zd.alpha_i,
                    "alpha_f": zd.alpha_f, "delta_zero_sq": zd.delta_zero_sq},
           **doc}
    out.mkdir(parents=True, exist_ok=True)
    output.write_json(out / "feasibility.json", doc)
    title = f"{rob.name} / {g.name}"
    fig = plots_contact.grf_figure(
        figs["profiles"], figs["values"], value_label=figs["scale_label"], mu=mu, eps=eps,
        swing=figs["swing"], joint_names=figs["joints"], title=f"{title}: stance phase")
    output.save_figure(fig, out / "grf")
    fig = plots_contact.region_figure(
        figs["region"], scale_label=figs["scale_label"], mu=mu, eps=eps,
        cases=figs["case_points"], title=f"{title}: feasible region")
    output.save_figure(fig, out / "feasible_region")
    output.write_text_atomic(out / "feasibility.md", markdown(doc))
    if not quiet:
        _table(doc)
    return doc


def _thrust_text(t) -> str:
    if isinstance(t, dict):
        return "schedule " + ", ".join(f"{k}: [{', '.join(fmt(x, '.3g') for x in v)}]"
                                       for k, v in t["values"].items())
    return fmt(t, "g")


def markdown(doc: dict) -> str:
    """``feasibility.md``: the verdict, tables and the figures, from the JSON document."""
    imp, sw, fits = doc["impact"], doc["swing_foot"], doc["fits"]
    p = doc["provenance"]
    lines = [
        f"# Contact feasibility: {doc['robot']['name']} / {doc['gait']['name']}",
        "",
        f"thrustwalk {p['version']}, {p['created_utc']}; robot `{p['robot']['file']}` "
        f"(sha256 {p['robot']['sha256'][:12]}), gait `{p['gait']['file']}` "
        f"(sha256 {p['gait']['sha256'][:12]}); command `{p['command']}`.",
        "",
        f"**Verdict: {doc['verdict']}** (mu = {doc['mu']:g}, eps = {doc['eps']:g} N"
        + (f", thruster `{doc['thruster']}`" if doc["thruster"] else "") + ").",
        "",
        f"Friction: {doc['friction_cone']}.",
        "",
        "## Cases",
        "",
        "| thrust [N] | verdict | zeta* | min F^v [N] | at alpha [rad] | max abs(F^h)/F^v "
        "| at alpha [rad] | impact impulse (h, v) [N s] | lift-off [m/s] | polynomial verdict |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in doc["cases"]:
        poly = c["polynomial"]
        pv = "—" if poly is None else (("feasible" if poly["feasible"] else "infeasible")
                                       + ("" if poly["agrees"] else " (disagrees)"))
        imp_c = c["impact_impulse"]
        lines.append(
            f"| {_thrust_text(c['thrust'])} | {'feasible' if c['feasible'] else 'INFEASIBLE'} "
            f"| {fmt(c['zeta_star'])} | {fmt(c['min_vertical_force'])} "
            f"| {fmt(c['alpha_at_min_vertical_force'])} | {fmt(c['max_friction_ratio'])} "
            f"| {fmt(c['alpha_at_max_friction_ratio'])} "
            f"| {'—' if imp_c is None else f'({imp_c[0]:.4g}, {imp_c[1]:.4g})'} "
            f"| {fmt(c['liftoff_velocity'])} | {pv} |")
    bad = [c for c in doc["cases"] if not c["feasible"]]
    if bad:
        lines += ["", "Reasons:", ""]
        lines += [f"- {_thrust_text(c['thrust'])}: {c['reason']}" for c in bad]
    lines += [
        "",
        "## Impact",
        "",
        "The impulse is proportional to sigma_N^-; its direction does not depend on speed.",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| impulse per unit abs(sigma_N^-) (h, v) [N s per kg m^2/s] | "
        f"({imp['impulse_per_unit_sigma'][0]:.4g}, {imp['impulse_per_unit_sigma'][1]:.4g}) |",
        f"| friction ratio abs(F_2^h)/F_2^v | {fmt(imp['friction_ratio'])} |",
        f"| trailing-foot vertical velocity per unit abs(sigma_N^-) [m/s per kg m^2/s] | "
        f"{imp['trailing_foot_velocity_per_unit_sigma'][1]:.4g} |",
        f"| admissible | {'yes' if imp['admissible'] else 'no: ' + '; '.join(imp['reasons'])} |",
        "",
        "## Swing foot",
        "",
        f"Minimum height for s in [{sw['window_s'][0]:g}, {sw['window_s'][1]:g}]: "
        f"{1e3 * sw['min_height']:.4g} mm at alpha = {sw['alpha_at_min_height']:.4g} rad; "
        f"maximum {1e3 * sw['max_height']:.4g} mm.",
        ("" if not sw["scuffs"] else
         f"**Warning:** the swing foot goes {1e6 * -sw['deepest']:.3g} um below the ground near "
         f"alpha = {sw['alpha_at_deepest']:.4g} rad (tolerance {1e6 * sw['scuff_tolerance']:g} "
         "um); not part of the verdict."),
        "",
        "## Polynomial fits of Lambda_0..2",
        "",
        f"Chebyshev polynomials in alpha ({fits['basis']}); "
        + ("degree fixed by --degree." if fits["tolerance_relative"] is None else
           f"degree chosen for a relative max error <= {fits['tolerance_relative']:g}."),
        "",
        "| term | degree | max error | relative | unit |",
        "|---|---|---|---|---|",
    ]
    for key, unit in (("L_0", "N"), ("L_1", "N per kg^2 m^4/s^2"), ("L_2", "N per N"),
                      ("L_T", "N per N m")):
        f = fits[key]
        lines.append(f"| {key} | {f['degree']} | {f['max_error']:.3g} | "
                     f"{f['relative_error']:.3g} | {unit} |")
    lines += [
        "",
        "## Figures",
        "",
        "Ground reaction force, friction ratio, joint torques and swing-foot height along the "
        "step:",
        "",
        "![ground reaction force](grf.png)",
        "",
        f"Feasible region over {doc['region']['x']} and {doc['region']['y']}; "
        + (f"the periodic orbit is feasible for {doc['region']['x']} in "
           f"[{doc['region']['fixed_point_feasible_range'][0]:.4g}, "
           f"{doc['region']['fixed_point_feasible_range'][1]:.4g}] (grid resolution)."
           if doc["region"]["fixed_point_feasible_range"] else
           "no feasible periodic orbit on the grid."),
        "",
        "![feasible region](feasible_region.png)",
        "",
    ]
    return "\n".join(lines)


def _table(doc: dict) -> None:
    from rich.table import Table

    t = Table(title=f"feasibility: {doc['robot']['name']} / {doc['gait']['name']} "
                    f"(mu = {doc['mu']:g}, verdict: {doc['verdict']})")
    for col in ("thrust [N]", "verdict", "min F^v [N]", "max |F^h|/F^v", "lift-off [m/s]"):
        t.add_column(col, overflow="fold")
    for c in doc["cases"]:
        t.add_row(_thrust_text(c["thrust"]), "feasible" if c["feasible"] else "INFEASIBLE",
                  fmt(c["min_vertical_force"]), fmt(c["max_friction_ratio"]),
                  fmt(c["liftoff_velocity"]))
    con = console()
    con.print(t)
    for c in doc["cases"]:
        if not c["feasible"]:
            con.print(f"{_thrust_text(c['thrust'])}: {c['reason']}", markup=False)


def register(app: typer.Typer) -> None:
    @app.command("feasibility", help=HELP, epilog=EPILOG)
    def feasibility_cli(
        robot: RobotArg = "three_link",
        gait: GaitArg = "three_link_walk",
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help=f"Constant thrust values [N]: start:stop:step or a comma list "
                             f"(default {DEFAULT_THRUST}).")] = None,
        schedule: Annotated[str | None, typer.Option(
            "--schedule", help="Gait-format YAML file whose `thrust:` section (piecewise in "
                               "alpha, per thruster [N] or generalised [N m]) is evaluated "
                               "instead of --thrust.")] = None,
        mu: Annotated[float | None, typer.Option(
            "--mu", help="Friction coefficient [-] (default: the gait's `mu`).")] = None,
        eps: Annotated[float, typer.Option(
            "--eps", help="Minimum vertical ground force [N].")] = 0.0,
        thruster: Annotated[str | None, typer.Option(
            "--thruster", help="Thruster that --thrust drives (default: the first).")] = None,
        degree: Annotated[int | None, typer.Option(
            "--degree", help="Degree of the polynomial fits L_k (default: from --fit-tol).")
        ] = None,
        fit_tol: Annotated[float, typer.Option(
            "--fit-tol", help="Relative max error target of the fits L_k [-].")] = 1e-3,
        out: OutOpt = Path("out/feasibility"),
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors():
            values = None if thrust is None else parse_values(thrust, "--thrust", "N")
            doc = run_feasibility(robot, gait, thrust=values, schedule=schedule, mu=mu, eps=eps,
                                  thruster=thruster, degree=degree, fit_tol=fit_tol, out=out,
                                  quiet=quiet)
            if not quiet:
                console().print(f"verdict: {doc['verdict']}; wrote {out}/feasibility.json, "
                                f".md, grf.png/.pdf, feasible_region.png/.pdf")
