"""Result files: atomic writes (temp file, then rename), provenance, NaN-free JSON."""

from __future__ import annotations

import csv
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


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]],
              comments: Sequence[str] = (), provenance: dict | None = None) -> Path:
    """CSV with ``# comment`` lines first (provenance as one JSON line, units), then a header
    row."""
    buf = io.StringIO()
    if provenance is not None:
        buf.write(f"# provenance: {json.dumps(jsonable(provenance), separators=(',', ':'))}\n")
    for c in comments:
        buf.write(f"# {c}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow(["" if v is None else (repr(float(v)) if isinstance(v, float) else v)
                    for v in row])
    return write_text_atomic(path, buf.getvalue())


def save_figure(fig: Any, stem: Path, formats: Sequence[str] = ("png", "pdf")) -> list[Path]:
    """Save a matplotlib figure as ``stem.png`` and ``stem.pdf``, each atomically."""
    out = []
    for ext in formats:
        buf = io.BytesIO()
        fig.savefig(buf, format=ext, dpi=200, bbox_inches="tight",
                    metadata={"Creator": f"thrustwalk {__version__}"} if ext == "pdf" else None)
        out.append(write_bytes_atomic(Path(f"{stem}.{ext}"), buf.getvalue()))
    return out


def file_ref(path: str, sha256: str) -> dict[str, str]:
    return {"file": str(path), "sha256": sha256}


def provenance(robot: Any = None, gait: Any = None, **extra: Any) -> dict[str, Any]:
    """Tool version, command line, time, and hashes of the robot and gait files."""
    prov: dict[str, Any] = {
        "tool": "thrustwalk",
        "version": __version__,
        "command": shlex.join(["thrustwalk", *sys.argv[1:]]),
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
    }
    if robot is not None:
        prov["robot"] = file_ref(robot.source_file, robot.source_sha256)
    if gait is not None:
        prov["gait"] = file_ref(gait.source_file, gait.source_sha256)
    prov.update(extra)
    return prov
