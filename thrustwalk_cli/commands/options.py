"""Options shared by several commands, defined once: one name per concept, units in the help."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

RobotArg = Annotated[
    str,
    typer.Argument(help="Robot: a bundled name (three_link, rabbit) or a path to a YAML file."),
]
GaitArg = Annotated[
    str | None,
    typer.Argument(help="Gait: a bundled name (three_link_walk, rabbit_walk) or a YAML path "
                        "(default: the robot's bundled gait)."),
]
OutOpt = Annotated[
    Path, typer.Option("--out", "-o", help="Output folder (created if missing; an existing "
                                           "file is refused).")
]
QuietOpt = Annotated[
    bool, typer.Option("--quiet", "-q", help="No progress and no summary table (warnings and "
                                             "errors still go to standard error).")
]
JsonOpt = Annotated[
    str | None, typer.Option("--json", metavar="PATH", help="Also write the JSON document to "
                             "PATH; '-' writes it to standard output instead of the summary "
                             "table, for piping.")
]
FormatsOpt = Annotated[
    str, typer.Option("--formats", help="Files to write besides the JSON, a comma list of "
                                        "the kinds this command writes (csv, png, pdf, svg; "
                                        "feasibility: png, pdf, md, no csv; optimize: png, "
                                        "pdf), or none (only the JSON; no figure is drawn).")
]
TitlesOpt = Annotated[
    bool, typer.Option("--titles", help="Put a title (robot / gait: what) on every figure "
                                        "(off: figures for a paper carry captions instead).")
]
ThrustOpt = Annotated[
    str | None, typer.Option("--thrust", help="Constant thrust values [N]: start:stop:step or "
                                              "a comma list (default: the gait's thrust: "
                                              "section, else 0:-50:-10).")
]
ThrusterOpt = Annotated[
    str | None, typer.Option("--thruster", metavar="NAME",
                             help="Thruster driven by the thrust values (default: the first).")
]
# the thruster models (thrust/dynamics.MODELS and piecewise): listed here without importing
# numpy (help stays fast); tests/test_cli.py checks the list against the option table
THRUST_MODEL_NAMES = "ideal | first-order | second-order | piecewise"


def thrust_model_opt(default: str, piecewise: bool = True):
    """The ``--thrust-model`` option. ``piecewise``: the command takes a gait's ``thrust:``
    schedule, its default for a gait that has one and no ``--thrust``, else ``default``
    (simulate and stability: second-order; mujoco: ideal); without ``piecewise`` (control),
    ``default`` says all that happens without the option."""
    names = THRUST_MODEL_NAMES if piecewise else THRUST_MODEL_NAMES.replace(" | piecewise", "")
    if piecewise:
        default = f"piecewise for a gait with a thrust: section and no --thrust, else {default}"
    return typer.Option("--thrust-model", help=f"{names} (`constant`: the deprecated name of "
                                               f"ideal; default: {default}).")


# the thruster models' parameters: one help text each; a command gives its default in its
# signature (simulate, stability, mujoco: wn 2, xi 1, tau 0.5; control: wn 20, xi 1, tau
# 0.05, its controller's fast thruster), which --help shows as [default: ...]
WnOpt = Annotated[float, typer.Option("--wn", help="Second-order thruster natural frequency "
                                                   "[rad/s].")]
XiOpt = Annotated[float, typer.Option("--xi", help="Second-order thruster damping ratio [1].")]
TauOpt = Annotated[float, typer.Option("--tau", help="First-order thruster time constant [s].")]
F0Opt = Annotated[float, typer.Option("--f0", help="Thrust at t = 0 of the dynamic thrusters "
                                                   "[N].")]


def thrusters_opt(driven: str = "driven by --thrust"):
    """The repeatable ``--thruster NAME`` option (simulate, mujoco, control); ``driven``
    says what drives it (control: its controller)."""
    return typer.Option("--thruster", metavar="NAME", help=f"Thruster {driven} (repeat for "
                                                           "several; default: the first).")


ThrustersOpt = Annotated[list[str] | None, thrusters_opt()]
PushOpt = Annotated[
    list[str] | None, typer.Option("--push", metavar="STEP:PHASE:PX[:PY]",
                                   help="Impulse [N s] at the end of the stance link (the hip "
                                        "of a one-link stance leg; a kneed walker's stance "
                                        "knee) at phase s of a step (repeatable).")
]
MuOpt = Annotated[
    float | None, typer.Option("--mu", help="Friction coefficient [-] (default: the gait's "
                                            "`mu`).")
]
SlopeOpt = Annotated[
    float, typer.Option("--slope", help="Ground angle [rad], positive uphill, |slope| < pi/2"
                                        "; speed is along the ground.")
]
MinVerticalForceOpt = Annotated[
    float, typer.Option("--min-vertical-force", help="Minimum vertical ground force F^v along "
                                                     "the step [N].")
]
TargetSpeedOpt = Annotated[
    float | None, typer.Option("--target-speed", help="Target average walking speed [m/s].")
]
MaxOutputOpt = Annotated[
    float, typer.Option("--max-output", help="Refuse a sweep whose CSV table would exceed this "
                                             "many megabytes [MB].")
]
TimestepOpt = Annotated[
    float | None, typer.Option("--timestep", help="MuJoCo timestep [s] (default: the "
                                                  "preset's).")
]
SolrefOpt = Annotated[
    str | None, typer.Option("--solref", metavar="TIMECONST,DAMPRATIO",
                             help="Contact solref [s, 1] (default: the preset's).")
]
SolimpOpt = Annotated[
    str | None, typer.Option("--solimp", metavar="D0,DWIDTH,WIDTH[,MID,POWER]",
                             help="Contact solimp (default: the preset's).")
]
FootRadiusOpt = Annotated[
    float | None, typer.Option("--foot-radius", help="Radius of the feet's spheres [m] "
                                                     "(default 0.001).")
]
ContactOpt = Annotated[
    str, typer.Option("--contact", help="MuJoCo contact preset: soft (MuJoCo's default "
                                        "contact), default, or stiff (with a small timestep; "
                                        "the rigid-impact limit). --solref, --solimp, "
                                        "--timestep change one setting.")
]
