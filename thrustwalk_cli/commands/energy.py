"""``thrustwalk energy``: what walking with thrust costs (SPEC 15), and, with a gait library,
at each speed the cheapest way there."""

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
    OutOpt,
    QuietOpt,
    RobotArg,
    SlopeOpt,
    ThrusterOpt,
    TitlesOpt,
)

HELP = """Cost of transport and power of a gait over constant thrust values.

For every constant thrust value [N] on one thruster, on the zero-dynamics periodic orbit (exact
quadrature, no simulation): speed [m/s], step time [s], step length [m], the joints' net,
positive and absolute work [J], their electrical energy [J] (with the robot file's motor:
models), the thrust's work on the walker and the thrusters' input energy [J] (power: models),
the impact loss [J], the cost of transport E/(m g d) [1] (mechanical and total, split legs /
thrust), the average powers [W] and the orbit's verdict (the limit-cycle command's). A missing
model leaves its numbers empty with the reason; an orbit that does not exist or is unstable has
no energies. The summary ends with the headline: what the largest thrust does to speed and CoT.

With --library DIR (the folder of a design-gait sweep over target_speed, e.g. `thrustwalk
sweep sweeps/gait_library.yaml --out DIR`): every library gait designed without thrust, at
zero thrust, against this gait pushed by thrust: at each speed the cheaper strategy (linear
interpolation in speed between walkable orbits; the total CoT when every orbit has it, else
the mechanical one), and where thrust pays and where it does not.

Writes DIR/energy.json, DIR/energy.csv (one row per thrust value), the figures DIR/cot_speed
(CoT against speed, legs / thrust split) and DIR/power_step (power along the step at the
nominal and the extreme thrust, joints and thrusters stacked), .png and .pdf; with --library
also DIR/library_energy.csv, DIR/pareto.csv and the figure DIR/pareto.
"""

EPILOG = ("Example: thrustwalk energy three_link three_link_walk --thrust 0:-50:-5 "
          "--library out/gait_library --out out/energy")


def run_energy(robot: str | None, gait: str | None, thrust: list[float] | None,
               thruster: str | None, out: Path, quiet: bool, *, slope: float = 0.0,
               library: str | None = None, json: str | None = None,
               formats: set[str] | None = None, titles: bool = False) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files.output import provenance
    from ..studies.energy import energy

    check_out(out, json=json)
    walker = load_walker(robot, gait)
    result = energy(walker, thrust, thruster, slope=slope, library=library)
    doc = write_result(result, out, provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles)
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out), markup=False)
    warn([w for w in doc["warnings"] if w not in walker.warnings])  # the gait's: printed
    return doc


def _cot(c: dict, key: str) -> str:
    """A case's cost of transport (SPEC 15) for the table; the missing mark without energies
    or where a power model is missing (the lines under the table say which)."""
    from ..studies.documents import fmt

    e = c.get("energy")
    return fmt(e["cot"][key] if e else None, ".3g")


def _split(c: dict, basis: str) -> str:
    from ..studies.documents import MISSING

    e = c.get("energy")
    if not e or e["cot"][basis] is None:
        return MISSING
    return f"{e['cot'][basis + '_legs']:.2g}+{e['cot'][basis + '_thrust']:.2g}"


def _power(c: dict, basis: str) -> str:
    from ..studies.documents import MISSING

    e = c.get("energy")
    if not e:
        return MISSING
    p = e["average_power"]
    keys = (("legs_electrical", "thrust_input") if basis == "total"
            else ("legs_mechanical", "thrust_mechanical"))
    if any(p[k] is None for k in keys):
        return MISSING
    return f"{p[keys[0]] + p[keys[1]]:.4g}"


def _table(doc: dict) -> None:
    from ..studies.documents import fmt
    from .slope import _few

    basis = doc["energy"]["basis"]
    rows = [[fmt(c["thrust"]), fmt(c["speed"]), _cot(c, "mechanical"),
             _cot(c, "total"), _split(c, basis), _power(c, basis), c["verdict"]]
            for c in _few(doc["cases"])]
    n = len(doc["cases"])
    shown = "" if n == len(rows) else f"; {len(rows)} of {n} rows shown"
    show_table(f"energy: {doc['robot']['name']} / {doc['gait']['name']} (per step on the "
               f"periodic orbit; split and power: {basis}{shown})",
               [("thrust\n[N]", True), ("speed\n[m/s]", True),
                ("CoT\nmech", True), ("CoT\ntotal", True), ("legs+\nthrust", True),
                ("power\n[W]", True), ("verdict", False)], rows)
    con = console()
    for m in doc["energy"]["missing"]:
        con.print(m, markup=False)
    bad = [c for c in doc["cases"] if c["energy"] is None]
    if bad:
        con.print(f"{len(bad)} thrust value(s) without energies; first ({fmt(bad[0]['thrust'])} "
                  f"N): {bad[0]['energy_reason']}", markup=False)
    con.print(doc["headline"], markup=False)
    lib = doc.get("library")
    if lib is None:
        return
    rows = [[g["gait"], fmt(g["target_speed"]), fmt(g["speed"]), _cot(g, basis), g["verdict"]]
            for g in lib["gaits"]]
    show_table(f"gait library {lib['folder']} at zero thrust ({basis} CoT)",
               [("gait", False), ("target\n[m/s]", True), ("speed\n[m/s]", True),
                (f"CoT\n{basis}", True), ("verdict", False)], rows)
    for s in lib["skipped"]:
        con.print(f"skipped {s}", markup=False)
    con.print(lib["headline"], markup=False)


def register(app: typer.Typer) -> None:
    @app.command("energy", help=HELP, epilog=EPILOG)
    def energy_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help="Constant thrust values [N]: start:stop:step or a comma list "
                             "(default 0:-50:-10; 0 for a robot without thrusters).")] = None,
        thruster: ThrusterOpt = None,
        slope: SlopeOpt = 0.0,
        library: Annotated[str | None, typer.Option(
            "--library", metavar="DIR", help="A gait library (the output folder of a "
                                             "design-gait sweep over target_speed) to compare "
                                             "with: at each speed [m/s] the cheapest way "
                                             "there.")] = None,
        out: OutOpt = Path("out/energy"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            values = None if thrust is None else parse_values(thrust, "--thrust", "N")
            run_energy(robot, gait, values, thruster, out, quiet, slope=slope, library=library,
                       json=json, formats=parse_formats(formats), titles=titles)
