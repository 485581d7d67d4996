"""Disk cache of compiled models, keyed by a hash of the robot's structure. Never imports SymPy.

An entry is one generated Python file whose first line records the key and the SHA-256 of
the rest. Entries are written to a unique temporary file and renamed into place, so readers
never see a partial file; an entry whose key or checksum does not match (stale, corrupted,
truncated) is reported as a miss and rebuilt by the caller. A folder where an entry should be
is never removed: the caller reports it and works without that entry.

Building an entry is locked (:func:`build_lock`: ``ENTRY.lock`` beside it, ``flock``): of
several processes that miss the same entry at once (four first runs, Dask workers sharing a
cache), one builds it while the others wait, say so through :func:`report_wait`'s reporter,
and then load what it built.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

MAGIC = "# thrustwalk-model"


class NoCacheDir(Exception):
    """There is no sensible place for the cache (no home directory and no override)."""


def _home() -> Path | None:
    """The user's home: ``$HOME`` if set to an absolute path, else the password database's.
    ``None`` when neither gives a real directory (never ``/``: an empty ``HOME`` must not
    make the cache land in ``/.cache``)."""
    home = os.environ.get("HOME", "")
    if not (home and os.path.isabs(home)):
        home = ""
        try:
            import pwd

            home = pwd.getpwuid(os.getuid()).pw_dir
        except (ImportError, KeyError, OSError):
            home = os.environ.get("USERPROFILE", "") if sys.platform == "win32" else ""
    if not home or not os.path.isabs(home) or Path(home) == Path(Path(home).anchor):
        return None
    return Path(home)


def cache_dir() -> Path:
    """Where compiled models live, following the platform's conventions:

    ``$THRUSTWALK_CACHE_DIR`` if set; on Windows ``%LOCALAPPDATA%\\thrustwalk\\Cache``; on
    macOS ``~/Library/Caches/thrustwalk``; elsewhere ``$XDG_CACHE_HOME/thrustwalk`` (only an
    absolute ``XDG_CACHE_HOME`` counts, as the XDG specification says) or
    ``~/.cache/thrustwalk``. Raises :class:`NoCacheDir` when there is no home directory.
    """
    env = os.environ.get("THRUSTWALK_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    if sys.platform == "win32":
        local = os.environ.get("LOCALAPPDATA", "")
        if local and os.path.isabs(local):
            return Path(local) / "thrustwalk" / "Cache"
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    if sys.platform != "darwin" and xdg and os.path.isabs(xdg):
        return Path(xdg) / "thrustwalk"
    home = _home()
    if home is None:
        raise NoCacheDir("no home directory (HOME is unset or empty); set "
                         "THRUSTWALK_CACHE_DIR to keep compiled models between runs")
    if sys.platform == "darwin":
        return home / "Library" / "Caches" / "thrustwalk"
    return home / ".cache" / "thrustwalk"


def entry_name(name: str, key: str) -> str:
    safe = "".join(ch if ch.isalnum() or ch in "_-" else "_" for ch in name)[:40]
    return f"{safe}-{key[:20]}.py"


def entry_path(name: str, key: str) -> Path:
    return cache_dir() / entry_name(name, key)


def _digest(body: str) -> str:
    return hashlib.sha256(body.encode()).hexdigest()


def write_entry(path: Path, key: str, body: str) -> None:
    """Atomically write ``body`` with a header holding ``key`` and its checksum."""
    path.parent.mkdir(parents=True, exist_ok=True)
    text = f"{MAGIC} key={key} sha256={_digest(body)}\n{body}"
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def verify_entry(path: Path, key: str) -> str | None:
    """Return why the entry cannot be trusted, or None if it is valid."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return "missing"
    except (OSError, UnicodeDecodeError) as exc:
        return f"unreadable ({exc.__class__.__name__})"
    head, sep, body = text.partition("\n")
    if not sep or not head.startswith(MAGIC + " "):
        return "no header"
    fields = dict(kv.split("=", 1) for kv in head[len(MAGIC) + 1:].split() if "=" in kv)
    if fields.get("key") != key:
        return "stale key"
    if fields.get("sha256") != _digest(body):
        return "checksum mismatch"
    return None


def import_entry(path: Path, key: str) -> ModuleType:
    """Import a verified entry as a private module (not registered in ``sys.modules``).

    Any failure (a syntax error behind a valid checksum, a missing function) propagates: the
    caller rebuilds the entry.
    """
    spec = importlib.util.spec_from_file_location(f"thrustwalk_model_{key[:20]}", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot import {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def module_from_source(source: str, key: str, label: str = "<memory>") -> ModuleType:
    """Build the model module in memory, without touching the disk (cache fallback)."""
    module = ModuleType(f"thrustwalk_model_{key[:20]}")
    module.__file__ = label
    exec(compile(source, label, "exec"), module.__dict__)  # our own generated code
    return module
#: the longest wait [s] for another process's build of an entry; then this process builds too
LOCK_WAIT_SECONDS = 900.0
_REPORTER: list[Callable[[str], None] | None] = [None]


def set_wait_reporter(fn: Callable[[str], None] | None) -> Callable[[str], None] | None:
    """Who is told (one line) that this process waits for another one's build of a cache
    entry (the command line prints it; the library itself never prints). Returns the
    previous reporter."""
    old, _REPORTER[0] = _REPORTER[0], fn
    return old


def report_wait(message: str) -> None:
    """Tell the reporter of :func:`set_wait_reporter` (if any)."""
    if _REPORTER[0] is not None:
        _REPORTER[0](message)


def lock_path(entry: Path) -> Path:
    return entry.with_name(entry.name + ".lock")


@contextlib.contextmanager
def build_lock(entry: Path | None, what: str,
               on_wait: Callable[[str], None] | None = None,
               wait_seconds: float | None = None) -> Iterator[bool]:
    """Hold the exclusive lock on building ``entry`` (``flock`` of ``ENTRY.lock`` beside it;
    released when the holder exits, even by ``kill -9``). When another process holds it,
    ``on_wait`` (default :func:`report_wait`) is told once, naming ``what`` is built, and
    this process waits for it (at most ``wait_seconds``, default ``LOCK_WAIT_SECONDS``).
    Yields whether the lock is held: False without ``fcntl`` (Windows), without an entry,
    when the lock file cannot be made (an unusable cache folder, a folder in its place) or
    after the longest wait; the caller then builds without it (as before the lock existed:
    correct, only slower)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield False
        return
    if entry is None:
        yield False
        return
    lock = lock_path(entry)
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError:
        yield False
        return
    try:
        held = True
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            (on_wait or report_wait)(f"another thrustwalk process is building {what}: "
                                     "waiting for it, then loading it")
            deadline = time.monotonic() + (LOCK_WAIT_SECONDS if wait_seconds is None
                                           else wait_seconds)
            while True:
                time.sleep(0.05)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    if time.monotonic() > deadline:
                        held = False
                        break
        except OSError:
            held = False
        yield held
    finally:
        os.close(fd)  # releases the lock


def read_body(path: Path) -> str:
    """The generated source of a verified entry, without its header line."""
    return path.read_text().partition("\n")[2]


def write_meta(path: Path, data: dict) -> None:
    """Atomically write a small JSON sidecar (e.g. how long a numba compile took)."""
    import json

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(data, fh)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def read_meta(path: Path) -> dict | None:
    """The sidecar written by :func:`write_meta`, or None if missing or unreadable."""
    import json

    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


@functools.cache
def package_file(package: str, relative: str) -> str:
    """The text of one file of an installed package, found without importing it: a cheap
    stamp of its version for cache keys (package metadata lookups cost tens of
    milliseconds). ``"missing"`` when it cannot be read."""
    import importlib.util

    try:
        spec = importlib.util.find_spec(package)
        return (Path(spec.origin).parent / relative).read_text()
    except (ImportError, AttributeError, TypeError, OSError, ValueError):
        return "missing"


def files_digest(paths: list[Path], extra: str = "") -> str:
    """SHA-256 of the bytes of ``paths`` (thrustwalk's own sources) and ``extra``."""
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    h.update(extra.encode())
    return h.hexdigest()
