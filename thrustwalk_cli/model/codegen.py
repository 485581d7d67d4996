"""Generate Python source for the numeric model from SymPy expressions (imports SymPy).

Each quantity becomes two functions with common-subexpression elimination:

* ``NAME(*args)``: vectorised NumPy; every argument has shape ``(..., k)``, the result has
  shape ``(..., rows, cols)`` (or ``(..., rows)`` for vectors). Constant entries broadcast.
* ``NAME_s(*args)``: one state, ``math`` functions, sequences in, flat row-major list out
  (the fast path inside ODE right-hand sides; see shared/PERF_NOTES.md).
* ``NAME_nb(*args, out)`` (``numba=True``): one state, ``math`` functions, 1-D float arrays in,
  the flat row-major result written into ``out``; plain Python that numba compiles as it is
  (the compiled simulation jit-compiles these, see :mod:`thrustwalk_cli.model.jit`).

The generated module imports only ``math`` and ``numpy``.
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.pycode import PythonCodePrinter


class _NpPrinter(NumPyPrinter):
    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": False, "inline": True})

    def _module_format(self, fqn: str, register: bool = True) -> str:  # numpy.cos -> _np.cos
        return "_np." + fqn.split(".")[-1]


class _MathPrinter(PythonCodePrinter):
    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": False, "inline": True})

    def _module_format(self, fqn: str, register: bool = True) -> str:  # math.cos -> _m.cos
        return "_m." + fqn.split(".")[-1]


def generate_function(
    name: str,
    M: sp.Matrix,
    args: list[tuple[str, list[sp.Symbol]]],
    doc: str,
    vector: bool = False,
    numba: bool = False,
) -> str:
    """Source of ``name`` (vectorised) and ``name_s`` (scalar) evaluating matrix ``M``, and
    with ``numba`` also ``name_nb`` (scalar, array in, written into ``out``).

    ``args``: ``[(argument_name, [symbols in order])]``; the docstring lists the order.
    ``vector``: a column matrix is returned as a vector ``(..., rows)``.
    """
    flat = list(M) if M.shape[0] * M.shape[1] else []
    repl, reduced = sp.cse(flat, symbols=sp.numbered_symbols("t_"), order="none")
    shape = (M.shape[0],) if vector else tuple(M.shape)
    order = "; ".join(f"{a} = [{', '.join(str(s) for s in syms)}]" for a, syms in args)
    used = set().union(*(e.free_symbols for e in flat)) if flat else set()
    used |= set().union(*(e.free_symbols for _, e in repl)) if repl else set()
    sig = ", ".join(a for a, _ in args)
    np_p, m_p = _NpPrinter(), _MathPrinter()
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
        lines.append(f"    {s} = {np_p.doprint(e)}")
    lines.append(f"    _out = _np.empty(_b + {shape!r})")
    for k, e in enumerate(reduced):
        if len(shape) == 1:
            idx = f"..., {k}"
        else:
            idx = f"..., {k // shape[1]}, {k % shape[1]}"
        lines.append(f"    _out[{idx}] = {np_p.doprint(e)}")
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
        lines.append(f"    {s} = {m_p.doprint(e)}")
    items = ", ".join(m_p.doprint(sp.Float(e) if e.is_Number else e) for e in reduced)
    lines.append(f"    return [{items}]")
    lines.append("")
    if numba:
        lines.append(f"def {name}_nb({sig}, out):")
        lines.append(f'    """Scalar {name} into ``out`` (flat, row-major, {len(reduced)} '
                     f'values). {order}."""')
        for a, syms in args:
            for i, s in enumerate(syms):
                if s in used:
                    lines.append(f"    {s} = {a}[{i}]")
        for s, e in repl:
            lines.append(f"    {s} = {m_p.doprint(e)}")
        for k, e in enumerate(reduced):
            lines.append(f"    out[{k}] = {m_p.doprint(sp.Float(e) if e.is_Number else e)}")
        lines.append("")
    return "\n".join(lines)


def generate_module(header: str, functions: list[str], constants: dict[str, object]) -> str:
    """Assemble a self-contained module: imports, constants, functions."""
    out = [f'"""{header}"""', "import math as _m", "import numpy as _np", ""]
    for k, v in constants.items():
        out.append(f"{k} = {v!r}")
    out.append("")
    out.extend(functions)
    return "\n".join(out) + "\n"
