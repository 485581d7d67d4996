"""Reading result folders: every result JSON (one with ``provenance``) and the figures beside
it, for the index of ``thrustwalk report``."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from .yamlio import read_input

MAX_RESULT_MB = 256  # a result JSON above this is skipped (with a note), never read


@dataclass(frozen=True)
class ResultFile:
    """One result JSON below a folder: its path relative to the folder (POSIX), the document,
    and the figures in its folder as ``(png, pdf or None)`` relative paths."""

    relative: str
    document: dict
    figures: tuple[tuple[str, str | None], ...]


def read_results(folder: Path, problems: list[str] | None = None) -> list[ResultFile]:
    """Every ``*.json`` below ``folder`` (sorted) that is a result document (a mapping with a
    ``provenance`` mapping). Other JSON files are skipped; a file that looks like a result but
    cannot be read (not UTF-8, not JSON, a ``provenance`` that is not a mapping) is skipped
    with one line in ``problems``."""
    folder = Path(folder)
    out = []
    for js in sorted(folder.rglob("*.json")):
        if js.name.startswith("."):
            continue  # run manifests and temporaries
        try:  # a regular file of sane size (a FIFO named *.json would block for ever)
            doc = json.loads(read_input(js, MAX_RESULT_MB).decode("utf-8"))
        except InputError as exc:
            _note(problems, js, exc.problems[0].message)
            continue
        except UnicodeDecodeError:
            _note(problems, js, "not UTF-8 text")
            continue
        except json.JSONDecodeError as exc:
            _note(problems, js, f"not JSON ({exc.msg}, line {exc.lineno})")
            continue
        except OSError as exc:
            _note(problems, js, f"cannot be read ({exc.strerror or exc})")
            continue
        if not isinstance(doc, dict) or "provenance" not in doc:
            continue
        if not isinstance(doc["provenance"], dict):
            _note(problems, js, "its provenance is not a mapping")
            continue
        figs = []
        for fig in sorted(js.parent.glob("*.png")):
            pdf = fig.with_suffix(".pdf")
            figs.append((fig.relative_to(folder).as_posix(),
                         pdf.relative_to(folder).as_posix() if pdf.exists() else None))
        out.append(ResultFile(js.relative_to(folder).as_posix(), doc, tuple(figs)))
    return out


def _note(problems: list[str] | None, path: Path, why: str) -> None:
    if problems is not None:
        problems.append(f"{path}: skipped, {why}")


# ---------------------------------------------------------------------- the gait library
@dataclass(frozen=True)
class LibraryGait:
    """One feasible design of a gait library (a ``design-gait`` sweep's folder): its gait
    name, the gait file (absolute path) and the row of ``library.csv`` (column -> text, the
    axes with their units in the names, e.g. ``target_speed_m_s``, ``thrust_N``)."""

    name: str
    file: str
    row: dict

    def number(self, column: str) -> float | None:
        """The row's number in ``column`` (None when absent or empty)."""
        text = self.row.get(column)
        try:
            return None if text in (None, "") else float(text)
        except ValueError:
            return None


LIBRARY_HINT = ("a gait library is the folder a design-gait sweep writes, e.g. "
                "`thrustwalk sweep sweeps/gait_library.yaml`")


def read_gait_library(folder: str | Path) -> tuple[LibraryGait, ...]:
    """The feasible gaits of a gait library: ``folder`` holds a sweep's marker
    (``.thrustwalk-sweep.json``) naming the ``design-gait`` study and its ``library.csv`` (one
    row per design point; ``file`` empty where the design failed). Anything else (a missing
    folder, another sweep, a folder without ``library.csv`` or without any feasible gait, a
    gait file outside the folder or missing) is an :class:`InputError` on ``library``, one
    line."""
    from .output import SWEEP_MARKER

    root = Path(folder)

    def bad(message: str) -> InputError:
        return InputError.param("library", message)

    if not root.is_dir():
        raise bad(f"{root} is not a folder ({LIBRARY_HINT})")
    marker = root / SWEEP_MARKER
    if not marker.is_file():
        raise bad(f"{root} is not a gait library: no sweep marker {SWEEP_MARKER} ("
                  f"{LIBRARY_HINT})")
    try:
        info = json.loads(read_input(marker, 1).decode("utf-8"))
    except (InputError, UnicodeDecodeError, json.JSONDecodeError, OSError):
        raise bad(f"{root} is not a gait library: its {SWEEP_MARKER} cannot be read") from None
    study = info.get("study") if isinstance(info, dict) else None
    if study != "design-gait":
        raise bad(f"{root} is not a gait library: it holds a {study or 'unknown'} sweep, not a "
                  f"design-gait sweep ({LIBRARY_HINT})")
    table = root / "library.csv"
    if not table.is_file():
        raise bad(f"{root} has no library.csv (the sweep has not finished: run it again to "
                  "complete it)")
    try:
        lines = read_input(table, MAX_RESULT_MB).decode("utf-8").splitlines()
    except (InputError, UnicodeDecodeError, OSError):
        raise bad(f"{table} cannot be read") from None
    header = lines[0].split(",") if lines else []
    if "gait" not in header or "file" not in header:
        raise bad(f"{table} is not a gait library table (no `gait` and `file` columns)")
    out = []
    base = root.resolve()
    for line in lines[1:]:
        if not line.strip():
            continue
        row = dict(zip(header, line.split(",")))
        if not row.get("file"):
            continue  # no feasible gait at that point
        path = (root / row["file"]).resolve()
        if base not in path.parents:
            raise bad(f"{table}: gait file {row['file']!r} is outside the library folder")
        if not path.is_file():
            raise bad(f"{table}: gait file {row['file']} is missing")
        out.append(LibraryGait(row.get("gait") or path.stem, str(path), row))
    if not out:
        raise bad(f"{root}: library.csv lists no feasible gait")
    return tuple(out)
