"""numba-compiled functions of a model, cached on disk beside the model (PERF_NOTES).

A *jit module* is one generated Python file in the model cache: some numba-ready source (the
compiled simulation kernel, or the batch evaluators below), then the model's own generated
module (its ``NAME_nb`` scalar functions, whose definitions replace the placeholders of the
source above them), then a footer that wraps the listed functions, callees first, in
``numba.njit(signature, cache=True)``: explicit signatures compile each function once, when
the module is imported. numba keeps the machine code in ``__pycache__`` beside that file,
so a second process loads it instead of compiling (the file name carries a hash of everything
that went into it; numba checks its own version and the CPU). A JSON sidecar records how long
the one-time compile took, so ``thrustwalk compile`` can report it without importing numba.

numba is imported only when a jit module is imported, never by ``import thrustwalk_cli`` or a
cached model.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from . import cache
from .compiled import CompiledModel

OPTIONS = "cache=True, nogil=True, error_model='numpy'"


def _numba_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("numba")
    except PackageNotFoundError:  # pragma: no cover - numba is a dependency
        return "missing"


def model_signatures(model_names: Sequence[str]) -> dict[str, str]:
    """numba signatures of the model's ``NAME_nb`` functions (1-D float arrays in, ``out``)."""
    from .compiled import FUNCTIONS

    return {f"{n}_nb": "(" + ", ".join(["float64[::1]"] * (len(FUNCTIONS[n][0]) + 1)) + ")"
            for n in sorted(model_names)}


def entry_path(model: CompiledModel, tag: str, source: str, names: dict[str, str],
               inline: Sequence[str] = ()) -> Path:
    """Where the jit module of ``model`` for ``source`` lives (a hash of all its inputs)."""
    h = hashlib.sha256()
    for part in (model.key, tag, source, repr(sorted(names.items())), repr(tuple(inline)),
                 OPTIONS, _numba_version()):
        h.update(part.encode())
        h.update(b"\0")
    return cache.entry_path(f"{model.robot.name}-{tag}", model.key[:10] + h.hexdigest()[:16])


def _module_source(model: CompiledModel, source: str, names: dict[str, str],
                   inline: Sequence[str]) -> str:
    body = cache.read_body(model.cache_path)
    footer = [
        "", "# ---- numba: compile the functions above once, cache them beside this file",
        "import numba as _numba", "",
        *([f"for _name in {tuple(inline)!r}:",
           "    globals()[_name] = _numba.njit(inline='always', error_model='numpy')("
           "globals()[_name])", ""] if inline else []),
        "_JIT = {",
        *[f"    {k!r}: {v!r}," for k, v in names.items()],
        "}",
        "for _name, _sig in _JIT.items():",
        f"    globals()[_name] = _numba.njit(_sig, {OPTIONS})(globals()[_name])", "",
    ]
    return (source.rstrip() + "\n\n\n# ---- the model's generated functions\n" + body.rstrip()
            + "\n" + "\n".join(footer))


@dataclass
class JitModule:
    """A loaded jit module. ``compile_seconds``: the one-time numba compile (measured now, or
    as recorded when it happened); ``cache_hit``: the machine code came from the disk
    cache; ``load_seconds``: this import."""

    module: ModuleType
    path: Path
    load_seconds: float
    cache_hit: bool
    compile_seconds: float | None


_LOADED: dict[str, JitModule] = {}


def _import(path: Path, key: str) -> ModuleType:
    """Import a verified jit module under a stable name (numba's cache refers to the
    compiled functions by module name when it loads them in another process)."""
    import importlib.util
    import sys

    name = f"thrustwalk_jit_{key.replace('-', '_')}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:  # pragma: no cover - the file was just written
        raise ImportError(f"cannot import {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def load(model: CompiledModel, tag: str, source: str, names: dict[str, str],
         inline: Sequence[str] = (), rebuild: bool = False) -> JitModule:
    """The jit module of ``model`` for ``source``: written to the cache if missing, then
    imported, which compiles every function in ``names`` (name -> numba signature, callees
    first) or loads its machine code from numba's cache; the functions in ``inline`` are
    inlined into their callers. ``rebuild``: discard both."""
    path = entry_path(model, tag, source, names, inline)
    key = path.stem
    memo = _LOADED.get(str(path))
    if memo is not None and not rebuild:
        return memo
    meta_path = path.with_suffix(".json")
    if rebuild:
        for old in path.parent.glob(f"__pycache__/{path.stem}.*"):
            old.unlink(missing_ok=True)
        meta_path.unlink(missing_ok=True)
    if rebuild or cache.verify_entry(path, key) is not None:
        cache.write_entry(path, key, _module_source(model, source, names, inline))
    t0 = time.perf_counter()
    module = _import(path, key) if not rebuild else _reimport(path, key)
    seconds = time.perf_counter() - t0
    misses = sum(sum(getattr(module, n).stats.cache_misses.values()) for n in names)
    hit = misses == 0
    if hit:
        compile_seconds = (cache.read_meta(meta_path) or {}).get("compile_seconds")
    else:
        compile_seconds = seconds
        cache.write_meta(meta_path, {"compile_seconds": seconds, "numba": _numba_version()})
    jm = JitModule(module, path, seconds, hit, compile_seconds)
    _LOADED[str(path)] = jm
    return jm


def _reimport(path: Path, key: str) -> ModuleType:
    import sys

    sys.modules.pop(f"thrustwalk_jit_{key.replace('-', '_')}", None)
    return _import(path, key)


def status(model: CompiledModel, tag: str, source: str, names: dict[str, str],
           inline: Sequence[str] = ()) -> dict:
    """Whether the jit module is on disk with numba's machine code and its recorded compile
    time, checked without importing numba: ``{"cached": bool, "compile_seconds": float|None,
    "entry": path}``."""
    path = entry_path(model, tag, source, names, inline)
    meta = cache.read_meta(path.with_suffix(".json"))
    ok = (meta is not None and cache.verify_entry(path, path.stem) is None
          and any(path.parent.glob(f"__pycache__/{path.stem}.*.nbi")))
    return {"cached": bool(ok), "compile_seconds": (meta or {}).get("compile_seconds"),
            "entry": str(path)}


# ----------------------------------------------------------------- batch model evaluation
BATCH_SOURCE = '''"""Batch evaluators of the model's scalar functions (numba loops over states)."""
import numpy as np


def D_nb(q, out):  # placeholder: the model's generated function follows in this file
    raise NotImplementedError


def h_nb(q, dq, out):  # placeholder
    raise NotImplementedError


def D_h_batch(Q, DQ, Dout, hout):
    """``D(q_k)`` into ``Dout[k]`` (flat N*N) and ``h(q_k, q'_k)`` into ``hout[k]``."""
    for k in range(Q.shape[0]):
        D_nb(Q[k], Dout[k])
        h_nb(Q[k], DQ[k], hout[k])
    return 0
'''
BATCH_NAMES = {"D_h_batch": "(float64[:, ::1], float64[:, ::1], float64[:, ::1], "
                             "float64[:, ::1])"}


def batch_module(model: CompiledModel) -> JitModule:
    """The compiled batch evaluators of ``model`` (compiled or loaded on first use)."""
    return load(model, "batch", BATCH_SOURCE, {**model_signatures(["D", "h"]), **BATCH_NAMES})


def D_h_batch(model: CompiledModel, q: np.ndarray, dq: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """``D(q)`` (K, N, N) [kg m^2] and ``h = C q' + G`` (K, N) [N m] for K states through
    compiled code (the same values as ``model.D``/``model.h``)."""
    n = model.n
    Q = np.ascontiguousarray(np.asarray(q, float).reshape(-1, n))
    DQ = np.ascontiguousarray(np.asarray(dq, float).reshape(-1, n))
    Dout = np.empty((Q.shape[0], n * n))
    hout = np.empty((Q.shape[0], n))
    batch_module(model).module.D_h_batch(Q, DQ, Dout, hout)
    return Dout.reshape(-1, n, n), hout
