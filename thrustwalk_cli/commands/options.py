"""Options shared by several commands, defined once (name, help text with units)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

RobotArg = Annotated[
    str,
    typer.Argument(help="Robot: a bundled name (three_link, rabbit) or a path to a YAML file."),
]
GaitArg = Annotated[
    str,
    typer.Argument(help="Gait: a bundled name (three_link_walk, rabbit_walk) or a YAML path."),
]
OutOpt = Annotated[
    Path, typer.Option("--out", "-o", help="Output folder (created if missing).")
]
QuietOpt = Annotated[
    bool, typer.Option("--quiet", "-q", help="No progress bar and no summary table.")
]
ThrusterOpt = Annotated[
    str | None, typer.Option("--thruster", help="Thruster driven by the thrust values "
                                                "(default: the first).")
]
MuOpt = Annotated[
    float | None, typer.Option("--mu", help="Friction coefficient [-] (default: the gait's "
                                            "`mu`).")
]
EpsOpt = Annotated[
    float, typer.Option("--eps", help="Minimum vertical ground force [N].")
]
FormatsOpt = Annotated[
    str, typer.Option("--formats", help="Figure formats, comma-separated: png, pdf, svg, or "
                                        "none (no figures; matplotlib is not loaded).")
]
