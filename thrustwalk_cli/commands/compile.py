"""``thrustwalk compile``: compile (or load from the cache) a robot model and summarise it."""

from __future__ import annotations

from typing import Annotated

import typer

from .common import cli_errors, console
from .options import QuietOpt, RobotArg

HELP = """Compile a robot file with SymPy into cached numeric dynamics.

Derives D, C, G, B_F, the unpinned model, swing-foot kinematics and the impact map (in
absolute link angles: a 20-link chain takes seconds), generates vectorised code and the
instruction tape that the compiled simulation interprets, and caches them by the robot's
structure (the per-robot cost: SymPy and code generation; a compile longer than 2 s shows
its progress). The robot's numbers (masses, lengths, inertias, gravity) are
inputs of the compiled model, not part of its code: a robot that differs only in its numbers
(another torso mass) reuses the cached model. The compiled simulation kernel is the same for
every robot: numba compiles it once per machine, the first time it is needed, and caches it.
Prints links, coordinates, total mass [kg], thrusters, times [s] and the cache entries.
"""
EPILOG = "Example: thrustwalk compile rabbit --rebuild"


def run_compile(robot: str, rebuild: bool = False, kernel: bool = True,
                quiet: bool = True) -> dict:
    from ..studies.compile import compile_kernel
    from .common import ensure_kernel, load_model

    model = load_model(robot, rebuild)
    out = model.summary()
    if kernel:
        out["kernel"] = ensure_kernel(quiet) or compile_kernel()
    else:
        out["kernel"] = None
    return out


def register(app: typer.Typer) -> None:
    @app.command("compile", help=HELP, epilog=EPILOG)
    def compile_cli(
        ctx: typer.Context,
        robot: RobotArg = "three_link",
        rebuild: Annotated[bool, typer.Option(
            "--rebuild", help="Ignore the cache and compile the robot again (the "
                              "simulation kernel, shared by every robot, is compiled only "
                              "when missing).")] = False,
        kernel: Annotated[bool, typer.Option(
            "--kernel/--no-kernel", help="Also make sure the numba simulation kernel is "
                                         "compiled (once per machine, for every robot; "
                                         "cached).")] = True,
        quiet: QuietOpt = False,
    ) -> None:
        with cli_errors(ctx):
            s = run_compile(robot, rebuild, kernel, quiet)
            if quiet:
                return
            from rich.table import Table

            t = Table(title=f"robot {s['name']}", show_header=False)
            t.add_row("links", str(s["links"]))
            t.add_row("coordinates", ", ".join(s["coordinates"]))
            t.add_row("actuated (q_b)", ", ".join(s["actuated"]))
            t.add_row("unactuated (q_N)", s["unactuated"])
            t.add_row("total mass", f"{s['total_mass']:.4g} kg")
            t.add_row("gravity", f"{s['gravity']:.4g} m/s^2")
            t.add_row("thrusters", ", ".join(s["thrusters"]) or "none")
            how = ("cache hit" if s["cache_hit"]
                   else "compiled: SymPy, generated code and tape, per robot structure")
            t.add_row("time", f"{s['seconds']:.3f} s ({how})")
            tp = s["tape"]
            t.add_row("tape", f"{tp['instructions']} instructions ({tp['instructions_accel']} "
                              f"per right-hand side), {tp['registers']} registers")
            t.add_row("numbers", f"{s['numbers']} inputs of the compiled model (masses, "
                                 "lengths, inertias, gravity; zeros are part of the structure)")
            t.add_row("cache entry", s["cache_entry"])
            for note in s["notes"]:
                t.add_row("note", note)
            k = s["kernel"]
            if k is not None:
                secs = "?" if k["seconds"] is None else f"{k['seconds']:.1f} s"
                t.add_row("numba kernel", f"cache hit (compiled once in {secs}, shared by "
                          "every robot)" if k["cache_hit"] else
                          f"compiled in {secs} (once per machine, for every robot)")
                t.add_row("kernel entry", k["entry"])
                if k["note"]:
                    t.add_row("note", k["note"])
            console().print(t)
