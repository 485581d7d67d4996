"""Typed errors of the core. Only the CLI turns them into exit codes (2 for bad input).

A :class:`Problem` is located either in an input file (``file:line: key.path: message``) or at
a parameter of a Python function (``params``: the parameter names, e.g. ``("mu",)``). The core
names parameters, never command-line flags; a message may mention another parameter in
backquotes (`` `zeta0` ``), which the command line renders as its flag.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Problem:
    """One problem: ``file:line: key.path: message``, or ``param: message``."""

    file: str
    line: int | None
    path: str
    message: str
    params: tuple[str, ...] = ()

    def __str__(self) -> str:
        if self.params:
            return f"{'/'.join(self.params)}: {self.message}"
        where = f"{self.file}:{self.line}" if self.line is not None else self.file
        parts = [p for p in (where, self.path, self.message) if p]
        return ": ".join(parts)


def param_problem(params: str | Sequence[str], message: str) -> Problem:
    """A problem with the value of one parameter (or a combination of several)."""
    names = (params,) if isinstance(params, str) else tuple(params)
    return Problem("", None, "", message, names)


class InputError(Exception):
    """Bad user input (file, parameter). Carries every problem found, one line each."""

    def __init__(self, problems: Sequence[Problem | str] | Problem | str):
        if isinstance(problems, (str, Problem)):
            problems = [problems]
        self.problems: list[Problem] = [p if isinstance(p, Problem) else Problem("", None, "", p)
                                        for p in problems]
        super().__init__("\n".join(str(p) for p in self.problems))

    @classmethod
    def param(cls, params: str | Sequence[str], message: str) -> InputError:
        """The error for one bad parameter value: ``InputError.param("mu", "must be > 0")``."""
        return cls(param_problem(params, message))


class ComputationError(Exception):
    """A numerical computation that failed (integrator, solver); never silently ignored."""


# Where a problem found after loading is reported: a parameter name, or a function making a
# file:line Problem from a key path (e.g. the ``thrust:`` section of a gait file).
Where = str | tuple[str, ...] | Callable[[tuple, str], Problem]


def locate(where: Where, key: tuple, message: str) -> Problem:
    """The :class:`Problem` for ``message`` at key path ``key``, reported at ``where``."""
    if callable(where):
        return where(key, message)
    return param_problem(where, message)
