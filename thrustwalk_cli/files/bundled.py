"""Bundled robots and gaits, and references to them: a path or a bundled name."""

from __future__ import annotations

import os
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


#: how a message of :func:`resolve_inside` says which parameter takes such a file instead
#: (followed by the parameter in backquotes; a command renders it as its option)
EXPLICITLY = "to read it, give it explicitly:"


def _is_name(ref: str) -> bool:
    """A bundled name rather than a path: no ``/`` and no ``.yaml``/``.yml`` ending."""
    return "/" not in ref and "\\" not in ref and not ref.endswith((".yaml", ".yml"))


def _bundled(ref: str, kind: str) -> Path | None:
    for d in _bundled_dirs(kind):
        f = d / f"{ref}.yaml"
        if f.is_file():
            return f
    return None


def _exists(p: Path) -> bool:
    """An existing path that is not a folder (a special file is found here and refused when
    read, by :func:`~.yamlio.read_input`)."""
    return p.exists() and not p.is_dir()


def resolve(ref: str, kind: str, base: Path | None = None) -> Path:
    """A path (absolute, relative to ``base`` or to the working folder) or a bundled name."""
    candidates = []
    p = Path(ref)
    if base is not None and not p.is_absolute():
        candidates.append(base / p)
    candidates.append(p)
    for c in candidates:
        if _exists(c):
            return c
    if _is_name(ref):
        found = _bundled(ref, kind)
        if found is not None:
            return found
    raise InputError(f"{ref}: no such file and no bundled {kind[:-1]} of that name "
                     f"(bundled: {', '.join(bundled_names(kind))})")


def resolve_inside(ref: str, kind: str, root: Path, base: Path | None = None,
                   how: str = "") -> Path:
    """A reference a file makes on someone else's behalf (a sweep file's ``robot:`` and
    ``gait:``; the ``robot:`` of a gait that a sweep file named): a bundled name, or a path
    relative to ``base`` (default ``root``) that stays inside the folder ``root``. An absolute
    path, a path whose ``..`` leaves ``root``, and one that leaves it through a symbolic link
    are refused (:class:`InputError`, one line; nothing is read), so that a sweep file cannot
    make thrustwalk read, and quote, a file elsewhere (``gait: ../../../../etc/shadow``).
    ``how``: how to give such a file instead (appended to the message). A path that exists
    beside ``base`` wins over a bundled name, as in :func:`resolve`."""
    root = Path(os.path.abspath(root))
    base = root if base is None else Path(os.path.abspath(base))
    p = Path(ref)
    rule = (f"outside the folder {root} of the file naming it: only files in that folder and "
            f"bundled {kind} are read on a file's behalf" + (f"; {how}" if how else ""))
    if _is_name(ref) and not _exists(base / p):
        found = _bundled(ref, kind)
        if found is not None:
            return found
        raise InputError(f"{ref}: no such file and no bundled {kind[:-1]} of that name "
                         f"(looked in {base}; bundled: {', '.join(bundled_names(kind))})")
    if p.is_absolute():
        raise InputError(f"{ref}: an absolute path, {rule}")
    target = Path(os.path.normpath(base / p))
    if target != root and root not in target.parents:
        raise InputError(f"{ref}: {rule}")
    if target.exists():
        real, real_root = Path(os.path.realpath(target)), Path(os.path.realpath(root))
        if real != real_root and real_root not in real.parents:
            raise InputError(f"{ref}: leads through a symbolic link {rule}")
    if not _exists(target):
        what = "a folder" if target.is_dir() else "no such file"
        raise InputError(f"{ref}: {what} in {target.parent}")
    return target
