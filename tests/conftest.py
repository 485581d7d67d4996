"""Shared fixtures: compile the canonical robots once per session into a private cache (which
starts with the simulation kernel compiled once per checkout: tests/kernel_cache.py); one CLI
runner; the bundled walkers. Tests of cache faults use their own folders."""

from __future__ import annotations

import contextlib
import os
import re
import sys
from pathlib import Path

# BLAS single-threaded, as under the command line (thrustwalk_cli/cli.py): results that pass
# through an optimiser (design-gait's SLSQP) depend on the BLAS thread count in their last
# digits, and the golden documents are made this way too (tests/golden_cases.py)
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import matplotlib  # noqa: E402
import pytest  # noqa: E402
from kernel_cache import locked, seed_kernel, shared_kernel  # noqa: E402 (tests/ is on sys.path)

matplotlib.use("Agg")


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the shared kernel before any test (and before pytest-xdist starts workers),
    saying so on the terminal when it is not compiled yet (not when only collecting: `make
    test`'s set-up collects while the kernel compiles)."""
    if hasattr(session.config, "workerinput"):
        return  # an xdist worker: the controller did it (the fixture below checks again)
    if session.config.option.collectonly:
        return
    tr = session.config.pluginmanager.get_plugin("terminalreporter")
    shared_kernel(tr.write_line if tr is not None else None)


# ------------------------------------------------------------- running on every core (xdist)
def _modules_with_module_fixtures(root: Path) -> set[str]:
    """The test modules (node-id paths) that define a module-scoped fixture or say
    ``ONE_WORKER = True`` (their tests share results computed once per process)."""
    out = set()
    for path in Path(__file__).parent.glob("test_*.py"):
        text = path.read_text()
        if re.search(r"""fixture\(\s*scope=["']module["']""", text) or \
                re.search(r"^ONE_WORKER = True", text, re.M):
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
    compiled simulation kernel of this checkout's tests (see :func:`shared_kernel`). The
    pytest-xdist workers of one run share it (a robot compiled by one worker is loaded by the
    others, as processes sharing a user's cache do: the cache's build lock makes one compile),
    seeded once under a lock."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        run_tmp = tmp_path_factory.getbasetemp().parent  # shared by the run's workers
        path = run_tmp / "model-cache"
        with locked(run_tmp):
            if not (path / ".seeded").exists():
                path.mkdir(exist_ok=True)
                seed_kernel(path, shared_kernel())
                (path / ".seeded").touch()
    else:
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
    stderr kept apart). ``sys.argv`` is the command line while it runs (provenance records
    it). The click command that typer builds from the app (about 50 ms of CPU: every option
    of every command) is built once for the session, as a process builds it once."""
    from unittest import mock

    import typer.main
    import typer.testing

    from thrustwalk_cli.cli import app

    runner = typer.testing.CliRunner()
    command = typer.main.get_command(app)
    built = (mock.patch.object(typer.testing, "_get_command", lambda _app: command)
             if hasattr(typer.testing, "_get_command") else contextlib.nullcontext())

    def run(*args: str):
        argv = [str(a) for a in args]
        old = sys.argv
        sys.argv = ["thrustwalk", *argv]
        try:
            with built:
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
