"""Declarative schemas for the YAML inputs; validation collects every problem.

Declare a schema with the factory functions (``number``, ``vector``, ``mapping``, ...)::

    LINK = mapping(
        field("mass", number("kg", gt=0), "link mass"),
        field("com", vector(2, "m"), "centre of mass, link frame", default=[0, 0]),
    )
    ROBOT = mapping(
        field("parameters", parameters(), "named numbers usable in expressions", default={}),
        field("links", list_of(LINK, min_len=1), "the links"),
    )
    result = check(load_yaml("robot.yaml"), ROBOT)  # resolve_parameters + validate
    result.raise_if_problems()

A ``number`` is a YAML int/float or a string holding an arithmetic expression (see
:mod:`thrustwalk_cli.files.expr`) of the document's ``parameters``. Expression columns in
messages are 1-based.
"""

from __future__ import annotations

import copy
import difflib
import json
import keyword
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from ..errors import InputError, Problem, WrongKind
from .expr import DEFAULT_CONSTANTS, DEFAULT_FUNCTIONS, Expr, ExprError
from .expr import parse as parse_expr
from .yamlio import Document, KeyPath, format_path


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_TYPE_NAMES = {type(None): "null", bool: "a boolean", int: "an integer", float: "a number",
               list: "a list", dict: "a mapping"}


LARGEST = 1e9  # [SI] a number beyond this in a robot or gait file is a typo


def _type_name(value: Any) -> str:
    if isinstance(value, str):
        return f"a string {value!r}" if len(value) <= 40 else "a string"
    return _TYPE_NAMES.get(type(value), type(value).__name__)


def _fmt(v: float) -> str:
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e15 else repr(float(v))


def suggest(word: str, options: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(options), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def problem(doc: Document, path: KeyPath, message: str) -> Problem:
    """A :class:`Problem` at ``path`` of ``doc`` (for semantic checks after validation)."""
    return Problem(doc.file, doc.line_of(path), format_path(path), message)


def raise_if_problems(problems: Sequence[Problem]) -> None:
    """Raise :class:`InputError` carrying all ``problems`` if there are any."""
    if problems:
        raise InputError(list(problems))


class _Ctx:
    """Validation state: the document, parameters in scope, problems collected so far."""

    def __init__(self, doc: Document, params: Mapping[str, float],
                 problems: list[Problem] | None = None, broken: frozenset[str] = frozenset()):
        self.doc, self.params, self.broken = doc, params, broken
        self.problems = [] if problems is None else problems

    def report(self, path: KeyPath, message: str) -> None:
        self.problems.append(problem(self.doc, path, message))


@dataclass(frozen=True)
class Bounds:
    """Optional limits: ``gt``/``ge`` (exclusive/inclusive lower), ``lt``/``le`` (upper)."""

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None

    def violation(self, v: float) -> str | None:
        """``"must be > 0, got -5"`` if ``v`` is out of bounds, else None."""
        for op, lim, bad in (
            (">", self.gt, lambda a, b: a <= b), (">=", self.ge, lambda a, b: a < b),
            ("<", self.lt, lambda a, b: a >= b), ("<=", self.le, lambda a, b: a > b),
        ):
            if lim is not None and bad(v, lim):
                return f"must be {op} {_fmt(lim)}, got {_fmt(v)}"
        return None

    def __str__(self) -> str:
        lo_op, lo = (">", self.gt) if self.gt is not None else (">=", self.ge)
        hi_op, hi = ("<", self.lt) if self.lt is not None else ("<=", self.le)
        if lo is not None and hi is not None:
            return f"{_fmt(lo)} {lo_op.replace('>', '<')} x {hi_op} {_fmt(hi)}"
        if lo is not None:
            return f"{lo_op} {_fmt(lo)}"
        return f"{hi_op} {_fmt(hi)}" if hi is not None else ""


def _check_number(value: Any, path: KeyPath, ctx: _Ctx, bounds: Bounds,
                  integer: bool = False) -> Any:
    """A finite float (or int if ``integer``) within ``bounds``; None after a problem."""
    kinds = (int, str, Expr) if integer else (int, float, str, Expr)
    if isinstance(value, bool) or not isinstance(value, kinds):
        want = "an integer" if integer else "a number"
        return ctx.report(path, f"expected {want}, got {_type_name(value)}")
    source = ""
    if isinstance(value, (str, Expr)):
        try:
            v = (value if isinstance(value, Expr) else parse_expr(value)).evaluate(ctx.params)
        except ExprError as exc:
            m = re.match(r"unknown name '(\w+)'", exc.message)
            if m and m.group(1) in ctx.broken:
                return None  # the parameter's own problem is reported once, at its definition
            hint = "" if not m else suggest(m.group(1), sorted(ctx.params)) or (
                "" if ctx.params else "; no parameters are defined")
            col = exc.column + 1
            return ctx.report(path, f"expression error at column {col}: {exc.message}{hint}")
        if integer and not v.is_integer():
            return ctx.report(path, f"expected an integer, got {_fmt(v)} (from '{value}')")
        source = f" (from '{value}')"
    else:
        v = float(value) if isinstance(value, float) or abs(value) < 1e308 else math.inf
    if not math.isfinite(v):
        return ctx.report(path, f"must be finite, got {v}")
    if abs(v) > LARGEST:
        return ctx.report(path, f"{_fmt(v)}{source} is beyond any physical value in SI units "
                                f"(at most {_fmt(LARGEST)} in size)")
    bad = bounds.violation(v)
    if bad:
        return ctx.report(path, bad + source)
    return int(v) if integer else float(v)


# ---------------------------------------------------------------------------- kinds

_EXPECT = {
    "string": (str, "a string"), "boolean": (bool, "true or false"),
    "vector": (list, "a list of numbers"), "matrix": (list, "a list of rows (lists of numbers)"),
    "list_of": (list, "a list"), "mapping": (dict, "a mapping"), "dict_of": (dict, "a mapping"),
}


@dataclass(frozen=True)
class Field:
    """One key of a mapping: its kind, documentation and default (or ``REQUIRED``)."""

    key: str
    kind: Kind
    doc: str = ""
    default: Any = REQUIRED

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@dataclass(frozen=True)
class Kind:
    """What a value must be. Build kinds with the factory functions below."""

    tag: str  # number integer string boolean choice null_or vector matrix mapping list_of ...
    unit: str = ""
    bounds: Bounds = Bounds()
    item: Kind | None = None  # child of null_or / list_of / dict_of
    fields: tuple[Field, ...] = ()  # mapping keys
    choices: tuple[str, ...] = ()
    n: int | None = None  # vector length / matrix rows
    m: int | None = None  # matrix columns
    min_len: int = 0  # list/vector minimum length; string: 1 = must not be blank
    max_len: int | None = None  # list/vector maximum length (a sanity limit, named in errors)
    key_name: str = "name"  # dict_of: what the free keys are

    def label(self) -> str:
        """Human name of the kind, for docs."""
        item = self.item.label() if self.item is not None else ""
        return {
            "choice": "one of " + ", ".join(f"`{c}`" for c in self.choices),
            "null_or": f"{item} or null",
            "vector": f"vector[{self.n}]" if self.n is not None else "vector",
            "matrix": f"matrix[{self.n}x{self.m}]" if self.n is not None else "matrix",
            "list_of": f"list of {item}",
            "dict_of": f"map of {self.key_name} -> {item}",
            "parameters": "map of name -> number or expression",
        }.get(self.tag, self.tag)

    def limits(self) -> str:
        """Bounds and length limits, for docs."""
        if self.tag == "null_or" and self.item is not None:
            return self.item.limits()
        own = self.item.limits() if self.tag == "list_of" and self.item else str(self.bounds)
        each = own and not own.startswith("each") and self.tag in ("vector", "matrix", "list_of")
        own = f"each {own}" if each else own
        size = f"length >= {self.min_len}" if self.min_len and self.tag != "string" else ""
        most = f"length <= {self.max_len}" if self.max_len is not None else ""
        return "; ".join(p for p in (own, size, most) if p)

    def check(self, v: Any, path: KeyPath, ctx: _Ctx) -> Any:
        """Convert plain value ``v`` found at ``path``; report problems; None if invalid."""
        t = self.tag
        if t in ("number", "integer"):
            return _check_number(v, path, ctx, self.bounds, t == "integer")
        if t == "null_or":
            return None if v is None or self.item is None else self.item.check(v, path, ctx)
        if t == "parameters":  # checked by resolve_parameters; here only the resolved values
            return {k: ctx.params[k] for k in v if k in ctx.params} if isinstance(v, dict) else {}
        if t == "choice":
            if isinstance(v, str) and v in self.choices:
                return v
            got, hint = (repr(v), suggest(v, self.choices)) if isinstance(v, str) else (
                _type_name(v), "")
            return ctx.report(path, f"must be one of: {', '.join(self.choices)}; got {got}{hint}")
        typ, want = _EXPECT[t]
        if not isinstance(v, typ):
            return ctx.report(path, f"expected {want}, got {_type_name(v)}")
        if t == "boolean":
            return v
        if t == "string":
            return v if v.strip() or not self.min_len else ctx.report(path, "must not be empty")
        if t in ("vector", "list_of") and self.n is not None and len(v) != self.n:
            return ctx.report(path, f"expected {self.n} values, got {len(v)}")
        if t in ("vector", "list_of") and self.max_len is not None and len(v) > self.max_len:
            return ctx.report(path, f"{len(v)} items: the limit is {self.max_len}")
        if t in ("vector", "list_of") and len(v) < self.min_len:
            ctx.report(path, f"expected at least {self.min_len} item(s), got {len(v)}")
            if t == "vector":
                return None
        if t == "vector":
            out = [_check_number(x, path + (i,), ctx, self.bounds) for i, x in enumerate(v)]
            return None if None in out else out
        if t == "matrix":
            return self._check_matrix(v, path, ctx)
        if t == "list_of" and self.item is not None:
            return [self.item.check(x, path + (i,), ctx) for i, x in enumerate(v)]
        if t == "dict_of" and self.item is not None:
            return {k: self.item.check(x, path + (k,), ctx) for k, x in v.items()}
        return self._check_mapping(v, path, ctx)

    def _check_matrix(self, v: list[Any], path: KeyPath, ctx: _Ctx) -> Any:
        if not all(isinstance(row, list) for row in v):
            return ctx.report(path, "expected a list of rows (lists of numbers)")
        if self.n is not None and len(v) != self.n:
            return ctx.report(path, f"expected {self.n} rows, got {len(v)}")
        width = self.m if self.m is not None else len(v[0]) if v else 0
        row_kind = Kind("vector", bounds=self.bounds, n=width)
        out = [row_kind.check(row, path + (i,), ctx) for i, row in enumerate(v)]
        return None if None in out else out

    def _check_mapping(self, v: dict[str, Any], path: KeyPath, ctx: _Ctx) -> Any:
        keys = [f.key for f in self.fields]
        for key in v:
            if key not in keys:
                hint = suggest(key, keys)
                ctx.report(path + (key,),
                           f"unknown key '{key}' (expected one of: {', '.join(keys)}){hint}")
        out: dict[str, Any] = {}
        for f in self.fields:
            if f.key in v:
                out[f.key] = f.kind.check(v[f.key], path + (f.key,), ctx)
            elif f.required:
                ctx.report(path + (f.key,), "missing required key")
            elif f.default is None:
                out[f.key] = None
            else:
                out[f.key] = f.kind.check(copy.deepcopy(f.default), path + (f.key,), ctx)
        return out


def field(key: str, kind: Kind, doc: str = "", default: Any = REQUIRED) -> Field:
    """A mapping key; omit ``default`` to make it required."""
    return Field(key, kind, doc, default)


def number(unit: str = "", **bounds: float) -> Kind:
    """A finite float (YAML number or expression); bounds: ``gt``, ``ge``, ``lt``, ``le``."""
    return Kind("number", unit, Bounds(**bounds))


def integer(unit: str = "", **bounds: float) -> Kind:
    """A YAML integer (booleans rejected); bounds as for :func:`number`."""
    return Kind("integer", unit, Bounds(**bounds))


def string(nonempty: bool = True) -> Kind:
    """A YAML string (not blank unless ``nonempty=False``)."""
    return Kind("string", min_len=int(nonempty))


def boolean() -> Kind:
    """``true`` or ``false``."""
    return Kind("boolean")


def choice(*choices: str) -> Kind:
    """One of the given strings."""
    return Kind("choice", choices=tuple(choices))


def null_or(kind: Kind) -> Kind:
    """``null`` or a value of ``kind``."""
    return Kind("null_or", kind.unit, item=kind)


def vector(n: int | None = None, unit: str = "", *, min_len: int = 0,
           max_len: int | None = None, **bounds: float) -> Kind:
    """A list of numbers (exactly ``n`` if given); bounds apply to every element."""
    return Kind("vector", unit, Bounds(**bounds), n=n, min_len=min_len, max_len=max_len)


def matrix(shape: tuple[int, int] | None = None, unit: str = "", **bounds: float) -> Kind:
    """A list of equal-length rows of numbers (of ``shape`` if given)."""
    n, m = shape if shape is not None else (None, None)
    return Kind("matrix", unit, Bounds(**bounds), n=n, m=m)


def mapping(*fields: Field) -> Kind:
    """A mapping with exactly these keys; unknown keys are problems."""
    return Kind("mapping", fields=tuple(fields))


def list_of(item: Kind, min_len: int = 0, max_len: int | None = None) -> Kind:
    """A list of items of kind ``item``, ``min_len`` to ``max_len`` long."""
    return Kind("list_of", item.unit, item=item, min_len=min_len, max_len=max_len)


def dict_of(value: Kind, key_name: str = "name") -> Kind:
    """A mapping with free string keys (``key_name`` documents them) to ``value`` values."""
    return Kind("dict_of", value.unit, item=value, key_name=key_name)


def parameters() -> Kind:
    """The ``parameters:`` section, checked by :func:`resolve_parameters`."""
    return Kind("parameters")


# ---------------------------------------------------------------------------- parameters


def resolve_parameters(
    doc: Document, path: KeyPath = ("parameters",)
) -> tuple[dict[str, float], list[Problem]]:
    """Evaluate the ``name: number-or-expression`` map at ``path`` in dependency order.

    Reports invalid names, names shadowing ``pi``/functions, unknown names and cycles;
    parameters depending on a broken one are skipped without a further problem.
    """
    ctx = _Ctx(doc, {})
    section: Any = doc.data
    for key in path:
        if not isinstance(section, dict) or key not in section:
            return {}, []
        section = section[key]
    if not isinstance(section, dict):
        ctx.report(path, f"expected a mapping of names to numbers, got {_type_name(section)}")
        return {}, ctx.problems
    raw: dict[str, Any] = {}  # name -> float | Expr | None (broken)
    deps: dict[str, set[str]] = {}
    for name, value in section.items():
        p = path + (name,)
        deps[name] = set()
        if not _IDENT.fullmatch(name) or keyword.iskeyword(name):
            why = "a reserved word" if keyword.iskeyword(name) else "use letters, digits, '_'"
            ctx.report(p, f"invalid parameter name '{name}' ({why})")
        elif name in DEFAULT_CONSTANTS or name in DEFAULT_FUNCTIONS:
            ctx.report(p, f"parameter name '{name}' shadows a built-in")
        elif not isinstance(value, str):
            raw[name] = _check_number(value, p, ctx, Bounds())
        else:
            try:
                raw[name] = parse_expr(value)
            except ExprError as exc:
                raw[name] = ctx.report(p, f"expression error at column {exc.column + 1}: "
                                       f"{exc.message}")
                continue
            unknown = sorted(raw[name].names() - set(section))
            for u in unknown:
                ctx.report(p, f"unknown name '{u}' in expression '{value}'"
                           f"{suggest(u, sorted(section))}")
            raw[name], deps[name] = (None, set()) if unknown else (raw[name], raw[name].names())
    values: dict[str, float] = {}
    done: set[str] = set()
    progress = True
    while progress:  # Kahn's algorithm, in document order
        progress = False
        for name, value in raw.items():
            if name in done or not deps[name] <= done:
                continue
            done.add(name)
            progress = True
            if value is not None and all(d in values for d in deps[name]):
                v = _check_number(value, path + (name,), _Ctx(doc, values, ctx.problems), Bounds())
                if v is not None:
                    values[name] = v
    _report_cycles([n for n in raw if n not in done], deps, path, ctx)
    return values, ctx.problems


def _report_cycles(left: list[str], deps: dict[str, set[str]], path: KeyPath, ctx: _Ctx) -> None:
    """Every name in ``left`` lies on or behind a cycle; report each cycle once."""
    order = {n: i for i, n in enumerate(left)}
    seen: set[str] = set()
    for start in left:
        walk: list[str] = []
        node = start
        while node not in seen:
            seen.add(node)
            walk.append(node)
            node = min((d for d in deps[node] if d in order), key=order.__getitem__)
        if node in walk:
            cycle = walk[walk.index(node):]
            k = cycle.index(min(cycle, key=order.__getitem__))
            cycle = cycle[k:] + cycle[:k]
            ctx.report(path + (cycle[0],), "parameter cycle: " + " -> ".join(cycle + cycle[:1]))


def override_parameters(doc: Document, values: Mapping[str, float] | None,
                        path: KeyPath = ("parameters",)) -> Document:
    """``doc`` with the named ``parameters`` replaced by the numbers ``values`` (SI, as the
    file states them): the description the file would be with those numbers edited in.
    Expressions of other parameters that use a replaced one follow it; lines stay those of the
    file. A name the file does not define is an :class:`InputError` at ``path``."""
    if not values:
        return doc
    section: Any = doc.data.get(path[0]) if isinstance(doc.data, dict) else None
    for key in path[1:]:
        section = section.get(key) if isinstance(section, dict) else None
    names = sorted(section) if isinstance(section, dict) else []
    unknown = [k for k in values if k not in names]
    if unknown:
        raise InputError([problem(doc, path, f"no parameter '{k}' to replace (defined: "
                                              f"{', '.join(names) or 'none'}){suggest(k, names)}")
                          for k in unknown])
    data = copy.deepcopy(doc.data)
    target = data
    for key in path:
        target = target[key]
    for k, v in values.items():
        target[k] = float(v)
    return replace(doc, data=data)


# ---------------------------------------------------------------------------- validation


@dataclass
class ValidationResult:
    """Converted ``data`` (defaults filled in, numbers as float) and every problem found."""

    doc: Document
    data: Any
    problems: list[Problem]
    params: dict[str, float]

    @property
    def ok(self) -> bool:
        return not self.problems

    def line_of(self, path: KeyPath) -> int | None:
        return self.doc.line_of(path)

    def problem(self, path: KeyPath, message: str) -> Problem:
        """A :class:`Problem` at ``path`` (for semantic checks done after validation)."""
        return problem(self.doc, path, message)

    def raise_if_problems(self) -> None:
        raise_if_problems(self.problems)


def validate(
    doc: Document, schema: Kind, params: Mapping[str, float] | None = None,
    broken: frozenset[str] = frozenset(),
) -> ValidationResult:
    """Check ``doc.data`` against ``schema`` with ``params`` in scope of every expression
    (``broken``: parameters whose own definition failed; their uses are not reported again)."""
    params = dict(params or {})
    ctx = _Ctx(doc, params, broken=broken)
    data = schema.check(doc.data, (), ctx)
    return ValidationResult(doc, data, ctx.problems, params)


# keys only one kind of thrustwalk file has at its top level (how a file given in the wrong
# place is recognised: by its keys, never by quoting its content)
KIND_KEYS = {
    "robot": ("links", "coordinates", "feet", "relabel", "thrusters", "gravity"),
    "gait": ("bezier", "alpha", "controller"),
    "sweep": ("study", "collect", "grid", "zip", "random"),
    "URDF side": ("joints", "stance_foot", "swing_foot", "unactuated", "plane"),
    "terrain": ("steps", "rough", "s_max"),
}
KIND_USE = {
    "robot": "the ROBOT argument or a robot: key",
    "gait": "the GAIT argument or a gait: key",
    "sweep": "thrustwalk sweep FILE",
    "URDF side": "the side file of thrustwalk import-urdf",
    "terrain": "the terrain of thrustwalk simulate",
}


def expect_kind(doc: Document, kind: str, schema: Kind | None = None) -> None:
    """Refuse a file that is not a ``kind`` file with one line naming the file and the kind,
    never quoting its content (a file given in the wrong place, or any other file: its keys
    and values would otherwise be echoed as unknown keys and bad values):

    * a thrustwalk file of another kind (a gait file passed as the robot, say): at least two
      top-level keys of another kind and none of its own; the line says where it belongs;
    * with ``schema`` (the kind's key table), any file whose top level is not a mapping
      holding at least one key of that table (``/etc/passwd``, a CSV, a JSON list).

    A file with at least one key of its kind is the kind's, and its problems are reported
    in detail. Called by :func:`~.yamlio.load_yaml` before any other problem of the file."""
    data = doc.data
    keys = set(data) if isinstance(data, dict) else set()
    if keys & set(KIND_KEYS.get(kind, ())):
        return
    for other, marks in KIND_KEYS.items():
        if other != kind and len(keys & set(marks)) >= 2:
            raise WrongKind(Problem(doc.file, None, "", f"this is {_a(other)} file, not "
                                    f"{_a(kind)} file (a {other} file belongs in "
                                    f"{KIND_USE[other]})"), other, str(doc.file))
    if schema is None:
        return
    own = [f.key for f in schema.fields]
    if not keys & set(own):
        what = (f"a mapping without any key of {_a(kind)} file" if isinstance(data, dict)
                else "not a mapping of keys")
        raise InputError(Problem(doc.file, None, "", (
            f"not {_a(kind)} file: its top level is {what} (keys such as "
            f"{', '.join(own[:4])}; docs/files.md)")))


def _a(word: str) -> str:
    """``word`` with its indefinite article."""
    return ("an " if word[:1] in "aeiou" else "a ") + word


def kind_check(kind: str, schema: Kind):
    """``expect(doc)`` for :func:`~.yamlio.load_yaml`: :func:`expect_kind` of ``kind``."""
    def expect(doc: Document) -> None:
        expect_kind(doc, kind, schema)
    return expect


def check(
    doc: Document, schema: Kind, parameters_path: KeyPath | None = ("parameters",)
) -> ValidationResult:
    """:func:`resolve_parameters` then :func:`validate`; problems sorted by line."""
    params, problems = resolve_parameters(doc, parameters_path) if parameters_path else ({}, [])
    declared = doc.data.get(parameters_path[0]) if parameters_path and isinstance(
        doc.data, dict) else None
    broken = frozenset(declared) - set(params) if isinstance(declared, dict) else frozenset()
    result = validate(doc, schema, params, broken)
    result.problems = sorted(problems + result.problems, key=lambda p: p.line or 0)
    return result


# ---------------------------------------------------------------------------- docs


def _rows(kind: Kind, prefix: str, out: list[str]) -> None:
    for f in kind.fields:
        key = f"{prefix}.{f.key}" if prefix else f.key
        default = "required" if f.required else f"`{json.dumps(f.default)}`"
        cells = [f"`{key}`", f.kind.label(), f.kind.unit, default, f.kind.limits(), f.doc]
        out.append("| " + " | ".join(c.replace("|", "\\|").replace("\n", " ") for c in cells)
                   + " |")
        inner = f.kind
        while inner.item is not None:
            key += {"list_of": "[]", "dict_of": f".<{inner.key_name}>"}.get(inner.tag, "")
            inner = inner.item
        _rows(inner, key, out)


def markdown_table(schema: Kind) -> str:
    """A Markdown table of every key: path (``[]`` = list item), kind, unit, default, bounds."""
    out = ["| Key | Kind | Unit | Default | Bounds | Description |", "|---|---|---|---|---|---|"]
    _rows(schema, "", out)
    return "\n".join(out) + "\n"
