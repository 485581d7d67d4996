"""Robot -> SymPy -> generated code -> cached :class:`CompiledModel` (SPEC section 1).

``load_model(robot)`` loads the model from the disk cache or derives and compiles it; SymPy is
imported only when compiling. The robot's numbers (``Robot.numbers()``: masses, lengths,
inertias, gravity) are inputs of the compiled model, not constants in its code, so the cache
key is the robot's *structure* (``Robot.structure()``: names, link tree, coordinates, R, b,
thruster layout, which numbers are zero), the tool version and the generator sources: robots
that differ only in their numbers (a sweep over a torso mass) share one compiled model, and
each :class:`CompiledModel` binds its robot's numbers. The numeric checks (D positive
definite, the relabelling swaps the feet) run for every new set of numbers and raise
:class:`InputError` naming the robot file and key.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np

from .._version import __version__
from ..description.robot import Robot
from ..errors import InputError, Problem, check_flag, check_instance
from . import cache
from .compiled import FUNCTIONS, VECTORS, CompiledModel
from .tape import PROGRAMS


def _generator_digest() -> str:
    """Hash of the derivation and code-generation sources: editing them invalidates caches."""
    h = hashlib.sha256()
    here = Path(__file__).parent
    for name in ("derive.py", "derive_reference.py", "codegen.py", "tape.py"):
        h.update((here / name).read_bytes())
    h.update(repr(sorted(FUNCTIONS.items())).encode())
    return h.hexdigest()


def model_key(robot: Robot, folded: bool = False) -> str:
    """Cache key: hash of the robot's structure (not its numbers, which are inputs), the tool
    version and the generator sources. ``folded``: the key of a model with the numbers
    substituted (:func:`folded_model`), which includes them."""
    blob = json.dumps(
        {"robot": robot.structure(), "version": __version__, "codegen": _generator_digest(),
         **({"folded": robot.canonical()} if folded else {})},
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()


def _problem(robot: Robot, path: str, message: str) -> Problem:
    return Problem(robot.source_file, robot.line_of(path), path, message)


#: the steps of a compile that a progress callback is told about: the parts of the
#: derivation, one per generated function, one per tape program, the module, the checks
DERIVATION_PARTS = ("mass distribution", "mass matrix", "gravity and centre of mass",
                    "Coriolis and gravity terms", "kinematics", "thrusters")
STEPS = len(DERIVATION_PARTS) + len(FUNCTIONS) + len(PROGRAMS) + 2

#: ``progress(done, total, phase)``: ``done`` of ``total`` steps of a compile are finished,
#: ``phase`` names the last one (``"derivation: mass matrix"``, ``"code generation: D"``,
#: ``"tape: accel"``, ``"checks"``)
Progress = Callable[[int, int, str], None]


def generate_source(robot: Robot, key: str, folded: bool = False,
                    progress: Progress | None = None) -> str:
    """Derive with SymPy and generate the model module's source (imports SymPy lazily): the
    robot's numbers are inputs of its ``bind(P)`` (:func:`derive.derive`), or, when
    ``folded``, constants in code made by the reference derivation
    (:func:`derive_reference.derive_reference`, what :func:`folded_model` compiles). ``progress`` is
    told about every step but the checks (:data:`Progress`)."""
    from . import codegen, derive, derive_reference

    global COMPILES
    COMPILES += 1
    step = [0]

    def tell(phase: str) -> None:
        step[0] += 1
        if progress is not None:
            progress(step[0], STEPS, phase)

    if folded:
        der = derive_reference.derive_reference(robot, folded=True)
        hoist = codegen.Hoist(der.numbers.inputs)
        for part in DERIVATION_PARTS:
            tell(f"derivation: {part}")
    else:
        der = derive.derive(robot, progress=lambda part: tell(f"derivation: {part}"))
        hoist = der.hoist
    defs = der.defs if der.programs is not None else None
    qN = der.q[-1]
    D = list(der.exprs["D"])
    if any(qN in e.free_symbols for e in D) or (defs is not None and any(
            qN in e.free_symbols for _, e in codegen.needed_definitions(defs, D))):
        raise InputError(_problem(
            robot, "coordinates.unactuated",
            "the inertia matrix depends on q_N (dD/dq_N != 0): q_N must be an absolute angle "
            "and q_b relative joint angles, otherwise SPEC 3's zero dynamics do not apply",
        ))
    argsyms = {"q": der.q, "dq": der.dq, "dq_u": der.dq + der.dxy}
    printers = codegen.Printers()
    funcs = []
    for name, (args, doc) in FUNCTIONS.items():
        M = der.exprs[name] if defs is not None else hoist.matrix(der.exprs[name])
        funcs.append(codegen.generate_function(
            name, M, [(a, argsyms[a]) for a in args], doc, vector=name in VECTORS, defs=defs,
            printers=printers))
        tell(f"code generation: {name}")
    programs = derive_reference.tape_programs(der)
    if defs is None:
        programs = {name: (n_in, [hoist(e) for e in exprs])
                    for name, (n_in, exprs) in programs.items()}
    tape = codegen.generate_tape(programs, der.q + der.dq, hoist.symbols, defs,
                                 progress=lambda name: tell(f"tape: {name}"))
    header = (
        f"Generated by thrustwalk {__version__} for robot {robot.name!r}"
        f"{' (numbers folded in)' if folded else ''}. Do not edit.\n\n"
        f"Coordinates q (in order): {robot.coordinate_names!r}\n"
        f"Inputs P of bind(P) (Robot.numbers(), in order): PARAMS"
    )
    exports = [f for name in FUNCTIONS for f in (name, name + "_s")]
    source = codegen.generate_module(
        header, funcs,
        {"KEY": key, "N": robot.n, "TAPE": tape,
         "PARAMS": [name for name, _ in robot.numbers()]},
        hoist.source(der.numbers.symbols), exports, tape["consts"])
    tell("code generation: coefficients and module")
    return source


#: how many models this process has derived and generated (SymPy), for tests and benchmarks
COMPILES = 0


def load_model(robot: Robot, *, rebuild: bool = False,
               progress: Progress | None = None) -> CompiledModel:
    """Load the compiled model of the robot's structure from the cache, or compile it (SPEC 1)
    and cache it, and bind the robot's numbers to it.

    A cache entry that is missing, stale, corrupted, partially written or that fails to import
    (a syntax error behind a valid checksum) is rebuilt, under the entry's build lock
    (:func:`~.cache.build_lock`: of processes compiling the same new robot at once, one
    derives it and the others wait, say so through the cache's wait reporter, and load it).
    When the cache cannot be used at all (no home directory, the cache path is a file, a
    read-only or full disk, a folder where the entry should be: never removed) the model is
    compiled in memory for this process and the model's ``notes`` say why in one
    line; nothing raises for cache trouble.
    Checks: dD/dq_N = 0 (when compiling) and, for every new set of numbers, D symmetric
    positive definite, R invertible and mapping the swing foot to the stance foot
    (``InputError`` naming the file and key otherwise). ``progress`` (:data:`Progress`) is
    told about every step of a compile (never called for a model from the cache).
    """
    check_instance("robot", robot, Robot, "a Robot (tw.load_robot)")
    rebuild = check_flag("rebuild", rebuild)
    t0 = time.perf_counter()
    key = model_key(robot)
    notes: list[str] = []
    try:
        path: Path | None = cache.entry_path(robot.name, key)
    except cache.NoCacheDir as exc:
        path = None
        notes.append(f"model cache unavailable: {exc}; compiling in memory")
    entry, memo_key = path, str(path) if path else "memory:" + key
    memo = _LOADED.get(memo_key)
    if not rebuild and memo is not None and memo[0] == _signature(entry) and memo[1] == key:
        # already imported in this process and the entry is untouched: no re-import, and the
        # robot's numbers are bound to the same code
        _, _, module, mpath, mnotes = memo
        model = CompiledModel(robot, module, mpath, key, True, time.perf_counter() - t0,
                              mnotes)
        _check_numbers(model)
        return model
    model = None
    if path is not None and not rebuild and cache.verify_entry(path, key) is None:
        try:
            model = CompiledModel(robot, cache.import_entry(path, key), path, key, True, 0.0,
                                  tuple(notes))
        except Exception as exc:  # noqa: BLE001 - any broken entry is rebuilt
            notes.append(f"model cache entry {path} could not be loaded "
                         f"({exc.__class__.__name__}); rebuilt")
    if model is None:
        with cache.build_lock(path, f"the model of robot {robot.name!r}") as locked:
            if locked and not rebuild and path is not None and not notes and \
                    cache.verify_entry(path, key) is None:
                try:  # another process built it while this one waited
                    model = CompiledModel(robot, cache.import_entry(path, key), path, key,
                                          True, 0.0, ())
                except Exception:  # noqa: BLE001 - rebuilt below
                    model = None
            if model is None:
                source = generate_source(robot, key, progress=progress)
                module, path, note = _store(path, key, source)
                if note:
                    notes.append(note)
                model = CompiledModel(robot, module, path, key, False, 0.0, tuple(notes))
    model.load_seconds = time.perf_counter() - t0
    _LOADED[memo_key] = (_signature(entry), key, model._m, model.cache_path, model.notes)
    _check_numbers(model)
    if progress is not None and not model.cache_hit:
        progress(STEPS, STEPS, "checks")
    return model


def folded_model(robot: Robot, *, progress: Progress | None = None) -> CompiledModel:
    """The robot's model compiled by the reference derivation
    (:func:`derive_reference.derive_reference`: Christoffel sums in ``q``, the derivation before
    issue 26) with its numbers substituted into the code (as constants), in memory and never
    cached: the reference for the model of :func:`load_model` (the tests compare the two;
    16 links take minutes)."""
    key = model_key(robot, folded=True)
    source = generate_source(robot, key, folded=True, progress=progress)
    model = CompiledModel(robot, cache.module_from_source(source, key), None, key, False, 0.0)
    check_model(model)
    return model


def _check_numbers(model: CompiledModel) -> None:
    """:func:`check_model` once per structure and set of numbers in this process."""
    ident = (model.key, model.numbers.tobytes())
    if ident in _CHECKED:
        return
    check_model(model)
    if len(_CHECKED) >= 4096:
        _CHECKED.clear()
    _CHECKED.add(ident)


_CHECKED: set[tuple[str, bytes]] = set()


def _store(path: Path | None, key: str, source: str) -> tuple[ModuleType, Path | None, str]:
    """Write a fresh entry and import it; on any disk trouble build the module in memory.

    Returns (module, entry path or None, one-line note or '')."""
    if path is None:
        return cache.module_from_source(source, key), None, ""
    try:
        cache.write_entry(path, key, source)
        why = cache.verify_entry(path, key)
        if why is not None:
            raise OSError(f"entry reads back {why}")
        return cache.import_entry(path, key), path, ""
    except (OSError, ImportError, SyntaxError) as exc:
        return (cache.module_from_source(source, key), None,
                f"model cache unusable: {_why_unusable(path, exc)}; compiled model kept in "
                f"memory for this run")


def _why_unusable(path: Path, exc: BaseException) -> str:
    """One line on why ``path`` cannot hold a cache entry."""
    if path.is_dir():
        return f"entry {path} is a folder"
    for anc in path.parents:
        if anc.exists():
            if not anc.is_dir():
                return f"{anc} is a file, not a folder"
            break
    reason = getattr(exc, "strerror", None) or str(exc) or exc.__class__.__name__
    where = getattr(exc, "filename", None) or path.parent
    return f"{where}: {reason}"


# Model modules imported in this process, by cache entry: (entry mtime and size, key, module,
# entry path or None, notes). A rewritten or corrupted entry changes its signature and goes
# through verification again.
_LOADED: dict[str, tuple[tuple[int, int] | None, str, ModuleType, Path | None,
                         tuple[str, ...]]] = {}


def _signature(path: Path | None) -> tuple[int, int] | None:
    if path is None:
        return None
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_mtime_ns, st.st_size)


_PRIMES = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79,
           83, 89, 97, 101, 103, 107, 109, 113)


def _spread(samples: int, n: int, seed: int) -> np.ndarray:
    """(samples, n) points of ``[-1, 1]^n``: ``2 frac(0.5 + seed/7 + i sqrt(p_j)) - 1`` over
    i = 1..samples (a Kronecker sequence: equidistributed, rationally independent axes)."""
    primes = np.array([_PRIMES[j % len(_PRIMES)] + 0.1 * (j // len(_PRIMES))
                       for j in range(n)], float)
    i = np.arange(1, samples + 1, dtype=float)[:, None]
    return 2.0 * np.mod(0.5 + seed / 7.0 + i * np.sqrt(primes)[None, :], 1.0) - 1.0


def check_model(model: CompiledModel, samples: int = 16, seed: int = 0) -> None:
    """Numeric checks of a model with its numbers bound, at ``samples`` configurations in
    ``[-1, 1]^N`` [rad] (:func:`_spread`: deterministic, and without importing
    ``numpy.random``, about 10 ms of every command that loads a model)."""
    robot = model.robot
    q = _spread(samples, model.n, seed)
    D = model.D(q)
    problems = []
    if not np.allclose(D, np.swapaxes(D, -1, -2), rtol=0, atol=1e-12 * max(1.0, np.abs(D).max())):
        problems.append(_problem(robot, "links", "inertia matrix D is not symmetric"))
    elif np.linalg.eigvalsh(D).min() <= 0:
        problems.append(_problem(robot, "links",
                                 "inertia matrix D is not positive definite: check masses and "
                                 "inertias (a link with no mass and no inertia?)"))
    R = model.R
    if abs(np.linalg.det(R)) < 1e-9:
        problems.append(_problem(robot, "relabel", "relabelling matrix R is singular"))
    else:
        p = model.p_swing(q)
        qp = model.relabel(q)
        err_foot = np.abs(model.p_swing(qp) + p).max()
        err_com = np.abs(model.p_com(qp) - (model.p_com(q) - p)).max()
        if err_foot > 1e-9 or err_com > 1e-9:
            problems.append(_problem(
                robot, "relabel",
                f"relabelling does not swap the feet: after q+ = R q + b the swing foot is "
                f"{err_foot:.3g} m and the centre of mass {err_com:.3g} m away from where the "
                f"leg swap puts them (check R, b or the declared symmetry)"))
    if problems:  # the numbers are wrong, not the (shared) compiled code: the entry stays
        raise InputError(problems)
