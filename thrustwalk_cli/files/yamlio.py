"""Line-aware safe YAML loading.

The text is composed into a node tree with ``yaml.SafeLoader`` (nothing is constructed from
arbitrary tags) and converted here into plain Python values while the 1-based line of every
key path is recorded, so later checks can point at ``file:line: key.path``.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ..errors import InputError, Problem

PathKey = str | int
KeyPath = tuple[PathKey, ...]

MAX_NODES = 1_000_000  # guards against alias bombs ("billion laughs")
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


def load_yaml_text(text: str, file: str = "<string>", *, raw: bytes | None = None) -> Document:
    """Parse YAML ``text``; raises :class:`InputError` listing every problem found."""
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
            raise InputError([_syntax_problem(file, text, exc)]) from None
    if root is None:
        raise InputError([Problem(file, None, "", "file is empty")])
    conv = _Converter(file)
    try:
        data = conv.convert(root, ())
    except _TooLarge as exc:
        msg = f"document too large (more than {MAX_NODES} nodes after alias expansion)"
        raise InputError([Problem(file, exc.line, "", msg)]) from None
    if conv.problems:
        raise InputError(conv.problems)
    return Document(file=file, text=text, data=data, sha256=digest, lines=conv.lines)


def load_yaml(path: str | Path) -> Document:
    """Read and parse a YAML file (UTF-8); raises :class:`InputError` on any problem."""
    file = str(path)
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise InputError([Problem(file, None, "", "file not found")]) from None
    except IsADirectoryError:
        raise InputError([Problem(file, None, "", "is a directory, not a file")]) from None
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise InputError([Problem(file, None, "", f"cannot read file: {reason}")]) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError([Problem(file, line, "", "file is not valid UTF-8 text")]) from None
    return load_yaml_text(text, file, raw=raw)
