"""``thrustwalk simulate``: full-order closed-loop hybrid simulation with thruster dynamics."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from .common import (
    check_out,
    cli_errors,
    console,
    ensure_kernel,
    load_walker,
    parse_formats,
    parse_values,
    progress,
    show_table,
    warn,
    write_result,
    wrote_line,
)
from .options import (
    F0Opt,
    FormatsOpt,
    GaitArg,
    JsonOpt,
    MuOpt,
    OutOpt,
    QuietOpt,
    RobotArg,
    SlopeOpt,
    TauOpt,
    ThrustersOpt,
    TitlesOpt,
    WnOpt,
    XiOpt,
    thrust_model_opt,
)

HELP = """Full-order hybrid simulation of the closed loop with thruster dynamics.

Controller: input-output linearisation y'' = -Kp y - Kd y' (gains from the gait file), which
cancels the thrust on the joints. Guard: swing-foot height crossing 0 downward after mid-step;
impact map and leg relabelling; thruster states carry across impacts. One run per steady thrust
value F_ss [N] (--thrust); each is compared step by step with the zero-dynamics prediction and
the reduced cascade (the zero dynamics in time). Thrust models: ideal (the thrust is the
command; `constant` is its deprecated name); first-order lag (tau [s]); second-order F'' + 2 xi
wn F' + wn^2 F = wn^2 F_ss (wn [rad/s], the paper's slow thruster); piecewise in alpha (the
gait's thrust: section; the default for a gait that has one when no --thrust is given). The
start is just after an impact on the predicted orbit (zeta^- = zeta* of the thrust at t = 0, or
of zero thrust with --start nominal), scaled by 1 + --perturb, or --zeta0 [kg^2 m^4/s^2], or
an explicit state --q0/--dq0.

A walker that falls (stance leg past horizontal, alpha reversing, negative vertical ground
force), scuffs (a strike before s = --min-impact-s, 0.75, counts as a scuff) or has an
infeasible impact, and a steady thrust without a periodic orbit to start on, are reported in
simulation.json (success, reason) with exit 0 (the other values still run); an integrator or
controller failure exits 1 (files are still written). A completed run whose impacts are
farther than --impact-s-tol from s = 1 or whose zeta^- leaves the zero-dynamics prediction by
more than --zeta-tol (a grazing or missed touchdown), or with a step out of the friction cone
(mu) or a saturated torque, has status "warning" with the reason, never "ok".

With --slope GAMMA [rad, positive uphill] the walker is on a slope: the run is in the
slope frame (gravity and world-frame thrusters turned, link-frame thrusters not; guard, impact
and relabelling unchanged), compared with the zero dynamics on that slope; speed is along the
ground, with the climb rate beside it, and ground forces are tangential and normal to it.
With --terrain FILE (docs/files.md) the walker walks steps or rough ground: step k's swing foot
lands h_k above its stance foot (the guard), a step-down is met on the gait continued past
s = 1 until the file's s_max (past it: missed_footing); each step records its terrain_height.

Writes DIR/simulation.json, DIR/steps.csv, DIR/trajectory.csv (.npz above 20000 samples),
DIR/thrust_time.png/.pdf, DIR/phase_portrait.png/.pdf and, with --animate, DIR/walker.gif.
"""

EPILOG = ("Example: thrustwalk simulate three_link three_link_walk --steps 30 --thrust-model "
          "second-order --thrust 0:-10:-2 --wn 2 --xi 1 --out out/sim")


def _floats(text: str | None, option: str) -> list[float] | None:
    return None if text is None else parse_values(text, option)


def run_simulate(robot: str | None, gait: str | None, *, steps: int, thrust_model: str | None,
                 thrust: str | None, wn: float, xi: float, tau: float, f0: float,
                 thrusters: list[str] | None, perturb: float, zeta0: float | None,
                 q0: str | None, dq0: str | None, start_orbit: str,
                 torque_limit: float | None, rtol: float, atol: float, method: str,
                 samples: int, scuff_tol: float, reduced: bool, animate: bool, out: Path,
                 quiet: bool, mu: float | None = None, json: str | None = None,
                 formats: set[str] | None = None, titles: bool = False,
                 min_impact_s: float = 0.75, impact_s_tol: float = 1e-3,
                 zeta_tol: float = 1e-3, integrator: str = "DOP853",
                 slope: float = 0.0, terrain: Path | None = None) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files import output
    from ..studies.simulate import default_f_ss, simulate

    values = _floats(thrust, "--thrust")
    q, dq = _floats(q0, "--q0"), _floats(dq0, "--dq0")
    check_out(out, json=json)
    walker = load_walker(robot, gait)
    gait_schedule = thrust_model is None and values is None and walker.gait.thrust is not None
    if gait_schedule and not quiet:
        warn(["no --thrust or --thrust-model given: the walker runs on the gait's own thrust: "
              "schedule (piecewise), started on its orbit"])
    n_runs = (1 if gait_schedule or thrust_model == "piecewise" else
              len(default_f_ss(walker)) if values is None else max(1, len(values)))
    args = dict(steps=steps, thrust_model=thrust_model, thrust=values, wn=wn, xi=xi,
                tau=tau, f0=f0, thruster=thrusters, perturb=perturb, zeta0=zeta0, q0=q, dq0=dq,
                start=start_orbit, torque_limit=torque_limit, rtol=rtol, atol=atol,
                method=method, integrator=integrator, samples=samples, scuff_tol=scuff_tol,
                min_impact_s=min_impact_s, impact_s_tol=impact_s_tol, zeta_tol=zeta_tol,
                reduced=reduced, mu=mu, slope=slope, terrain=terrain)
    simulate(walker, **args, check_only=True)  # every option before the kernel is compiled
    if method == "compiled" and not reduced:
        ensure_kernel(quiet)
    with progress("simulating steps", n_runs * steps, quiet) as advance:
        result = simulate(walker, **args, progress=advance)
    extra = {}
    if animate:
        gif = result.animation()
        if gif is None:
            warn(["nothing to animate: no full-order run has samples (every run failed at "
                  "its start, or --reduced)"])
        else:
            extra["walker.gif"] = gif
    doc = write_result(result, out, output.provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles, extra=extra)
    for r in doc["runs"]:
        if r["status"] != "ok":
            status = "" if r["status"] == "warning" else f"{r['status']}: "  # said once
            warn([f"run {r['run']} (F_ss = {r['f_ss']}): {status}{r['reason']}"] +
                 [f"run {r['run']}: {w}" for w in r["warnings"] if w not in r["deviations"]])
    if not quiet and json != "-":
        _table(doc)
        console().print(wrote_line(out), markup=False)
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    def status(r: dict) -> str:
        if r["status"] == "ok":
            return "ok"
        if r["status"] == "warning":
            return "warning (off the prediction)" if r["deviations"] else "warning"
        return f"{r['failure']} ({r['reason'].split(':')[0]})"

    rows = [[fmt(r["f_ss"]), str(r["steps_completed"]), fmt(r["final_zeta_minus"]),
             fmt(r["predicted"]["zeta_star"]) if r["predicted"]["exists"] else "no orbit",
             fmt(r["final_relative_error"], ".2e"),
             status(r)] for r in doc["runs"]]
    on = f", on the slope {doc['slope']['angle']:.4g} rad" if doc.get("slope") else ""
    show_table(f"simulate: {doc['robot']['name']} / {doc['gait']['name']}{on} "
               f"({doc['settings']['thrust_model']}, delta_zero^2 = "
               f"{doc['zero_dynamics']['delta_zero_sq']:.4f})",
               [("F_ss\n[N]", True), ("steps", True), ("final ζ⁻\n[kg^2 m^4/s^2]", True),
                ("predicted ζ*\n[kg^2 m^4/s^2]", True), ("rel. error\n[-]", True),
                ("status", False)], rows)


def register(app: typer.Typer) -> None:
    @app.command("simulate", help=HELP, epilog=EPILOG)
    def simulate_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        steps: Annotated[int, typer.Option("--steps", help="Steps per run.")] = 30,
        thrust_model: Annotated[str | None, thrust_model_opt("second-order")] = None,
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help="Steady thrust F_ss [N], one run per value: start:stop:step or "
                             "a comma list (default 0:-50:-10, or 0 for a robot without "
                             "thrusters; not with piecewise).")] = None,
        wn: WnOpt = 2.0,
        xi: XiOpt = 1.0,
        tau: TauOpt = 0.5,
        f0: F0Opt = 0.0,
        thruster: ThrustersOpt = None,
        perturb: Annotated[float, typer.Option(
            "--perturb", help="Relative change of the start's pre-impact zeta^- [1], e.g. "
                              "0.2 = 20 % more.")] = 0.0,
        start: Annotated[str, typer.Option(
            "--start", help="Start on the fixed point of the thrust at t = 0 (predicted) or "
                            "of zero thrust (nominal).")] = "predicted",
        zeta0: Annotated[float | None, typer.Option(
            "--zeta0", help="Start's pre-impact zeta^- [kg^2 m^4/s^2] (default: the predicted "
                            "fixed point).")] = None,
        q0: Annotated[str | None, typer.Option(
            "--q0", help="Explicit initial configuration [rad], comma list.")] = None,
        dq0: Annotated[str | None, typer.Option(
            "--dq0", help="Explicit initial rates [rad/s], comma list.")] = None,
        torque_limit: Annotated[float | None, typer.Option(
            "--torque-limit", help="Joint torque bound |u| [N m] (default: none).")] = None,
        mu: MuOpt = None,
        slope: SlopeOpt = 0.0,
        terrain: Annotated[Path | None, typer.Option(
            "--terrain", help="Terrain file (YAML, docs/files.md): a slope and step heights "
                              "(explicit or rough, seeded).")] = None,
        rtol: Annotated[float, typer.Option("--rtol", help="Integrator relative tolerance.")
                        ] = 1e-9,
        atol: Annotated[float, typer.Option(
            "--atol", help="Integrator absolute tolerance [rad, rad/s].")] = 1e-9,
        method: Annotated[str, typer.Option(
            "--method", help="compiled (numba kernel, DOP853; compiled once per machine) or "
                             "scipy (solve_ivp, the reference). A solve_ivp name (DOP853, "
                             "RK45, Radau, LSODA, BDF) means scipy with that "
                             "integrator.")] = "compiled",
        integrator: Annotated[str, typer.Option(
            "--integrator", help="solve_ivp method with --method scipy: DOP853, RK45, Radau, "
                                 "LSODA, BDF.")] = "DOP853",
        samples: Annotated[int, typer.Option(
            "--samples", help="Stored trajectory samples per step.")] = 80,
        scuff_tol: Annotated[float, typer.Option(
            "--scuff-tol", help="Depth the swing foot may dip before mid-step [m].")] = 1e-4,
        min_impact_s: Annotated[float, typer.Option(
            "--min-impact-s", help="Early-strike threshold [1]: a swing-foot strike before this "
                                   "s counts as a scuff (0.5 <= value < 1).")] = 0.75,
        impact_s_tol: Annotated[float, typer.Option(
            "--impact-s-tol", help="Warn when a step's impact is farther than this from s = 1 "
                                   "[1].")] = 1e-3,
        zeta_tol: Annotated[float, typer.Option(
            "--zeta-tol", help="Warn when a step's zeta^- differs from the zero-dynamics "
                               "prediction by more than this [1, relative].")] = 1e-3,
        reduced: Annotated[bool, typer.Option(
            "--reduced", help="Fast preview: the reduced cascade (zero dynamics plus thruster "
                              "states) only.")] = False,
        animate: Annotated[bool, typer.Option(
            "--animate", help="Also write DIR/walker.gif (the last run).")] = False,
        out: OutOpt = Path("out/simulate"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            doc = run_simulate(
                robot, gait, steps=steps, thrust_model=thrust_model, thrust=thrust, wn=wn,
                xi=xi, tau=tau, f0=f0, thrusters=thruster, perturb=perturb, zeta0=zeta0, q0=q0,
                dq0=dq0, start_orbit=start, torque_limit=torque_limit, rtol=rtol,
                atol=atol, method=method, samples=samples, scuff_tol=scuff_tol,
                reduced=reduced, animate=animate, out=out, quiet=quiet, mu=mu, json=json,
                formats=parse_formats(formats), titles=titles, min_impact_s=min_impact_s,
                impact_s_tol=impact_s_tol, zeta_tol=zeta_tol, integrator=integrator,
                slope=slope, terrain=terrain)
        if any(r["failure"] in ("integrator", "controller") for r in doc["runs"]):
            sys.stderr.write("error: an integrator or controller failure ended a run (see "
                             f"{out}/simulation.json)\n")
            raise typer.Exit(1)
