"""``thrustwalk shape``: center-manifold shaping with piecewise-constant thrust."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ..errors import InputError
from .common import (
    check_out,
    cli_errors,
    console,
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
    MaxOutputOpt,
    OutOpt,
    QuietOpt,
    RobotArg,
    SlopeOpt,
    TitlesOpt,
)

if TYPE_CHECKING:
    from ..studies.shape import ShapeRequest

HELP = """Shape the limit cycle with thrust switched at knots alpha_j along the step.

Thrust is constant on each interval [alpha_j, alpha_{j+1}): in --mode generalized the paper's
T_j [N m], a generalised force on q_N; in --mode force the thrust F_j [N] of one thruster.
Reports b_F = int 1/kappa_1 [kg m^2 rad] and Gamma_j = int beta/kappa_1 [kg m^3 rad] per
interval, zeta* [kg^2 m^4/s^2] nominal and shaped, and both the true fixed-point shift
sum b_F T_j / (1 - delta_zero^2) and the paper's one-step value sum b_F T_j (the paper
omits the factor 1/(1 - delta_zero^2); see the README's conventions).

Schedules: a --pattern in j (interval 1..n-1) and k (swept by --k), by default the paper's
k*(j-2) on 4 knots with the interior knots solved so that the fixed point is unchanged
(shape only; mark free knots with ?); or the gait file's piecewise thrust: section; or the
minimum-norm values reaching --target-zeta [kg^2 m^4/s^2] or --target-speed [m/s]. A gait
with a constant thrust (from design-gait --design-thrust) is shaped around that thrust.

Writes DIR/shape.json, DIR/shape.csv (orbits), DIR/shape.png/.pdf (limit cycles, black every
10) and DIR/vector_field.png/.pdf (nominal vs shaped zero-dynamics field, k = --field-k).
"""

EPILOG = ("Example: thrustwalk shape three_link three_link_walk --knots 0,?,?,1 "
          "--pattern 'k*(j-2)' --k 0:50:2 --out out/shape")


def _number(text: str | None, option: str, unit: str) -> float | None:
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"option {option}: expected a number [{unit}], got {text!r}") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise InputError(f"option {option}: must be finite [{unit}], got {text!r}")
    return v


def run_shape(robot: str | None, gait: str | None, request: ShapeRequest, out: Path,
              quiet: bool, *, json: str | None = None, formats: set[str] | None = None,
              titles: bool = False, max_output: float = 100.0, slope: float = 0.0) -> dict:
    """Plain function behind the command; returns the JSON document it wrote.

    Exit 1 (after writing shape.json with the reason) when no shape-only knots exist or a
    target cannot be reached.
    """
    from ..files.output import provenance
    from ..studies.shape import schedule_count, shape

    check_out(out, json=json)
    walker = load_walker(robot, gait)
    with progress("shaped limit cycles", schedule_count(walker, request), quiet) as advance:
        result = shape(walker, **request.keywords(), progress=advance,
                       max_output=max_output * 1e6, slope=slope)
    if result.base is not None and not quiet:
        warn(["the gait has a constant thrust: the patterns are shaped around it and the "
              "nominal orbit is the gait's own"])
    elif result.source == "gait" and not quiet:
        warn(["no --pattern given: the gait's own thrust: schedule is shaped"])
    doc = write_result(result, out, provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles)
    if result.cycles and not quiet and json != "-":
        _table(doc)
    if not result.success and result.cycles:  # shaped, but some schedule has no orbit
        warn([doc["reason"]])
    return doc


def _values_text(s: dict) -> str:
    if "T_j" in s:
        return ", ".join(f"{v:.4g}" for v in s["T_j"])
    return "; ".join(f"{n}: " + ", ".join(f"{v:.4g}" for v in vals)
                     for n, vals in s["F_j"].items())


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    c = console()
    kn = doc["knots"]
    unit = "N m" if doc["mode"] == "generalized" else "N"
    c.print(f"knots (fraction of step): {', '.join(f'{v:.6g}' for v in kn['fraction'])}; "
            f"alpha [rad]: {', '.join(f'{v:.6g}' for v in kn['alpha'])}", markup=False)
    c.print(f"b_F per interval [kg m^2 rad]: {', '.join(f'{v:.6g}' for v in doc['b_F'])}",
            markup=False)
    if doc["mode"] == "force":
        for name, vals in doc["Gamma_j"].items():
            c.print(f"Gamma_j {name} [kg m^3 rad]: {', '.join(f'{v:.6g}' for v in vals)}",
                    markup=False)
    if doc["knot_solver"]:
        ks = doc["knot_solver"]
        c.print(f"knot solver: {ks['reason']} ({ks['method']}; relative residual "
                f"{fmt(ks['relative_residual'], '.2g')})", markup=False)
    if doc["target"]:
        t = doc["target"]
        c.print(f"target {t['kind']} = {t['target']:.6g}: {t['reason']} (residual "
                f"{fmt(t['residual'], '.2g')})", markup=False)
    rows = doc["schedules"]
    shown = rows
    if len(rows) > 12:
        shown = [r for r in rows if r["k"] is not None and abs(r["k"] / 10 - round(r["k"] / 10))
                 < 1e-9] or rows[:: max(1, len(rows) // 10)]
    nom = doc["nominal"]
    z = "\n[kg^2 m^4/s^2]"
    show_table(f"shaping: {doc['robot']['name']} / {doc['gait']['name']}, {doc['mode']} mode "
               f"(nominal zeta* = {fmt(nom['zeta_star'])}, delta_zero^2 = "
               f"{doc['zero_dynamics']['delta_zero_sq']:.4f})",
               [("schedule", False), (f"values\n[{unit}]", False),
                ("zeta* shaped" + z, True), ("true shift" + z, True),
                ("paper one-step" + z, True), ("zeta+ shaped" + z, True),
                ("speed\n[m/s]", True), ("stable", False)],
               [[r["label"], _values_text(r), fmt(r["zeta_star"]["shaped"]),
                 fmt(r["shift"]["true_fixed_point_shift"], ".3g"),
                 fmt(r["shift"]["paper_one_step_shift"], ".3g"),
                 fmt(r["post_impact"]["shaped"]["zeta"]), fmt(r["speed"]),
                 "yes" if r["stable"] else ("no" if r["exists"] else r["reason"])]
                for r in shown])
    if len(shown) < len(rows):
        c.print(f"({len(rows) - len(shown)} more rows in shape.json)", markup=False)
    c.print("zeta in kg^2 m^4/s^2. true shift = one-step / (1 - delta_zero^2); the paper's "
            "value omits that factor (an erratum of the paper).", markup=False)


def register(app: typer.Typer) -> None:
    @app.command("shape", help=HELP, epilog=EPILOG)
    def shape_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        knots: Annotated[str | None, typer.Option(
            "--knots", help="Knots as fractions of the step, 0 first and 1 last, ? = solve "
            "(default: 0,?,...,?,1 with --n-knots knots for a pattern; equal spacing for a "
            "target).")] = None,
        alpha_knots: Annotated[bool, typer.Option(
            "--alpha-knots", help="--knots are alpha values [rad] (alpha_i first, alpha_f "
            "last) instead of fractions.")] = False,
        n_knots: Annotated[int, typer.Option(
            "--n-knots", help="Number of knots n when --knots is omitted.")] = 4,
        pattern: Annotated[str | None, typer.Option(
            "--pattern", help="Interval values T_j [N m] (or F_j [N]) as arithmetic in j and "
            "k, e.g. 'k*(j-2)' (default when the gait has no thrust: section).")] = None,
        k: Annotated[str | None, typer.Option(
            "--k", help="Values of k: start:stop:step or a comma list (default 0:50:2).")] = None,
        field_k: Annotated[str | None, typer.Option(
            "--field-k", help="k of the vector-field figure (default 60).")] = None,
        mode: Annotated[str | None, typer.Option(
            "--mode", help="generalized (T_j [N m] on q_N, default) or force (F_j [N] of "
            "--thruster).")] = None,
        thruster: Annotated[str | None, typer.Option(
            "--thruster", help="Thruster driven in force mode (default: the first).")] = None,
        target_zeta: Annotated[str | None, typer.Option(
            "--target-zeta", help="Minimum-norm values reaching this zeta* "
            "[kg^2 m^4/s^2].")] = None,
        target_speed: Annotated[str | None, typer.Option(
            "--target-speed", help="Minimum-norm values reaching this average speed "
            "[m/s].")] = None,
        out: OutOpt = Path("out/shape"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        max_output: MaxOutputOpt = 100.0,
        slope: SlopeOpt = 0.0,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            from ..studies.shape import ShapeRequest

            req = ShapeRequest(
                knots=None if knots is None else tuple(parse_knots(knots)),
                alpha_knots=alpha_knots, n_knots=n_knots,
                pattern=pattern,
                ks=None if k is None else tuple(parse_values(k, "--k")),
                field_k=_number(field_k, "--field-k", "as k"), mode=mode, thruster=thruster,
                target_zeta=_number(target_zeta, "--target-zeta", "kg^2 m^4/s^2"),
                target_speed=_number(target_speed, "--target-speed", "m/s"))
            doc = run_shape(robot, gait, req, out, quiet, json=json,
                            formats=parse_formats(formats), titles=titles,
                            max_output=max_output, slope=slope)
            if not doc["success"] and not doc.get("schedules"):  # nothing could be shaped
                import sys

                sys.stderr.write(f"error: {doc['reason']} (details in {out}/shape.json)\n")
                raise typer.Exit(1)
            if not quiet and json != "-":
                console().print(wrote_line(out), markup=False)
