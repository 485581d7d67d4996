"""``thrustwalk export-mjcf``: a robot as a MuJoCo model (MJCF, SPEC 16)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import cli_errors, console, warn
from .mujoco import contact_from_options
from .options import (
    ContactOpt,
    FootRadiusOpt,
    GaitArg,
    MuOpt,
    QuietOpt,
    RobotArg,
    SolimpOpt,
    SolrefOpt,
    TimestepOpt,
)

HELP = """Write a MuJoCo model (MJCF) of a planar thrustwalk robot.

The plane is MuJoCo's x-z plane: the root body (the stance leg's link) has slide joints
root_x, root_z (the stance foot's position) and the hinge root_angle (its absolute angle);
every other link is a body with a hinge named after its joint's coordinate (axis 0 -1 0: the
MuJoCo angle is thrustwalk's counter-clockwise relative angle), its mass, centre of mass and
planar inertia (iyy), and the rotor inertia as the hinge's armature. Feet: spheres of radius
--foot-radius at the foot points (friction --mu), the floor one radius below z = 0; only feet
and floor collide. Motors on the actuated hinges; each thruster is a site with an actuator
along its direction (in the world or its link). Contact and timestep: --contact preset
(soft, default, stiff) or --solref/--solimp/--timestep. With a GAIT: mu defaults to the
gait's and the key 'start' is a state just after an impact on the gait's orbit. MuJoCo's
own compiler checks the file when MuJoCo is installed (pip install 'thrustwalk[mujoco]');
the export does not need it.
"""
EPILOG = ("Example: thrustwalk export-mjcf three_link three_link_walk --out three_link.xml; "
          "then python -m mujoco.viewer --mjcf three_link.xml")


def register(app: typer.Typer) -> None:
    @app.command("export-mjcf", help=HELP, epilog=EPILOG)
    def export_mjcf_cli(
        ctx: typer.Context,
        robot: RobotArg,
        gait: GaitArg = None,
        out: Annotated[Path, typer.Option("--out", "-o", help="The MJCF file to write "
                                          "(replaced atomically).")] = Path("robot.xml"),
        mu: MuOpt = None,
        contact: ContactOpt = "default",
        timestep: TimestepOpt = None,
        solref: SolrefOpt = None,
        solimp: SolimpOpt = None,
        foot_radius: FootRadiusOpt = None,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            from ..files.output import check_file_target, write_text_atomic
            from ..studies.export_mjcf import export_mjcf

            check_file_target(out, "out")
            ct = contact_from_options(contact, timestep=timestep, solref=solref,
                                      solimp=solimp, foot_radius=foot_radius)
            res = export_mjcf(robot, gait, mu=mu, contact=ct)
            if res.checked is None:
                warn([n for n in res.notes if n.startswith("not checked")])
            write_text_atomic(out, res.xml)
            if quiet:
                return
            con = console()
            for n in res.notes:
                if not n.startswith("not checked"):
                    con.print(n, markup=False)
            what = (f"checked by MuJoCo {res.checked}'s compiler" if res.checked else
                    "not checked by MuJoCo")
            con.print(f"wrote {out} ({res.robot.n} bodies, {what})", markup=False)
