"""Result files: atomic writes (temp file, then rename), provenance, NaN-free JSON."""

from __future__ import annotations

import io
import json
import math
import os
import platform
import shlex
import sys
import tempfile
from collections.abc import Iterable, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from .._version import __version__

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


def jsonable(obj: Any) -> Any:
    """Plain JSON values: numpy scalars/arrays to Python, non-finite floats refused."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):
        return jsonable(obj.tolist())
    if isinstance(obj, float):
        if not math.isfinite(obj):
            raise ValueError("refusing to write a non-finite number to JSON")
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
    fields (commas and line breaks in text become ``;`` and spaces), empty = missing."""
    def cell(v: Any) -> str:
        if v is None:
            return ""
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float):
            if not math.isfinite(v):
                raise ValueError("refusing to write a non-finite number to CSV")
            return repr(v)
        return str(v).replace(",", ";").replace("\n", " ").replace("\r", " ").replace('"', "'")

    buf = io.StringIO()
    buf.write(",".join(cell(h) for h in header) + "\n")
    for row in rows:
        buf.write(",".join(cell(v) for v in row) + "\n")
    return write_text_atomic(path, buf.getvalue())


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
