"""The compiled simulation kernel of this checkout's tests, shared by every test session.

The numba modules that are the same for every robot (the simulation kernel and the batch tape
interpreter, :mod:`thrustwalk_cli.model.jit`) cost 20-60 s of compiling. They are compiled
once per checkout into a shared folder (``.pytest_cache/thrustwalk-kernel``, or
``$THRUSTWALK_TEST_KERNEL_DIR``), under a file lock so that concurrent processes (pytest-xdist
workers, `make test`'s set-up) compile them once between them; each test session's private
model cache then starts with a copy of them (numba's machine code beside them), so that no test
session and no process a test starts compiles the kernel again. A fresh clone (CI) builds its
own: nothing outside the checkout is reused.

``python tests/kernel_cache.py`` compiles them now, saying so (`make test` runs it while pip
installs the test dependencies); tests/conftest.py does the same at the start of a test run
when they are missing.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

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
def locked(folder: Path) -> Iterator[None]:
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
    from thrustwalk_cli.simulation import stepper

    with _cache_env(folder):
        out = []
        for tag, ident, names, nrt_free in (
                (stepper.TAG, stepper._fingerprint(), stepper._names(), stepper.NRT_FREE),
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
        with locked(folder):
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


if __name__ == "__main__":
    found = shared_kernel(lambda line: print(line, file=sys.stderr, flush=True))
    sys.exit(0 if found else 1)
