"""The package layers (docs/architecture.md): imports run downward only, no circles, each
third-party framework in its place, only the file layer reads input files, only commands write
results, and the core never names a command-line flag. ``ast`` only: nothing is imported.

The checker is run on the real package and on small synthetic trees that break one rule each,
so a rule that stops firing is noticed.
"""

from __future__ import annotations

import ast
import re
import textwrap
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "thrustwalk_cli"

# Layer of each top-level unit (a subpackage or a module of the package).
LAYER = {
    "errors": 0, "_version": 0,
    "thrust": 1, "description": 1, "plots": 1,
    "files": 2, "model": 2,
    "hzd": 3,
    "contact": 4, "simulation": 4,
    "energetics": 4.5,
    "optimize": 5, "design": 5, "floquet": 5, "walker": 5,
    "interchange": 5,
    "controller": 5.5,
    "resilience": 5.7,
    "sweep": 6,
    "studies": 7,
    "commands": 8,
    "cli": 9, "__main__": 9,
}
# Units a unit may import besides itself (always downward); everything else is forbidden.
# thrust/ sits beside description/, below it: a gait holds its thrust: section as written (a
# thrust.schedule.WrittenSchedule); thrust/ itself imports no description (a step and a robot
# are what it is handed).
LOW = {"errors", "_version", "thrust", "description"}
ALLOWED = {
    "errors": set(), "_version": set(),
    "thrust": {"errors", "_version"},
    "description": {"errors", "_version", "thrust"},
    "plots": set(),
    "files": LOW,
    "model": LOW,
    "hzd": LOW | {"model"},
    "contact": LOW | {"model", "hzd"},
    "simulation": LOW | {"model", "hzd"},
    "energetics": LOW | {"model", "hzd", "contact", "simulation"},
    "optimize": LOW | {"model", "hzd", "contact", "simulation", "energetics"},
    "design": LOW | {"model", "hzd", "contact", "simulation", "energetics"},
    "floquet": LOW | {"model", "hzd", "contact", "simulation"},
    "walker": LOW | {"model", "hzd", "contact", "simulation", "files"},
    "interchange": LOW | {"files", "model", "hzd", "contact", "simulation"},
    "controller": LOW | {"model", "hzd", "contact", "simulation", "optimize"},
    "resilience": LOW | {"model", "hzd", "contact", "simulation", "optimize", "controller"},
    "sweep": LOW,
    "studies": LOW | {"plots", "files", "model", "hzd", "contact", "simulation", "energetics",
                      "optimize",
                      "design", "floquet", "walker", "interchange", "controller", "resilience",
                      "sweep"},
    "commands": set(LAYER) - {"commands", "cli", "__main__"},
    "cli": {"_version", "commands"},
    "__main__": {"cli"},
}
# Third-party frameworks and the only units (or modules) that may import them.
FRAMEWORKS = {
    "typer": {"commands", "cli"}, "click": {"commands", "cli"}, "rich": {"commands"},
    "matplotlib": {"plots"}, "PIL": {"plots"},
    "sympy": {"model.derive", "model.derive_reference", "model.codegen"},
    "numba": {"model.jit", "simulation.stepper"},
    "distributed": {"sweep.executors"}, "dask": {"sweep.executors"},
    "mujoco": {"interchange.mujoco_run"},
}
# Optional frameworks: imported inside the function that needs them, never at module level, so
# that every other command runs without them installed.
LAZY = {"mujoco", "distributed", "dask"}
# One narrow adapter: where a unit may import a lower unit only through named modules
# ((importer unit, imported unit) -> the importing modules allowed).
ADAPTERS = {("interchange", "simulation"): {"interchange.mujoco_run"}}
# Modules that may read files (input parsing; the model cache and its generator digest).
READERS = {"files", "model.cache", "model.compiler"}
# Modules that may write files: result writing, the model cache, the docs generator.
WRITERS = {"files.output", "model.cache", "files.schema_docs", "commands"}
WRITE_FUNCTIONS = {"write_json", "write_csv", "write_text_atomic", "write_bytes_atomic",
                   "save_figure"}
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def _modules(root: Path) -> dict[str, Path]:
    """Dotted module name (relative to the package) -> file, ``__init__`` as the package."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts) or "__init__"] = path
    return out


def _unit(module: str) -> str:
    return module.split(".")[0]


def _matches(module: str, places: set[str]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in places)


def _imports(module: str, tree: ast.Module, modules: dict[str, Path]
             ) -> list[tuple[str, int, bool, set[str]]]:
    """(imported name, line, at module level, names taken) for every import in ``tree``;
    package-relative modules as dotted names without the package, others with a leading
    ``!`` (third party)."""
    is_pkg = modules[module].name == "__init__.py"
    base = module.split(".") if module != "__init__" else []
    if not is_pkg:
        base = base[:-1]
    top = {id(n) for n in tree.body}
    out = []
    for node in ast.walk(tree):
        level = id(node) in top
        if isinstance(node, ast.Import):
            for a in node.names:
                name = a.name
                own = name == PACKAGE.name or name.startswith(PACKAGE.name + ".")
                out.append((name.split(".", 1)[1] if own and "." in name else
                            ("__init__" if own else "!" + name), node.lineno, level, set()))
        elif isinstance(node, ast.ImportFrom):
            names = {a.name for a in node.names}
            if node.level == 0:
                mod = node.module or ""
                if mod == PACKAGE.name or mod.startswith(PACKAGE.name + "."):
                    rel = mod.split(".", 1)[1] if "." in mod else ""
                else:
                    out.append(("!" + mod, node.lineno, level, names))
                    continue
            else:
                parts = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                rel = ".".join(parts + ([node.module] if node.module else []))
            for n in names:  # "from . import cache": the submodule itself
                sub = f"{rel}.{n}" if rel else n
                if sub in modules:
                    out.append((sub, node.lineno, level, {n}))
                    names = names - {n}
            if names or not node.names:
                out.append((rel or "__init__", node.lineno, level, names))
    return out


def _strings(tree: ast.Module) -> list[ast.Constant]:
    """String constants that are not docstrings."""
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value,
                                                                     ast.Constant):
                docs.add(id(body[0].value))
    return [n for n in ast.walk(tree) if isinstance(n, ast.Constant)
            and isinstance(n.value, str) and id(n) not in docs]


def violations(root: Path) -> list[str]:
    """Every broken rule in the package at ``root``, one line each (``module:line: rule``)."""
    modules = _modules(root)
    trees = {m: ast.parse(p.read_text(), str(p)) for m, p in modules.items()}
    bad: list[str] = []
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for m, tree in trees.items():
        unit = _unit(m)
        if m == "__init__":
            continue  # the face: lazy re-exports through importlib, nothing at import time
        if modules[m].name == "__init__.py" and any(
                isinstance(n, (ast.Import, ast.ImportFrom)) for n in tree.body):
            bad.append(f"{m}:1: a subpackage's __init__ imports (names have one home)")
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name == "__getattr__" and not any(
                    isinstance(n, ast.Name) and n.id == "DeprecationWarning"
                    for n in ast.walk(node)):  # a deprecated old name warns: not a shim
                bad.append(f"{m}:{node.lineno}: module-level __getattr__ (a re-export shim)")
        for name, line, level, _ in _imports(m, tree, modules):
            if name.startswith("!"):
                lib = name[1:].split(".")[0]
                if lib in FRAMEWORKS and not _matches(m, FRAMEWORKS[lib]):
                    bad.append(f"{m}:{line}: imports {lib} (only in "
                               f"{', '.join(sorted(FRAMEWORKS[lib]))})")
                if lib in LAZY and level:
                    bad.append(f"{m}:{line}: imports {lib} at module level (an optional "
                               "package: import it where it is used)")
                continue
            if name == "__init__":
                bad.append(f"{m}:{line}: imports the package face (import from the home "
                           "module instead)")
                continue
            graph[m].add(name)
            target = _unit(name)
            if target != unit and target not in ALLOWED.get(unit, set()):
                bad.append(f"{m}:{line}: layer {unit} ({LAYER.get(unit)}) imports {name} "
                           f"(layer {target}, {LAYER.get(target)})")
            only = ADAPTERS.get((unit, target))
            if only is not None and m not in only:
                bad.append(f"{m}:{line}: imports {name} ({unit} reaches {target} only "
                           f"through {', '.join(sorted(only))})")
            symbolic = ("model.derive", "model.derive_reference", "model.codegen")
            if name in symbolic and level and unit == "model" and m not in symbolic:
                bad.append(f"{m}:{line}: imports {name} at module level (SymPy only when "
                           "compiling)")
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call):
                continue
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            if name in ("open", "read_text", "read_bytes") and not _matches(m, READERS):
                bad.append(f"{m}:{node.lineno}: reads a file ({name}; only the file layer)")
            if (name in ("write_text", "write_bytes", "mkstemp", "replace")
                    and (name != "replace" or getattr(getattr(f, "value", None), "id", "") == "os")
                    and not _matches(m, WRITERS)):
                bad.append(f"{m}:{node.lineno}: writes a file ({name}; only commands)")
            if name in WRITE_FUNCTIONS and not _matches(m, WRITERS):
                bad.append(f"{m}:{node.lineno}: writes a result ({name}; only commands)")
        if unit not in ("commands", "cli"):
            for s in _strings(tree):
                hit = FLAG.search(s.value)
                if hit:
                    bad.append(f"{m}:{s.lineno}: names the command-line flag {hit.group(0)} "
                               "(the core names parameters)")
    bad += [f"circle: {' -> '.join(c)}" for c in _circles(graph)]
    return bad


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


# ------------------------------------------------------------------------------ the package
@pytest.mark.slow
def test_package_keeps_its_layers():
    bad = violations(PACKAGE)
    assert not bad, "\n".join(bad)


def test_every_unit_has_a_layer():
    units = {_unit(m) for m in _modules(PACKAGE)} - {"__init__"}
    assert units <= set(LAYER), sorted(units - set(LAYER))


def test_one_stem_per_command():
    """Every command's stem reappears in studies/, tests/ and bench/ (plots/ where it draws)."""
    from thrustwalk_cli.cli import COMMANDS

    repo = PACKAGE.parent
    for cmd in COMMANDS:
        stem = cmd.__name__.rsplit(".", 1)[1]
        assert (PACKAGE / "studies" / f"{stem}.py").is_file(), stem
        assert (repo / "tests" / f"test_{stem}.py").is_file(), stem
    for plot in (PACKAGE / "plots").glob("*.py"):
        if plot.stem not in ("__init__", "style"):
            assert (PACKAGE / "studies" / plot.name).is_file(), plot.name
    for bench in (repo / "bench").glob("bench_*.py"):
        assert (PACKAGE / "studies" / f"{bench.stem[6:]}.py").is_file(), bench.name


# ------------------------------------------------------------------ the checker on purpose
def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    root = tmp_path / "thrustwalk_cli"
    for name, text in {"__init__.py": "", "errors.py": "", **files}.items():
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if p.parent != root and not (p.parent / "__init__.py").exists():
            (p.parent / "__init__.py").write_text('"""A layer."""\n')
        p.write_text(textwrap.dedent(text))
    return root


CLEAN = {
    "description/robot.py": "import numpy as np\nfrom ..errors import InputError\n",
    "model/compiler.py": "from ..description.robot import np\n\n\ndef f():\n"
                         "    from . import derive\n",
    "model/derive.py": "import sympy\n",
    "hzd/zero_dynamics.py": "from ..model.compiler import f\n",
    "commands/limit_cycle.py": "import typer\nfrom ..hzd.zero_dynamics import f\n",
}


@pytest.mark.parametrize("files, expected", [
    ({}, None),
    ({"hzd/bad.py": "from ..commands.limit_cycle import typer\n"}, "layer hzd (3) imports"),
    ({"thrust/bad.py": "from ..description.robot import np\n"}, "layer thrust (1) imports"),
    ({"thrust/bad.py": "from ..hzd.zero_dynamics import f\n"}, "layer thrust (1) imports"),
    ({"model/bad.py": "from ..files import output\n"}, "layer model (2) imports files"),
    ({"hzd/bad.py": "import typer\n"}, "imports typer"),
    ({"hzd/bad.py": "def f():\n    import matplotlib.pyplot\n"}, "imports matplotlib"),
    ({"hzd/bad.py": "import sympy\n"}, "imports sympy"),
    ({"hzd/bad.py": "def f():\n    import numba\n"}, "imports numba"),
    ({"studies/bad.py": "def f():\n    import distributed\n"}, "imports distributed"),
    ({"sweep/bad.py": "from ..studies.limit_cycle import f\n"}, "layer sweep (6) imports"),
    ({"model/compiler.py": "from . import derive\n"}, "at module level"),
    ({"hzd/a.py": "from . import b\n", "hzd/b.py": "def f():\n    from . import a\n"},
     "circle: hzd.a -> hzd.b"),
    ({"hzd/bad.py": "def __getattr__(name):\n    return name\n"}, "__getattr__"),
    ({"hzd/bad.py": "import warnings\n\n\ndef __getattr__(name):\n"
                    "    warnings.warn('x', UserWarning)\n    return name\n"}, "__getattr__"),
    ({"hzd/__init__.py": "from .zero_dynamics import f\n"}, "subpackage's __init__"),
    ({"hzd/bad.py": "def f(p):\n    return p.read_text()\n"}, "reads a file"),
    ({"hzd/bad.py": "def f(p):\n    p.write_text('x')\n"}, "writes a file"),
    ({"studies/bad.py": "from ..files.output import write_json\n\n\ndef f(p):\n"
                        "    write_json(p, {})\n"}, "writes a result"),
    ({"hzd/bad.py": "MSG = 'use --zeta0 instead'\n"}, "flag --zeta0"),
    ({"hzd/bad.py": "from .. import errors\nimport thrustwalk_cli\n"}, "package face"),
    ({"hzd/bad.py": "def f():\n    import mujoco\n"}, "imports mujoco (only in"),
    ({"interchange/mujoco_run.py": "import mujoco\n"}, "imports mujoco at module level"),
    ({"interchange/mjcf.py": "from ..simulation.closed_loop import f\n"},
     "interchange reaches simulation only through interchange.mujoco_run"),
])
def test_checker_fires_on_each_rule(tmp_path, files, expected):
    bad = violations(_tree(tmp_path, {**CLEAN, **files}))
    if expected is None:
        assert bad == []
    else:
        assert any(expected in b for b in bad), bad


def test_no_study_imports_another_studys_private_names():
    """Studies share code through public names only (issue 25: a private name imported from
    another study module is a second core hiding in the study layer)."""
    found = []
    for path in sorted((PACKAGE / "studies").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
                found += [f"{path.name}: from .{node.module} import {a.name}"
                          for a in node.names if a.name.startswith("_")]
    assert not found, "\n".join(found)


def test_no_module_above_600_lines_unless_one_idea():
    """Issue 25: no module above 600 lines unless its docstring says why it is one idea."""


    root = Path(__file__).resolve().parents[1] / "thrustwalk_cli"
    long = []
    for path in sorted(root.rglob("*.py")):
        text = path.read_text()
        if text.count("\n") <= 600:
            continue
        doc = ast.get_docstring(ast.parse(text)) or ""
        if "One idea in one file" not in doc:
            long.append(f"{path.relative_to(root.parent)}: {text.count(chr(10))} lines")
    assert not long, "split these, or say in the docstring why each is one idea:\n" + \
        "\n".join(long)
