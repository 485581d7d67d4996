"""Every cross-reference in the package's docstrings names something that exists: a module,
function, class or attribute moved or renamed leaves no docstring pointing at its old name
(``:mod:``, ``:func:``, ``:class:``, ``:meth:``, ``:data:``, ``:attr:`` roles, absolute
``thrustwalk_cli.x.y``, relative ``.x.y`` or dotted from the package root or the module's own
subpackage). The check imports the modules (no compile, no kernel)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "thrustwalk_cli"
ROLE = re.compile(r":(?:mod|func|class|meth|data|attr|exc):`~?([A-Za-z_.][A-Za-z0-9_.]*)`")
EXTERNAL = ("numpy", "scipy", "matplotlib", "sympy", "numba", "typer", "rich", "yaml", "dask",
            "distributed", "mujoco", "pinocchio", "math", "collections", "typing",
            "dataclasses", "pathlib", "json", "os", "sys")


def _resolves(full: str) -> bool:
    parts = full.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for name in parts[i:]:
                obj = getattr(obj, name)
        except AttributeError:
            # a class attribute declared only by annotation (a dataclass field)
            owner = obj
            return parts[-1] in getattr(owner, "__annotations__", {})
        return True
    return False


def _candidates(ref: str, module: str) -> list[str]:
    package = module.rsplit(".", 1)[0]
    if ref.startswith("."):
        dots = len(ref) - len(ref.lstrip("."))
        base = package.split(".")
        base = base[:len(base) - (dots - 1)] if dots > 1 else base
        return [".".join(base + [ref.lstrip(".")])]
    if ref.startswith("thrustwalk_cli"):
        return [ref]
    return [f"{package}.{ref}", f"thrustwalk_cli.{ref}", f"{module}.{ref}"]


def _in_namespace(ref: str, module: str) -> bool:
    """``ref`` from a name the module defines or imports (``Problem._evaluate``)."""
    obj = importlib.import_module(module)
    try:
        for name in ref.split("."):
            obj = getattr(obj, name)
    except AttributeError:
        return False
    return True


def test_docstring_cross_references_resolve():
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG.parent).with_suffix("")
        module = ".".join(rel.parts).removesuffix(".__init__")
        for lineno, line in enumerate(path.read_text().splitlines(), 1):
            for ref in ROLE.findall(line):
                if ref.split(".")[0] in EXTERNAL or "." not in ref.strip("."):
                    continue
                if not (any(_resolves(c) for c in _candidates(ref, module))
                        or (not ref.startswith(".") and _in_namespace(ref, module))):
                    bad.append(f"{path.relative_to(PKG.parent)}:{lineno}: {ref}")
    assert not bad, "docstrings name what does not exist:\n" + "\n".join(bad)
