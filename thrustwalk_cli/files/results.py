"""Reading result folders: every result JSON (one with ``provenance``) and the figures beside
it, for the index of ``thrustwalk report``."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class ResultFile:
    """One result JSON below a folder: its path relative to the folder (POSIX), the document,
    and the figures in its folder as ``(png, pdf or None)`` relative paths."""

    relative: str
    document: dict
    figures: tuple[tuple[str, str | None], ...]


def read_results(folder: Path) -> list[ResultFile]:
    """Every ``*.json`` below ``folder`` (sorted) that is a result document (a mapping with
    ``provenance``); unreadable or other JSON files are skipped."""
    folder = Path(folder)
    out = []
    for js in sorted(folder.rglob("*.json")):
        try:
            doc = json.loads(js.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if not isinstance(doc, dict) or "provenance" not in doc:
            continue
        figs = []
        for fig in sorted(js.parent.glob("*.png")):
            pdf = fig.with_suffix(".pdf")
            figs.append((fig.relative_to(folder).as_posix(),
                         pdf.relative_to(folder).as_posix() if pdf.exists() else None))
        out.append(ResultFile(js.relative_to(folder).as_posix(), doc, tuple(figs)))
    return out
