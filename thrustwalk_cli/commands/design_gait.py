"""``thrustwalk design-gait``: find a stable, walkable Bezier gait for a robot."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from ..errors import ComputationError, InputError
from .common import cli_errors, console, progress, render_mentions
from .options import JsonOpt, QuietOpt, RobotArg

HELP = """Design a stable, hybrid-invariant Bezier gait by constrained optimisation.

Variables: the pre-impact posture q^- [rad], the free Bezier columns 2..M-1 [rad] (columns 0
and 1 follow from hybrid invariance) and zeta^- [kg^2 m^4/s^2]; with --design-thrust also one
constant thrust per thruster [N]. Objective on the zero-dynamics periodic orbit: 'effort' =
(1/L) int |u|^2 dt [N^2 m s] (default) or 'peak' = max |u_i| [N m]. Constraints: stable
periodic orbit with delta_zero^2 <= --max-delta-sq; target speed [m/s] and/or step length
[m]; swing foot >= --clearance [m] at mid-step and >= 0 over the step; stance F_v >=
--min-vertical-force [N] and |F_h| <= mu F_v; impact impulse in the friction cone and
trailing foot lifting off; swing foot moving down at touchdown at >= --min-touchdown-velocity
[m/s] (no grazing touchdown); joint ranges [rad] and torque limits [N m] from the robot file.

Writes DIR/NAME.yaml (the gait; a header records how it was made) and DIR/NAME.report.json
(objective, every constraint margin, fixed point, provenance). The written file is loaded back
and its fixed point compared with the design before it is kept. Exit codes: 0 a feasible gait
was written; 3 no feasible gait was found (only the report is written; it names the
constraint family that blocks, the violated inequality with its numbers, and the option that
usually helps); 2 bad input; 1 computation failure.
"""

EPILOG = ("Example: thrustwalk design-gait rabbit --target-speed 0.53 --starts 8 "
          "--out gaits --name rabbit_walk")

INFEASIBLE_EXIT = 3


def parse_alpha(text: str | None, names: list[str]) -> tuple[float, ...] | None:
    """``"q_T:-1,q_sh:1,q_sk:0.5"`` -> one coefficient per coordinate (missing = 0)."""
    if text is None:
        return None
    c = dict.fromkeys(names, 0.0)
    for part in text.split(","):
        key, sep, val = part.partition(":")
        key = key.strip()
        try:
            num = float(val)
        except ValueError:
            num = None
        if not sep or key not in c or num is None or num != num:
            raise InputError(f"option --alpha: expected name:value pairs over "
                             f"{', '.join(names)} (got {part.strip()!r})")
        c[key] = num
    return tuple(c.values())


def parse_thrust_range(text: str | None) -> tuple[str, float, float] | None:
    """``"hip_x:-50:0"`` -> ``("hip_x", -50.0, 0.0)`` [N]."""
    if text is None:
        return None
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        lo, hi = float(parts[1]), float(parts[2])
    except ValueError:
        raise InputError(f"option --thrust-range: expected NAME:LOW:HIGH in N, e.g. hip_x:-50:0 "
                         f"(got {text!r})") from None
    return parts[0].strip(), lo, hi


def run_design_gait(robot: str, out: Path, *, speed: float | None, step_length: float | None,
                    mu: float, order: int, starts: int, seed: int, clearance: float,
                    max_delta_sq: float, objective: str, design_thrust: bool,
                    thrust_weight: float, thrust_range: str | None,
                    min_vertical_force: float | None, alpha: str | None,
                    max_iter: int, name: str | None, compare: str | None,
                    quiet: bool, json: str | None = None,
                    min_touchdown_velocity: float = 0.05) -> dict:
    """Plain function behind the command; returns the report it wrote (``feasible`` says
    whether the gait file was written)."""
    from ..design.spec import DesignSpec
    from ..files import output
    from ..studies.design_gait import design_gait, reload_check, robot_reference
    from .common import check_out, load_model, load_walker

    check_out(out, whole=False, json=json)
    if out.suffix in (".yaml", ".yml"):
        raise InputError(f"option --out: a folder is expected (the gait goes to "
                         f"DIR/NAME.yaml, NAME from --name), got {out}")
    model = load_model(robot)
    rob = model.robot
    gait_name = name or f"{rob.name}_designed"
    if not gait_name.replace("_", "").replace("-", "").isalnum():
        raise InputError(f"option --name: letters, digits, _ and - only (got {gait_name!r})")
    gait_path = out / f"{gait_name}.yaml"
    spec = DesignSpec(speed=speed, step_length=step_length, mu=mu, order=order,
                      clearance=clearance, max_delta_sq=max_delta_sq,
                      min_vertical_force=min_vertical_force,
                      min_touchdown_velocity=min_touchdown_velocity, objective=objective,
                      thrust_design=design_thrust, thrust_weight=thrust_weight,
                      thrust_range=parse_thrust_range(thrust_range),
                      alpha_c=parse_alpha(alpha, rob.coordinate_names), starts=starts,
                      seed=seed, max_iter=max_iter, name=gait_name)
    spec.validate(model)
    cmp = load_walker(None, compare) if compare is not None else None
    with progress(f"design-gait {rob.name}: {starts} start(s)", starts, quiet) as advance:
        result = design_gait(model, spec, compare=cmp,
                             progress=lambda done, total, msg: advance(1))
    report_path = out / f"{gait_name}.report.json"
    prov = output.provenance(rob)
    body = result.document()
    doc = {"provenance": prov, "robot": body.pop("robot"),
           "gait_file": str(gait_path) if result.success else None, **body}
    text = None
    if result.success:
        text = result.gait_text(prov, robot_reference(rob, robot, gait_path), report_path.name)
        back = reload_check(model, text, str(gait_path), result.design)
        if not back["relative_error"] <= 1e-8:
            raise ComputationError(
                f"the written gait does not reproduce the designed fixed point "
                f"(zeta* {back['zeta_star']} vs {back['reference']})")
        doc["reload_check"] = back
        out.mkdir(parents=True, exist_ok=True)
        output.write_text_atomic(gait_path, text)
    out.mkdir(parents=True, exist_ok=True)
    output.write_json(report_path, doc)
    if json == "-":
        import json as _json

        sys.stdout.write(_json.dumps(output.jsonable(doc), indent=2) + "\n")
    elif json:
        output.write_json(Path(json), doc)
    if not quiet and json != "-":
        _summary(doc, gait_path, report_path)
    return doc


def _summary(doc: dict, out: Path, report: Path) -> None:
    from rich.markup import escape
    from rich.table import Table

    o, m = doc.get("fixed_point") or {}, doc.get("margins") or {}
    t = Table(title=f"design-gait {doc['robot']['name']}: "
                    + ("feasible" if doc["feasible"] else "NO FEASIBLE GAIT"))
    t.add_column("quantity", overflow="fold")
    t.add_column("value", justify="right", no_wrap=True)
    obj = doc["objective"]
    rows = [(f"objective {obj['name']} [{obj['unit']}]", obj["value"]),
            ("delta_zero^2", o.get("delta_zero_sq")), ("speed [m/s]", o.get("speed")),
            ("step length [m]", o.get("step_length")), ("step time [s]", o.get("step_time")),
            ("zeta* [kg^2 m^4/s^2]", o.get("zeta_star"))]
    rows += [(f"designed thrust {n} [N]", v)
             for n, v in zip(doc.get("thrusters") or [], doc.get("thrust") or [])]
    for key in ("clearance_mid_step", "min_swing_height", "vertical_force", "friction",
                "impact_friction", "liftoff_velocity", "touchdown_velocity"):
        rows.append((f"margin {key}", m.get(key)))
    for label, v in rows:
        t.add_row(escape(label), "—" if v is None else f"{v:.5g}")
    console().print(t)
    if "compare" in doc:
        c = doc["compare"]
        console().print(f"compare {c['gait']}: objective {c.get('objective')}, "
                        f"feasible {c['feasible']} (failed: {', '.join(c['failed']) or 'none'})")
    if doc["feasible"]:
        console().print(f"wrote {out} and {report}", markup=False)
    else:
        console().print(f"wrote {report} (no gait file)", markup=False)


def register(app: typer.Typer) -> None:
    @app.command("design-gait", help=HELP, epilog=EPILOG)
    def design_gait_cli(
        ctx: typer.Context,
        robot: RobotArg,
        out: Annotated[Path, typer.Option(
            "--out", "-o", help="Output folder: the gait goes to DIR/NAME.yaml, the report to "
                                "DIR/NAME.report.json.")] = Path("out/design_gait"),
        speed: Annotated[float | None, typer.Option(
            "--target-speed", help="Target average speed [m/s].")] = None,
        step_length: Annotated[float | None, typer.Option(
            "--step-length", help="Target step length [m] (swing-foot x at impact).")] = None,
        mu: Annotated[float, typer.Option("--mu", help="Friction coefficient [1].")] = 0.7,
        order: Annotated[int, typer.Option("--order", help="Bezier order M [1].")] = 6,
        starts: Annotated[int, typer.Option(
            "--starts", help="Solver starts (start 0 is the default start) [1].")] = 8,
        seed: Annotated[int, typer.Option("--seed", help="Seed of the random starts.")] = 0,
        clearance: Annotated[float, typer.Option(
            "--clearance", help="Swing-foot height at mid-step [m] (0 for straight legs).")
        ] = 0.03,
        max_delta_sq: Annotated[float, typer.Option(
            "--max-delta-sq", help="Upper bound on delta_zero^2 [1] (stability margin).")
        ] = 0.9,
        objective: Annotated[str, typer.Option(
            "--objective", help="effort: (1/L) int |u|^2 dt [N^2 m s]; peak: max |u| [N m].")
        ] = "effort",
        thrust_design: Annotated[bool, typer.Option(
            "--design-thrust", help="Co-design one constant thrust per thruster [N].")
        ] = False,
        thrust_weight: Annotated[float, typer.Option(
            "--thrust-weight", help="Weight w of w |F|^2 in the effort [m^2].")] = 1.0,
        thrust_range: Annotated[str | None, typer.Option(
            "--thrust-range", help="Also feasible for every constant thrust of one thruster in "
                                   "LOW..HIGH [N], e.g. hip_x:-50:0.")] = None,
        min_vertical_force: Annotated[float | None, typer.Option(
            "--min-vertical-force", help="eps in F_v >= eps [N] (default 10 % of weight).")
        ] = None,
        min_touchdown_velocity: Annotated[float, typer.Option(
            "--min-touchdown-velocity", help="The swing foot moves down onto the ground at "
                                             "least this fast just before impact [m/s] (0 "
                                             "allows a grazing touchdown).")] = 0.05,
        alpha_c: Annotated[str | None, typer.Option(
            "--alpha", help="alpha = c q as name:value pairs [1], e.g. q_T:-1,q_sh:1,q_sk:0.5 "
                            "(default: minus the mean angle of the stance-leg links).")] = None,
        max_iter: Annotated[int, typer.Option(
            "--max-iter", help="SLSQP iterations per start [1].")] = 150,
        name: Annotated[str | None, typer.Option(
            "--name", help="Gait name and file stem (default: ROBOT_designed).")] = None,
        compare: Annotated[str | None, typer.Option(
            "--compare", help="Also evaluate this existing gait with the same objective and "
                              "constraints (written to the report).")] = None,
        json: JsonOpt = None,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            doc = run_design_gait(
                robot, out, speed=speed, step_length=step_length, mu=mu, order=order,
                starts=starts, seed=seed, clearance=clearance, max_delta_sq=max_delta_sq,
                objective=objective, design_thrust=thrust_design, thrust_weight=thrust_weight,
                thrust_range=thrust_range,
                min_vertical_force=min_vertical_force, alpha=alpha_c, max_iter=max_iter,
                name=name, compare=compare, quiet=quiet, json=json,
                min_touchdown_velocity=min_touchdown_velocity)
            if not doc["feasible"]:
                sys.stderr.write(f"infeasible: {render_mentions(doc['reason'], ctx)}\n")
                raise typer.Exit(INFEASIBLE_EXIT)
