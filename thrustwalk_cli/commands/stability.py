"""``thrustwalk stability``: Floquet multipliers of the full-order closed loop with thruster
states, for one setting or a sweep of one parameter."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from .common import (
    MAX_VALUES,
    check_out,
    cli_errors,
    console,
    ensure_kernel,
    load_walker,
    parse_formats,
    parse_values,
    progress,
    render_mentions,
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
    TauOpt,
    ThrusterOpt,
    TitlesOpt,
    WnOpt,
    XiOpt,
    thrust_model_opt,
)

HELP = """Floquet multipliers of the full-order hybrid closed loop, thruster states included.

The Poincare map on the impact surface (state just before impact: q [rad], q' [rad/s] and the
thruster states [N, N/s]) is the impact map followed by one closed-loop step of the compiled
simulation. Its fixed point is found by Newton's method from the zero-dynamics prediction (the
residual is reported). Its Jacobian on the guard's tangent space (dimension 2N - 1 + n_z; the
trivial multiplier normal to the guard is dropped) is computed two ways, by central differences
(the step chosen from a sweep, its convergence reported) and by the variational equations along
the orbit with the saltation matrix at the guard, and their multipliers must agree: each within
max(1e-6, 10 x the finite-difference error estimate carried to that multiplier, the
finite-difference entries' error estimate), or within --agreement-tol when given (the
Jacobians' entry difference is reported, not judged). The multipliers [1] are sorted by modulus
with their eigenvectors' dominant components; the one of the zero dynamics is identified and
compared with delta_zero^2; the spectral radius gives the verdict: stable, unstable, or
undetermined (Newton did not converge, the multipliers disagree, or the radius is within its
error bar of 1, the reason saying what to try), never better than the evidence; "no orbit" when
the zero dynamics has no periodic orbit to start from.

--vary NAME=VALUES sweeps one parameter, one analysis per value: kp [1/s^2], kd [1/s] (the output
gains y'' = -kp y - kd y'), wn [rad/s], xi [1] (second-order thruster), tau [s] (first-order
thruster) or thrust [N] (F_ss). VALUES is start:stop:logK (K values evenly spaced in log),
start:stop:step, or a comma list.

With --slope GAMMA [rad, positive uphill] the analysis is on a slope: the orbit, the
compiled simulation and the variational equations are in the slope frame (gravity and
world-frame thrusters turned); delta_zero^2 does not depend on the slope.

Writes DIR/stability.json, DIR/multipliers.csv, DIR/multipliers.png/.pdf (the complex plane
with the unit circle) and, with --vary, DIR/spectral_radius.png/.pdf (the modulus of each
multiplier against the parameter, delta_zero^2 as reference). Undetermined cases are warnings
(exit 0); bad options exit 2.
"""

EPILOG = ("Example: thrustwalk stability three_link three_link_walk --thrust-model second-order "
          "--wn 2 --xi 0.7 --thrust -20 --vary wn=0.5:50:log20 --out out/stability")

MAX_SWEEP = 200  # values of one --vary (each takes a few seconds)


def parse_vary(text: str) -> tuple[str, list[float]]:
    """``NAME=start:stop:logK`` (K log-spaced values, both ends included), ``NAME=start:stop:
    step`` or ``NAME=v1,v2,...`` -> (name, values). :class:`InputError` naming ``--vary``."""
    def bad(msg: str) -> InputError:
        return InputError(f"option --vary: {msg} (got {text!r}; use e.g. wn=0.5:50:log20 or "
                          "kp=100,400,1600)")

    name, sep, spec = text.partition("=")
    name, spec = name.strip(), spec.strip()
    if not sep or not name or not spec:
        raise bad("expected NAME=VALUES")
    parts = spec.split(":")
    if len(parts) == 3 and parts[2].strip().lower().startswith("log"):
        try:
            lo, hi = float(parts[0]), float(parts[1])
            k = int(parts[2].strip()[3:])
        except ValueError:
            raise bad("a log range is start:stop:logK with K an integer") from None
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo <= 0 or hi <= 0:
            raise bad("a log range needs start and stop > 0")
        if not 2 <= k <= MAX_VALUES:
            raise bad(f"a log range needs 2 to {MAX_VALUES} values")
        if k > MAX_SWEEP:
            raise bad(f"{k} values: the limit is {MAX_SWEEP}")
        r = math.log(hi / lo)
        return name, [lo * math.exp(r * i / (k - 1)) for i in range(k)]
    values = parse_values(spec, "--vary")
    if len(values) > MAX_SWEEP:
        raise bad(f"{len(values)} values: the limit is {MAX_SWEEP}")
    return name, values


def _one_thrust(text: str | None) -> float | None:
    if text is None:
        return None
    values = parse_values(text, "--thrust")
    if len(values) != 1:
        raise InputError("option --thrust: one steady thrust per analysis (got "
                         f"{len(values)} values); sweep it with --vary thrust=START:STOP:STEP")
    return values[0]


def run_stability(robot: str | None, gait: str | None, *, thrust_model: str | None,
                  thrust: str | None, thruster: str | None, wn: float, xi: float, tau: float,
                  kp: float | None, kd: float | None, vary: str | None, rtol: float,
                  atol: float, out: Path, quiet: bool, json: str | None = None,
                  formats: set[str] | None = None, titles: bool = False,
                  agreement_tol: float | None = None, ctx: typer.Context | None = None,
                  slope: float = 0.0) -> dict:
    """Plain function behind the command; returns the JSON document it wrote."""
    from ..files import output
    from ..floquet.multipliers import check_agreement_tol
    from ..studies.stability import stability

    F = _one_thrust(thrust)
    check_agreement_tol(agreement_tol)
    sweep = parse_vary(vary) if vary is not None else None
    check_out(out)
    walker = load_walker(robot, gait)
    n = 1 if sweep is None else len(sweep[1])
    args = dict(thrust_model=thrust_model, thrust=F, thruster=thruster, wn=wn, xi=xi, tau=tau,
                kp=kp, kd=kd, vary=sweep, rtol=rtol, atol=atol, agreement_tol=agreement_tol,
                slope=slope)
    stability(walker, **args, check_only=True)  # every option before the kernel is compiled
    ensure_kernel(quiet)
    with progress("analysing settings", n, quiet) as advance:
        result = stability(walker, **args, progress=advance)
    doc = write_result(result, out, output.provenance(walker.robot, walker.gait), json=json,
                       formats=formats, titles=titles)
    warn([w for w in doc["warnings"] if w not in walker.warnings])
    if not quiet and json != "-":
        _table(doc)
        console().print(f"verdict: {doc['verdict']}: {render_mentions(doc['reason'], ctx)}",
                        markup=False)
        console().print(wrote_line(out), markup=False)
    return doc


def _table(doc: dict) -> None:
    from ..studies.documents import fmt

    vary = doc["settings"]["vary"]
    rows = []
    for c in doc["cases"]:
        ag = (c["jacobian"] or {}).get("agreement") or {}
        zdm = c["zero_dynamics"] or {}
        fp = c["fixed_point"] or {}
        lead = c["multipliers"][:3]
        rows.append(([fmt(c["value"])] if vary else []) + [
            fmt(c["spectral_radius"], ".6g"),
            fmt(None if not zdm else zdm["multiplier"]["re"], ".6g"),
            fmt(zdm.get("difference"), ".1e"),
            fmt(((fp.get("newton") or {}).get("residual")), ".1e"),
            fmt(ag.get("multipliers"), ".1e"),
            ", ".join(f"{m['modulus']:.3g} ({m['kind']})" for m in lead) or "—",
            c["verdict"]])
    cols = ([(f"{vary['parameter']}\n[{vary['unit']}]", True)] if vary else []) + [
        ("spectral\nradius [1]", True), ("ZD multiplier\n[1]", True),
        ("|λ_Z - δ²|\n[1]", True), ("Newton\nresidual [1]", True),
        ("FD vs var.\nλ [1]", True), ("largest |λ| [1]", False), ("verdict", False)]
    s = doc["settings"]
    on = f", on the slope {doc['slope']['angle']:.4g} rad" if doc.get("slope") else ""
    show_table(f"stability: {doc['robot']['name']} / {doc['gait']['name']}{on} "
               f"({s['thrust_model']}, delta_zero^2 = "
               f"{doc['zero_dynamics']['delta_zero_sq']:.6f})", cols, rows)


def register(app: typer.Typer) -> None:
    @app.command("stability", help=HELP, epilog=EPILOG)
    def stability_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        gait: GaitArg = None,
        thrust_model: Annotated[str | None, thrust_model_opt("second-order")] = None,
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help="Steady thrust F_ss [N], one value (default 0; sweep it with "
                             "--vary thrust=...).")] = None,
        thruster: ThrusterOpt = None,
        wn: WnOpt = 2.0,
        xi: XiOpt = 1.0,
        tau: TauOpt = 0.5,
        kp: Annotated[float | None, typer.Option(
            "--kp", help="Output gain K_p [1/s^2] (default: the gait's).")] = None,
        kd: Annotated[float | None, typer.Option(
            "--kd", help="Output gain K_d [1/s] (default: the gait's).")] = None,
        vary: Annotated[str | None, typer.Option(
            "--vary", metavar="NAME=VALUES",
            help="Sweep one parameter: kp [1/s^2], kd [1/s], wn [rad/s], xi [1], tau [s] or "
                 "thrust [N]; VALUES start:stop:logK, start:stop:step or a comma list, e.g. "
                 "wn=0.5:50:log20.")] = None,
        rtol: Annotated[float, typer.Option(
            "--rtol", help="Relative tolerance of the compiled simulation (finite differences "
                           "need about 1e-12).")] = 1e-12,
        atol: Annotated[float, typer.Option(
            "--atol", help="Absolute tolerance [rad, rad/s, N].")] = 1e-12,
        agreement_tol: Annotated[float | None, typer.Option(
            "--agreement-tol",
            help="Largest accepted difference [1] between the multipliers of the finite "
                 "differences and the variational equations (default: max(1e-6, 10 x the "
                 "finite-difference error estimate of each multiplier, the finite-difference "
                 "entries' error estimate)); the spectral radius "
                 "must still clear 1 by more than the disagreement.")] = None,
        slope: SlopeOpt = 0.0,
        out: OutOpt = Path("out/stability"),
        json: JsonOpt = None,
        formats: FormatsOpt = "csv,png,pdf",
        titles: TitlesOpt = False,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            run_stability(robot, gait, thrust_model=thrust_model, thrust=thrust,
                          thruster=thruster, wn=wn, xi=xi, tau=tau, kp=kp, kd=kd, vary=vary,
                          rtol=rtol, atol=atol, out=out, quiet=quiet, json=json,
                          formats=parse_formats(formats), titles=titles,
                          agreement_tol=agreement_tol, ctx=ctx, slope=slope)
