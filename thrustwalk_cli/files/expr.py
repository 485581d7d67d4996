"""Restricted arithmetic expressions: a hand-written tokenizer and recursive-descent parser.

Nothing is ever passed to ``eval``/``exec``/``compile``. Grammar (Python precedence)::

    expr    := term (('+' | '-') term)*
    term    := unary (('*' | '/') unary)*
    unary   := ('+' | '-') unary | power
    power   := primary ('**' unary)?          # right-associative; -2**2 == -4
    primary := NUMBER | NAME | FUNC '(' expr ')' | '(' expr ')'

Functions take exactly one argument and must be whitelisted (default ``sin``, ``cos``,
``sqrt``); the default constant is ``pi``. Any other name is a free variable whose value
comes from the ``env`` mapping at evaluation time.
"""

from __future__ import annotations

import keyword
import math
import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Union

import numpy as np

MAX_LENGTH = 1000
MAX_DEPTH = 100

Function = Callable[[Any], Any]

DEFAULT_FUNCTIONS: Mapping[str, Function] = MappingProxyType(
    {"sin": math.sin, "cos": math.cos, "sqrt": math.sqrt}
)
DEFAULT_ARRAY_FUNCTIONS: Mapping[str, Function] = MappingProxyType(
    {"sin": np.sin, "cos": np.cos, "sqrt": np.sqrt}
)
DEFAULT_CONSTANTS: Mapping[str, float] = MappingProxyType({"pi": math.pi})

_TOKEN = re.compile(
    r"(?P<space>[ \t\r\n]+)"
    r"|(?P<num>[0-9]+\.?[0-9]*(?:[eE][+-]?[0-9]+)?|\.[0-9]+(?:[eE][+-]?[0-9]+)?)"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)|(?P<op>\*\*|[-+*/])|(?P<paren>[()])"
)
_WORDISH = re.compile(r"[A-Za-z0-9_.]*")  # what must not stick to a number, as in 2x or 1e
_DESCRIBE = {"end": "end of expression", "num": "number '{}'", "name": "name '{}'"}


class ExprError(ValueError):
    """A rejected or failed expression; ``column`` is the 0-based character offset."""

    def __init__(self, message: str, column: int = 0):
        super().__init__(message)
        self.message = message
        self.column = column


# ---------------------------------------------------------------------------- AST nodes
# ``pos`` is the 0-based column of the node's token (for error messages).


@dataclass(frozen=True)
class Num:
    value: float
    pos: int


@dataclass(frozen=True)
class Name:
    id: str
    pos: int


@dataclass(frozen=True)
class Unary:
    op: str
    operand: Node
    pos: int


@dataclass(frozen=True)
class Power:
    base: Node
    exponent: Node
    pos: int


@dataclass(frozen=True)
class Chain:
    """Left-associative ``first op x op x ...`` of ``+ -`` or ``* /`` (kept flat, not nested)."""

    first: Node
    rest: tuple[tuple[str, Node, int], ...]  # (operator, operand, column of the operator)


@dataclass(frozen=True)
class Call:
    func: str
    arg: Node
    pos: int


Node = Union[Num, Name, Unary, Power, Chain, Call]  # noqa: UP007 (runtime alias on 3.10)

# ---------------------------------------------------------------------------- tokenizer


@dataclass(frozen=True)
class _Tok:
    kind: str  # "num", "name", "op", "(", ")", "end"
    text: str
    pos: int

    def describe(self) -> str:
        return _DESCRIBE.get(self.kind, "'{}'").format(self.text)


def _char_error(ch: str, pos: int) -> ExprError:
    if ch == "^":
        return ExprError("'^' is not allowed; use '**' for powers", pos)
    if ch in "'\"":
        return ExprError(f"unexpected character {ch!r} (strings are not allowed)", pos)
    if ch == ",":
        return ExprError("unexpected ',' (functions take exactly one argument)", pos)
    return ExprError(f"unexpected character {ch!r}", pos)


def _tokenize(text: str) -> list[_Tok]:
    toks: list[_Tok] = []
    i = 0
    while i < len(text):
        m = _TOKEN.match(text, i)
        if m is None:
            if text[i] == "." and toks and toks[-1].kind in ("name", ")"):
                raise ExprError("attribute access ('.') is not allowed", i)
            raise _char_error(text[i], i)
        kind, word, end = m.lastgroup or "", m.group(), m.end()
        stuck = _WORDISH.match(text, end).end() if kind == "num" else end  # type: ignore[union-attr]
        if stuck > end:
            raise ExprError(f"invalid number '{text[i:stuck]}'", i)
        if kind == "name" and keyword.iskeyword(word):
            raise ExprError(f"keyword '{word}' is not allowed", i)
        if kind != "space":
            toks.append(_Tok(word if kind == "paren" else kind, word, i))
        i = end
    toks.append(_Tok("end", "", len(text)))
    return toks


# ---------------------------------------------------------------------------- parser


class _Parser:
    def __init__(self, text: str, functions: Mapping[str, Function]):
        self.toks = _tokenize(text)
        self.i = 0
        self.depth = 0
        self.functions = functions

    @property
    def tok(self) -> _Tok:
        return self.toks[self.i]

    def _next(self) -> _Tok:
        tok = self.toks[self.i]
        self.i += 1
        return tok

    def _is_op(self, *ops: str) -> bool:
        return self.tok.kind == "op" and self.tok.text in ops

    def _enter(self, pos: int) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise ExprError(f"expression nested deeper than {MAX_DEPTH} levels", pos)

    def parse(self) -> Node:
        node = self.expr()
        if self.tok.kind != "end":
            raise ExprError(f"unexpected {self.tok.describe()}", self.tok.pos)
        return node

    def expr(self) -> Node:
        return self._chain(self.term, ("+", "-"))

    def term(self) -> Node:
        return self._chain(self.unary, ("*", "/"))

    def _chain(self, operand: Callable[[], Node], ops: tuple[str, str]) -> Node:
        first, rest = operand(), []
        while self._is_op(*ops):
            op = self._next()
            rest.append((op.text, operand(), op.pos))
        return Chain(first, tuple(rest)) if rest else first

    def unary(self) -> Node:
        if self._is_op("+", "-"):
            op = self._next()
            self._enter(op.pos)
            operand = self.unary()
            self.depth -= 1
            return Unary(op.text, operand, op.pos)
        return self.power()

    def power(self) -> Node:
        node = self.primary()
        if self._is_op("**"):
            op = self._next()
            self._enter(op.pos)
            node = Power(node, self.unary(), op.pos)
            self.depth -= 1
        return node

    def _group(self, opener: _Tok) -> Node:
        self._enter(opener.pos)
        node = self.expr()
        self.depth -= 1
        if self.tok.kind != ")":
            if self.tok.kind == "end":
                raise ExprError("missing ')' to close this '('", opener.pos)
            raise ExprError(f"expected ')' but found {self.tok.describe()}", self.tok.pos)
        self._next()
        return node

    def primary(self) -> Node:
        tok = self._next()
        if tok.kind == "num":
            value = float(tok.text)
            if not math.isfinite(value):
                raise ExprError(f"number '{tok.text}' is too large", tok.pos)
            return Num(value, tok.pos)
        if tok.kind == "name":
            if self.tok.kind == "(":
                if tok.text not in self.functions:
                    raise ExprError(f"unknown function '{tok.text}'", tok.pos)
                return Call(tok.text, self._group(self._next()), tok.pos)
            if tok.text in self.functions:
                msg = f"function '{tok.text}' must be called, e.g. {tok.text}(x)"
                raise ExprError(msg, tok.pos)
            return Name(tok.text, tok.pos)
        if tok.kind == "(":
            return self._group(tok)
        if tok.kind == "end":
            msg = "empty expression" if self.i == 1 else "unexpected end of expression"
            raise ExprError(msg, tok.pos)
        raise ExprError(f"unexpected {tok.describe()}", tok.pos)


# ---------------------------------------------------------------------------- evaluation


_SCALAR_OPS: Mapping[str, Callable[[float, float], float]] = {
    "+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv, "**": math.pow
}


def _scalar_op(op: str, a: float, b: float, pos: int) -> float:
    try:
        r = _SCALAR_OPS[op](a, b)
    except ZeroDivisionError:
        raise ExprError("division by zero", pos) from None
    except OverflowError:
        raise ExprError(f"overflow in '{op}'", pos) from None
    except ValueError:
        if a == 0:
            raise ExprError("zero raised to a negative power", pos) from None
        raise ExprError("negative number raised to a non-integer power", pos) from None
    if not math.isfinite(r):
        raise ExprError(f"overflow in '{op}'", pos)
    return r


_ARRAY_OPS: Mapping[str, Function] = {
    "+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "**": np.power
}


def _array_op(op: str, a: np.ndarray, b: np.ndarray, pos: int) -> np.ndarray:
    try:
        return np.asarray(_ARRAY_OPS[op](a, b), dtype=float)
    except FloatingPointError as exc:
        raise ExprError(f"{exc} (in '{op}')", pos) from None
    except ValueError as exc:
        raise ExprError(f"shape mismatch in '{op}': {exc}", pos) from None


@dataclass(frozen=True, eq=False)
class Expr:
    """An immutable parsed expression (build it with :func:`parse`); ``str()`` is the source."""

    text: str
    root: Node
    functions: Mapping[str, Function]
    constants: Mapping[str, float]
    array_functions: Mapping[str, Function]

    def __str__(self) -> str:
        return self.text

    def names(self) -> frozenset[str]:
        """Free identifiers (function names and constants excluded)."""
        out: set[str] = set()
        stack: list[Node] = [self.root]
        while stack:
            node = stack.pop()
            if isinstance(node, Name) and node.id not in self.constants:
                out.add(node.id)
            elif isinstance(node, (Unary, Call)):
                stack.append(node.operand if isinstance(node, Unary) else node.arg)
            elif isinstance(node, Power):
                stack.extend((node.base, node.exponent))
            elif isinstance(node, Chain):
                stack.extend([node.first] + [x for _, x, _ in node.rest])
        return frozenset(out)

    def _run(self, env: Mapping[str, Any] | None, leaf: Callable[[Any, Node], Any],
             binop: Callable[[str, Any, Any, int], Any],
             call: Callable[[str, Any, int], Any]) -> Any:
        env = {} if env is None else env

        def ev(node: Node) -> Any:
            if isinstance(node, Num):
                return leaf(node.value, node)
            if isinstance(node, Name):
                if node.id in self.constants:
                    return leaf(self.constants[node.id], node)
                if node.id not in env:
                    raise ExprError(f"unknown name '{node.id}'", node.pos)
                return leaf(env[node.id], node)
            if isinstance(node, Unary):
                v = ev(node.operand)
                return -v if node.op == "-" else v
            if isinstance(node, Call):
                return call(node.func, ev(node.arg), node.pos)
            if isinstance(node, Power):
                return binop("**", ev(node.base), ev(node.exponent), node.pos)
            acc = ev(node.first)
            for op, operand, pos in node.rest:
                acc = binop(op, acc, ev(operand), pos)
            return acc

        try:
            return ev(self.root)
        except RecursionError:
            raise ExprError("expression too deeply nested", 0) from None

    def evaluate(self, env: Mapping[str, float] | None = None) -> float:
        """Evaluate with scalar values; the result is a finite float or ExprError is raised."""

        def leaf(value: Any, node: Node) -> float:
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ExprError(f"name '{node.id}' is not a number", node.pos) from None
            if not math.isfinite(v):
                raise ExprError(f"name '{node.id}' is not finite ({v})", node.pos)
            return v

        def call(func: str, arg: float, pos: int) -> float:
            try:
                r = float(self.functions[func](arg))
            except (ValueError, OverflowError, ZeroDivisionError):
                raise ExprError(f"math domain error in {func}({arg:g})", pos) from None
            if not math.isfinite(r):
                raise ExprError(f"{func}({arg:g}) is not finite", pos)
            return r

        return self._run(env, leaf, _scalar_op, call)

    def evaluate_array(self, env: Mapping[str, Any] | None = None) -> np.ndarray:
        """Evaluate with NumPy broadcasting (env values may be arrays); returns a float array."""

        def leaf(value: Any, node: Node) -> np.ndarray:
            try:
                return np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise ExprError(f"name '{node.id}' is not numeric", node.pos) from None

        def call(func: str, arg: np.ndarray, pos: int) -> np.ndarray:
            f = self.array_functions.get(func)
            f = np.vectorize(self.functions[func], otypes=[float]) if f is None else f
            try:
                return np.asarray(f(arg), dtype=float)
            except (FloatingPointError, ValueError, OverflowError, ZeroDivisionError):
                raise ExprError(f"math domain error in {func}()", pos) from None

        with np.errstate(all="raise"):
            result = self._run(env, leaf, _array_op, call)
        if not np.all(np.isfinite(result)):
            raise ExprError("result is not finite", 0)
        return result


def parse(
    text: str,
    functions: Mapping[str, Function] | None = None,
    constants: Mapping[str, float] | None = None,
    array_functions: Mapping[str, Function] | None = None,
) -> Expr:
    """Parse ``text`` into an :class:`Expr`; raises :class:`ExprError` on anything unexpected.

    ``functions`` (scalar, one argument) and ``constants`` replace the defaults when given;
    ``array_functions`` are used by ``evaluate_array`` (NumPy versions of ``functions``).
    """
    if not isinstance(text, str):
        raise ExprError(f"expected a string expression, got {type(text).__name__}", 0)
    if len(text) > MAX_LENGTH:
        msg = f"expression too long ({len(text)} characters, limit {MAX_LENGTH})"
        raise ExprError(msg, MAX_LENGTH)
    funcs = DEFAULT_FUNCTIONS if functions is None else MappingProxyType(dict(functions))
    consts = DEFAULT_CONSTANTS if constants is None else MappingProxyType(dict(constants))
    arr = MappingProxyType(dict(array_functions or {}))  # missing ones: np.vectorize(scalar)
    arr = DEFAULT_ARRAY_FUNCTIONS if functions is None and array_functions is None else arr
    try:
        root = _Parser(text, funcs).parse()
    except RecursionError:  # only reachable when called from an already very deep stack
        raise ExprError("expression too deeply nested", 0) from None
    return Expr(text, root, funcs, consts, arr)


def evaluate(text: str, env: Mapping[str, float] | None = None,
             functions: Mapping[str, Function] | None = None,
             constants: Mapping[str, float] | None = None) -> float:
    """Parse and evaluate ``text`` with scalar ``env`` in one go."""
    return parse(text, functions, constants).evaluate(env)
