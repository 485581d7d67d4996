"""Bundled robots and gaits, and references to them: a path or a bundled name."""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError


def _bundled_dirs(kind: str) -> list[Path]:
    """``robots`` / ``gaits`` inside the installed package, then beside it (a checkout)."""
    package = Path(__file__).resolve().parent.parent
    return [package / kind, package.parent / kind]


def bundled_names(kind: str) -> list[str]:
    """Names of the bundled ``robots`` or ``gaits``."""
    names: set[str] = set()
    for d in _bundled_dirs(kind):
        if d.is_dir():
            names |= {p.stem for p in d.glob("*.yaml")}
    return sorted(names)


def resolve(ref: str, kind: str, base: Path | None = None) -> Path:
    """A path (absolute, relative to ``base`` or to the working folder) or a bundled name."""
    candidates = []
    p = Path(ref)
    if base is not None and not p.is_absolute():
        candidates.append(base / p)
    candidates.append(p)
    for c in candidates:
        if c.is_file():
            return c
    if "/" not in ref and not ref.endswith((".yaml", ".yml")):
        for d in _bundled_dirs(kind):
            f = d / f"{ref}.yaml"
            if f.is_file():
                return f
    raise InputError(f"{ref}: no such file and no bundled {kind[:-1]} of that name "
                     f"(bundled: {', '.join(bundled_names(kind))})")
