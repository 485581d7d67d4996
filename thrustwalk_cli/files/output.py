"""Result files: atomic writes, result folders written as a whole, provenance, NaN-free JSON.

A single file is written to a temporary name and renamed over the target. A command's result
folder is written as a whole (:class:`ResultFolder`): every file goes into a fresh temporary
folder beside the target, a manifest (``.thrustwalk-run.json``: the command and the SHA-256
of every file) is written last, and the folder is swapped in at the end. A killed run or a full
disk therefore leaves the previous folder (or none), never a folder that mixes two runs;
temporaries of dead runs are removed by the next run.

A sweep's folder is different (:class:`SweepFolder`): it is written incrementally, one point
file at a time (each atomically) as the points finish, so that a stopped sweep resumes; its
marker ``.thrustwalk-sweep.json`` names the sweep it belongs to, and no other sweep, nor a
command that replaces its folder as a whole, may write into it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import platform
import shlex
import shutil
import sys
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from ..errors import ComputationError, InputError

_UMASK = os.umask(0)
os.umask(_UMASK)


def write_bytes_atomic(path: Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file in the same folder, then rename it over ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp creates 0600; results are ordinary files
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path: Path, text: str) -> Path:
    return write_bytes_atomic(path, text.encode())


MANIFEST = ".thrustwalk-run.json"
SWEEP_MARKER = ".thrustwalk-sweep.json"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def complete_run(folder: Path) -> bool:
    """``folder`` holds one whole run: its manifest lists exactly the files present, each with
    its SHA-256."""
    try:
        manifest = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
        files = manifest["files"]
        present = {p.relative_to(folder).as_posix() for p in folder.rglob("*")
                   if p.is_file() and p.name != MANIFEST}
        return set(files) == present and all(
            hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest
            for name, digest in files.items())
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False


def clean_stale(target: Path) -> list[Path]:
    """Tidy what runs killed while writing ``target`` left beside it (``.NAME.tmp-PID-*`` and
    ``.NAME.old-PID-*`` of processes that no longer exist). A run killed between moving the
    previous folder aside and moving its own in left no ``target``: the newest complete run
    (its own folder if its manifest was written, else the previous one) is put back first;
    the rest is removed. Returns the paths removed."""
    removed: list[Path] = []
    parent = target.parent
    if not parent.is_dir():
        return removed
    stale: dict[str, list[Path]] = {"tmp": [], "old": []}
    for p in sorted(parent.glob(f".{target.name}.*-*-*")):
        kind, _, rest = p.name[len(target.name) + 2:].partition("-")
        pid = rest.split("-", 1)[0]
        if kind in stale and pid.isdigit() and not _alive(int(pid)):
            stale[kind].append(p)
    if not target.exists():
        news = [p for p in stale["tmp"] if p.is_dir() and complete_run(p)]
        olds = [p / "run" for p in stale["old"] if (p / "run").is_dir()]
        back = max(news, key=lambda p: p.stat().st_mtime) if news else (olds[0] if olds else None)
        if back is not None:
            os.rename(back, target)
    for p in stale["tmp"] + stale["old"]:
        if p.exists():
            shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
            removed.append(p)
    return removed


def written_by_thrustwalk(folder: Path) -> bool:
    """A result folder thrustwalk wrote: it has a manifest, or (written before manifests
    existed) a JSON result whose ``provenance.tool`` is ``thrustwalk``."""
    if (folder / MANIFEST).is_file():
        return True
    for p in folder.glob("*.json"):
        doc = _read_json(p, 50)  # a regular file only (a FIFO would block), 50 MB at most
        if isinstance(doc, dict) and isinstance(doc.get("provenance"), dict) and \
                doc["provenance"].get("tool") == "thrustwalk":
            return True
    return False


def check_target(target: Path, *, whole: bool) -> None:
    """Refuse an output folder that cannot work, before any computation: an existing file, a
    path under a file, a read-only place, and (``whole``: a result folder replaced as a whole)
    a non-empty folder that thrustwalk did not write. :class:`InputError` on ``out``."""
    t = Path(target)
    if t.exists() and not t.is_dir():
        raise InputError.param("out", f"{t} is a file, not a folder")
    for anc in t.parents:
        if anc.exists():
            if not anc.is_dir():
                raise InputError.param("out", f"cannot create {t}: {anc} is a file")
            break
    else:  # pragma: no cover - relative paths always reach '.'
        anc = Path(".")
    place = t if t.is_dir() else anc
    if not os.access(place, os.W_OK | os.X_OK):
        raise InputError.param("out", f"cannot write in {place}: permission denied or a "
                                      "read-only file system")
    if whole and (t / SWEEP_MARKER).is_file():
        raise InputError.param("out", f"{t} is a sweep's folder (its points are kept for "
                                      "resuming): give another folder")
    if whole and t.is_dir() and any(t.iterdir()) and not written_by_thrustwalk(t):
        raise InputError.param("out", f"{t} is a folder with files that thrustwalk did not "
                                      "write; give a new or empty folder (its contents "
                                      "would be replaced)")


def check_file_target(target: Path, param: str = "json") -> None:
    """Refuse a single output file that cannot be written, before any computation: a folder,
    a path under a file, a read-only place. :class:`InputError` on ``param``."""
    t = Path(target)
    if t.is_dir():
        raise InputError.param(param, f"{t} is a folder, not a file")
    for anc in t.parents:
        if anc.exists():
            if not anc.is_dir():
                raise InputError.param(param, f"cannot create {t}: {anc} is a file")
            if not os.access(anc, os.W_OK | os.X_OK):
                raise InputError.param(param, f"cannot write in {anc}: permission denied or a "
                                              "read-only file system")
            break


@contextlib.contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """An exclusive advisory lock on ``folder`` (``flock`` on the folder itself: no lock file
    is left behind). Serialises the swap of two runs writing the same target; a no-op where
    ``fcntl`` does not exist (Windows)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing releases the lock


class ResultFolder:
    """One run's result folder, written as a whole (see the module docstring).

    ``folder = ResultFolder(target)`` checks the target (an existing file, a non-empty folder
    that thrustwalk did not write, or a path that cannot be created is an :class:`InputError`
    on the parameter ``out``), ``folder.path(name)`` is where to write each file, and
    ``folder.commit(provenance)`` writes the manifest and swaps the folder in;
    ``folder.abort()`` discards everything."""

    def __init__(self, target: Path):
        self.target = Path(target)
        t = self.target
        check_target(t, whole=True)
        try:
            t.parent.mkdir(parents=True, exist_ok=True)
        except (FileExistsError, NotADirectoryError):
            raise InputError.param("out", f"cannot create {t}: a part of the path is a "
                                          "file") from None
        clean_stale(t)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{t.name}.tmp-{os.getpid()}-",
                                         dir=t.parent))
        os.chmod(self.tmp, 0o777 & ~_UMASK)

    def path(self, name: str) -> Path:
        return self.tmp / name

    def commit(self, provenance: dict | None = None) -> Path:
        """Write the manifest last, then swap the folder in (the old one, if any, is moved
        aside and removed)."""
        files = {p.relative_to(self.tmp).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
                 for p in sorted(self.tmp.rglob("*")) if p.is_file()}
        manifest = {"tool": "thrustwalk", "version": __version__, "files": files}
        if provenance is not None:
            manifest["command"] = provenance.get("command")
        write_json(self.tmp / MANIFEST, manifest)
        with _folder_lock(self.target.parent):  # two runs writing the same target
            old = None
            if self.target.exists():
                old = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.old-{os.getpid()}-",
                                            dir=self.target.parent))
                os.rename(self.target, old / "run")
            try:
                os.rename(self.tmp, self.target)
            except OSError:
                if old is not None:  # put the previous run back
                    os.rename(old / "run", self.target)
                    shutil.rmtree(old, ignore_errors=True)
                raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return self.target

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)


def jsonable(obj: Any, path: str = "") -> Any:
    """Plain JSON values: numpy scalars/arrays to Python. A non-finite float is a
    :class:`ComputationError` naming its key path (results never hold NaN or infinity)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v, f"{path}.{k}" if path else str(k)) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v, f"{path}[{i}]") for i, v in enumerate(obj)]
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):
        return jsonable(obj.tolist(), path)
    if isinstance(obj, float):
        if not math.isfinite(obj):
            raise ComputationError(f"the result {path or 'value'} is {obj} (an overflow: are the "
                                   "inputs physically sensible?)")
        return obj
    if obj is None or isinstance(obj, (bool, int, str)):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot serialise {type(obj).__name__}")


def write_json(path: Path, obj: Any) -> Path:
    return write_text_atomic(path, json.dumps(jsonable(obj), indent=2) + "\n")


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> Path:
    """A CSV that ``pandas.read_csv(path)`` and ``numpy.genfromtxt(path, names=True,
    delimiter=",")`` load with no options: the header on the first line, no comment lines
    (units are in the column names, notes and provenance in the JSON beside it), no quoted
    fields (commas and line breaks in text become ``;`` and spaces), empty = missing. A numpy
    scalar is written as the Python number it holds (``0.5``, ``true``, never
    ``np.float64(0.5)``). Column by column: a column of floats (Python's or numpy's float64)
    is checked finite at once and written by ``float.__repr__`` (the shortest repr that reads
    back to the same number, as ``repr`` of the Python float); a column of text, flags,
    integers and blanks writes each distinct value once; any other cell by cell."""
    def cell(v: Any) -> str:
        if v is None:
            return ""
        if type(v).__module__ == "numpy" and hasattr(v, "item"):
            v = v.item()  # a numpy scalar: repr(np.float64(x)) is 'np.float64(x)', not x
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float):
            if not math.isfinite(v):
                raise ComputationError(f"a non-finite number ({v}) in the table {path.name} (an "
                                       "overflow: are the inputs physically sensible?)")
            return repr(v)
        return str(v).replace(",", ";").replace("\n", " ").replace("\r", " ").replace('"', "'")

    def column(values: tuple) -> list[str]:
        kinds = set(map(type, values))
        if kinds <= _FLOATS and np.all(np.isfinite(np.array(values, float))):
            return list(map(float.__repr__, values))
        if kinds <= _REPEATED:  # text, flags, counts, missing: each value's cell once
            memo: dict = {}
            return [memo[k] if (k := (type(v), v)) in memo else memo.setdefault(k, cell(v))
                    for v in values]
        return [cell(v) for v in values]

    rows = [tuple(r) for r in rows]
    lines = [",".join(cell(h) for h in header)]
    if rows:
        width = max(map(len, rows))
        if all(len(r) == width for r in rows):
            lines += map(",".join, zip(*(column(c) for c in zip(*rows))))
        else:  # ragged rows: cell by cell
            lines += [",".join(cell(v) for v in r) for r in rows]
    return write_text_atomic(path, "\n".join(lines) + "\n")


_FLOATS = {float, np.float64}
_REPEATED = {str, bool, int, type(None), np.bool_}


def file_ref(path: str, sha256: str) -> dict[str, str]:
    return {"file": str(path), "sha256": sha256}


def created_utc() -> str:
    """Now in UTC, or ``SOURCE_DATE_EPOCH`` when set (reproducible result files)."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    when = (datetime.fromtimestamp(int(epoch), timezone.utc) if epoch.isdigit()
            else datetime.now(timezone.utc))
    return when.isoformat(timespec="seconds")


def provenance(robot: Any = None, gait: Any = None, **extra: Any) -> dict[str, Any]:
    """Tool version, command line, time, and hashes of the robot and gait files."""
    prov: dict[str, Any] = {
        "tool": "thrustwalk",
        "version": __version__,
        "command": shlex.join(["thrustwalk", *sys.argv[1:]]),
        "created_utc": created_utc(),
        "python": platform.python_version(),
    }
    if robot is not None:
        prov["robot"] = file_ref(robot.source_file, robot.source_sha256)
    if gait is not None:
        prov["gait"] = file_ref(gait.source_file, gait.source_sha256)
    prov.update(extra)
    return prov


class SweepFolder:
    """The folder of one sweep, written incrementally (module docstring).

    ``SweepFolder(target, marker)`` checks ``target`` before any work: a file, a path under a
    file or a read-only place, a folder of another sweep (its marker has another
    ``identity``), a command's result folder or any other non-empty folder is an
    :class:`InputError` on ``out``; a sweep already running into it (an exclusive lock held
    for the whole run; a killed run releases it) too. Then it removes the temporaries a killed
    run left and writes the marker. ``finished()`` reads the point records written so far,
    ``write_point(record)`` writes one (atomically: never a half-written point file),
    ``path(name)`` is where a summary file goes; ``close()`` releases the lock. ``records``:
    the subfolder of the point records (``points``; a robustness run's ``trials``)."""

    POINTS = "points"

    def __init__(self, target: Path, marker: dict, records: str = POINTS):
        t = self.target = Path(target)
        self.records = records
        check_target(t, whole=False)
        if t.is_dir() and any(t.iterdir()):
            own = _read_json(t / SWEEP_MARKER)
            if own is None:
                what = ("the result folder of a command (replaced as a whole)"
                        if (t / MANIFEST).exists() else "not a sweep's folder")
                raise InputError.param("out", f"{t} is {what}: give a new or empty folder "
                                              "for the sweep")
            if own.get("identity") != marker["identity"]:
                raise InputError.param("out", (
                    f"{t} holds another sweep ('{own.get('sweep')}' from {own.get('file')}, "
                    f"{own.get('points')} points); a sweep resumes only into its own folder: "
                    "give another folder, or remove this one"))
        try:
            (t / self.records).mkdir(parents=True, exist_ok=True)
        except (FileExistsError, NotADirectoryError):
            raise InputError.param("out", f"cannot create {t}: a part of the path is a "
                                          "file") from None
        self._fd = _try_lock(t)
        if self._fd is False:
            raise InputError.param("out", f"another thrustwalk sweep is running into {t}")
        for folder in (t, t / self.records):
            for tmp in folder.glob(".*.tmp"):  # left by a killed run (we hold the lock)
                tmp.unlink(missing_ok=True)
        if not (t / SWEEP_MARKER).is_file():
            write_json(t / SWEEP_MARKER, {"tool": "thrustwalk", "version": __version__,
                                          **marker})
        self.notes: list[str] = []

    def point_path(self, key: str) -> Path:
        return self.target / self.records / f"{key[:20]}.json"

    def finished(self, keys: Iterable[str], label: str = "point") -> dict[str, dict]:
        """The records of the points ``keys`` (in point order: ``label`` N is the N-th)
        already written and verified (key -> record). A point file that does not verify runs
        again and is replaced, with a note in ``notes`` naming the point: one that cannot be
        read (truncated, not JSON, a special file), that does not hold its key's record, or
        whose checksum (``sha256``, :func:`record_digest`, written with every record) does
        not match its content (edited by hand) or is missing. A folder where a point file
        should be is moved aside (``NAME.json.moved-aside``), never deleted."""
        out = {}
        bad: list[str] = []
        for i, key in enumerate(keys):
            p = self.point_path(key)
            if not os.path.lexists(p):
                continue
            if p.is_dir() and not p.is_symlink():
                moved = _move_aside(p)
                bad.append(f"{label} {i}: {p} is a folder, not a point file: moved aside to "
                           f"{moved.name}; the {label} runs again")
                continue
            rec, why = _read_record(p, key)
            if rec is None:
                bad.append(f"{label} {i}: {p} {why}; the {label} runs again")
                continue
            out[key] = rec
        if len(bad) > MAX_NOTES:
            more = len(bad) - MAX_NOTES + 1
            bad = bad[:MAX_NOTES - 1] + [f"{more} more {label} files did not verify and run "
                                         "again"]
        self.notes.extend(bad)
        return out

    def write_point(self, record: dict) -> Path:
        """Write a point's record with its checksum ``sha256`` (:func:`record_digest`)."""
        rec = jsonable(record)
        rec["sha256"] = record_digest(rec)
        return write_json(self.point_path(record["key"]), rec)

    def path(self, name: str) -> Path:
        return self.target / name

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def _read_json(path: Path, limit_mb: float = 256) -> dict | None:
    """A JSON object from ``path``, or None (missing, unreadable, not a regular file, above
    ``limit_mb`` MB, not a JSON object)."""
    from .yamlio import read_input

    try:
        doc = json.loads(read_input(path, limit_mb).decode("utf-8"))
    except (InputError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


MAX_NOTES = 10  # notes on point files that did not verify, at most (then a count)
_RECORD_KEYS = ("key", "index", "status", "reason", "fields", "document", "extra",
                "next_start")


def record_digest(record: dict) -> str:
    """The checksum of a point record: the SHA-256 of its canonical JSON (sorted keys, exact
    floats) without ``sha256`` itself and ``seconds`` (the wall time, the one field that
    differs between runs of the same point)."""
    body = {k: v for k, v in record.items() if k not in ("sha256", "seconds")}
    return hashlib.sha256(json.dumps(jsonable(body), sort_keys=True,
                                     separators=(",", ":")).encode()).hexdigest()


def _read_record(path: Path, key: str) -> tuple[dict | None, str]:
    """The verified record of point ``key`` in ``path``, or None and why not."""
    from .yamlio import read_input

    try:
        raw = read_input(path, 256)
    except InputError as exc:
        return None, f"cannot be read ({exc.problems[0].message})"
    try:
        rec = json.loads(raw.decode("utf-8"))
    except ValueError:
        return None, "is not a whole JSON record (truncated or damaged)"
    if not isinstance(rec, dict) or rec.get("key") != key or \
            rec.get("status") not in ("ok", "failed") or \
            any(k not in rec for k in _RECORD_KEYS):
        return None, "does not hold this point's record"
    if rec.get("sha256") != record_digest(rec):
        return None, ("has no checksum" if "sha256" not in rec else
                      "does not match its checksum (edited or damaged)")
    return rec, ""


def _move_aside(path: Path) -> Path:
    """Rename ``path`` to ``NAME.moved-aside`` (``-2``, ``-3``, ... when taken)."""
    n = 1
    while True:
        new = path.with_name(path.name + ".moved-aside" + (f"-{n}" if n > 1 else ""))
        if not os.path.lexists(new):
            os.rename(path, new)
            return new
        n += 1


def _try_lock(folder: Path):
    """An exclusive, non-blocking ``flock`` on ``folder``: its descriptor, False when another
    process holds it, None where ``fcntl`` does not exist (Windows: no lock)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        return None
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return False
    return fd
