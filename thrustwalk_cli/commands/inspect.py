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


LABELS = {  # key -> (label, unit) of the summary table
    "q": ("q", "rad"), "dq": ("q'", "rad/s"), "G": ("G", "N m"), "C_dq": ("C q'", "N m"),
    "B_F_thrust": ("B_F F_T", "N m"), "swing_foot": ("swing foot (x, y)", "m"),
    "com": ("centre of mass (x, y)", "m"), "potential_energy": ("potential energy", "J"),
    "kinetic_energy": ("kinetic energy", "J"), "thrust": ("thrust", "N"),
}


def _numbers(v) -> str:
    if isinstance(v, (int, float)):
        return f"{v:.6g}"
    return "  ".join(f"{x:.6g}" for x in v)


def _table(doc: dict) -> None:
    from rich.table import Table

    c = console()
    t = Table(title=f"state of {', '.join(doc['coordinates'])}")
    t.add_column("quantity", overflow="fold")
    t.add_column("unit", no_wrap=True)
    t.add_column("value", no_wrap=True, justify="right")
    for key, (label, unit) in LABELS.items():
        if key in doc:
            t.add_row(label, unit, _numbers(doc[key]))
    if "impact" in doc:
        imp = doc["impact"]
        t.add_row("after impact q'+", "rad/s", _numbers(imp["dq_plus"]))
        t.add_row("impact impulse F_2 (x, y)", "N s", _numbers(imp["impulse"]))
        t.add_row("old stance foot velocity", "m/s", _numbers(imp["old_stance_foot_velocity"]))
    c.print(t)
    for name, rows in (("D", doc["D"]), ("B_F", doc["B_F"])):
        m = Table(title=f"{name} [{'kg m^2' if name == 'D' else 'm'}]", show_header=False)
        for _ in range(len(rows[0]) if rows and rows[0] else 0):
            m.add_column(no_wrap=True, justify="right")
        for row in rows:
            m.add_row(*(f"{x:.6g}" for x in row))
        if rows and rows[0]:
            c.print(m)


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
        json_file: Annotated[str | None, typer.Option(
            "--json", metavar="PATH", help="Also write the numbers to this JSON file; '-' "
                                            "writes them to standard output instead of the "
                                            "table.")] = None,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            if not q:
                raise InputError("option --q: required (one angle per coordinate, in rad)")
            from ..studies.inspect import inspect_state
            from .common import load_model, warn

            model = load_model(robot)
            doc = inspect_state(model, q, dq, thrust)
            warn(doc["warnings"])
            if json_file is not None:
                import json
                import sys

                from ..files import output

                full = {"provenance": output.provenance(model.robot), **doc}
                if json_file == "-":
                    sys.stdout.write(json.dumps(output.jsonable(full), indent=2) + "\n")
                else:
                    target = Path(json_file)
                    output.check_file_target(target, "json_file")
                    output.write_json(target, full)
            if not quiet and json_file != "-":
                _table(doc)
