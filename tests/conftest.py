"""Shared fixtures: compile the canonical robots once per session into a private cache; one
CLI runner; the bundled walkers.

The numba modules that are the same for every robot (the simulation kernel and the batch tape
interpreter, :mod:`thrustwalk_cli.model.jit`) cost 20-60 s of compiling. They are compiled
once per checkout into a shared folder (``.pytest_cache/thrustwalk-kernel``, or
``$THRUSTWALK_TEST_KERNEL_DIR``), at the start of the test run with a message, under a file
lock so that parallel workers (pytest-xdist) compile them once between them; each session's
private cache then starts with a copy of them (numba's machine code beside them), so no test
session and no process a test starts compiles the kernel again. A fresh clone (CI) builds its
own: nothing outside the checkout is reused. Tests of cache faults use their own folders."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

# BLAS single-threaded, as under the command line (thrustwalk_cli/cli.py): results that pass
# through an optimiser (design-gait's SLSQP) depend on the BLAS thread count in their last
# digits, and the golden documents are made this way too (tests/golden_cases.py)
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import matplotlib  # noqa: E402
import pytest  # noqa: E402

matplotlib.use("Agg")

REPO = Path(__file__).resolve().parents[1]
KERNEL_DIR_ENV = "THRUSTWALK_TEST_KERNEL_DIR"


def shared_kernel_dir() -> Path:
    """Where this checkout's tests keep the compiled jit modules between runs."""
    env = os.environ.get(KERNEL_DIR_ENV)
    return Path(env).resolve() if env else REPO / ".pytest_cache" / "thrustwalk-kernel"


@contextlib.contextmanager
def _cache_env(path: Path) -> Iterator[None]:
    old = os.environ.get("THRUSTWALK_CACHE_DIR")
    os.environ["THRUSTWALK_CACHE_DIR"] = str(path)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("THRUSTWALK_CACHE_DIR", None)
        else:
            os.environ["THRUSTWALK_CACHE_DIR"] = old


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An exclusive lock between the processes of a test run (no-op without fcntl)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: at worst each worker compiles
        yield
        return
    with open(folder / ".lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _jit_entries(folder: Path) -> list[tuple[Path, bool]]:
    """(entry file, cached with numba's machine code?) of every robot-independent jit module
    in ``folder`` (checked without importing numba)."""
    from thrustwalk_cli.model import jit, tape
    from thrustwalk_cli.simulation import compiled
    from thrustwalk_cli.simulation import kernel as K

    with _cache_env(folder):
        out = []
        for tag, ident, names, nrt_free in (
                (compiled.TAG, compiled._fingerprint(), compiled._names(), K.NRT_FREE),
                (jit.BATCH_TAG, jit._batch_source(), tape.SIGNATURES, tape.NRT_FREE)):
            st = jit.status(tag, ident, names, nrt_free)
            out.append((Path(st["entry"]), st["cached"]))
        return out


COMPILE = ("from thrustwalk_cli.studies.compile import compile_kernel\n"
           "from thrustwalk_cli.model import jit\n"
           "compile_kernel()\n"
           "jit.batch_module()\n")


def shared_kernel(say: Callable[[str], None] | None = None) -> list[Path]:
    """The compiled jit modules of this checkout's tests: compiled into
    :func:`shared_kernel_dir` if missing (in a child process, so that no test process has
    imported numba or holds a module loaded from there), once between concurrent test
    processes. Returns their entry files (the ``.py``; numba's files are in
    ``__pycache__``), or [] when they could not be made (each session then compiles its own,
    as a user's first run would)."""
    folder = shared_kernel_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with _locked(folder):
            entries = _jit_entries(folder)
            if not all(ok for _, ok in entries):
                if say is not None:
                    say(f"compiling the simulation kernel once for this checkout's tests "
                        f"(~30 s) into {folder}")
                t0 = time.monotonic()
                subprocess.run([sys.executable, "-c", COMPILE], check=True, timeout=1800,
                               env=dict(os.environ, THRUSTWALK_CACHE_DIR=str(folder)),
                               capture_output=True, text=True)
                entries = _jit_entries(folder)
                if say is not None:
                    say(f"compiled the simulation kernel in {time.monotonic() - t0:.1f} s")
            current = {p.stem for p, _ in entries}
            for old in [*folder.glob("jit-*"), *folder.glob("__pycache__/jit-*")]:
                if old.name.split(".")[0] not in current:  # an older kernel's files
                    old.unlink(missing_ok=True)
            return [p for p, ok in entries if ok]
    except (OSError, subprocess.SubprocessError) as exc:
        if say is not None:
            detail = getattr(exc, "stderr", "") or str(exc)
            say(f"warning: no shared simulation kernel ({detail.strip()[-500:]}): each test "
                "session compiles its own")
        return []


def seed_kernel(cache: Path, entries: list[Path]) -> None:
    """Copy the compiled jit modules ``entries`` into the model cache ``cache``, with their
    times (numba's index checks the source file's time and size), as if compiled there."""
    (cache / "__pycache__").mkdir(parents=True, exist_ok=True)
    for entry in entries:
        for f in entry.parent.glob(f"{entry.stem}.*"):
            shutil.copy2(f, cache / f.name)
        for f in entry.parent.glob(f"__pycache__/{entry.stem}.*"):
            shutil.copy2(f, cache / "__pycache__" / f.name)


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the shared kernel before any test (and before pytest-xdist starts workers),
    saying so on the terminal when it is not compiled yet."""
    if hasattr(session.config, "workerinput"):
        return  # an xdist worker: the controller did it (the fixture below checks again)
    tr = session.config.pluginmanager.get_plugin("terminalreporter")
    shared_kernel(tr.write_line if tr is not None else None)


# ------------------------------------------------------------- running on every core (xdist)
def _modules_with_module_fixtures(root: Path) -> set[str]:
    """The test modules (node-id paths) that define a module-scoped fixture."""
    out = set()
    for path in Path(__file__).parent.glob("test_*.py"):
        if re.search(r"""fixture\(\s*scope=["']module["']""", path.read_text()):
            out.add(path.relative_to(root).as_posix())
    return out


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """``pytest -n N`` (``make test``): each test goes to the next free worker, except that
    the tests of a module defining a module-scoped fixture go to one worker together, so that
    the fixture is computed once, not once per worker (and again whenever a worker's tests
    alternate between modules). Modules with more tests are handed out first. An explicit
    ``--dist`` other than ``load`` is obeyed as it is."""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    grouped = _modules_with_module_fixtures(config.rootpath)

    class ModuleFixtureScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            return module if module in grouped else nodeid

    return ModuleFixtureScheduling(config, log)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """In pytest-xdist workers, the tests marked slow come first (tests are handed out in
    this order after the modules kept together), so that no long test starts last. A run
    without workers keeps the order of the files."""
    if hasattr(config, "workerinput"):
        items.sort(key=lambda item: item.get_closest_marker("slow") is None)


@pytest.fixture(scope="session", autouse=True)
def _cache_dir(tmp_path_factory: pytest.TempPathFactory):
    """Every test run uses its own model cache (never the user's), which starts with the
    compiled simulation kernel of this checkout's tests (see :func:`shared_kernel`)."""
    path = tmp_path_factory.mktemp("model-cache")
    seed_kernel(path, shared_kernel())
    old = os.environ.get("THRUSTWALK_CACHE_DIR")
    os.environ["THRUSTWALK_CACHE_DIR"] = str(path)
    yield path
    if old is None:
        os.environ.pop("THRUSTWALK_CACHE_DIR", None)
    else:
        os.environ["THRUSTWALK_CACHE_DIR"] = old


@pytest.fixture(scope="session")
def walker3(_cache_dir):
    """The bundled 3-link robot and gait (:class:`thrustwalk_cli.walker.Walker`)."""
    from thrustwalk_cli.walker import load_walker

    return load_walker("three_link", "three_link_walk")


@pytest.fixture(scope="session")
def walker_rabbit(_cache_dir):
    """The bundled RABBIT robot and gait."""
    from thrustwalk_cli.walker import load_walker

    return load_walker("rabbit", "rabbit_walk")


@pytest.fixture(scope="session")
def three_link(walker3):
    """The compiled 3-link model."""
    return walker3.model


@pytest.fixture(scope="session")
def rabbit(walker_rabbit):
    """The compiled RABBIT model."""
    return walker_rabbit.model


@pytest.fixture(scope="session")
def walk3(walker3):
    """The bundled 3-link gait on its robot: (model, gait, zero dynamics)."""
    return walker3.model, walker3.gait, walker3.zd


@pytest.fixture(scope="session")
def cli():
    """Run ``thrustwalk ARGS...`` in-process; returns the click result (exit_code, stdout,
    stderr kept apart)."""
    from typer.testing import CliRunner

    from thrustwalk_cli.cli import app

    runner = CliRunner()

    def run(*args: str):
        argv = [str(a) for a in args]
        old = sys.argv
        sys.argv = ["thrustwalk", *argv]  # as on a command line (provenance records it)
        try:
            return runner.invoke(app, argv, catch_exceptions=False)
        finally:
            sys.argv = old
    return run


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


@pytest.fixture(scope="session")
def cli_subprocess(_cache_dir):
    """Run ``python -m thrustwalk_cli ARGS...`` in a fresh process (for what in-process runs
    cannot show: tracebacks on stderr, signals, environment). Keyword arguments override
    environment variables; returns the ``subprocess.CompletedProcess``."""
    import subprocess
    import sys

    def run(args, timeout: float = 300, cwd=None, **env):
        full = dict(os.environ)
        full.update(env)
        return subprocess.run([sys.executable, "-m", "thrustwalk_cli", *map(str, args)],
                              capture_output=True, text=True, timeout=timeout, env=full,
                              cwd=cwd)
    return run


class CountingExecutor:
    """A sweep executor that counts the engine tasks submitted to the one it wraps."""

    def __init__(self, inner):
        self.inner, self.submitted, self.workers = inner, 0, inner.workers

    def submit(self, fn, task):
        self.submitted += 1
        return self.inner.submit(fn, task)

    def wait(self, handles):
        return self.inner.wait(handles)

    def close(self):
        self.inner.close()

    def describe(self):
        return self.inner.describe()


@pytest.fixture
def counting():
    """``counting(executor)``: the executor wrapped so that it counts submitted tasks."""
    return CountingExecutor
