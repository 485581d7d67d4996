"""``thrustwalk inspect``: numeric dynamics of a robot at one state."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from .common import cli_errors, console
from .options import QuietOpt, RobotArg

HELP = """Evaluate the model at one state: D [kg m^2], C q' [N m], G [N m], B_F [m],
swing-foot position [m] and, with --dq, the impact map (post-impact rates [rad/s] after
relabelling and the impulse F_2 [N s]). Angles in rad, in the robot's coordinate order.
"""
EPILOG = ("Example: thrustwalk inspect three_link --q 0.1,0.2,-0.3 --dq 0,1,-1 "
          "--json state.json")


def run_inspect(robot: str, q: str, dq: str | None, thrust: str | None) -> dict:
    """Evaluate the model; returns the JSON document (keys fixed by the robot-model issue)."""
    from ..studies.compile import compile_robot
    from ..studies.inspect import inspect_state

    return inspect_state(compile_robot(robot), q, dq, thrust)


def register(app: typer.Typer) -> None:
    @app.command("inspect", help=HELP, epilog=EPILOG)
    def inspect_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        q: Annotated[str, typer.Option("--q", help="Configuration [rad], comma-separated.")] = "",
        dq: Annotated[str | None, typer.Option(
            "--dq", help="Rates [rad/s]; adds C q' and the impact map.")] = None,
        thrust: Annotated[str | None, typer.Option(
            "--thrust", help="Thrust per thruster [N]; adds B_F F_T.")] = None,
        json_file: Annotated[Path | None, typer.Option(
            "--json", help="Also write the numbers to this JSON file.")] = None,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            if not q:
                raise InputError("option --q: required (one angle per coordinate, in rad)")
            from ..studies.compile import compile_robot
            from ..studies.inspect import inspect_state

            model = compile_robot(robot)
            doc = inspect_state(model, q, dq, thrust)
            if json_file is not None:
                from ..files import output

                output.write_json(json_file, {"provenance": output.provenance(model.robot),
                                              **doc})
            if not quiet:
                c = console()
                for key, val in doc.items():
                    c.print(f"[bold]{key}[/bold]: {val}")
