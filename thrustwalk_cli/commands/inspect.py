"""``thrustwalk inspect``: numeric dynamics of a robot at one state."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from .common import QuietOpt, RobotArg, cli_errors, console

HELP = """Evaluate the model at one state: D [kg m^2], C q' [N m], G [N m], B_F [m],
swing-foot position [m] and, with --dq, the impact map (post-impact rates [rad/s] after
relabelling and the impulse F_2 [N s]). Angles in rad, in the robot's coordinate order.
"""
EPILOG = ("Example: thrustwalk inspect three_link --q 0.1,0.2,-0.3 --dq 0,1,-1 "
          "--json state.json")


def _vector(text: str, option: str, n: int, names: list[str]) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"option {option}: expected {n} comma-separated numbers "
                         f"({', '.join(names)}), got {text!r}") from None
    if len(vals) != n:
        raise InputError(f"option {option}: expected {n} values ({', '.join(names)}), "
                         f"got {len(vals)}")
    return vals


def run_inspect(robot: str, q: str, dq: str | None, thrust: str | None) -> dict:
    """Evaluate the model; returns the JSON document (keys fixed by the robot-model issue)."""
    from ..model import load_model
    from ..robot_io import load_robot

    model = load_model(load_robot(robot))
    names = model.robot.coordinate_names
    qv = _vector(q, "--q", model.n, names)
    doc: dict = {"coordinates": names, "q": qv}
    doc.update(model.evaluate_state(
        qv,
        None if dq is None else _vector(dq, "--dq", model.n, names),
        None if thrust is None else _vector(thrust, "--thrust", model.n_thrusters,
                                            model.robot.thruster_names)))
    return doc


def register(app: typer.Typer) -> None:
    @app.command("inspect", help=HELP, epilog=EPILOG)
    def inspect_cli(
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
        with cli_errors():
            if not q:
                raise InputError("option --q: required (one angle per coordinate, in rad)")
            doc = run_inspect(robot, q, dq, thrust)
            if json_file is not None:
                from .. import output
                from ..robot_io import load_robot

                rob = load_robot(robot)
                output.write_json(json_file, {"provenance": output.provenance(rob), **doc})
            if not quiet:
                c = console()
                for key, val in doc.items():
                    c.print(f"[bold]{key}[/bold]: {val}")
