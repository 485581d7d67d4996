"""Tests of the declarative schemas (thrustwalk_cli.files.schema)."""

from __future__ import annotations

import pytest

from thrustwalk_cli.errors import InputError, Problem
from thrustwalk_cli.files.schema import (
    Kind,
    boolean,
    check,
    choice,
    dict_of,
    field,
    integer,
    list_of,
    mapping,
    markdown_table,
    matrix,
    null_or,
    number,
    parameters,
    problem,
    raise_if_problems,
    resolve_parameters,
    string,
    validate,
    vector,
)
from thrustwalk_cli.files.yamlio import load_yaml_text

LINK = mapping(
    field("name", string(), "link name"),
    field("mass", number("kg", gt=0), "link mass"),
    field("com", vector(2, "m"), "centre of mass in the link frame", default=[0, 0]),
    field("inertia", number("kg m^2", ge=0), "inertia about the COM", default=0),
    field("parent", null_or(string()), "parent link", default=None),
    field("frame", choice("world", "link"), "thrust frame", default="world"),
)
SCHEMA = mapping(
    field("parameters", parameters(), "named numbers for expressions", default={}),
    field("name", string(), "robot name"),
    field("steps", integer(ge=1, le=100), "number of steps", default=10),
    field("plot", boolean(), "draw a figure", default=False),
    field("links", list_of(LINK, min_len=1), "the links, root first"),
    field("coeffs", dict_of(vector(min_len=1), "coordinate"), "rows of coefficients",
          default={}),
    field("gain", matrix((2, 2)), "a 2x2 gain | matrix", default=[[1, 0], [0, 1]]),
    field("limits", vector(unit="N", ge=-100, le=100), "per-thruster limits", default=[]),
)

GOOD = """\
name: demo
parameters:
  m: 2 * half      # defined before 'half' on purpose: any order works
  half: 2.5
  r: 1e-3          # PyYAML reads this as a string; it is an expression
links:
  - name: leg
    mass: m
    com: [0, r/2]
  - name: torso
    parent: leg
    mass: 10
    inertia: m * r**2
coeffs:
  q1: [1, -2, 0.5]
"""


def _check(text: str, schema: Kind = SCHEMA) -> tuple[object, list[str]]:
    result = check(load_yaml_text(text, "r.yaml"), schema)
    return result.data, [str(p) for p in result.problems]


def test_valid_document_converted() -> None:
    result = check(load_yaml_text(GOOD, "r.yaml"), SCHEMA)
    assert result.ok, [str(p) for p in result.problems]
    data = result.data
    assert data["parameters"] == {"m": 5.0, "half": 2.5, "r": 1e-3}
    assert data["links"][0] == {
        "name": "leg", "mass": 5.0, "com": [0.0, 0.0005], "inertia": 0.0,
        "parent": None, "frame": "world",
    }
    assert data["links"][1]["inertia"] == pytest.approx(5e-6)
    link = data["links"][1]
    assert [type(x) for x in (link["mass"], link["inertia"], *link["com"])] == [float] * 4, (
        "numbers (also YAML ints and defaults) become floats"
    )
    assert data["steps"] == 10 and data["plot"] is False, "defaults filled in"
    assert data["gain"] == [[1.0, 0.0], [0.0, 1.0]] and data["limits"] == []
    assert data["coeffs"] == {"q1": [1.0, -2.0, 0.5]}


def test_three_mistakes_three_problems() -> None:
    text = GOOD.replace("mass: 10", "mass: -5").replace("name: leg", "nam: leg")
    text += "extra: 1\n"
    _, probs = _check(text)
    assert probs == [
        "r.yaml:7: links[0].nam: unknown key 'nam' (expected one of: name, mass, com, "
        "inertia, parent, frame); did you mean 'name'?",
        "r.yaml:7: links[0].name: missing required key",
        "r.yaml:12: links[1].mass: must be > 0, got -5",
        "r.yaml:16: extra: unknown key 'extra' (expected one of: parameters, name, steps, "
        "plot, links, coeffs, gain, limits)",
    ], probs


@pytest.mark.parametrize(
    "yaml_value,message",
    [
        ("[1, 2]", "expected a number, got a list"),
        ("true", "expected a number, got a boolean"),
        ("null", "expected a number, got null"),
        ("{a: 1}", "expected a number, got a mapping"),
        ("-5", "must be > 0, got -5"),
        ("0", "must be > 0, got 0"),
        ("m - 10", "must be > 0, got -5 (from 'm - 10')"),
        ("m * rr", "expression error at column 5: unknown name 'rr'; did you mean 'r'?"),
        ("2 ^ m", "expression error at column 3: '^' is not allowed; use '**' for powers"),
        ("m / (r - r)", "expression error at column 3: division by zero"),
        (".inf", "must be finite, got inf"),
        (".nan", "must be finite, got nan"),
        ("'__import__(\"os\")'", "expression error at column 12: unexpected character '\"' "
         "(strings are not allowed)"),
    ],
)
def test_number_errors(yaml_value: str, message: str) -> None:
    _, probs = _check(GOOD.replace("mass: 10", f"mass: {yaml_value}"))
    assert probs == [f"r.yaml:12: links[1].mass: {message}"], f"{yaml_value}: {probs}"


@pytest.mark.parametrize(
    "kind,value,message",
    [
        (number(ge=0), "-1", "must be >= 0, got -1"),
        (number(lt=1), "1", "must be < 1, got 1"),
        (number(le=1), "1.5", "must be <= 1, got 1.5"),
        (number(gt=0, lt=3.14), "3.14", "must be < 3.14, got 3.14"),
        (integer(ge=1), "0", "must be >= 1, got 0"),
        (integer(), "1.5", "expected an integer, got a number"),
        (integer(), "'3 / 2'", "expected an integer, got 1.5 (from '3 / 2')"),
        (integer(ge=0), "'2 * 3'", None),
        (integer(), "yes", "expected an integer, got a boolean"),
        (string(), "3", "expected a string, got an integer"),
        (string(), "'  '", "must not be empty"),
        (boolean(), "1", "expected true or false, got an integer"),
        (choice("world", "link"), "wrld", "must be one of: world, link; got 'wrld'; "
         "did you mean 'world'?"),
        (choice("world", "link"), "3", "must be one of: world, link; got an integer"),
        (null_or(number(gt=0)), "-1", "must be > 0, got -1"),
        (vector(2), "[1, 2, 3]", "expected 2 values, got 3"),
        (vector(2), "3", "expected a list of numbers, got an integer"),
        (vector(min_len=1), "[]", "expected at least 1 item(s), got 0"),
        (matrix((2, 2)), "[[1, 2]]", "expected 2 rows, got 1"),
        (matrix(), "[1, 2]", "expected a list of rows (lists of numbers)"),
        (matrix(), "3", "expected a list of rows (lists of numbers), got an integer"),
        (list_of(number(), min_len=2), "[1]", "expected at least 2 item(s), got 1"),
        (list_of(number()), "{a: 1}", "expected a list, got a mapping"),
        (dict_of(number()), "[1]", "expected a mapping, got a list"),
        (mapping(field("a", number())), "[]", "expected a mapping, got a list"),
    ],
)
def test_kind_errors(kind: Kind, value: str, message: str | None) -> None:
    doc = load_yaml_text(f"y: 1\nx: {value}\n", "k.yaml")
    result = validate(doc, mapping(field("x", kind), field("y", number())), {})
    probs = [str(p) for p in result.problems]
    if message is None:
        assert probs == [], f"{kind.label()} {value}: {probs}"
        return
    assert len(probs) == 1 and probs[0].endswith(message), f"{kind.label()} {value}: {probs}"
    assert probs[0].startswith("k.yaml:2: x"), probs[0]


def test_nested_element_paths() -> None:
    schema = mapping(field("m", matrix((2, 2), ge=0)), field("v", vector(3)))
    doc = load_yaml_text("m:\n  - [1, 2]\n  - [3, -4]\nv: [1, x, 3]\n", "n.yaml")
    probs = [str(p) for p in validate(doc, schema, {}).problems]
    assert probs == [
        "n.yaml:3: m[1][1]: must be >= 0, got -4",
        "n.yaml:4: v[1]: expression error at column 1: unknown name 'x'; "
        "no parameters are defined",
    ], probs
    doc = load_yaml_text("m: [[1, 2], [3]]\nv: [1, 2, 3]\n", "n.yaml")
    probs = [str(p) for p in validate(doc, schema, {}).problems]
    assert probs == ["n.yaml:1: m[1]: expected 2 values, got 1"], probs


def test_null_or_accepts_null() -> None:
    doc = load_yaml_text("x: null\ny: 2\n")
    schema = mapping(field("x", null_or(number())), field("y", null_or(number())))
    result = validate(doc, schema, {})
    assert result.ok and result.data == {"x": None, "y": 2.0}


def _params(text: str) -> tuple[dict[str, float], list[str]]:
    values, probs = resolve_parameters(load_yaml_text(text, "p.yaml"))
    return values, [str(p) for p in probs]


def test_parameters_any_order() -> None:
    values, probs = _params("parameters:\n  c: b * 2\n  b: a + 1\n  a: 1\n  t: 2*pi\n")
    assert probs == [] and values == pytest.approx({"a": 1, "b": 2, "c": 4, "t": 6.2831853})


def test_parameter_cycles() -> None:
    values, probs = _params(
        "parameters:\n  a: b + 1\n  b: a\n  c: c * 2\n  d: a + 1\n  e: 3\n"
    )
    assert probs == [
        "p.yaml:2: parameters.a: parameter cycle: a -> b -> a",
        "p.yaml:4: parameters.c: parameter cycle: c -> c",
    ], probs
    assert values == {"e": 3.0}, "d depends on the cycle: skipped without a new problem"
    values, probs = _params("parameters:\n  x: z\n  y: x\n  z: y\n")
    assert probs == ["p.yaml:2: parameters.x: parameter cycle: x -> z -> y -> x"], probs


@pytest.mark.parametrize(
    "entry,message",
    [
        ("a: bb + 1", "unknown name 'bb' in expression 'bb + 1'; did you mean 'b'?"),
        ("pi: 3", "parameter name 'pi' shadows a built-in"),
        ("sin: 3", "parameter name 'sin' shadows a built-in"),
        ("2x: 3", "invalid parameter name '2x' (use letters, digits, '_')"),
        ("a b: 3", "invalid parameter name 'a b' (use letters, digits, '_')"),
        ("lambda: 3", "invalid parameter name 'lambda' (a reserved word)"),
        ("a: [1]", "expected a number, got a list"),
        ("a: true", "expected a number, got a boolean"),
        ("a: b +", "expression error at column 4: unexpected end of expression"),
        ("a: b / (b - 2)", "expression error at column 3: division by zero"),
    ],
)
def test_parameter_errors(entry: str, message: str) -> None:
    values, probs = _params(f"parameters:\n  b: 2\n  {entry}\n")
    assert len(probs) == 1, f"{entry}: {probs}"
    assert probs[0].startswith("p.yaml:3: parameters"), f"{entry}: {probs[0]}"
    assert probs[0].endswith(message), f"{entry}: {probs[0]}"
    assert values["b"] == 2.0


def test_parameters_section_shape() -> None:
    assert _params("name: x\n") == ({}, []), "no section: no parameters"
    values, probs = _params("parameters: [1, 2]\n")
    assert probs == ["p.yaml:1: parameters: expected a mapping of names to numbers, got a list"]


def test_problem_helper_and_raise() -> None:
    result = check(load_yaml_text(GOOD, "r.yaml"), SCHEMA)
    p = result.problem(("links", 1, "parent"), "unknown link 'foo'")
    assert p == Problem("r.yaml", 11, "links[1].parent", "unknown link 'foo'")
    assert problem(result.doc, ("links", 1, "joint"), "x").line == 10, "falls back to item"
    raise_if_problems([])  # nothing to raise
    with pytest.raises(InputError) as info:
        raise_if_problems([p, p])
    assert len(info.value.problems) == 2
    assert str(info.value).splitlines()[0] == "r.yaml:11: links[1].parent: unknown link 'foo'"
    bad = check(load_yaml_text("name: 3\nlinks: []\n", "b.yaml"), SCHEMA)
    with pytest.raises(InputError) as info:
        bad.raise_if_problems()
    assert [p.line for p in info.value.problems] == [1, 2], str(info.value)


def _all_keys(kind: Kind, prefix: str = "") -> list[str]:
    keys = []
    for f in kind.fields:
        key = f"{prefix}.{f.key}" if prefix else f.key
        keys.append(key)
        inner = f.kind
        while inner.item is not None:
            key += {"list_of": "[]", "dict_of": f".<{inner.key_name}>"}.get(inner.tag, "")
            inner = inner.item
        keys += _all_keys(inner, key)
    return keys


def test_markdown_table_lists_every_key() -> None:
    table = markdown_table(SCHEMA)
    lines = table.strip().splitlines()
    keys = _all_keys(SCHEMA)
    assert "links[].mass" in keys and len(keys) == 14
    for key in keys:
        assert any(line.startswith(f"| `{key}` |") for line in lines), f"row for {key}"
    assert len(lines) == 2 + len(keys), "header, separator, one row per key"
    assert all(line.count(" | ") == 5 for line in lines[2:]), "six cells per row (| escaped)"
    mass = next(line for line in lines if line.startswith("| `links[].mass` |"))
    assert mass == "| `links[].mass` | number | kg | required | > 0 | link mass |", mass
    com = next(line for line in lines if line.startswith("| `links[].com` |"))
    assert "vector[2]" in com and "`[0, 0]`" in com and "| m |" in com, com
    steps = next(line for line in lines if line.startswith("| `steps` |"))
    assert "1 <= x <= 100" in steps, steps
