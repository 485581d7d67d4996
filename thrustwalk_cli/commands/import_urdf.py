"""``thrustwalk import-urdf``: a robot YAML from a URDF file (SPEC 16)."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Annotated

import typer

from .common import cli_errors, console, warn
from .options import QuietOpt

HELP = """Write a thrustwalk robot file from a URDF of a planar walker.

The sagittal plane is the URDF root link's x-z plane (--plane for another); every movable
joint must be revolute or continuous about the plane normal. Fixed joints merge their links
(masses add, centres of mass average, inertias add by the parallel-axis theorem); each link
keeps its mass [kg], its centre of mass projected on the plane [m] (an out-of-plane offset is
dropped and reported) and its inertia about the plane normal [kg m^2]. The tree is re-rooted
at the stance foot's link; q = 0 is the URDF's zero pose. Coordinates: one relative angle per
revolute joint, named after it (actuated), and the absolute angle of the URDF root link's
body (--unactuated for another). The legs swapped at impact are found from the bodies between
the two feet (checked to be mirror images), unless the side file gives `relabel:`.
Rotor inertia, gear ratio, torque limits and ranges: <transmission> mechanicalReduction and
<limit effort lower upper>, and the side file (--side; its keys are in docs/files.md).
Every number of the robot file is commented with the URDF element and line it came from.

The URDF is untrusted XML: at most 16 MB, no DTD, no entities, no external references; meshes
are never read. A problem is one line naming the element and its line (exit 2); nothing is
written then.
"""
EPILOG = ("Example: thrustwalk import-urdf rabbit.urdf --stance-foot left_foot:0,0,0 "
          "--swing-foot right_foot:0,0,0 --side rabbit_side.yaml --out rabbit.yaml. Another: "
          "thrustwalk import-urdf walker.urdf --stance-foot l_shin:0,0,-0.4 --swing-foot "
          "r_shin:0,0,-0.4 --thruster back:torso:0,0,0.3:-1,0 --out walker.yaml")


def command_line(urdf: Path, stance_foot, swing_foot, plane, thrusters, side, unactuated,
                 name, out: Path) -> str:
    """The command as run (for the robot file's header)."""
    args = ["thrustwalk", "import-urdf", str(urdf)]
    for flag, v in (("--stance-foot", stance_foot), ("--swing-foot", swing_foot),
                    ("--plane", plane), ("--side", side), ("--unactuated", unactuated),
                    ("--name", name)):
        if v is not None:
            args += [flag, str(v)]
    for t in thrusters or ():
        args += ["--thruster", t]
    return shlex.join(args + ["--out", str(out)])


def register(app: typer.Typer) -> None:
    @app.command("import-urdf", help=HELP, epilog=EPILOG)
    def import_urdf_cli(
        ctx: typer.Context,
        urdf: Annotated[Path, typer.Argument(help="The URDF file.", metavar="FILE.urdf")],
        out: Annotated[Path, typer.Option("--out", "-o", help="The robot file to write "
                                          "(YAML; replaced atomically).")],
        stance_foot: Annotated[str | None, typer.Option(
            "--stance-foot", metavar="LINK:X,Y,Z", help="The stance foot: a URDF link and a "
            "point in its frame [m] (or stance_foot: in the side file).")] = None,
        swing_foot: Annotated[str | None, typer.Option(
            "--swing-foot", metavar="LINK:X,Y,Z", help="The swing foot: a URDF link and a "
            "point in its frame [m].")] = None,
        plane: Annotated[str | None, typer.Option(
            "--plane", help="Sagittal plane: two axes of the URDF root's frame, forward then "
            "up: xz (default), yz or xy.")] = None,
        thrusters: Annotated[list[str] | None, typer.Option(
            "--thruster", metavar="NAME:LINK:X,Y,Z:DX,DZ[:world|link]",
            help="A thruster at a point of a URDF link [m], pushing along (DX, DZ) in the "
                 "plane's axes at the URDF zero pose, fixed in the world (default) or the "
                 "link; repeat for more.")] = None,
        side: Annotated[Path | None, typer.Option(
            "--side", help="Side file (YAML): rotor inertias, gear ratios, limits, names, "
                           "relabelling, feet, thrusters, gravity.")] = None,
        unactuated: Annotated[str | None, typer.Option(
            "--unactuated", metavar="LINK", help="URDF link whose absolute angle is the "
            "unactuated coordinate (default: the URDF root link).")] = None,
        name: Annotated[str | None, typer.Option(
            "--name", help="Robot name (default: the URDF's <robot name>).")] = None,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            from ..files.output import check_file_target, write_text_atomic
            from ..studies.import_urdf import import_urdf

            check_file_target(out, "out")
            if out.resolve() == urdf.resolve():
                from ..errors import InputError

                raise InputError.param("out", "the robot file would replace the URDF")
            cmd = command_line(urdf, stance_foot, swing_foot, plane, thrusters, side,
                               unactuated, name, out)
            res = import_urdf(urdf, stance_foot, swing_foot, plane=plane,
                              thrusters=thrusters or (), side=side, unactuated=unactuated,
                              name=name, out=out, command=cmd)
            warn(res.notes)
            write_text_atomic(out, res.yaml)
            if quiet:
                return
            from rich.markup import escape
            from rich.table import Table

            r = res.robot
            doc = res.document()
            t = Table(title=escape(f"robot {r.name} from {urdf}"))
            t.add_column("link", overflow="fold")
            t.add_column("parent", overflow="fold")
            t.add_column("mass [kg]", no_wrap=True, justify="right")
            t.add_column("URDF links", overflow="fold")
            for lk in doc["links"]:
                t.add_row(escape(lk["name"]), escape(lk["parent"] or "(stance foot)"),
                          f"{lk['mass']:.4g}", escape(", ".join(lk["urdf_links"])))
            con = console()
            con.print(t)
            act = [c.name for c in r.coordinates if c.actuated]
            un = next(c for c in r.coordinates if not c.actuated)
            con.print(escape(f"coordinates: {', '.join(act)} (actuated), {un.name} (absolute "
                             f"angle of {un.link}); total mass {r.total_mass:.4g} kg"),
                      highlight=False)
            if doc["swap"]:
                con.print(escape("legs swapped at impact: " + ", ".join(
                    f"{a} <-> {b}" for a, b in doc["swap"])), highlight=False)
            con.print(escape(f"wrote {out} (check it with: thrustwalk compile {out})"),
                      highlight=False)
