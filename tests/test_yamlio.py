"""Tests of line-aware safe YAML loading (thrustwalk_cli.files.yamlio)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from thrustwalk_cli.errors import InputError
from thrustwalk_cli.files.yamlio import format_path, load_yaml, load_yaml_text

ROBOT = """\
# a comment
name: demo
parameters:
  r: 1.0
links:
  - name: leg
    mass: 5
    com: [0, 0.5]
  - name: torso      # second item
    mass: 10
    point_masses:
      - {mass: 1, at: [0, 1]}
      -
        mass: 2
        at: [0, 2]
flags: {a: true, b: null, c: 1.5, d: text}
"""


def _problems(text: str) -> list[str]:
    with pytest.raises(InputError) as info:
        load_yaml_text(text, "f.yaml")
    return [str(p) for p in info.value.problems]


def test_plain_values() -> None:
    doc = load_yaml_text(ROBOT, "robot.yaml")
    assert doc.file == "robot.yaml"
    assert doc.data["links"][0] == {"name": "leg", "mass": 5, "com": [0, 0.5]}
    assert doc.data["flags"] == {"a": True, "b": None, "c": 1.5, "d": "text"}
    assert type(doc.data["links"][1]["mass"]) is int, "ints stay ints"
    assert doc.text == ROBOT


@pytest.mark.parametrize(
    "path,line",
    [
        ((), 2),
        (("name",), 2),
        (("parameters",), 3),
        (("parameters", "r"), 4),
        (("links",), 5),
        (("links", 0), 6),
        (("links", 0, "mass"), 7),
        (("links", 0, "com"), 8),
        (("links", 0, "com", 1), 8),
        (("links", 1), 9),
        (("links", 1, "mass"), 10),
        (("links", 1, "point_masses", 0), 12),
        (("links", 1, "point_masses", 0, "at", 1), 12),
        (("links", 1, "point_masses", 1), 14),
        (("links", 1, "point_masses", 1, "at"), 15),
        (("flags", "d"), 16),
    ],
)
def test_line_numbers(path: tuple, line: int) -> None:
    doc = load_yaml_text(ROBOT)
    assert doc.line_of(path) == line, f"line of {format_path(path) or '<root>'}"


def test_line_of_falls_back_to_ancestor() -> None:
    doc = load_yaml_text(ROBOT)
    assert doc.line_of(("links", 1, "inertia")) == 9, "missing key -> its mapping's line"
    assert doc.line_of(("links", 7, "mass")) == 5, "missing item -> the list's line"
    assert doc.line_of(("nope", "deeper")) == 2, "unknown top key -> root line"
    p = doc.problem(("links", 1, "inertia"), "missing required key")
    assert str(p) == "<string>:9: links[1].inertia: missing required key"


def test_format_path() -> None:
    cases = {
        (): "",
        ("links",): "links",
        ("links", 2, "mass"): "links[2].mass",
        ("coeffs", "q1", 0): "coeffs.q1[0]",
        (3,): "[3]",
        ("a", "odd key"): "a['odd key']",
    }
    for path, text in cases.items():
        assert format_path(path) == text, f"format_path({path!r})"


def test_duplicate_key_reports_second_occurrence() -> None:
    probs = _problems("a: 1\nb:\n  c: 2\n  d: 3\n  c: 4\n")
    assert probs == ["f.yaml:5: b.c: duplicate key 'c' (first defined on line 3)"], probs


def test_non_string_keys_rejected() -> None:
    probs = _problems("1: a\nyes: b\n~: c\n1.5: d\nok: e\n")
    assert len(probs) == 4, probs
    assert probs[0] == "f.yaml:1: mapping key '1' is an integer, not a string (quote it)"
    assert probs[1].startswith("f.yaml:2: mapping key 'yes'"), probs[1]
    assert "boolean" in probs[1] and "null" in probs[2] and "number" in probs[3], probs
    nested = _problems("a:\n  ? [1, 2]\n  : 3\n")
    assert nested == ["f.yaml:2: a: mapping keys must be plain strings"], nested


@pytest.mark.parametrize(
    "text,line,fragment",
    [
        ("a: [1, 2\nb: 3\n", 2, "expected ',' or ']'"),
        ("a: 1\n  b: 2\n", 2, "mapping values are not allowed here"),
        ("a: 'open\n", 2, "found unexpected end of stream"),
        ("a: 1\n---\nb: 2\n", 2, "expected a single document"),
        ("a:\n\tb: 1\n", 2, "found character '\\t'"),
        ("a: \x07\n", 1, "special characters are not allowed"),
    ],
)
def test_syntax_errors_are_one_line(text: str, line: int, fragment: str) -> None:
    probs = _problems(text)
    assert len(probs) == 1, f"{text!r}: {probs}"
    assert probs[0].startswith(f"f.yaml:{line}: "), f"{text!r}: {probs[0]}"
    assert fragment in probs[0], f"{text!r}: {probs[0]}"
    assert "\n" not in probs[0] and "Traceback" not in probs[0], f"{text!r}: one line only"


def test_unsafe_tags_rejected_and_not_executed(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    texts = [
        "a: !!python/object/apply:os.system ['touch x']\n",
        "a: !!python/name:os.system\n",
        "a: !custom 1\n",
        "a: !!binary aGVsbG8=\n",
    ]
    for text in texts:
        probs = _problems(text)
        assert len(probs) == 1 and "unsupported YAML tag" in probs[0], f"{text!r}: {probs}"
    assert not (tmp_path / "x").exists(), "nothing may be executed"


def test_aliases_and_merge_keys() -> None:
    doc = load_yaml_text("base: &b {x: 1, y: 2}\nd:\n  <<: *b\n  y: 5\ne: *b\n")
    assert doc.data["d"] == {"y": 5, "x": 1}, "own keys win over merged ones"
    assert doc.data["e"] == {"x": 1, "y": 2}
    assert doc.line_of(("d", "y")) == 4
    probs = _problems("a: &x [1, *x]\n")
    assert probs == ["f.yaml:1: a[1]: recursive alias is not allowed"], probs


def test_scalars_follow_safe_loader() -> None:
    doc = load_yaml_text("a: 0x10\nb: 1_000\nc: .inf\nd: 1e-3\ne: 2020-01-02\nf: '5'\n")
    assert doc.data["a"] == 16 and doc.data["b"] == 1000 and doc.data["c"] == float("inf")
    assert doc.data["d"] == "1e-3", "PyYAML reads 1e-3 as a string (schema evaluates it)"
    assert doc.data["e"] == "2020-01-02" and doc.data["f"] == "5"


def test_load_file(tmp_path: Path) -> None:
    path = tmp_path / "robot.yaml"
    raw = ROBOT.encode("utf-8")
    path.write_bytes(raw)
    for given in (path, str(path)):
        doc = load_yaml(given)
        assert doc.file == str(given)
        assert doc.sha256 == hashlib.sha256(raw).hexdigest()
        assert doc.line_of(("links", 1, "mass")) == 10
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: 1\nb: [\n")
    with pytest.raises(InputError) as info:
        load_yaml(bad)
    assert str(info.value).startswith(f"{bad}:"), str(info.value)


def test_missing_empty_and_undecodable_files(tmp_path: Path) -> None:
    cases = {
        tmp_path / "nope.yaml": (None, "file not found"),
        tmp_path / "empty.yaml": (b"", "file is empty"),
        tmp_path / "comments.yaml": (b"# only a comment\n\n", "file is empty"),
        tmp_path / "latin1.yaml": (b"a: 1\nb: caf\xe9\n", "not valid UTF-8"),
    }
    for path, (content, fragment) in cases.items():
        if content is not None:
            path.write_bytes(content)
        with pytest.raises(InputError) as info:
            load_yaml(path)
        probs = info.value.problems
        assert len(probs) == 1 and fragment in probs[0].message, f"{path.name}: {probs}"
        assert probs[0].file == str(path), f"{path.name}: file named"
    with pytest.raises(InputError, match="directory"):
        load_yaml(tmp_path)


def test_problems_collected_together() -> None:
    probs = _problems("a: 1\na: 2\n3: x\nb: !foo 1\n")
    assert len(probs) == 3, probs
    assert [p.split(":")[1] for p in probs] == ["2", "3", "4"], probs
