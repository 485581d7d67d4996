"""Typed errors of the core. Only the CLI turns them into exit codes (2 for bad input).

A :class:`Problem` is located either in an input file (``file:line: key.path: message``) or at
a parameter of a Python function (``params``: the parameter names, e.g. ``("mu",)``). The core
names parameters, never command-line flags; a message may mention another parameter in
backquotes (`` `zeta0` ``), which the command line renders as its flag.
"""

from __future__ import annotations

import math
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


class WrongKind(InputError):
    """A thrustwalk file of another kind where one kind was expected (a gait file passed as
    the robot): ``found`` is the file's kind and ``file`` its path."""

    def __init__(self, problem: Problem, found: str, file: str):
        super().__init__(problem)
        self.found, self.file = found, file


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


# ------------------------------------------------------------------ checking parameters
# The one place where the public functions check the type and range of a parameter before any
# work: every problem is an :class:`InputError` naming the parameter (never a bare TypeError,
# ValueError or OverflowError from deep inside).
LARGEST = 1e9  # [SI] a parameter beyond this in size is a typo, not a request
LARGEST_COUNT = 2**63 - 1  # a count or seed beyond this does not fit any integer type used


def _shown(value: object) -> str:
    """A short description of a value of the wrong kind (its type, and a short repr)."""
    text = repr(value)
    if len(text) > 40:
        text = text[:30] + "..."
    return f"{type(value).__name__} {text}"


def _fmt(v: float) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def check_number(name: str, value: object, *, gt: float | None = None,
                 ge: float | None = None, lt: float | None = None, le: float | None = None,
                 integer: bool = False, optional: bool = False, unit: str = "",
                 largest: float | None = None) -> float | int | None:
    """``value`` as a float (``integer``: an int) after checking that it is a real number
    (not a bool, a string, a list, None unless ``optional``), finite, at most ``largest`` in
    size (default :data:`LARGEST`; counts :data:`LARGEST_COUNT`) and within the bounds ``gt``,
    ``ge``, ``lt``, ``le`` [``unit``]; :class:`InputError` naming ``name`` otherwise."""
    import math
    import numbers

    if value is None and optional:
        return None
    want = "a whole number" if integer else "a number"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError.param(name, f"must be {want}, got {_shown(value)}")
    try:
        v = float(value)
    except OverflowError:  # an int too large for a float
        v = math.copysign(math.inf, value)
    if math.isnan(v):
        raise InputError.param(name, f"must be {want}, got nan")
    big = (LARGEST_COUNT if integer else LARGEST) if largest is None else largest
    if not abs(v) <= big:
        raise InputError.param(name, f"{value if math.isinf(v) else _fmt(v)} is beyond any "
                                     f"usable value (at most {big:g} in size)")
    if integer:
        if not v.is_integer():
            raise InputError.param(name, f"must be {want}, got {v:g}")
        out: float | int = int(value) if isinstance(value, numbers.Integral) else int(v)
    else:
        out = v
    u = f" {unit}" if unit else ""
    if integer and ge is not None and le is not None and not ge <= v <= le:
        raise InputError.param(name, f"must be {_fmt(ge)}..{_fmt(le)}{u} (got {out})")
    for bound, ok, word in ((gt, lambda b: v > b, ">"), (ge, lambda b: v >= b, ">="),
                            (lt, lambda b: v < b, "<"), (le, lambda b: v <= b, "<=")):
        if bound is not None and not ok(bound):
            raise InputError.param(name, f"must be {word} {_fmt(bound)}{u} (got {_fmt(out)})")
    return out


def check_count(name: str, value: object, *, ge: int = 1, le: int | None = None,
                optional: bool = False) -> int | None:
    """A whole number in ``ge`` ... ``le`` (a count, a number of steps, a seed)."""
    return check_number(name, value, ge=ge, le=le, integer=True, optional=optional)


def check_numbers(name: str, values: object, *, min_len: int = 1, max_len: int | None = None,
                  optional: bool = False, **bounds) -> tuple[float, ...] | None:
    """A sequence of numbers (a list, tuple or 1-D array; not a string or a mapping),
    ``min_len`` to ``max_len`` long, each checked by :func:`check_number` with ``bounds``."""
    if values is None and optional:
        return None
    if isinstance(values, (str, bytes, dict)) or not hasattr(values, "__iter__") or \
            getattr(values, "ndim", 1) != 1:
        raise InputError.param(name, f"must be a sequence of numbers, got {_shown(values)}")
    items = list(values)
    if max_len is not None and len(items) > max_len:
        raise InputError.param(name, f"{len(items)} values: the limit is {max_len}")
    if len(items) < min_len:
        raise InputError.param(name, f"needs at least {min_len} value(s), got {len(items)}")
    out = []
    for i, v in enumerate(items):
        try:
            out.append(check_number(name, v, **bounds))
        except InputError as exc:
            raise InputError.param(name, f"value {i + 1}: {exc.problems[0].message}") from None
    return tuple(out)


def check_choice(name: str, value: object, choices: Sequence[str], *,
                 optional: bool = False) -> str | None:
    """One of the strings ``choices``."""
    if value is None and optional:
        return None
    if not isinstance(value, str) or value not in choices:
        got = repr(value) if isinstance(value, str) else _shown(value)
        raise InputError.param(name, f"must be one of {', '.join(choices)} (got {got})")
    return value


def check_text(name: str, value: object, *, optional: bool = False) -> str | None:
    """A non-blank string (a name, a path, an address)."""
    if value is None and optional:
        return None
    if not isinstance(value, str) or not value.strip():
        raise InputError.param(name, f"must be a non-empty string, got {_shown(value)}")
    return value


def check_texts(name: str, values: object, *, optional: bool = False
                ) -> tuple[str, ...] | None:
    """A sequence of non-blank strings; one string is one name (``thruster="back"`` as
    ``["back"]``, as the one-thruster functions take it), never its letters."""
    if values is None and optional:
        return None
    if isinstance(values, str):
        return (check_text(name, values),)
    if isinstance(values, (bytes, dict)) or not hasattr(values, "__iter__"):
        raise InputError.param(name, f"must be a sequence of names, got {_shown(values)}")
    return tuple(check_text(name, v) for v in values)


def check_flag(name: str, value: object) -> bool:
    """``True`` or ``False`` (a numpy bool too)."""
    if type(value).__name__ not in ("bool", "bool_"):
        raise InputError.param(name, f"must be True or False, got {_shown(value)}")
    return bool(value)


def check_instance(name: str, value: object, kind: type | tuple[type, ...], what: str,
                   *, optional: bool = False) -> object:
    """An object of class ``kind`` (``what``: how to describe it, e.g. "a Walker (from
    tw.load_walker)")."""
    if value is None and optional:
        return None
    if not isinstance(value, kind):
        raise InputError.param(name, f"must be {what}, got {_shown(value)}")
    return value


def check_callable(name: str, value: object) -> object:
    """None or a function (a progress callback)."""
    if value is not None and not callable(value):
        raise InputError.param(name, f"must be a function or None, got {_shown(value)}")
    return value


def check_path(name: str, value: object, *, optional: bool = False) -> str | None:
    """A file path or bundled name: a non-blank string or a path object, as a string."""
    import os

    if value is None and optional:
        return None
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if not isinstance(value, str) or not value.strip():
        raise InputError.param(name, f"must be a file path or name, got {_shown(value)}")
    return value


def check_number_map(name: str, value: object, *, optional: bool = False, **bounds
                     ) -> dict[str, float] | None:
    """A mapping of names (strings) to numbers (each checked by :func:`check_number` with
    ``bounds``), e.g. robot parameters ``{"MT": 12.0}``."""
    from collections.abc import Mapping

    if value is None and optional:
        return None
    if not isinstance(value, Mapping):
        raise InputError.param(name, f"must be a mapping of names to numbers, got "
                                     f"{_shown(value)}")
    out = {}
    for key, v in value.items():
        if not isinstance(key, str) or not key.strip():
            raise InputError.param(name, f"names must be non-empty strings, got {_shown(key)}")
        try:
            out[key] = check_number(name, v, **bounds)
        except InputError as exc:
            raise InputError.param(name, f"{key}: {exc.problems[0].message}") from None
    return out


def check_pushes(name: str, push: object, robot, steps: int
                 ) -> list[tuple[float, float, float, float]]:
    """``push`` as (step, phase, P_x, P_y) [N s] tuples: a step 1 ... ``steps``, a phase in
    [0, 1) and an impulse of at most :meth:`Robot.push_bound` (a push that changes the whole
    robot's velocity by more than 10 m/s is a crash, not a push): ``robot`` is the
    :class:`~thrustwalk_cli.description.robot.Robot` pushed."""
    if push is None:
        return []
    if isinstance(push, (str, bytes, dict)) or not hasattr(push, "__iter__"):
        raise InputError.param(name, f"must be a sequence of (step, phase, P_x, P_y) tuples, "
                                     f"got {type(push).__name__} {push!r:.40}")
    out = []
    for p in push:
        v = check_numbers(name, p, min_len=3, max_len=4)
        stp, s, px, py = v[0], v[1], v[2], v[3] if len(v) == 4 else 0.0
        if not (float(stp).is_integer() and 1 <= stp <= steps and 0.0 <= s < 1.0):
            raise InputError.param(name, f"a push needs a step in 1..{steps} and a phase in "
                                         f"[0, 1) (got step {stp:g}, phase {s:g})")
        robot.check_push(name, float(math.hypot(px, py)))
        out.append((stp, s, px, py))
    return out


def renamed_keyword(function: str, new: str, value: object, old: str, old_value: object
                    ) -> object:
    """The value of ``function``'s parameter ``new``, formerly named ``old`` (the old keyword
    works for one release): ``old_value`` with a DeprecationWarning naming ``new`` when only
    the old keyword is given (None: not given), an :class:`InputError` naming both when both
    are, else ``value``."""
    if old_value is None:
        return value
    if value is not None:
        raise InputError.param((new, old), f"`{old}` is the old name of `{new}`: give one")
    import warnings

    warnings.warn(f"{function}({old}=...) is deprecated (kept for one release): use "
                  f"{function}({new}=...)", DeprecationWarning, stacklevel=3)
    return old_value
