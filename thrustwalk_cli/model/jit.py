"""Robot-independent numba modules, compiled once per machine and cached (PERF_NOTES).

A *jit module* is one generated Python file in the thrustwalk cache folder: numba-ready source
(the tape interpreter of :mod:`thrustwalk_cli.model.tape`, and for the simulation the kernel
assembled by :mod:`thrustwalk_cli.simulation.stepper`) followed by a footer that wraps the
listed functions, callees first, in ``numba.njit(signature, cache=True)``: explicit signatures
compile each function once, when the module is first imported on this machine. numba keeps the
machine code in ``__pycache__`` beside that file, so every later process loads it instead of
compiling (the file name carries a hash of everything that went into it; numba checks its own
version and the CPU). Robots are data (tapes) passed to these functions, so a new robot never
triggers a compile. A JSON sidecar records how long the one-time compile took, so ``thrustwalk
compile`` can report it without importing numba. The functions a module names as
allocation-free are compiled without numba's reference counting (``_nrt=False``): there an
array argument or a view costs nothing, elsewhere two atomic updates.

When the cache folder cannot be used (no home directory, read-only, full), the module is
compiled into a private temporary folder for this process and :attr:`JitModule.note` says
so in one line: slower (the compile is paid again by the next process), never an error.

numba is imported only when a jit module is imported, never by ``import thrustwalk_cli`` or a
cached model.
"""

from __future__ import annotations

import functools
import hashlib
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from . import cache
from .compiled import CompiledModel
from .tape import NRT_FREE as TAPE_NRT_FREE
from .tape import SIGNATURES as TAPE_SIGNATURES
from .tape import interpreter_source

OPTIONS = "cache=True, nogil=True, error_model='numpy'"
# for the functions a module lists as allocation-free: compiled without numba's reference
# counting (``_nrt=False``), so an array argument or a view costs no atomic increment and
# decrement (measured: an event function 85 -> 10 ns; a simulated step 20-35 % faster). Such
# a function must not allocate an array (numba refuses to compile it then). Where numba does
# not know the option, they are compiled as the others.
NRT_FREE_OPTION = "_nrt=False"
# the signature that marks a function compiled only into its callers (numba's IR inlining,
# ``inline='always'``): no library of its own, so its code is optimized and translated to
# machine code once, in its caller's library, instead of once more at every level of the call
# chain above it (numba links every callee's code into each caller and optimizes the whole);
# for functions with one call site, or small wrappers. Never compiled when the module loads.
INLINE = "inline"
# LLVM's optimisation level and loop vectorisation for these modules' compile only (numba's
# defaults, 3 and on, are restored after it; numba reads them when it optimizes each function):
# measured on the simulation kernel and the batch interpreter, one fresh compile each, 2 cores,
# user CPU 44.3 s at numba's defaults, 38.8 s without loop vectorisation, 30.5 s at level 1
# without it, and 22.3 s at level 0; the compiled code of level 1 runs as fast as level 3's
# (a full-order step of the 3-link walker 0.35 vs 0.36 ms, of RABBIT 0.82 vs 0.83 ms; level 0:
# 2.7 and 6.9 ms) and computes the same numbers bit for bit (no fast-math: LLVM keeps every
# floating-point operation and its order at any level). The hot loops are scalar code over a
# handful of coordinates, which the vectoriser cannot widen anyway.
OPT_LEVEL = 1
LOOP_VECTORIZE = 0


def _numba_version() -> str:
    return cache.package_file("numba", "_version.py")


def _digest(tag: str, source: str, names: dict[str, str],
            nrt_free: frozenset[str] = frozenset()) -> str:
    """Hash of a jit module's identity. ``source`` is the module's text or a fingerprint of
    everything it is made from (cheaper: checking a warm cache must not build the text)."""
    key = (tag, id(source), id(names), nrt_free)
    hit = _DIGESTS.get(key)
    if hit is not None and hit[0] is source and hit[1] is names:
        return hit[2]
    h = hashlib.sha256()
    for part in (tag, source, repr(sorted(names.items())), OPTIONS, _numba_version(),
                 sys.version, repr(sorted(nrt_free)), NRT_FREE_OPTION,
                 _module_source("", names, nrt_free)):  # the footer: how they are compiled
        h.update(part.encode())
        h.update(b"\0")
    _DIGESTS[key] = (source, names, h.hexdigest())
    return h.hexdigest()


_DIGESTS: dict[tuple, tuple[str, dict, str]] = {}  # the same source objects: hashed once


def entry_path(tag: str, source: str, names: dict[str, str], folder: Path | None = None,
               nrt_free: frozenset[str] = frozenset()) -> Path:
    """Where the jit module for ``source`` lives: ``jit-TAG-HASH.py`` in the cache folder
    (or in ``folder``)."""
    d = _digest(tag, source, names, nrt_free)
    if folder is not None:
        return folder / cache.entry_name(f"jit-{tag}", d)
    return cache.entry_path(f"jit-{tag}", d)


def _module_source(source: str, names: dict[str, str],
                   nrt_free: frozenset[str] = frozenset()) -> str:
    footer = [
        "", "# ---- numba: compile the functions above once, cache them beside this file",
        "import numba as _numba", "",
        "_JIT = {",
        *[f"    {k!r}: {v!r}," for k, v in names.items()],
        "}",
        f"_NRT_FREE = {sorted(nrt_free)!r}  # allocation-free: no reference counting",
        "import numba.core.cpu as _cpu",
        "_NO_RC = ({'_nrt': False} if hasattr(_cpu.CPUTargetOptions, '_nrt')",
        "          else {})  # (an option numba might rename: then reference counting)",
        "import numba.core.config as _config",
        "_SAVED = (_config.OPT, _config.LOOP_VECTORIZE)  # this module's settings (OPT_LEVEL)",
        f"_config.OPT = type(_config.OPT)({OPT_LEVEL})",
        f"_config.LOOP_VECTORIZE = {LOOP_VECTORIZE}",
        "try:",
        "    for _name, _sig in _JIT.items():",
        "        _kw = _NO_RC if _name in _NRT_FREE else {}",
        f"        if _sig == {INLINE!r}:  # compiled into its callers only",
        "            globals()[_name] = _numba.njit(inline='always', "
        f"{OPTIONS})(globals()[_name])",
        "        else:",
        "            globals()[_name] = _numba.njit(_sig, "
        f"{OPTIONS}, **_kw)(globals()[_name])",
        "finally:",
        "    _config.OPT, _config.LOOP_VECTORIZE = _SAVED", "",
    ]
    return source.rstrip() + "\n" + "\n".join(footer)


@dataclass
class JitModule:
    """A loaded jit module. ``compile_seconds``: the one-time numba compile (measured now, or
    as recorded when it happened); ``cache_hit``: the machine code came from the disk cache;
    ``load_seconds``: this import; ``note``: one line when the cache folder was unusable."""

    module: ModuleType
    path: Path
    load_seconds: float
    cache_hit: bool
    compile_seconds: float | None
    note: str = ""


_LOADED: dict[str, JitModule] = {}
_PRIVATE: list[Path] = []  # this process's fallback folder, made on first need


def _private_folder() -> Path:
    if not _PRIVATE:
        _PRIVATE.append(Path(tempfile.mkdtemp(prefix="thrustwalk-jit-")))
    return _PRIVATE[0]


def _import(path: Path) -> ModuleType:
    """Import a verified jit module under a stable name (numba's cache refers to the
    compiled functions by module name when it loads them in another process)."""
    import importlib.util

    name = f"thrustwalk_jit_{path.stem.replace('-', '_')}"
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


def _place(tag: str, source: str | Callable[[], str], names: dict[str, str], rebuild: bool,
           fingerprint: str | None = None, nrt_free: frozenset[str] = frozenset()
           ) -> tuple[Path, str]:
    """Write the module file if needed; returns (path, note). Falls back to a private
    temporary folder when the cache folder is unusable. ``source``: the text, or a function
    that makes it (called only when the file must be written) with ``fingerprint``
    identifying it."""
    ident = fingerprint if fingerprint is not None else source
    cached_text: list[str] = []

    def text() -> str:
        if not cached_text:
            cached_text.append(_module_source(source() if callable(source) else source, names,
                                              nrt_free))
        return cached_text[0]
    try:
        path = entry_path(tag, ident, names, nrt_free=nrt_free)
        if rebuild:
            for old in path.parent.glob(f"__pycache__/{path.stem}.*"):
                old.unlink(missing_ok=True)
            path.with_suffix(".json").unlink(missing_ok=True)
        if rebuild or cache.verify_entry(path, path.stem) is not None:
            cache.write_entry(path, path.stem, text())
            if cache.verify_entry(path, path.stem) is not None:
                raise OSError(f"{path} reads back wrong")
        return path, ""
    except (OSError, cache.NoCacheDir) as exc:
        why = getattr(exc, "strerror", None) or str(exc) or exc.__class__.__name__
        try:
            shared = entry_path(tag, ident, names, nrt_free=nrt_free)
            if shared.is_dir():  # never removed: the user's folder, reported
                why = f"cache entry {shared} is a folder, left as it is"
        except (OSError, cache.NoCacheDir):
            pass
        path = entry_path(tag, ident, names, _private_folder(), nrt_free)
        if cache.verify_entry(path, path.stem) is not None:
            cache.write_entry(path, path.stem, text())
        return path, (f"cache folder unusable ({why}): the compiled kernel is kept in a "
                      f"temporary folder for this process only")


def load(tag: str, source: str | Callable[[], str], names: dict[str, str],
         rebuild: bool = False, fingerprint: str | None = None,
         nrt_free: frozenset[str] = frozenset(), what: str = "",
         on_wait: Callable[[str], None] | None = None) -> JitModule:
    """The jit module for ``source`` (its text, or a function making it, identified by
    ``fingerprint``): written to the cache if missing, then imported, which compiles every
    function in ``names`` (name -> numba signature, callees first) or loads its machine code
    from numba's cache. ``rebuild``: discard both and compile again. ``nrt_free``: the names
    of functions that allocate no array, compiled without reference counting.

    Unless the module is cached whole (:func:`status`), writing and compiling it hold its
    build lock (:func:`~.cache.build_lock`): of processes that compile it at once, one
    compiles and the others wait (``on_wait`` is told once, naming ``what``; default: the
    cache's wait reporter) and then load its machine code."""
    ident = fingerprint if fingerprint is not None else source
    key = _digest(tag, ident, names, nrt_free)
    memo = _LOADED.get(key)
    if memo is not None and not rebuild:
        return memo
    entry = None
    if rebuild or not status(tag, ident, names, nrt_free)["cached"]:
        try:
            entry = entry_path(tag, ident, names, nrt_free=nrt_free)
        except cache.NoCacheDir:
            entry = None
    with cache.build_lock(entry, what or f"the compiled module {tag}", on_wait):
        path, note = _place(tag, source, names, rebuild, fingerprint, nrt_free)
        t0 = time.perf_counter()
        if rebuild:
            sys.modules.pop(f"thrustwalk_jit_{path.stem.replace('-', '_')}", None)
        module = _import(path)
        seconds = time.perf_counter() - t0
        misses = sum(sum(getattr(module, n).stats.cache_misses.values())
                     for n, sig in names.items() if sig != INLINE)
        hit = misses == 0
        meta_path = path.with_suffix(".json")
        if hit:
            compile_seconds = (cache.read_meta(meta_path) or {}).get("compile_seconds")
        else:
            compile_seconds = seconds
            try:
                import numba

                cache.write_meta(meta_path, {"compile_seconds": seconds,
                                             "numba": numba.__version__})
            except OSError:
                pass
    jm = JitModule(module, path, seconds, hit, compile_seconds, note)
    _LOADED[key] = jm
    return jm


def status(tag: str, ident: str, names: dict[str, str],
           nrt_free: frozenset[str] = frozenset()) -> dict:
    """Whether the jit module (``ident``: its text or fingerprint, as given to :func:`load`)
    is on disk with numba's machine code and its recorded compile time, checked without
    importing numba: ``{"cached": bool, "compile_seconds": float|None, "entry": path}``."""
    try:
        path = entry_path(tag, ident, names, nrt_free=nrt_free)
    except cache.NoCacheDir:
        return {"cached": False, "compile_seconds": None, "entry": ""}
    meta = cache.read_meta(path.with_suffix(".json"))
    ok = (meta is not None and cache.verify_entry(path, path.stem) is None
          and any(path.parent.glob(f"__pycache__/{path.stem}.*.nbi")))
    return {"cached": bool(ok), "compile_seconds": (meta or {}).get("compile_seconds"),
            "entry": str(path)}


# ----------------------------------------------------------------- batch model evaluation
BATCH_TAG = "tape"


@functools.cache
def _batch_source() -> str:
    return ('"""The tape interpreter of thrustwalk (model/tape.py), compiled by numba."""\n'
            "import numpy as np\n\n\n" + interpreter_source())


def batch_module(rebuild: bool = False) -> JitModule:
    """The compiled batch interpreter (compiled once per machine, for every robot)."""
    return load(BATCH_TAG, _batch_source(), TAPE_SIGNATURES, rebuild=rebuild,
                nrt_free=TAPE_NRT_FREE)


def run_batch(model: CompiledModel, program: str, x: np.ndarray, chunk: int = 64
              ) -> np.ndarray:
    """Outputs of one tape ``program`` (see :mod:`thrustwalk_cli.model.tape`) for K states
    ``x`` (K, n_in) through compiled code: (K, n_out)."""
    tape = model.tape
    p = tape.programs[program]
    n_in = int(tape.code[p])
    X = np.ascontiguousarray(np.asarray(x, float).reshape(-1, n_in))
    out = np.empty((X.shape[0], tape.n_out(program)))
    batch_module().module.tape_batch(tape.code, p, tape.consts, tape.n_inputs, tape.nreg, X,
                                     out, chunk)
    return out


def D_h_batch(model: CompiledModel, q: np.ndarray, dq: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """``D(q)`` (K, N, N) [kg m^2] and ``h = C q' + G`` (K, N) [N m] for K states through
    compiled code (the tape's ``accel`` program: the same values as ``model.D``/``model.h``
    to rounding). SPEC 1."""
    n = model.n
    Q = np.asarray(q, float).reshape(-1, n)
    DQ = np.asarray(dq, float).reshape(-1, n)
    out = run_batch(model, "accel", np.concatenate([Q, DQ], axis=1))
    return out[:, :n * n].reshape(-1, n, n), out[:, n * n:n * n + n]
