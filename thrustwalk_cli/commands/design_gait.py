"""``thrustwalk design-gait``: find a stable, walkable Bezier gait for a robot."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer

from ..errors import ComputationError, InputError
from .common import cli_errors, console, parse_formats, progress, render_mentions
from .options import JsonOpt, QuietOpt, RobotArg, SlopeOpt

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

Writes DIR/NAME.yaml (the gait; a header records how it was made, with a WARNING line when
SLSQP did not certify the optimum or the robot file gives no torque limits or joint ranges),
DIR/NAME.report.json (objective, every constraint margin, fixed point, warnings, provenance)
and DIR/NAME.stick.png/.pdf (the gait as a stick figure over one step). The written file is
loaded back and its fixed point compared with the design before it is kept. Exit codes: 0 a
feasible gait was written; 3 no feasible gait was found (only the report is written; it names
the constraint family that blocks, the violated inequality with its numbers, and the option
that usually helps); 2 bad input; 1 computation failure. A failure after the search never
loses it: the design is written as DIR/NAME.failed.yaml and DIR/NAME.failed.report.json
(marked failed; a temporary folder if DIR cannot take them) and the error line says where.
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
                    min_touchdown_velocity: float = 0.05,
                    formats: set[str] | None = None,
                    render: Callable[[str], str] = str, slope: float = 0.0) -> dict:
    """Plain function behind the command; returns the report it wrote (``feasible`` says
    whether the gait file was written). ``formats``: figure kinds (png, pdf; default both);
    ``render``: writes the parameters that warnings in the gait header mention (in
    backquotes) as flags.

    Once the search is over, its result is never lost: if anything after it fails (building
    the report, the reload check, writing, a bug), the gait is written as
    ``DIR/NAME.failed.yaml`` (its header opens with ``NOT A VERIFIED GAIT`` and why) and the
    report as ``DIR/NAME.failed.report.json`` (``status: failed``, ``feasible: false``,
    ``error``), or, when ``DIR`` cannot take them, in a new temporary folder; then
    :class:`ComputationError` says what failed and where the files are."""
    from ..design.spec import DesignSpec
    from ..model.slope import check_slope
    from ..studies.design_gait import design_gait
    from .common import check_out, load_model, load_walker, warn

    check_out(out, whole=False, json=json)
    if out.suffix in (".yaml", ".yml"):
        raise InputError(f"option --out: a folder is expected (the gait goes to "
                         f"DIR/NAME.yaml, NAME from --name), got {out}")
    model = load_model(robot)
    rob = model.robot
    gait_name = name or f"{rob.name}_designed"
    if not gait_name.replace("_", "").replace("-", "").isalnum():
        raise InputError(f"option --name: letters, digits, _ and - only (got {gait_name!r})")
    spec = DesignSpec(speed=speed, step_length=step_length, mu=mu, order=order,
                      clearance=clearance, max_delta_sq=max_delta_sq,
                      min_vertical_force=min_vertical_force,
                      min_touchdown_velocity=min_touchdown_velocity, objective=objective,
                      thrust_design=design_thrust, thrust_weight=thrust_weight,
                      thrust_range=parse_thrust_range(thrust_range),
                      alpha_c=parse_alpha(alpha, rob.coordinate_names), starts=starts,
                      seed=seed, max_iter=max_iter, name=gait_name)
    spec.validate(model)
    slope = check_slope(slope)  # before the search
    cmp = load_walker(None, compare) if compare is not None else None
    with progress(f"design-gait {rob.name}: {starts} start(s)", starts, quiet) as advance:
        result = design_gait(model, spec, compare=cmp,
                             progress=lambda done, total, msg: advance(1), slope=slope)
    # the search is over: from here on, whatever fails, what it found is written
    step = ["building the report"]
    try:
        doc, files = _keep(result, model, robot, out, gait_name, formats, step, render)
    except Exception as exc:  # noqa: BLE001 - any failure, a bug included: keep the design
        why = f"{step[0]} failed: {_error_text(exc)}"
        saved, doc = _save_failed(result, robot, out, gait_name, why, step[0], render)
        try:
            _write_json_option(doc, json)
        except Exception:  # noqa: BLE001 - the message below matters more
            pass
        where = (f"the design found by the search is kept, marked as failed, in "
                 f"{' and '.join(str(p) for p in saved)}" if saved else
                 "the design could not be written anywhere (the solver log above is all "
                 "that is left)")
        raise ComputationError(f"{why}; {where}") from exc
    _write_json_option(doc, json)
    if result.warnings or doc.get("figure_error"):
        warn([*result.warnings, *([doc["figure_error"]] if doc.get("figure_error") else [])])
    if not quiet and json != "-":
        _summary(doc, out / f"{gait_name}.yaml", out / f"{gait_name}.report.json", files)
    return doc


def _error_text(exc: BaseException) -> str:
    """One line for an exception (a bug names its type)."""
    if isinstance(exc, ComputationError):
        text = str(exc)
    elif isinstance(exc, InputError):
        text = "; ".join(str(p) for p in exc.problems)
    elif isinstance(exc, OSError):
        text = f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}"
    else:
        text = f"internal error {type(exc).__name__}: {exc}"
    return " ".join(text.split())


def _keep(result, model, robot: str, out: Path, gait_name: str, formats: set[str] | None,
          step: list[str], render: Callable[[str], str]) -> tuple[dict, list[Path]]:
    """Build the report, the gait text (reload-checked) and the stick figure in memory, then
    write them (gait and figures only for a feasible design). ``step[0]`` names the step under
    way (for the message if one fails). Returns the report and the files written."""
    from ..files import output
    from ..files.gait_file import robot_reference
    from ..studies.design_gait import reload_check

    gait_path = out / f"{gait_name}.yaml"
    report_path = out / f"{gait_name}.report.json"
    rob = model.robot
    prov = output.provenance(rob)
    body = result.document()
    doc = {"provenance": prov, "robot": body.pop("robot"),
           "gait_file": str(gait_path) if result.success else None, **body}
    text, figures = None, {}
    if result.success:
        step[0] = "writing the gait text"
        text = result.gait_text(prov, robot_reference(rob, robot, gait_path), report_path.name,
                                render)
        step[0] = "the reload check"
        back = reload_check(result.model, text, str(gait_path), result.design)
        if not back["relative_error"] <= 1e-8:
            raise ComputationError(
                f"the written gait does not reproduce the designed fixed point "
                f"(zeta* {back['zeta_star']} vs {back['reference']})")
        doc["reload_check"] = back
        kinds = [k for k in ("png", "pdf") if formats is None or k in formats]
        if kinds:
            figures, err = _draw(result, kinds)
            if err:
                doc["figure_error"] = err
        doc["figures"] = [str(out / f) for f in figures]
    files = []
    step[0] = "writing the gait file"
    out.mkdir(parents=True, exist_ok=True)
    if text is not None:
        files.append(output.write_text_atomic(gait_path, text))
    step[0] = "writing the stick figure"
    for fname, data in figures.items():
        files.append(output.write_bytes_atomic(out / fname, data))
    step[0] = "writing the report"
    files.append(output.write_json(report_path, doc))
    return doc, files


def _draw(result, kinds: list[str]) -> tuple[dict[str, bytes], str | None]:
    """The stick figure as bytes per file name; a figure that cannot be drawn does not cost the
    verified gait: its error comes back instead (a warning)."""
    from .._version import __version__
    from ..plots.style import close, render

    try:
        out = {}
        for stem, fig in result.figures().items():
            for kind in kinds:
                out[f"{stem}.{kind}"] = render(fig, kind, f"thrustwalk {__version__}")
            close(fig)
        return out, None
    except Exception as exc:  # noqa: BLE001 - a drawing bug is reported, the gait is kept
        return {}, f"the stick figure could not be drawn ({_error_text(exc)}); gait and " \
                   "report are written"


def _save_failed(result, robot: str, out: Path, gait_name: str, why: str, step: str,
                 render: Callable[[str], str]) -> tuple[list[Path], dict]:
    """Write the design after a failure: ``NAME.failed.yaml`` (a feasible design's gait, its
    header opening with why it is not verified) and ``NAME.failed.report.json`` (``status:
    failed``), in ``out`` or, when that fails, in a new temporary folder. Returns the files
    written (none if nothing could be) and the report."""
    import tempfile

    from ..files import output

    doc = _failed_doc(result, why, step)
    for attempt in range(2):
        try:
            folder = out if attempt == 0 else Path(
                tempfile.mkdtemp(prefix=f"thrustwalk-{gait_name}-"))
            gpath = folder / f"{gait_name}.failed.yaml"
            rpath = folder / f"{gait_name}.failed.report.json"
            text = _failed_text(result, robot, gpath, rpath.name, why, render)
            folder.mkdir(parents=True, exist_ok=True)
            files = []
            if text is not None:
                files.append(output.write_text_atomic(gpath, text))
            doc["failed_gait_file"] = str(gpath) if text is not None else None
            files.append(output.write_json(rpath, doc))
            return files, doc
        except Exception:  # noqa: BLE001 - try the next folder
            continue
    return [], doc


def _failed_doc(result, why: str, step: str) -> dict:
    """The report of a design whose keeping failed: the full report when it can be built,
    else the essentials (coefficients, alpha, thrust, re-check), marked failed."""
    from ..files import output

    try:
        prov = output.provenance(result.robot)
    except Exception:  # noqa: BLE001
        prov = {"tool": "thrustwalk"}
    try:
        body = result.document()
    except Exception:  # noqa: BLE001 - a bug in the report: keep what the design holds
        d = result.design
        body = {"robot": {"name": result.robot.name, "file": result.robot.source_file},
                "reason": d.reason, "alpha_c": list(d.c), "alpha_f": d.gait.alpha_f,
                "coefficients": [list(r) for r in d.gait.A], "thrust": list(d.thrust),
                "objective": {"name": d.spec.objective, "value": d.objective},
                "fixed_point": d.check.get("orbit"), "margins": d.check.get("margins"),
                "warnings": list(d.warnings)}
    recheck = result.success
    return {"provenance": prov, "robot": body.pop("robot", None), **body,
            "status": "failed", "feasible": False, "recheck_feasible": recheck,
            "error": why, "failed_step": step, "gait_file": None,
            "reason": f"design-gait failed after the search ({why}); the independent re-check "
                      f"of the design found it {'feasible' if recheck else 'infeasible'}"}


def _failed_text(result, robot: str, path: Path, report_name: str, why: str,
                 render: Callable[[str], str]) -> str | None:
    """The gait text of a feasible design kept after a failure (None for an infeasible one)."""
    from ..files import output
    from ..files.gait_file import robot_reference
    from ..studies.design_gait import failed_line, gait_yaml

    if not result.success:
        return None
    rob = result.robot
    try:
        ref = robot_reference(rob, robot, path)
    except Exception:  # noqa: BLE001
        ref = str(Path(rob.source_file).resolve()) if rob.source_file else rob.name
    try:
        return result.gait_text(output.provenance(rob), ref, report_name, render, failure=why)
    except Exception:  # noqa: BLE001 - the bare gait with the failure line
        return gait_yaml(result.design, result.model, ref,
                         [failed_line(why), f"Report: {report_name}."])


def _write_json_option(doc: dict, json: str | None) -> None:
    """The report to standard output (``-``) or to the ``--json`` file."""
    from ..files import output

    if json == "-":
        import json as _json

        sys.stdout.write(_json.dumps(output.jsonable(doc), indent=2) + "\n")
    elif json:
        output.write_json(Path(json), doc)


def _summary(doc: dict, out: Path, report: Path, files: list[Path]) -> None:
    from rich.markup import escape
    from rich.table import Table

    from ..design.verify import MARGIN_TOL
    from ..studies.documents import fmt, fmt_margin

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
    en = doc.get("energy") or {}
    cot = en.get("cot") or {}
    rows += [("CoT mechanical [1]", cot.get("mechanical")),
             ("CoT total [1]", cot.get("total"))]
    texts = [(label, fmt(v, ".5g")) for label, v in rows]
    for key in ("clearance_mid_step", "min_swing_height", "vertical_force", "friction",
                "impact_friction", "liftoff_velocity", "touchdown_velocity"):
        # within the re-check's tolerance: 0 (a dip of -9e-8 m passes the 1e-6 m check)
        texts.append((f"margin {key}", fmt_margin(m.get(key), ".5g", MARGIN_TOL.get(key, 0.0))))
    for label, text in texts:
        t.add_row(escape(label), text)
    console().print(t)
    if en and not en.get("exists"):
        console().print(f"energy: {en.get('reason')}", markup=False)
    for line in en.get("missing") or ():
        console().print(f"energy: {line}", markup=False)
    if "compare" in doc:
        c = doc["compare"]
        console().print(f"compare {c['gait']}: objective {c.get('objective')}, "
                        f"feasible {c['feasible']} (failed: {', '.join(c['failed']) or 'none'})")
    opt = doc.get("optimality") or {}
    if doc["feasible"] and opt and not opt.get("certified"):
        console().print(f"optimum NOT certified (start {opt.get('start')}: SLSQP "
                        f"{opt.get('slsqp_message')!r}); see the warning above", markup=False)
    if doc["feasible"]:
        console().print(f"wrote {', '.join(str(f) for f in files)}", markup=False)
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
            "--objective", help="effort: (1/L) int |u|^2 dt [N^2 m s]; peak: max |u| [N m]; cot: "
                               "mechanical cost of transport, joints' and thrusters' positive "
                               "work over m g L [1].")
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
        slope: SlopeOpt = 0.0,
        json: JsonOpt = None,
        formats: Annotated[str, typer.Option(
            "--formats", help="Figure kinds written beside the gait (NAME.stick.png/.pdf): "
                              "png, pdf or none.")] = "png,pdf",
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
                min_touchdown_velocity=min_touchdown_velocity,
                formats=parse_formats(formats, ("png", "pdf")),
                render=lambda text: render_mentions(text, ctx), slope=slope)
            if not doc["feasible"]:
                sys.stderr.write(f"infeasible: {render_mentions(doc['reason'], ctx)}\n")
                raise typer.Exit(INFEASIBLE_EXIT)
