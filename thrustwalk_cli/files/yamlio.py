"""Line-aware safe YAML loading.

The text is composed into a node tree with ``yaml.SafeLoader`` (nothing is constructed from
arbitrary tags) and converted here into plain Python values while the 1-based line of every
key path is recorded, so later checks can point at ``file:line: key.path``.
"""

from __future__ import annotations

import hashlib
import os
import re
import stat
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ..errors import InputError, Problem

PathKey = str | int
KeyPath = tuple[PathKey, ...]

MAX_NODES = 1_000_000  # guards against alias bombs ("billion laughs")
MAX_FILE_MB = 16  # [MB] an input file larger than this is refused unread (10^6 bytes a MB)
MAX_DEPTH = 64  # nesting levels; the composer and converter recurse once per level

_TAG = "tag:yaml.org,2002:"
_PLAIN_TAGS = {_TAG + t for t in ("null", "bool", "int", "float", "str")}
_SIMPLE_KEY = re.compile(r"[A-Za-z0-9_\-]+")
_KEY_KINDS = {"int": "an integer", "float": "a number", "bool": "a boolean", "null": "null"}


def _short_tag(tag: str) -> str:
    return "!!" + tag[len(_TAG) :] if tag.startswith(_TAG) else tag


def format_path(path: Iterable[PathKey]) -> str:
    """Render a key path: ``("links", 2, "mass")`` -> ``links[2].mass``."""
    out = ""
    for key in path:
        if isinstance(key, int):
            out += f"[{key}]"
        elif _SIMPLE_KEY.fullmatch(key):
            out += f".{key}" if out else key
        else:
            out += f"[{key!r}]"
    return out


@dataclass(frozen=True)
class Document:
    """A loaded YAML file: plain ``data`` plus the line of every key path."""

    file: str
    text: str
    data: Any
    sha256: str
    lines: dict[KeyPath, int] = field(default_factory=dict, repr=False)

    def line_of(self, path: Iterable[PathKey]) -> int | None:
        """Line of the node at ``path``, else of its nearest existing ancestor."""
        path = tuple(path)
        for n in range(len(path), -1, -1):
            line = self.lines.get(path[:n])
            if line is not None:
                return line
        return None

    def problem(self, path: Iterable[PathKey], message: str) -> Problem:
        """A :class:`Problem` located at ``path`` of this document."""
        path = tuple(path)
        return Problem(self.file, self.line_of(path), format_path(path), message)


class _Converter:
    """Turns a composed node tree into plain values, recording lines and problems."""

    def __init__(self, file: str):
        self.file = file
        self.lines: dict[KeyPath, int] = {}
        self.problems: list[Problem] = []
        self.count = 0
        self.active: set[int] = set()
        self.constructor = yaml.SafeLoader("")

    def _problem(self, line: int | None, path: KeyPath, message: str) -> None:
        self.problems.append(Problem(self.file, line, format_path(path), message))

    def convert(self, node: yaml.Node, path: KeyPath, line: int | None = None) -> Any:
        line = node.start_mark.line + 1 if line is None else line
        self.lines.setdefault(path, line)
        self.count += 1
        if self.count > MAX_NODES:
            raise _TooLarge(line)
        if id(node) in self.active:
            self._problem(line, path, "recursive alias is not allowed")
            return None
        self.active.add(id(node))
        try:
            if isinstance(node, yaml.ScalarNode):
                return self._scalar(node, path, line)
            if isinstance(node, yaml.SequenceNode):
                if node.tag != _TAG + "seq":
                    self._problem(line, path, f"unsupported YAML tag '{_short_tag(node.tag)}'")
                    return None
                return [self.convert(item, path + (i,)) for i, item in enumerate(node.value)]
            return self._mapping(node, path, line)
        finally:
            self.active.discard(id(node))

    def _scalar(self, node: yaml.ScalarNode, path: KeyPath, line: int) -> Any:
        if node.tag == _TAG + "timestamp":
            return node.value  # dates stay text
        if node.tag not in _PLAIN_TAGS:
            self._problem(line, path, f"unsupported YAML tag '{_short_tag(node.tag)}'")
            return None
        try:
            return self.constructor.construct_object(node, deep=True)
        except (yaml.YAMLError, ValueError) as exc:  # e.g. !!int "abc"
            self._problem(line, path, f"invalid {_short_tag(node.tag)} value: {exc}")
            return None

    def _entries(
        self, node: yaml.MappingNode, path: KeyPath
    ) -> list[tuple[yaml.Node, yaml.Node]]:
        """Key/value node pairs with YAML merge keys (``<<: *anchor``) expanded."""
        own: list[tuple[yaml.Node, yaml.Node]] = []
        merged: list[tuple[yaml.Node, yaml.Node]] = []
        for key, value in node.value:
            if key.tag != _TAG + "merge":
                own.append((key, value))
                continue
            sources = value.value if isinstance(value, yaml.SequenceNode) else [value]
            for src in sources:
                if isinstance(src, yaml.MappingNode):
                    merged.extend(self._entries(src, path))
                else:
                    self._problem(key.start_mark.line + 1, path, "'<<' must merge a mapping")
        own_keys = {k.value for k, _ in own if isinstance(k, yaml.ScalarNode)}
        seen: set[str] = set()
        keep: list[tuple[yaml.Node, yaml.Node]] = []
        for key, value in reversed(merged):  # later merge sources lose to earlier ones
            if not isinstance(key, yaml.ScalarNode):
                keep.append((key, value))
            elif key.value not in own_keys and key.value not in seen:
                seen.add(key.value)
                keep.append((key, value))
        return own + keep[::-1]

    def _mapping(self, node: yaml.MappingNode, path: KeyPath, line: int) -> Any:
        if node.tag != _TAG + "map":
            self._problem(line, path, f"unsupported YAML tag '{_short_tag(node.tag)}'")
            return None
        out: dict[str, Any] = {}
        first_line: dict[str, int] = {}
        for key_node, value_node in self._entries(node, path):
            key_line = key_node.start_mark.line + 1
            if not isinstance(key_node, yaml.ScalarNode):
                self._problem(key_line, path, "mapping keys must be plain strings")
                continue
            if key_node.tag != _TAG + "str":
                kind = _KEY_KINDS.get(key_node.tag[len(_TAG) :], _short_tag(key_node.tag))
                self._problem(
                    key_line, path,
                    f"mapping key {key_node.value!r} is {kind}, not a string (quote it)",
                )
                continue
            key = key_node.value
            if key in out:
                self._problem(
                    key_line, path + (key,),
                    f"duplicate key '{key}' (first defined on line {first_line[key]})",
                )
                continue
            first_line[key] = key_line
            out[key] = self.convert(value_node, path + (key,), key_line)
        return out


class _TooLarge(Exception):
    def __init__(self, line: int | None):
        self.line = line


def _syntax_problem(file: str, text: str, exc: yaml.YAMLError) -> Problem:
    if isinstance(exc, yaml.reader.ReaderError):
        line = text.count("\n", 0, max(exc.position, 0)) + 1
        char = exc.character if isinstance(exc.character, int) else ord(exc.character)
        return Problem(file, line, "", f"YAML error: {exc.reason} (character #x{char:02x})")
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        message = exc.problem or exc.context or "invalid YAML"
        if exc.context and exc.problem and exc.problem.startswith("but "):
            message = f"{exc.context} {exc.problem}"
        elif exc.context and exc.problem:
            where = ""
            if exc.context_mark is not None and exc.context_mark.line + 1 != line:
                where = f" started on line {exc.context_mark.line + 1}"
            message += f" ({exc.context}{where})"
        return Problem(file, line, "", f"YAML syntax error: {message}")
    return Problem(file, None, "", f"YAML error: {str(exc).splitlines()[0]}")


def _check_depth(text: str, file: str, loader=yaml.SafeLoader) -> None:
    """Refuse nesting deeper than ``MAX_DEPTH`` (before composing: the composer would
    overflow Python's stack on, say, 500 nested lists). Scanning is iterative."""
    depth = 0
    starts = (yaml.BlockMappingStartToken, yaml.BlockSequenceStartToken,
              yaml.FlowMappingStartToken, yaml.FlowSequenceStartToken)
    ends = (yaml.BlockEndToken, yaml.FlowMappingEndToken, yaml.FlowSequenceEndToken)
    for tok in yaml.scan(text, Loader=loader):
        if isinstance(tok, starts):
            depth += 1
            if depth > MAX_DEPTH:
                raise InputError([Problem(file, tok.start_mark.line + 1, "",
                                          f"nesting deeper than {MAX_DEPTH} levels")])
        elif isinstance(tok, ends):
            depth -= 1


_FAST = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_TOP_KEY = re.compile(r"^([A-Za-z_][A-Za-z0-9_.\-]*)[ \t]*:(?=[ \t]|$)", re.MULTILINE)


def _top_keys(text: str) -> dict[str, None] | None:
    """The top-level keys of YAML text that does not parse, found line by line (``key:`` at
    the start of a line): enough to tell which kind of file it was meant to be (None: no
    line looks like a key)."""
    return dict.fromkeys(_TOP_KEY.findall(text)) or None


Expect = Callable[[Document], None]


def load_yaml_text(text: str, file: str = "<string>", *, raw: bytes | None = None,
                   expect: Expect | None = None) -> Document:
    """Parse YAML ``text``; raises :class:`InputError` listing every problem found.

    ``expect(doc)``: the check that the file is of the expected kind (raises
    :class:`InputError` naming the kind, never quoting the content), made before any other
    problem is reported: on the data as parsed, or, when the text is not valid YAML, on its
    top-level keys found line by line. A file of another kind is thus never quoted in a
    message (a syntax error or an unknown key of ``/etc/shadow`` would be)."""
    raw = text.encode("utf-8") if raw is None else raw
    digest = hashlib.sha256(raw).hexdigest()
    try:
        # libyaml when present (5x faster: most of a warm command's parsing time); on any
        # error the pure-Python parser again, whose messages the problems are worded from
        _check_depth(text, file, _FAST)
        root = yaml.compose(text, Loader=_FAST)
    except (yaml.YAMLError, InputError):
        try:
            _check_depth(text, file)
            root = yaml.compose(text, Loader=yaml.SafeLoader)
        except yaml.YAMLError as exc:
            if expect is not None:
                expect(Document(file=file, text=text, data=_top_keys(text), sha256=digest))
            raise InputError([_syntax_problem(file, text, exc)]) from None
        except InputError:
            if expect is not None:
                expect(Document(file=file, text=text, data=_top_keys(text), sha256=digest))
            raise
    if root is None:
        raise InputError([Problem(file, None, "", "file is empty")])
    conv = _Converter(file)
    try:
        data = conv.convert(root, ())
    except _TooLarge as exc:
        msg = f"document too large (more than {MAX_NODES} nodes after alias expansion)"
        raise InputError([Problem(file, exc.line, "", msg)]) from None
    doc = Document(file=file, text=text, data=data, sha256=digest, lines=conv.lines)
    if expect is not None:
        expect(doc)
    if conv.problems:
        raise InputError(conv.problems)
    return doc


_SPECIAL = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
            (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def read_input(path: str | Path, limit_mb: float = MAX_FILE_MB) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit_mb`` MB (10^6 bytes).

    A missing file, a folder, a special file (a FIFO, a device such as ``/dev/zero``, a
    socket: never read, so never a hang or an endless read) and a file above the limit are
    an :class:`InputError` in one line naming the file. The file is opened without blocking
    (a FIFO without a writer would block an ordinary open) and read up to the limit, so a
    file that grows while read is refused too."""
    file = str(path)
    limit = int(limit_mb * 1e6)

    def bad(message: str) -> InputError:
        return InputError([Problem(file, None, "", message)])

    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise bad("file not found") from None
    except IsADirectoryError:
        raise bad("is a directory, not a file") from None
    except OSError as exc:
        raise bad(f"cannot read file: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise bad("is a directory, not a file")
        if not stat.S_ISREG(st.st_mode):
            what = next((w for test, w in _SPECIAL if test(st.st_mode)), "not a regular file")
            raise bad(f"is {what}, not a regular file: thrustwalk reads only regular files")
        too_big = f"larger than {limit_mb:g} MB: not an input file of thrustwalk (the limit)"
        if st.st_size > limit:
            raise bad(too_big)
        chunks, size = [], 0
        while True:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
            if size > limit:
                raise bad(too_big)
        return b"".join(chunks)
    except OSError as exc:
        raise bad(f"cannot read file: {exc.strerror or exc}") from None
    finally:
        os.close(fd)


def load_yaml(path: str | Path, expect: Expect | None = None) -> Document:
    """Read (:func:`read_input`: a regular file of at most ``MAX_FILE_MB`` MB) and parse a
    YAML file (UTF-8); raises :class:`InputError` on any problem. ``expect``: as for
    :func:`load_yaml_text`."""
    file = str(path)
    raw = read_input(path)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if expect is not None:
            expect(Document(file=file, text="", data=_top_keys(
                raw.decode("utf-8", "replace")), sha256=""))
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError([Problem(file, line, "", "file is not valid UTF-8 text")]) from None
    return load_yaml_text(text, file, raw=raw, expect=expect)
