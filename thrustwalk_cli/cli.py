"""The ``thrustwalk`` command line. Thin: each command parses, calls a study, writes, renders.

Start-up is kept light (no NumPy, SymPy or matplotlib until a command runs): command modules
import only typer at module level.
"""

from __future__ import annotations

import copy
import os
import sys

import typer
from typer.core import TyperGroup

from ._version import __version__
from .commands import (
    compile,
    control,
    design_gait,
    energy,
    export_mjcf,
    feasibility,
    import_urdf,
    inspect,
    limit_cycle,
    mujoco,
    optimize,
    report,
    robustness,
    rough_ground,
    shape,
    simulate,
    slope,
    stability,
    sweep,
)

# Help lists the commands in this order.
COMMANDS = (compile, import_urdf, export_mjcf, inspect, limit_cycle, shape, feasibility,
            slope, energy, optimize, simulate, mujoco, control, stability, robustness,
            rough_ground, design_gait, sweep, report)

class _OneLineErrors(TyperGroup):
    """The command group, with usage errors (an unknown option, a value of the wrong type, a
    missing argument) printed as one line, like every other bad input:
    ``error: option --steps: ...`` (exit 2), never a usage block and never a traceback."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True,
             **extra):
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        from typer._click import exceptions as ex

        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except ex.NoArgsIsHelpError as exc:  # `thrustwalk` alone: the help
            exc.show()
            sys.exit(exc.exit_code)
        except ex.UsageError as exc:
            sys.stderr.write(f"error: {usage_line(exc)}\n")
            sys.exit(2)
        except typer.Abort:
            sys.stderr.write("error: aborted\n")
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)


def usage_line(exc) -> str:
    """One line for a usage error, naming the option and pointing to ``--help``."""
    from typer._click import exceptions as ex

    ctx = exc.ctx
    where = f"see '{ctx.command_path} --help'" if ctx is not None else "see --help"
    if isinstance(exc, ex.NoSuchOption):
        near = sorted(exc.possibilities or ())
        hint = f"did you mean {' or '.join(near)}? " if near else ""
        return f"no such option {exc.option_name} ({hint}{where})"
    if isinstance(exc, ex.BadOptionUsage):
        message = exc.message
        prefix = f"Option '{exc.option_name}' "
        if message.startswith(prefix):
            message = message[len(prefix):]
        return f"option {exc.option_name}: {message} ({where})"
    if isinstance(exc, ex.BadParameter):
        param = exc.param
        opts = [o for o in getattr(param, "opts", ()) if o.startswith("--")] if param else []
        if opts:
            name = f"option {opts[0]}"
        elif param is not None and getattr(param, "name", None):
            name = f"argument {param.name.upper()}"
        else:
            name = "a value"
        message = "required" if isinstance(exc, ex.MissingParameter) else exc.message
        return f"{name}: {message} ({where})"
    message = exc.format_message()
    return f"{message[:1].lower()}{message[1:].rstrip('.')} ({where})"


app = typer.Typer(
    name="thrustwalk",
    cls=_OneLineErrors,
    help=(
        "Thruster-assisted bipedal walking with hybrid zero dynamics.\n\n"
        "Robots and gaits are YAML files (bundled names such as 'three_link' work from any "
        "folder). Results go to an output folder as JSON, CSV and figures."
    ),
    no_args_is_help=True,
    add_completion=True,
    rich_markup_mode=None,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"thrustwalk {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="Show the version and exit."),
) -> None:
    """Thruster-assisted bipedal walking with hybrid zero dynamics."""


for _module in COMMANDS:
    _module.register(app)


def invoked_app(args: list[str]) -> typer.Typer:
    """``app`` with only the command that ``args`` names, when it names one.

    Typer inspects every registered command's signature and annotations before it parses
    anything (about 0.1 s of CPU for all the commands); a command line runs one command, so
    the others need not be built. Help for the whole tool, shell completion and an unknown
    name (which typer answers with the known ones) keep every command."""
    if any(k.startswith("_THRUSTWALK_COMPLETE") for k in os.environ):
        return app
    name = next((a for a in args if not a.startswith("-")), None)
    chosen = [c for c in app.registered_commands if c.name == name]
    if not chosen:
        return app
    one = copy.copy(app)
    one.registered_commands = chosen
    return one


# BLAS runs single-threaded under the command line unless the environment says otherwise:
# thrustwalk's matrices are small (a robot's N x N) and its parallelism is worker processes
# and compiled threads, while an OpenBLAS thread pool costs about 0.07 s of CPU at numpy's
# import and its threads spin beside the workers.
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def main() -> None:
    os.environ.setdefault("MPLBACKEND", "Agg")  # figures only go to files: no screen needed
    for var in BLAS_THREADS:  # before numpy is imported (the command modules import typer)
        os.environ.setdefault(var, "1")
    invoked_app(sys.argv[1:])()
