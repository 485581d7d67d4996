"""Generate Python source for the numeric model from SymPy expressions (imports SymPy).

Each quantity becomes two functions with common-subexpression elimination:

* ``NAME(*args)``: vectorised NumPy; every argument has shape ``(..., k)``, the result has
  shape ``(..., rows, cols)`` (or ``(..., rows)`` for vectors). Constant entries broadcast.
* ``NAME_s(*args)``: one state, ``math`` functions, sequences in, flat row-major list out
  (the fast path inside ODE right-hand sides; see shared/PERF_NOTES.md).

and :func:`generate_tape` turns groups of expressions into a *tape*, plain data that the
robot-independent interpreter of :mod:`thrustwalk_cli.model.tape` evaluates in compiled code
(the compiled simulation and the batch evaluators): a new robot costs SymPy and this
translation, never a numba compile.

The robot's numbers are inputs: the generated module's ``bind(P)`` takes them (in the order
of ``PARAMS``, ``Robot.numbers()``), computes every coefficient that depends on them alone
once (:class:`Hoist`: ``k0 = P3*P7**2 + ...``) and returns the functions above as closures
over those coefficients, plus ``_consts``, the tape's constants for those numbers. So one
generated module (and one tape) serves every value of the numbers.

The generated module imports only ``math`` and ``numpy``.
"""

from __future__ import annotations

from collections.abc import Callable

import sympy as sp
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.pycode import PythonCodePrinter


class _NpPrinter(NumPyPrinter):
    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": False, "inline": True, "order": "none"})

    def _module_format(self, fqn: str, register: bool = True) -> str:  # numpy.cos -> _np.cos
        return "_np." + fqn.split(".")[-1]


class _MathPrinter(PythonCodePrinter):
    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": False, "inline": True, "order": "none"})

    def _module_format(self, fqn: str, register: bool = True) -> str:  # math.cos -> _m.cos
        return "_m." + fqn.split(".")[-1]


class Printers:
    """The two printers (NumPy, ``math``) with a memo: a definition that several functions
    need is printed once."""

    def __init__(self) -> None:
        self.np, self.m = _NpPrinter(), _MathPrinter()
        self.memo: dict[tuple[bool, sp.Expr], str] = {}

    def __call__(self, e: sp.Expr, numpy: bool) -> str:
        key = (numpy, e)
        r = self.memo.get(key)
        if r is None:
            r = (self.np if numpy else self.m).doprint(e)
            self.memo[key] = r
        return r


def needed_definitions(defs: dict[sp.Symbol, sp.Expr], exprs: list[sp.Expr]
                       ) -> list[tuple[sp.Symbol, sp.Expr]]:
    """The definitions that ``exprs`` read, directly or through other definitions, in the
    order of ``defs`` (each after the ones it reads)."""
    seen: set[sp.Symbol] = set()
    stack = [s for e in exprs for s in e.free_symbols if s in defs]
    while stack:
        s = stack.pop()
        if s in seen:
            continue
        seen.add(s)
        stack.extend(x for x in defs[s].free_symbols if x in defs and x not in seen)
    return [(s, e) for s, e in defs.items() if s in seen]


def generate_function(
    name: str,
    M: sp.Matrix,
    args: list[tuple[str, list[sp.Symbol]]],
    doc: str,
    vector: bool = False,
    defs: dict[sp.Symbol, sp.Expr] | None = None,
    printers: Printers | None = None,
) -> str:
    """Source of ``name`` (vectorised) and ``name_s`` (scalar) evaluating matrix ``M``.

    ``args``: ``[(argument_name, [symbols in order])]``; the docstring lists the order.
    ``vector``: a column matrix is returned as a vector ``(..., rows)``.
    ``defs``: definitions that ``M`` is written in (:func:`thrustwalk_cli.model.derive.derive`):
    the ones it needs become the function's temporaries, in order, with no
    common-subexpression search; without ``defs``, SymPy's ``cse`` finds the temporaries.
    """
    flat = list(M) if M.shape[0] * M.shape[1] else []
    if defs is None:
        repl, reduced = sp.cse(flat, symbols=sp.numbered_symbols("t_"), order="none")
    else:
        repl, reduced = needed_definitions(defs, flat), flat
    pr = printers or Printers()
    shape = (M.shape[0],) if vector else tuple(M.shape)
    order = "; ".join(f"{a} = [{', '.join(str(s) for s in syms)}]" for a, syms in args)
    used = set().union(*(e.free_symbols for e in flat)) if flat else set()
    used |= set().union(*(e.free_symbols for _, e in repl)) if repl else set()
    sig = ", ".join(a for a, _ in args)
    dims = ", ".join(map(str, shape))
    lines = [f"def {name}({sig}):", f'    """{doc}\n\n    Argument order: {order}.',
             f'    Returns shape (..., {dims})."""']
    batch = []
    for a, syms in args:
        lines.append(f"    {a} = _np.asarray({a}, dtype=float)")
        batch.append(f"{a}.shape[:-1]")
        for i, s in enumerate(syms):
            if s in used:
                lines.append(f"    {s} = {a}[..., {i}]")
    lines.append(f"    _b = _np.broadcast_shapes({', '.join(batch)})")
    for s, e in repl:
        lines.append(f"    {s} = {pr(e, True)}")
    lines.append(f"    _out = _np.empty(_b + {shape!r})")
    for k, e in enumerate(reduced):
        if len(shape) == 1:
            idx = f"..., {k}"
        else:
            idx = f"..., {k // shape[1]}, {k % shape[1]}"
        lines.append(f"    _out[{idx}] = {pr(e, True)}")
    lines.append("    return _out")
    lines.append("")
    lines.append(f"def {name}_s({sig}):")
    lines.append(f'    """Scalar {name}: sequences in, flat row-major list out. {order}."""')
    for a, syms in args:
        names_ = [str(s) if s in used else "_" for s in syms]
        if len(syms) == 1:
            lines.append(f"    {names_[0]}, = {a}")
        else:
            lines.append(f"    {', '.join(names_)} = {a}")
    for s, e in repl:
        lines.append(f"    {s} = {pr(e, False)}")
    items = ", ".join(pr(sp.Float(e) if e.is_Number else e, False) for e in reduced)
    lines.append(f"    return [{items}]")
    lines.append("")
    return "\n".join(lines)


class Hoist:
    """Coefficients that depend on the robot's numbers alone, computed once per bound
    vector instead of at every call: each maximal such subexpression (the number factors of a
    product, the number terms of a sum, a whole entry) becomes a symbol ``k<j>``; equal
    subexpressions share one."""

    def __init__(self, inputs: set[sp.Symbol]):
        self.P = set(inputs)
        self.table: dict[sp.Expr, sp.Symbol] = {}
        self.memo: dict[sp.Expr, sp.Expr] = {}

    @property
    def symbols(self) -> set[sp.Symbol]:
        return set(self.table.values())

    def k(self, e: sp.Expr) -> sp.Expr:
        if e.is_Number:
            return e
        s = self.table.get(e)
        if s is None:
            s = sp.Symbol(f"k{len(self.table)}", real=True)
            self.table[e] = s
        return s

    def __call__(self, e: sp.Expr) -> sp.Expr:
        if not self.P:
            return e
        r = self.memo.get(e)
        if r is None:
            r = self._hoist(e)
            self.memo[e] = r
        return r

    def _hoist(self, e: sp.Expr) -> sp.Expr:
        fs = e.free_symbols
        if not fs & self.P:
            return e
        if fs <= self.P:
            return self.k(e)
        if e.is_Add or e.is_Mul:
            own = [a for a in e.args if a.free_symbols <= self.P]
            rest = [self(a) for a in e.args if not a.free_symbols <= self.P]
            if any(a.free_symbols for a in own):
                return e.func(self.k(e.func(*own)), *rest)
            return e.func(*own, *rest)
        return e.func(*[self(a) for a in e.args])

    def matrix(self, M: sp.Matrix) -> sp.Matrix:
        return M.applyfunc(self) if self.P and M.shape[0] * M.shape[1] else M

    def source(self, params: list[sp.Symbol]) -> list[str]:
        """Lines (indented for ``bind``) unpacking ``P`` and computing every ``k``."""
        m_p = _MathPrinter()
        exprs = list(self.table)
        used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
        names = [str(s) if s in used else "_" for s in params]
        lines = [f"    {', '.join(names)}{',' if len(names) == 1 else ''} = P"] if params \
            else []
        if exprs:
            repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("x_"), order="none")
            lines += [f"    {s} = {m_p.doprint(e)}" for s, e in repl]
            lines += [f"    {self.table[e]} = {m_p.doprint(sp.Float(r) if r.is_Number else r)}"
                      for e, r in zip(exprs, reduced)]
        return lines


def generate_module(header: str, functions: list[str], constants: dict[str, object],
                    bind_lines: list[str], exports: list[str], tape_consts: list) -> str:
    """Assemble a self-contained module: imports, constants, and ``bind(P)``, which runs
    ``bind_lines`` (the numbers' coefficients, :meth:`Hoist.source`) and returns the
    ``functions`` (defined inside it: closures over those coefficients) by name, with
    ``_consts``, the tape's constants (numbers, and coefficients by name)."""
    # the header holds names from the robot file: written as a string literal by repr, never
    # spliced into quotes (a name holding triple quotes would otherwise end the docstring and
    # run as code when the module is imported)
    out = [repr(header), "import math as _m", "import numpy as _np", ""]
    for k, v in constants.items():
        out.append(f"{k} = {v!r}")
    out.append(f"_EXPORTS = {tuple(exports)!r}")
    out += ["", "", "def bind(P):",
            '    """The model\'s functions for the numbers ``P`` (in the order of ``PARAMS``):',
            '    name -> function, and ``_consts`` (the tape\'s constants)."""']
    out += bind_lines
    for f in functions:
        out += [("    " + ln) if ln else "" for ln in f.split("\n")]
    consts = ", ".join(c if isinstance(c, str) else repr(float(c)) for c in tape_consts)
    out += [f"    _consts = [{consts}]", "    _l = locals()",
            "    return {_n: _l[_n] for _n in _EXPORTS + ('_consts',) if _n in _l}", ""]
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- tapes
class _TapeBuilder:
    """Expression trees -> instructions ``(op, dst, a, b)`` on a register file.

    Registers ``0 .. n_in-1`` hold the inputs, then the constants (shared by every program),
    then temporaries. Identical subtrees and identical instructions are computed once (value
    numbering). ``sin``/``cos`` of an integer combination of inputs come from the sines and
    cosines of the inputs themselves by the angle-addition formulas (one ``sin`` and one
    ``cos`` per input angle instead of one call per distinct argument).
    """

    def __init__(self, inputs: list[sp.Symbol], params: set[sp.Symbol] = frozenset(),
                 defs: dict[sp.Symbol, sp.Expr] | None = None):
        from .tape import OPS

        self.op_code = OPS
        self.inputs = {s: i for i, s in enumerate(inputs)}
        self.params = params
        self.defs = defs or {}
        self.consts: dict[float | sp.Symbol, int] = {}

    def start(self) -> None:
        self.reg = dict(self.inputs)
        self.ins: list[tuple[int, int, int, int]] = []
        self.vn: dict[tuple[int, int, int], int] = {}
        self.memo: dict[sp.Expr, int] = {}
        self.trig: dict[tuple, tuple[int, int]] = {}
        self.next = 0  # temporaries are numbered from 0 here, placed after the constants

    def const(self, v) -> int:
        """The register of a number, or of a coefficient ``k`` of the robot's numbers
        (:class:`Hoist`: a constant whose value the bound model supplies)."""
        v = v if isinstance(v, sp.Symbol) else float(v)
        if v not in self.consts:
            self.consts[v] = len(self.consts)
        return -1 - self.consts[v]  # constants: negative ids until the layout is fixed

    def op(self, name: str, a: int, b: int = 0) -> int:
        code = self.op_code[name]
        if name in ("add", "mul") and a > b:
            a, b = b, a
        key = (code, a, b)
        if key in self.vn:
            return self.vn[key]
        d = len(self.inputs) + 1_000_000 + self.next  # a temporary (renumbered later)
        self.next += 1
        self.ins.append((code, d, a, b))
        self.vn[key] = d
        return d

    def emit(self, e: sp.Expr) -> int:
        r = self.memo.get(e)
        if r is None:
            r = self._emit(e)
            self.memo[e] = r
        return r

    def _signed(self, e: sp.Expr) -> tuple[int, int]:
        c, _ = e.as_coeff_Mul()
        if c.is_Number and c < 0:
            return -1, self.emit(-e)
        return 1, self.emit(e)

    def _emit(self, e: sp.Expr) -> int:
        if e.is_Symbol:
            if e in self.params:
                return self.const(e)
            if e in self.defs:
                return self.emit(self.defs[e])
            if e not in self.reg:
                raise ValueError(f"tape: unknown symbol {e}")
            return self.reg[e]
        if e.is_Number:
            return self.const(e)
        if e.is_Add:
            terms = [self._signed(a) for a in e.args]
            pos = [r for s, r in terms if s > 0]
            neg = [r for s, r in terms if s < 0]
            if pos:
                acc = pos[0]
                for r in pos[1:]:
                    acc = self.op("add", acc, r)
            else:
                acc = self.op("neg", neg[0])
                neg = neg[1:]
            for r in neg:
                acc = self.op("sub", acc, r)
            return acc
        if e.is_Mul:
            c, rest = e.as_coeff_Mul()
            if c.is_Number and c != 1:
                r = self.emit(rest)
                return self.op("neg", r) if c == -1 else self.op("mul", self.const(c), r)
            factors = [self.emit(a) for a in e.args]
            acc = factors[0]
            for r in factors[1:]:
                acc = self.op("mul", acc, r)
            return acc
        if e.is_Pow:
            base, x = e.args
            if x.is_Integer and 0 < x <= 8:
                rb = self.emit(base)
                acc = rb
                for _ in range(int(x) - 1):
                    acc = self.op("mul", acc, rb)
                return acc
            if x.is_Integer and -8 <= x < 0:
                return self.op("div", self.const(1.0), self.emit(base ** (-x)))
            return self.op("pow", self.emit(base), self.emit(x))
        if isinstance(e, (sp.sin, sp.cos)):
            combo = self._linear(e.args[0])
            if combo is not None:
                s, c = self._sincos(combo)
                return s if isinstance(e, sp.sin) else c
            return self.op("sin" if isinstance(e, sp.sin) else "cos", self.emit(e.args[0]))
        raise ValueError(f"tape: unsupported expression {type(e).__name__}")

    def _linear(self, a: sp.Expr) -> tuple | None:
        """``a`` as ((input register, integer coefficient), ...), or None; definitions that
        are integer combinations of inputs count as such."""
        acc: dict[int, int] = {}

        def walk(e: sp.Expr, m: int) -> bool:
            for k, v in e.as_coefficients_dict().items():
                if not v.is_Integer:
                    return False
                if k in self.inputs:
                    acc[self.inputs[k]] = acc.get(self.inputs[k], 0) + m * int(v)
                elif k in self.defs:
                    if not walk(self.defs[k], m * int(v)):
                        return False
                else:
                    return False
            return True
        if not walk(a, 1):
            return None
        return tuple(sorted((r, c) for r, c in acc.items() if c)) or None

    def _sincos(self, combo: tuple) -> tuple[int, int]:
        """Registers of ``sin`` and ``cos`` of ``sum k_i x_i``: ``sin(a + b) = s_a c_b + c_a
        s_b``, ``cos(a + b) = c_a c_b - s_a s_b``, ``sin(-a) = -sin a``."""
        r = self.trig.get(combo)
        if r is not None:
            return r
        if len(combo) == 1 and combo[0][1] == 1:
            i = combo[0][0]
            r = (self.op("sin", i), self.op("cos", i))
        elif len(combo) == 1 and combo[0][1] == -1:
            s, c = self._sincos(((combo[0][0], 1),))
            r = (self.op("neg", s), c)
        else:
            if len(combo) == 1:
                i, k = combo[0]
                sgn = 1 if k > 0 else -1
                a, b = ((i, k - sgn),), ((i, sgn),)
            else:
                a, b = combo[:-1], combo[-1:]
            sa, ca = self._sincos(a)
            sb, cb = self._sincos(b)
            r = (self.op("add", self.op("mul", sa, cb), self.op("mul", ca, sb)),
                 self.op("sub", self.op("mul", ca, cb), self.op("mul", sa, sb)))
        self.trig[combo] = r
        return r


def _fuse(order: list[tuple[int, int, int, int]], outs: list[int], ops: dict[str, int]
          ) -> list[tuple[int, int, int, int, int]]:
    """Fold a product read once into the sum or difference that reads it: ``a b + c``
    (fma), ``a b - c`` (fms), ``c - a b`` (fnma), rounded twice as before (numba does not
    contract them into hardware fused multiply-adds), one instruction fewer each."""
    mul, add, sub = ops["mul"], ops["add"], ops["sub"]
    unary = {ops[k] for k in ("neg", "sin", "cos")}
    uses: dict[int, int] = {}
    for op, _, x, y in order:
        for a in ((x,) if op in unary else (x, y)):
            uses[a] = uses.get(a, 0) + 1
    for r in outs:
        uses[r] = uses.get(r, 0) + 1
    prods = {d: (x, y) for op, d, x, y in order if op == mul}
    gone: set[int] = set()

    def single(r: int) -> bool:
        return r in prods and uses.get(r) == 1 and r not in gone
    out: list[tuple[int, int, int, int, int]] = []
    for op, d, x, y in order:
        if op == add and (single(x) or single(y)):
            p, other = (x, y) if single(x) else (y, x)
            gone.add(p)
            out.append((ops["fma"], d, *prods[p], other))
        elif op == sub and single(x):
            gone.add(x)
            out.append((ops["fms"], d, *prods[x], y))
        elif op == sub and single(y):
            gone.add(y)
            out.append((ops["fnma"], d, *prods[y], x))
        else:
            out.append((op, d, x, y, 0))
    return [ins for ins in out if not (ins[0] == mul and ins[1] in gone)]


def _pair_trig(order: list[tuple[int, int, int, int, int]], ops: dict[str, int]
               ) -> list[tuple[int, int, int, int, int]]:
    """``sin x`` directly followed by ``cos x`` -> ``sincos x`` (both values: the sine in its
    register, the cosine in the next) and a ``skip`` that holds the cosine's register."""
    out: list[tuple[int, int, int, int, int]] = []
    i = 0
    while i < len(order):
        ins = order[i]
        nxt = order[i + 1] if i + 1 < len(order) else None
        if ins[0] == ops["sin"] and nxt is not None and nxt[0] == ops["cos"] \
                and nxt[2] == ins[2]:
            out += [(ops["sincos"], ins[1], ins[2], 0, 0), (ops["skip"], nxt[1], 0, 0, 0)]
            i += 2
        else:
            out.append(ins)
            i += 1
    return out


def generate_tape(programs: dict[str, tuple[int, list[sp.Expr]]],
                  inputs: list[sp.Symbol], params: set[sp.Symbol] = frozenset(),
                  defs: dict[sp.Symbol, sp.Expr] | None = None,
                  progress: Callable[[str], None] | None = None) -> dict:
    """Compile groups of expressions into one tape (plain data, see
    :mod:`thrustwalk_cli.model.tape` for its layout and interpreter).

    ``programs``: name -> (number of inputs it reads, flat list of output expressions);
    ``inputs``: the input symbols in register order (``q`` then ``q'``). Each program keeps
    only the instructions its outputs need, ordered by depth (instructions of equal depth do
    not depend on each other, which keeps the processor's pipelines full); instruction j
    writes register ``base + j`` (each register written once; ``sincos`` also the next, whose
    instruction is a ``skip``: the sine and cosine of one angle are one library call).
    ``params``: symbols that are constants whose values come with the bound model (the
    coefficients of the robot's numbers): ``consts`` names them, and the bound model
    supplies their values. ``defs``: definitions the expressions are written in (each is
    emitted where a program first reads it). ``progress`` is called with each program's
    name when it is encoded.
    """
    b = _TapeBuilder(inputs, params, defs)
    raw = {}
    for name, (n_in, exprs) in programs.items():
        b.start()
        outs = [b.emit(e) for e in exprs]
        need, live = set(outs), []
        for ins in reversed(b.ins):
            if ins[1] in need:
                live.append(ins)
                need.update((ins[2], ins[3]))
        live.reverse()
        raw[name] = (n_in, outs, live)
    n_in_all, n_const = len(inputs), len(b.consts)
    base = n_in_all + n_const  # first temporary register
    unary = {b.op_code[k] for k in ("neg", "sin", "cos", "sincos", "skip")}
    sin, cos = b.op_code["sin"], b.op_code["cos"]

    def rank(ins: tuple[int, int, int, int]) -> tuple:
        """Sort key: depth, then operation; ``cos x`` right after ``sin x``."""
        if ins[0] in (sin, cos):
            return (level[ins[1]], sin, ins[2], ins[0] == cos)
        return (level[ins[1]], ins[0])
    if base + max((len(v[2]) for v in raw.values()), default=0) >= 1 << 19:
        raise ValueError("tape: more than 2^19 registers")

    code: list[int] = []
    offsets: dict[str, int] = {}
    nreg = base
    for name, (n_in, outs, live) in raw.items():
        level: dict[int, int] = {}
        for op, d, x, y in live:
            level[d] = 1 + max(level.get(a, 0) for a in ((x,) if op in unary else (x, y)))
        order = _pair_trig(_fuse(sorted(live, key=rank), outs, b.op_code), b.op_code)
        where = {ins[1]: base + j for j, ins in enumerate(order)}
        where.update({r: n_in_all + (-1 - r) for r in range(-n_const, 0)})  # constants
        enc: list[int] = []
        for op, _, x, y, z in order:  # one integer: op << 57 | a << 38 | b << 19 | c
            enc.append(op << 57 | where.get(x, x) << 38
                       | (0 if op in unary else where.get(y, y)) << 19 | where.get(z, z))
        offsets[name] = len(code)
        code += [n_in, len(outs), len(order), base, *(where.get(r, r) for r in outs), *enc]
        nreg = max(nreg, base + len(order))
        if progress is not None:
            progress(name)
    consts: list = [0.0] * n_const
    for v, i in b.consts.items():
        consts[i] = str(v) if isinstance(v, sp.Symbol) else v
    return {"code": code, "consts": consts, "programs": offsets, "nreg": nreg,
            "n_inputs": n_in_all}
