"""``thrustwalk limit-cycle``: fixed points and orbits of the zero dynamics over a thrust sweep."""

from __future__ import annotations

from pathlib import Path

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
    MaxOutputOpt,
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

HELP = """Limit cycles of the hybrid zero dynamics for constant thrust values.

For every thrust value: Poincare fixed point zeta* [kg^2 m^4/s^2], stability (delta_zero^2),
step time [s], step length [m], speed [m/s], sigma_N^+/- [kg m^2/s], alpha'^+/- [rad/s], the
exact minimum and maximum of |alpha'| and the swing foot's touchdown velocity [m/s] (near 0: a
grazing touchdown), with a verdict: walkable only when the orbit exists and is stable, the
gait is hybrid-invariant, the swing foot stays above the ground and the ground contact holds
on the orbit (the feasibility command's checks at --mu and --min-vertical-force: F_1^v >=
the minimum, |F_1^h| <= mu F_1^v along the step, the impact impulse in the cone, the
trailing foot lifting off; `thrustwalk feasibility` shows the forces). Thrust is in newtons; with
the bundled robots negative thrust pushes forward (the paper's convention). Without --thrust,
a gait with a thrust: section is analysed with its own schedule; for a robot without
thrusters the only thrust is 0 (the default). With --slope GAMMA [rad, positive uphill] the
walker is on a slope: gravity and world-frame thrusters turn into the slope frame,
speed is along the ground, the climb rate speed*sin(GAMMA) is reported beside it and the
ground forces are tangential and normal to the slope.

Writes DIR/limit_cycles.json, DIR/limit_cycles.csv, DIR/limit_cycles.png and .pdf, and
DIR/fixed_point_shift.png and .pdf (zeta* and speed versus thrust, with the affine law).
"""

EPILOG = ("Example: thrustwalk limit-cycle three_link three_link_walk --thrust 0:-50:-10 "
          "--out out/lc")


def run_limit_cycle(robot: str | None, gait: str | None, thrust: list[float] | None,
                    thruster: str | None, out: Path, quiet: bool, *, json: str | None = None,
                    formats: set[str] | None = None, titles: bool = False,
                    max_output: float = 100.0, mu: float | None = None,
                    min_vertical_force: float = 0.0, slope: float = 0.0) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files.output import provenance
    from ..studies.limit_cycle import limit_cycle

    check_out(out, json=json)
    walker = load_walker(robot, gait)
    result = limit_cycle(walker, thrust, thruster, max_output=max_output * 1e6, mu=mu,
                         min_vertical_force=min_vertical_force, slope=slope)
    if result.source == "gait" and not quiet:
        warn(["no --thrust given: the gait's own thrust: schedule is analysed"])
    doc = write_result(result, out, provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles)
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out), markup=False)
    warn([w for w in doc["warnings"] if w not in walker.warnings])  # the gait's: printed
    return doc


def _table(doc: dict) -> None:
    import re

    from ..studies.documents import fmt

    zd = doc["zero_dynamics"]
    slope = doc.get("slope")
    rows = [["gait" if c["thrust"] is None else fmt(c["thrust"]), fmt(c["zeta_star"]),
             fmt(c["step_time"]), fmt(c["speed"])]
            + ([fmt(c["climb_rate"])] if slope else [])
            + [fmt(c["min_abs_alpha_dot"]), fmt(c["touchdown_velocity"]),
               _cot(c, "mechanical"), _cot(c, "total"), _word(c, doc)]
            for c in doc["cycles"]]
    on = f", on the slope {slope['angle']:.4g} rad" if slope else ""
    show_table(f"limit cycles: {doc['robot']['name']} / {doc['gait']['name']} "
               f"(delta_zero^2 = {zd['delta_zero_sq']:.4f}{on})",
               [("thrust\n[N]", True), ("zeta*\n[kg^2 m^4/s^2]", True), ("T\n[s]", True),
                ("speed\n[m/s]", True)] + ([("climb\n[m/s]", True)] if slope else [])
               + [("min|α'|\n[rad/s]", True),
                  ("touchdown\n[m/s]", True), ("CoT\nmech", True), ("CoT\ntotal", True),
                  ("verdict", False)], rows)
    con = console()
    groups: dict[str, list[dict]] = {}
    for c in doc["cycles"]:
        if not c["walkable"]:  # one line per kind of verdict, its numbers aside
            groups.setdefault(re.sub(r"-?\d[\d.]*(e[-+]?\d+)?", "#", c["verdict"]), []).append(c)
    for cases in groups.values():
        first = cases[0]
        if first["thrust"] is None or len(doc["cycles"]) == 1:
            con.print(first["verdict"], markup=False)
            continue
        span = (f"{fmt(first['thrust'])} N" if len(cases) == 1 else
                f"{fmt(first['thrust'])} to {fmt(cases[-1]['thrust'])} N ({len(cases)} cases)")
        con.print(f"{span}: {first['verdict']}"
                  + (f" (at {fmt(first['thrust'])} N)" if len(cases) > 1 else ""), markup=False)
    ct = doc["contact"]
    if any(c["exists"] and c["stable"] and not c["contact"]["feasible"]
           for cases in groups.values() for c in cases):
        con.print(f"contact checked on each orbit at mu = {ct['mu']:g}, F^v >= "
                  f"{ct['min_vertical_force']:g} N; `thrustwalk feasibility` with the same "
                  "options shows the ground forces", markup=False)


def _cot(c: dict, key: str) -> str:
    """A case's cost of transport (SPEC 15) for the table; the missing mark (as every table's)
    without an orbit (the verdict column says so) or where a power model is missing (the
    JSON's energy.missing says which)."""
    from ..studies.documents import fmt

    e = c.get("energy") or {}
    return fmt(e["cot"][key] if e.get("exists") else None, ".3g")


def _word(c: dict, doc: dict) -> str:
    """The verdict of one case in a word for the table (the lines below it give the reason)."""
    if c["walkable"]:
        return "walkable"
    if not c["exists"]:
        return "no orbit"
    if not c["stable"]:
        return "unstable"
    if doc["swing_foot"].get("scuffs"):
        return "scuffs"
    why = c["contact"]["reason"]
    return ("lifts" if "vertical ground force" in why else "slips" if "friction ratio" in why
            else "impact" if "impact" in why or "lift" in why else "infeasible")


def register(app: typer.Typer) -> None:
    @app.command("limit-cycle", help=HELP, epilog=EPILOG)
    def limit_cycle_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        thrust: ThrustOpt = None,
        thruster: ThrusterOpt = None,
        out: OutOpt = Path("out/limit_cycle"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        max_output: MaxOutputOpt = 100.0,
        mu: MuOpt = None,
        min_vertical_force: MinVerticalForceOpt = 0.0,
        slope: SlopeOpt = 0.0,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            values = None if thrust is None else parse_values(thrust, "--thrust", "N")
            run_limit_cycle(robot, gait, values, thruster, out, quiet, json=json,
                            formats=parse_formats(formats), titles=titles,
                            max_output=max_output, mu=mu,
                            min_vertical_force=min_vertical_force, slope=slope)
