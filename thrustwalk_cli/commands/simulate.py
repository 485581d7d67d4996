"""``thrustwalk simulate``: full-order closed-loop hybrid simulation with thruster dynamics."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from .common import (
    cli_errors,
    console,
    figure_formats,
    parse_values,
    progress,
    write_result,
)
from .options import FormatsOpt, GaitArg, OutOpt, QuietOpt, RobotArg

HELP = """Full-order hybrid simulation of the closed loop with thruster dynamics.

Controller: input-output linearisation y'' = -Kp y - Kd y' (gains from the gait file), which
cancels the thrust on the joints. Guard: swing-foot height crossing 0 downward after mid-step;
impact map and leg relabelling; thruster states carry across impacts. One run per F_ss value
[N]; each is compared step by step with the zero-dynamics prediction and the reduced cascade
(the zero dynamics in time). Thrust models: constant; first-order lag (tau [s]); second-order
F'' + 2 xi wn F' + wn^2 F = wn^2 F_ss (wn [rad/s], the paper's slow thruster); piecewise in
alpha (the gait's thrust: section). The start is just after an impact on the predicted orbit
(zeta^- = zeta* of the thrust at t = 0, or of zero thrust with --start nominal), scaled by
1 + --perturb, or --zeta0 [kg^2 m^4/s^2], or an explicit state --q0/--dq0.

A walker that falls (stance leg past horizontal, alpha reversing, negative vertical ground
force), scuffs or has an infeasible impact is reported in simulation.json (success, reason)
with exit 0; an integrator or controller failure exits 1 (files are still written).

Writes DIR/simulation.json, DIR/steps.csv, DIR/trajectory.csv (.npz above 20000 samples),
DIR/thrust_time.png/.pdf, DIR/phase_portrait.png/.pdf and, with --animate, DIR/walker.gif.
"""

EPILOG = ("Example: thrustwalk simulate three_link three_link_walk --steps 30 --thrust-model "
          "second-order --f-ss 0:-10:-2 --wn 2 --xi 1 --out out/sim")


def _floats(text: str | None, option: str) -> list[float] | None:
    return None if text is None else parse_values(text, option)


def run_simulate(robot: str, gait: str, *, steps: int, thrust_model: str, f_ss: str | None,
                 wn: float, xi: float, tau: float, f0: float, thrusters: list[str] | None,
                 perturb: float, zeta0: float | None, q0: str | None, dq0: str | None,
                 start_orbit: str,
                 torque_limit: float | None, rtol: float, atol: float, method: str,
                 samples: int, scuff_tol: float, reduced: bool, animate: bool, out: Path,
                 quiet: bool, integrator: str = "DOP853", formats: str = "png,pdf") -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files import output
    from ..studies.simulate import simulate
    from ..walker import load_walker

    values = _floats(f_ss, "--f-ss")
    q, dq = _floats(q0, "--q0"), _floats(dq0, "--dq0")
    walker = load_walker(robot, gait)
    n_runs = max(1, len(values)) if values is not None else (
        1 if thrust_model == "piecewise" else 6)
    with progress("simulating steps", n_runs * steps, quiet) as advance:
        result = simulate(
            walker, steps=steps, thrust_model=thrust_model, f_ss=values, wn=wn, xi=xi, tau=tau,
            f0=f0, thruster=thrusters, perturb=perturb, zeta0=zeta0, q0=q, dq0=dq,
            start=start_orbit, torque_limit=torque_limit, rtol=rtol, atol=atol, method=method,
            integrator=integrator, samples=samples, scuff_tol=scuff_tol, reduced=reduced,
            progress=advance)
    doc = write_result(result, out, output.provenance(walker.robot, walker.gait),
                       formats=figure_formats(formats))
    if animate:
        output.write_bytes_atomic(out / "walker.gif", result.animation())
    if not quiet:
        _table(doc)
    return doc


def _table(doc: dict) -> None:
    from rich.table import Table

    from ..studies.records import fmt

    t = Table(title=f"simulate: {doc['robot']['name']} / {doc['gait']['name']} "
                    f"({doc['settings']['thrust_model']}, delta_zero^2 = "
                    f"{doc['zero_dynamics']['delta_zero_sq']:.4f})")
    for col in ("F_ss [N]", "steps", "final ζ⁻", "predicted ζ*", "rel. error", "status"):
        t.add_column(col, overflow="fold")
    for r in doc["runs"]:
        t.add_row(fmt(r["f_ss"]), str(r["steps_completed"]), fmt(r["final_zeta_minus"]),
                  fmt(r["predicted"]["zeta_star"]), fmt(r["final_relative_error"], ".2e"),
                  "ok" if r["success"] else f"{r['failure']} ({r['reason'].split(':')[0]})")
    console().print(t)


def register(app: typer.Typer) -> None:
    @app.command("simulate", help=HELP, epilog=EPILOG)
    def simulate_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = "three_link_walk",
        steps: Annotated[int, typer.Option("--steps", help="Steps per run.")] = 30,
        thrust_model: Annotated[str, typer.Option(
            "--thrust-model",
            help="constant | first-order | second-order | piecewise.")] = "second-order",
        f_ss: Annotated[str | None, typer.Option(
            "--f-ss", help="Steady thrust F_ss [N], one run per value: start:stop:step or a "
                           "comma list (default 0:-50:-10; not with piecewise).")] = None,
        wn: Annotated[float, typer.Option(
            "--wn", help="Second-order thruster natural frequency [rad/s].")] = 2.0,
        xi: Annotated[float, typer.Option(
            "--xi", help="Second-order thruster damping ratio [1].")] = 1.0,
        tau: Annotated[float, typer.Option(
            "--tau", help="First-order thruster time constant [s].")] = 0.5,
        f0: Annotated[float, typer.Option(
            "--f0", help="Thrust at t = 0 of the dynamic thrusters [N].")] = 0.0,
        thruster: Annotated[list[str] | None, typer.Option(
            "--thruster", metavar="NAME",
            help="Thruster driven by F_ss (repeat for several; default: the "
                               "first).")] = None,
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
        rtol: Annotated[float, typer.Option("--rtol", help="Integrator relative tolerance.")
                        ] = 1e-9,
        atol: Annotated[float, typer.Option(
            "--atol", help="Integrator absolute tolerance [rad, rad/s].")] = 1e-9,
        method: Annotated[str, typer.Option(
            "--method", help="compiled (numba kernel, DOP853; compiled once per robot) or "
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
        reduced: Annotated[bool, typer.Option(
            "--reduced", help="Fast preview: the reduced cascade (zero dynamics plus thruster "
                              "states) only.")] = False,
        animate: Annotated[bool, typer.Option(
            "--animate", help="Also write DIR/walker.gif (the last run).")] = False,
        out: OutOpt = Path("out/simulate"),
        formats: FormatsOpt = "png,pdf",
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            doc = run_simulate(
                robot, gait, steps=steps, thrust_model=thrust_model, f_ss=f_ss, wn=wn, xi=xi,
                tau=tau, f0=f0, thrusters=thruster, perturb=perturb, zeta0=zeta0, q0=q0,
                dq0=dq0, start_orbit=start, torque_limit=torque_limit, rtol=rtol,
                atol=atol, method=method, samples=samples, scuff_tol=scuff_tol,
                reduced=reduced, animate=animate, out=out, quiet=quiet,
                integrator=integrator, formats=formats)
        tool = [r for r in doc["runs"] if r["failure"] in ("integrator", "controller")]
        for r in doc["runs"]:
            if not r["success"]:
                sys.stderr.write(f"warning: run {r['run']} (F_ss = {r['f_ss']}): "
                                 f"{r['reason']}\n")
        if not quiet:
            ext = "/".join("." + f for f in figure_formats(formats))
            figs = f", thrust_time{ext}, phase_portrait{ext}" if ext else ""
            console().print(f"wrote {out}/simulation.json, steps.csv, "
                            f"{doc['trajectory_file']}{figs}"
                            + (", walker.gif" if animate else ""))
        if tool:
            raise typer.Exit(1)
