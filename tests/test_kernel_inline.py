"""The simulation kernel's one-time compile (issue 26): which functions numba compiles as
libraries of their own, and the mechanism that compiles the others into their callers only.

numba links the code of every callee into each caller's library and optimizes and translates
the whole again, so every separately compiled function pays once more for everything below
it. The call graph here is read from the kernel's source (Python's ``ast``), independently of
the lists that choose what to inline.
"""

from __future__ import annotations

import ast
import shutil
import sys
import time

import numpy as np

from thrustwalk_cli.model import jit
from thrustwalk_cli.simulation import stepper

# the functions Python calls on the kernel module: the batch entry point, and the tape
# interpreter's one-state entry (tests/test_tape.py)
PYTHON_CALLS = {"run", "tape_run"}
# allocation-free functions with one caller that allocates: kept as libraries of their own, so
# that their hot loops run without reference counting (the integrator's steps, the tape
# interpreter's instructions over a chunk of states)
KEPT = {"integrate", "tape_chunks"}


def _call_sites() -> dict[str, list[str]]:
    """For every function the kernel compiles: the kernel functions calling it, once per call
    site."""
    names = stepper._names()
    sites: dict[str, list[str]] = {k: [] for k in names}
    for node in ast.parse(stepper.kernel_source()).body:
        if isinstance(node, ast.FunctionDef) and node.name in names:
            for call in ast.walk(node):
                if (isinstance(call, ast.Call) and isinstance(call.func, ast.Name)
                        and call.func.id in names):
                    sites[call.func.id].append(node.name)
    return sites


def test_kernel_compiles_no_function_with_one_caller_as_its_own_library():
    """Every function of the kernel called from one place in it is compiled into its caller
    (``jit.INLINE``), but for the allocation-free hot ones kept apart; what Python calls, and
    every function called from several places, keeps its signature."""
    names = stepper._names()
    sites = _call_sites()
    for name in PYTHON_CALLS | KEPT:
        assert names[name] != jit.INLINE, name
    alone = {k for k, v in sites.items()
             if len(v) == 1 and k not in PYTHON_CALLS and names[k] != jit.INLINE}
    assert alone <= KEPT, f"compiled as libraries of their own, with one caller: {alone}"
    # the step is compiled once, into run (run, sim_step and step_core were three libraries
    # that each linked and optimized the whole closed loop again)
    assert names["step_core"] == jit.INLINE and sites["step_core"] == ["run"]
    assert "sim_step" not in names
    for name, sig in names.items():
        if sig == jit.INLINE:
            assert sites[name], f"{name}: inlined but never called in the kernel"


def test_inlined_functions_are_not_compiled_at_load_and_a_warm_module_is_a_cache_hit(
        tmp_path, monkeypatch):
    """A jit module with an inlined function (``jit.INLINE``): loading it compiles only the
    functions with a signature, their results are those of the plain Python functions, a
    second process loads every one from numba's cache (no compile, ``status`` cached without
    numba), and the cache key differs from the same module compiled without inlining."""
    import subprocess

    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(jit, "_LOADED", {})
    source = ("import numpy as np\n"
              "def half(a, i):\n"
              "    return 0.5 * a[i]\n"
              "def total(a):\n"
              "    s = 0.0\n"
              "    for i in range(a.shape[0]):\n"
              "        s += half(a, i)\n"
              "    return s\n"
              f"# {time.time_ns()}: never compiled before\n")
    names = {"half": jit.INLINE, "total": "float64(float64[::1])"}
    a = np.array([0.1, 0.7, -2.5, 3.25])
    expected = 0.0
    for v in a:
        expected += 0.5 * v
    jm = jit.load("inl", source, names)
    try:
        assert not jm.cache_hit
        assert jm.module.total(a) == expected
        assert not jm.module.half.signatures, "an inlined function must not compile at load"
        assert jm.module.total.signatures
        st = jit.status("inl", source, names)
        assert st["cached"] and st["entry"] == str(jm.path)
        assert jit.entry_path("inl", source, {**names, "half": "float64(float64[::1], int64)"}
                              ) != jm.path
        code = ("import sys, json, numpy as np\n"
                "from thrustwalk_cli.model import jit\n"
                f"names = {{'half': jit.INLINE, 'total': {names['total']!r}}}\n"
                f"st = jit.status('inl', {source!r}, names)\n"
                "numba_before = 'numba' in sys.modules\n"
                f"jm = jit.load('inl', {source!r}, names)\n"
                f"print(json.dumps([st['cached'], numba_before, jm.cache_hit, "
                f"jm.module.total(np.array({a.tolist()!r}))]))\n")
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout
        cached, numba_before, hit, value = __import__("json").loads(out.strip().splitlines()[-1])
        assert cached and not numba_before and hit and value == expected
    finally:
        sys.modules.pop(f"thrustwalk_jit_{jm.path.stem.replace('-', '_')}", None)
        shutil.rmtree(tmp_path / "cache", ignore_errors=True)
