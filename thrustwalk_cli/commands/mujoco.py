"""``thrustwalk mujoco``: the gait's controller on MuJoCo's physics with soft contact, step by
step beside the rigid-impact model (SPEC 16)."""

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
    parse_push,
    parse_values,
    progress,
    show_table,
    warn,
    write_result,
    wrote_line,
)
from .options import (
    ContactOpt,
    F0Opt,
    FootRadiusOpt,
    FormatsOpt,
    GaitArg,
    JsonOpt,
    MuOpt,
    OutOpt,
    PushOpt,
    QuietOpt,
    RobotArg,
    SolimpOpt,
    SolrefOpt,
    TauOpt,
    ThrustersOpt,
    TimestepOpt,
    TitlesOpt,
    WnOpt,
    XiOpt,
    thrust_model_opt,
)

HELP = """Run the gait's controller on MuJoCo's physics (soft contact) and compare every step
with the rigid-impact model: a second opinion on the contact.

The robot is the MJCF of export-mjcf (feet: spheres of --foot-radius, friction --mu). The
controller is simulate's output-zeroing law (gains from the gait file), evaluated from
thrustwalk's model at MuJoCo's state every MuJoCo step; thrusters push at their points with
the dynamics of --thrust-model. The run starts just after an impact on the predicted orbit;
a touchdown is the swing foot's first contact once s > --min-impact-s, and the legs are
relabelled then (the model is re-rooted at the new stance foot). Per step: zeta^- (from
MuJoCo's state, thrustwalk's sigma_N), step time, step length, speed, and what the rigid model
cannot see: foot slip, friction use, bounce, double-support time, penetration; beside each
the rigid model's prediction (the reduced cascade from the same start) and the difference.
Contact: --contact soft|default|stiff (solref, solimp, timestep in docs/commands.md), or
--solref/--solimp/--timestep. A run that completes is "ok" when its last zeta^- is within
--zeta-tol of the rigid prediction and no step slips more than --slip-tol, else "warning"
with the gap; a fall is "failed" (exit 0; the files are written).

Writes DIR/mujoco.json, DIR/steps.csv, DIR/trajectory.csv, DIR/robot.xml (the model that
ran), DIR/phase_portraits.png/.pdf and DIR/walker.gif (rendered offscreen by MuJoCo with EGL
or OSMesa; skipped with a message where neither works, or with --no-video). Needs MuJoCo:
pip install 'thrustwalk[mujoco]'.
"""
EPILOG = ("Example: thrustwalk mujoco three_link three_link_walk --steps 20 --thrust 0,-20 "
          "--contact stiff --out out/mujoco")


def _floats(text: str | None, option: str, n: tuple[int, ...]) -> list[float] | None:
    if text is None:
        return None
    from ..errors import InputError

    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) not in n:
        raise InputError(f"option {option}: expected {' or '.join(map(str, n))} comma-separated "
                         f"numbers, got {text!r}")
    return vals


def contact_from_options(preset: str, *, timestep: float | None = None,
                         solref: str | None = None, solimp: str | None = None,
                         foot_radius: float | None = None, integrator: str | None = None):
    """The :class:`ContactModel` of the command line's contact options."""
    from ..interchange.mjcf import contact_settings

    return contact_settings(preset, timestep=timestep, solref=_floats(solref, "--solref", (2,)),
                            solimp=_floats(solimp, "--solimp", (3, 5)), integrator=integrator,
                            foot_radius=foot_radius)


def run_mujoco_command(robot: str, gait: str | None, *, steps: int, thrust_model: str | None,
                       thrust: str | None, wn: float, xi: float, tau: float, f0: float,
                       thrusters: list[str] | None, push: list[str] | None,
                       mu: float | None, contact: str, timestep: float | None,
                       solref: str | None, solimp: str | None, foot_radius: float | None,
                       integrator: str | None, perturb: float, min_impact_s: float,
                       zeta_tol: float, slip_tol: float, video: bool, out: Path,
                       quiet: bool, json: str | None = None, formats: set[str] | None = None,
                       titles: bool = False) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files import output
    from ..studies.mujoco import VIDEO_FPS, mujoco_run

    values = None if thrust is None else parse_values(thrust, "--thrust", "N")
    pushes = parse_push(push)
    ct = contact_from_options(contact, timestep=timestep, solref=solref, solimp=solimp,
                              foot_radius=foot_radius, integrator=integrator)
    check_out(out, json=json)
    walker = load_walker(robot, gait)
    n_runs = 1 if (values is None or thrust_model == "piecewise") else len(values)
    with progress("MuJoCo steps", n_runs * steps, quiet) as advance:
        result = mujoco_run(walker, steps=steps, thrust_model=thrust_model, thrust=values,
                            wn=wn, xi=xi, tau=tau, f0=f0, thruster=thrusters, push=pushes,
                            mu=mu, contact=ct, perturb=perturb, min_impact_s=min_impact_s,
                            zeta_tol=zeta_tol, slip_tol=slip_tol,
                            fps=VIDEO_FPS if video else 0.0, progress=advance)
    extra = {}
    if video:
        gif, note = result.video()
        if gif is None:
            warn([note])
        else:
            extra["walker.gif"] = gif
            if not quiet and json != "-":
                console(stderr=True).print(note, markup=False)
    doc = write_result(result, out, output.provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles, extra=extra)
    for r in doc["runs"]:
        if r["status"] != "ok":
            status = "" if r["status"] == "warning" else f"{r['status']}: "  # said once
            warn([f"run {r['run']} (F_ss = {r['f_ss']}): {status}{r['reason']}"])
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out), markup=False)
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    last: dict[int, dict] = {}
    for e in doc["steps"]:
        last[e["run"]] = e
    rows = []
    for r in doc["runs"]:
        e = last.get(r["run"])
        z = e["zeta_minus"] if e else {}
        rows.append([fmt(r["f_ss"]), str(r["steps_completed"]), fmt(z.get("mujoco")),
                     fmt(z.get("rigid")), fmt(None if z.get("relative") is None
                                              else 100 * z["relative"], "+.3g"),
                     fmt(None if e is None else 1e3 * e["slip_path"]["mujoco"], ".3g"),
                     fmt(None if e is None else 1e3 * e["penetration"]["mujoco"], ".3g"),
                     r["status"]])
    c = doc["mujoco"]["contact"]
    show_table(f"mujoco: {doc['robot']['name']} / {doc['gait']['name']} (contact "
               f"{c['preset']}, solref {c['solref'][0]:g} s, timestep {c['timestep']:g} s, "
               f"mu {doc['mujoco']['mu']:g})",
               [("F_ss\n[N]", True), ("steps", True), ("last ζ⁻ MuJoCo\n[kg^2 m^4/s^2]", True),
                ("rigid\n[kg^2 m^4/s^2]", True), ("gap\n[%]", True), ("slip\n[mm]", True),
                ("penetration\n[mm]", True), ("status", False)], rows)


def register(app: typer.Typer) -> None:
    @app.command("mujoco", help=HELP, epilog=EPILOG)
    def mujoco_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        steps: Annotated[int, typer.Option("--steps", help="Steps per run.")] = 20,
        thrust_model: Annotated[str | None, thrust_model_opt("ideal")] = None,
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help="Steady thrust F_ss [N], one run per value: start:stop:step or a "
                             "comma list (default 0).")] = None,
        wn: WnOpt = 2.0,
        xi: XiOpt = 1.0,
        tau: TauOpt = 0.5,
        f0: F0Opt = 0.0,
        thruster: ThrustersOpt = None,
        push: PushOpt = None,
        mu: MuOpt = None,
        contact: ContactOpt = "default",
        timestep: TimestepOpt = None,
        solref: SolrefOpt = None,
        solimp: SolimpOpt = None,
        foot_radius: FootRadiusOpt = None,
        integrator: Annotated[str | None, typer.Option(
            "--integrator", help="MuJoCo integrator: implicitfast (default) or Euler.")
                             ] = None,
        perturb: Annotated[float, typer.Option(
            "--perturb", help="Relative change of the start's zeta^- [1].")] = 0.0,
        min_impact_s: Annotated[float, typer.Option(
            "--min-impact-s", help="The guard is armed (the swing foot's contact switched on) "
                                   "from this s [1] (0.5 <= value < 1).")] = 0.75,
        zeta_tol: Annotated[float, typer.Option(
            "--zeta-tol", help="Warn when the last zeta^- differs from the rigid prediction "
                               "by more than this [1, relative].")] = 0.02,
        slip_tol: Annotated[float, typer.Option(
            "--slip-tol", help="Warn when the stance foot slips more than this in a step "
                               "[m].")] = 0.01,
        video: Annotated[bool, typer.Option(
            "--video/--no-video", help="Render DIR/walker.gif offscreen (EGL or OSMesa).")
                         ] = True,
        out: OutOpt = Path("out/mujoco"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            run_mujoco_command(
                robot, gait, steps=steps, thrust_model=thrust_model, thrust=thrust, wn=wn,
                xi=xi, tau=tau, f0=f0, thrusters=thruster, push=push, mu=mu, contact=contact,
                timestep=timestep, solref=solref, solimp=solimp, foot_radius=foot_radius,
                integrator=integrator, perturb=perturb, min_impact_s=min_impact_s,
                zeta_tol=zeta_tol, slip_tol=slip_tol, video=video, out=out, quiet=quiet,
                json=json, formats=parse_formats(formats), titles=titles)
