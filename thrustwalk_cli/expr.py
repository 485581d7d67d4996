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

_NUMBER = re.compile(r"[0-9]+\.?[0-9]*(?:[eE][+-]?[0-9]+)?|\.[0-9]+(?:[eE][+-]?[0-9]+)?")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_WORDISH = re.compile(r"[A-Za-z0-9_.]*")
_SPACE = " \t\r\n"


class ExprError(ValueError):
    """A rejected or failed expression; ``column`` is the 0-based character offset."""

    def __init__(self, message: str, column: int = 0):
        super().__init__(message)
        self.message = message
        self.column = column


# ---------------------------------------------------------------------------- AST nodes


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
class Binary:
    op: str
    left: Node
    right: Node
    pos: int


@dataclass(frozen=True)
class Call:
    func: str
    arg: Node
    pos: int


Node = Union[Num, Name, Unary, Binary, Call]  # noqa: UP007 (runtime alias on Python 3.10)

# ---------------------------------------------------------------------------- tokenizer


@dataclass(frozen=True)
class _Tok:
    kind: str  # "num", "name", "op", "(", ")", "end"
    text: str
    pos: int

    def describe(self) -> str:
        if self.kind == "end":
            return "end of expression"
        if self.kind == "num":
            return f"number '{self.text}'"
        if self.kind == "name":
            return f"name '{self.text}'"
        return f"'{self.text}'"


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
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        if ch in _SPACE:
            i += 1
            continue
        m = _NUMBER.match(text, i)
        if m:
            end = m.end()
            tail = _WORDISH.match(text, end)
            if tail and tail.end() > end:
                bad = text[i : tail.end()]
                raise ExprError(f"invalid number '{bad}'", i)
            toks.append(_Tok("num", m.group(), i))
            i = end
            continue
        m = _NAME.match(text, i)
        if m:
            word = m.group()
            if keyword.iskeyword(word) or keyword.issoftkeyword(word):
                raise ExprError(f"keyword '{word}' is not allowed", i)
            toks.append(_Tok("name", word, i))
            i = m.end()
            continue
        if ch == "." and toks and toks[-1].kind in ("name", ")"):
            raise ExprError("attribute access ('.') is not allowed", i)
        if text.startswith("**", i):
            toks.append(_Tok("op", "**", i))
            i += 2
            continue
        if ch in "+-*/":
            toks.append(_Tok("op", ch, i))
        elif ch in "()":
            toks.append(_Tok(ch, ch, i))
        else:
            raise _char_error(ch, i)
        i += 1
    toks.append(_Tok("end", "", n))
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
        node = self.term()
        while self._is_op("+", "-"):
            op = self._next()
            node = Binary(op.text, node, self.term(), op.pos)
        return node

    def term(self) -> Node:
        node = self.unary()
        while self._is_op("*", "/"):
            op = self._next()
            node = Binary(op.text, node, self.unary(), op.pos)
        return node

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
            node = Binary("**", node, self.unary(), op.pos)
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


def _scalar_binary(op: str, a: float, b: float, pos: int) -> float:
    try:
        if op == "+":
            r = a + b
        elif op == "-":
            r = a - b
        elif op == "*":
            r = a * b
        elif op == "/":
            r = a / b
        else:
            r = math.pow(a, b)
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
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
    "/": np.divide,
    "**": np.power,
}


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
            if isinstance(node, Name):
                if node.id not in self.constants:
                    out.add(node.id)
            elif isinstance(node, Unary):
                stack.append(node.operand)
            elif isinstance(node, Binary):
                stack.extend((node.left, node.right))
            elif isinstance(node, Call):
                stack.append(node.arg)
        return frozenset(out)

    def _lookup(self, node: Name, env: Mapping[str, Any]) -> Any:
        if node.id in self.constants:
            return self.constants[node.id]
        if node.id not in env:
            raise ExprError(f"unknown name '{node.id}'", node.pos)
        return env[node.id]

    def evaluate(self, env: Mapping[str, float] | None = None) -> float:
        """Evaluate with scalar values; the result is a finite float or ExprError is raised."""
        env = {} if env is None else env

        def ev(node: Node) -> float:
            if isinstance(node, Num):
                return node.value
            if isinstance(node, Name):
                value = self._lookup(node, env)
                try:
                    value = float(value)
                except (TypeError, ValueError):
                    raise ExprError(f"name '{node.id}' is not a number", node.pos) from None
                if not math.isfinite(value):
                    raise ExprError(f"name '{node.id}' is not finite ({value})", node.pos)
                return value
            if isinstance(node, Unary):
                v = ev(node.operand)
                return -v if node.op == "-" else v
            if isinstance(node, Binary):
                return _scalar_binary(node.op, ev(node.left), ev(node.right), node.pos)
            arg = ev(node.arg)
            try:
                r = float(self.functions[node.func](arg))
            except (ValueError, OverflowError, ZeroDivisionError):
                raise ExprError(f"math domain error in {node.func}({arg:g})", node.pos) from None
            if not math.isfinite(r):
                raise ExprError(f"{node.func}({arg:g}) is not finite", node.pos)
            return r

        return ev(self.root)

    def evaluate_array(self, env: Mapping[str, Any] | None = None) -> np.ndarray:
        """Evaluate with NumPy broadcasting (env values may be arrays); returns a float array."""
        env = {} if env is None else env

        def ev(node: Node) -> np.ndarray:
            if isinstance(node, Num):
                return np.asarray(node.value, dtype=float)
            if isinstance(node, Name):
                value = self._lookup(node, env)
                try:
                    return np.asarray(value, dtype=float)
                except (TypeError, ValueError):
                    raise ExprError(f"name '{node.id}' is not numeric", node.pos) from None
            if isinstance(node, Unary):
                v = ev(node.operand)
                return -v if node.op == "-" else v
            if isinstance(node, Binary):
                a, b = ev(node.left), ev(node.right)
                try:
                    return np.asarray(_ARRAY_OPS[node.op](a, b), dtype=float)
                except FloatingPointError as exc:
                    raise ExprError(f"{exc} (in '{node.op}')", node.pos) from None
                except ValueError as exc:
                    raise ExprError(f"shape mismatch in '{node.op}': {exc}", node.pos) from None
            func = self.array_functions.get(node.func)
            if func is None:
                func = np.vectorize(self.functions[node.func], otypes=[float])
            try:
                return np.asarray(func(ev(node.arg)), dtype=float)
            except (FloatingPointError, ValueError, OverflowError, ZeroDivisionError):
                raise ExprError(f"math domain error in {node.func}()", node.pos) from None

        with np.errstate(all="raise"):
            result = ev(self.root)
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
        raise ExprError(
            f"expression too long ({len(text)} characters, limit {MAX_LENGTH})", MAX_LENGTH
        )
    funcs = DEFAULT_FUNCTIONS if functions is None else MappingProxyType(dict(functions))
    consts = DEFAULT_CONSTANTS if constants is None else MappingProxyType(dict(constants))
    if array_functions is None:
        arr = DEFAULT_ARRAY_FUNCTIONS if functions is None else MappingProxyType({})
    else:
        arr = MappingProxyType(dict(array_functions))
    root = _Parser(text, funcs).parse()
    return Expr(text, root, funcs, consts, arr)


def evaluate(
    text: str,
    env: Mapping[str, float] | None = None,
    functions: Mapping[str, Function] | None = None,
    constants: Mapping[str, float] | None = None,
) -> float:
    """Parse and evaluate ``text`` with scalar ``env`` in one go."""
    return parse(text, functions, constants).evaluate(env)
