"""Shared fixtures: compile the canonical robots once per session into a private cache; one
CLI runner; the bundled walkers."""

from __future__ import annotations

import os

# BLAS single-threaded, as under the command line (thrustwalk_cli/cli.py): results that pass
# through an optimiser (design-gait's SLSQP) depend on the BLAS thread count in their last
# digits, and the golden documents are made this way too (tests/golden_cases.py)
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import matplotlib  # noqa: E402
import pytest  # noqa: E402

matplotlib.use("Agg")


@pytest.fixture(scope="session", autouse=True)
def _cache_dir(tmp_path_factory: pytest.TempPathFactory):
    """Every test run uses its own model cache (never the user's)."""
    path = tmp_path_factory.mktemp("model-cache")
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
        return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
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
