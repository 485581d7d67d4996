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
