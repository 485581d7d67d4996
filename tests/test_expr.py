"""Tests of the restricted arithmetic parser (thrustwalk_cli.files.expr)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from thrustwalk_cli.files.expr import MAX_DEPTH, MAX_LENGTH, ExprError, evaluate, parse

# (expression, value computed by Python itself)
PRECEDENCE = [
    ("1 + 2 * 3", 1 + 2 * 3),
    ("(1 + 2) * 3", (1 + 2) * 3),
    ("2 * 3 ** 2", 2 * 3**2),
    ("-2 ** 2", -(2**2)),
    ("(-2) ** 2", (-2) ** 2),
    ("2 ** -1", 2**-1),
    ("2 ** 3 ** 2", 2 ** (3**2)),
    ("-2 ** -2", -(2**-2)),
    ("10 - 4 - 3", 10 - 4 - 3),
    ("2 / 4 / 8", 2 / 4 / 8),
    ("8 / 2 * 4", 8 / 2 * 4),
    ("1 - -1", 1 - -1),
    ("--3", 3),
    ("+-+3", -3),
    ("-3 * -2", -3 * -2),
    ("1.5e-3 * 2", 1.5e-3 * 2),
    ("2E+2 + .5 + 3.", 2e2 + 0.5 + 3.0),
    ("7", 7.0),
    ("2 * pi", 2 * math.pi),
    ("sqrt(16) + cos(0) - sin(0)", math.sqrt(16) + math.cos(0) - math.sin(0)),
    ("sin(pi / 6) ** 2", math.sin(math.pi / 6) ** 2),
    ("-sqrt(4) ** 2", -(math.sqrt(4) ** 2)),
    ("((((1))))", 1.0),
    ("3 * (2 - 5) / 4 ** 0.5", 3 * (2 - 5) / 4**0.5),
    ("1 / 3 + 2 / 3 * 3 - 4 ** 2 / 8", 1 / 3 + 2 / 3 * 3 - 4**2 / 8),
]


@pytest.mark.parametrize("text,expected", PRECEDENCE, ids=[t for t, _ in PRECEDENCE])
def test_precedence_matches_python(text: str, expected: float) -> None:
    got = evaluate(text, {})
    assert isinstance(got, float), f"{text!r}: result is {type(got).__name__}, not float"
    assert got == pytest.approx(expected, rel=1e-15, abs=0), f"{text!r}: {got} != {expected}"


def test_names_and_environment() -> None:
    e = parse("m * r / 2 + sin(theta) * pi")
    assert e.names() == frozenset({"m", "r", "theta"}), "free names exclude functions/constants"
    assert str(e) == "m * r / 2 + sin(theta) * pi"
    got = e.evaluate({"m": 2.0, "r": 3.0, "theta": 0.5})
    assert got == pytest.approx(3.0 + math.sin(0.5) * math.pi)


def test_expr_is_immutable() -> None:
    e = parse("1 + x")
    with pytest.raises(dataclasses.FrozenInstanceError):
        e.text = "2"  # type: ignore[misc]


def test_custom_functions_and_constants() -> None:
    e = parse("tau * twice(x)", functions={"twice": lambda v: 2 * v}, constants={"tau": 6.0})
    assert e.names() == frozenset({"x"})
    assert e.evaluate({"x": 1.5}) == 18.0
    assert e.evaluate_array({"x": np.array([1.0, 2.0])}).tolist() == [12.0, 24.0]
    with pytest.raises(ExprError, match="unknown function 'sin'"):
        parse("sin(1)", functions={"twice": lambda v: 2 * v})


def test_evaluate_array_broadcasting() -> None:
    e = parse("k * (j - 2)")
    j = np.arange(5)
    got = e.evaluate_array({"k": 2, "j": j})
    np.testing.assert_array_equal(got, 2.0 * (j - 2), err_msg="k*(j-2) over j")
    grid = parse("a * b + sqrt(a)").evaluate_array(
        {"a": np.array([[1.0], [4.0]]), "b": np.array([1.0, 2.0, 3.0])}
    )
    assert grid.shape == (2, 3), "column x row broadcasts to a 2x3 grid"
    np.testing.assert_allclose(grid[1], [6.0, 10.0, 14.0])
    assert float(parse("-2 ** 2").evaluate_array({})) == -4.0


@pytest.mark.parametrize(
    "text,env,fragment",
    [
        ("sqrt(-1)", {}, "math domain error in sqrt"),
        ("1 / 0", {}, "division by zero"),
        ("1 / (x - x)", {"x": 3.0}, "division by zero"),
        ("0 ** -1", {}, "zero raised to a negative power"),
        ("(-8) ** (1 / 3)", {}, "negative number raised to a non-integer power"),
        ("10 ** 400", {}, "overflow"),
        ("1e300 * 1e300", {}, "overflow"),
        ("x + 1", {}, "unknown name 'x'"),
        ("x + 1", {"x": float("nan")}, "not finite"),
    ],
)
def test_evaluation_errors(text: str, env: dict[str, float], fragment: str) -> None:
    with pytest.raises(ExprError) as info:
        evaluate(text, env)
    assert fragment in info.value.message, f"{text!r}: message {info.value.message!r}"


def test_array_evaluation_errors() -> None:
    with pytest.raises(ExprError, match="math domain error in sqrt"):
        parse("sqrt(j)").evaluate_array({"j": np.array([-1.0, 1.0])})
    with pytest.raises(ExprError, match="divide by zero"):
        parse("1 / j").evaluate_array({"j": np.array([0.0, 1.0])})
    with pytest.raises(ExprError, match="shape mismatch"):
        parse("a + b").evaluate_array({"a": np.zeros(2), "b": np.zeros(3)})
    with pytest.raises(ExprError, match="unknown name 'j'"):
        parse("j").evaluate_array({})


def test_error_column_points_at_token() -> None:
    with pytest.raises(ExprError) as info:
        evaluate("m * rr", {"m": 1.0})
    assert (info.value.column, info.value.message) == (4, "unknown name 'rr'")
    with pytest.raises(ExprError) as info:
        parse("1 + 2 $")
    assert info.value.column == 6, "column of '$'"
    assert isinstance(info.value, ValueError), "ExprError is a ValueError"


def test_import_attack_is_rejected_and_not_executed(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    attacks = [
        "__import__('os').system('touch x')",
        '__import__("os").system("touch x")',
        "__import__(os).system(touch)",
        "().__class__",
        "lambda: __import__('os').system('touch x')",
    ]
    for text in attacks:
        with pytest.raises(ExprError) as info:
            evaluate(text, {"os": 1.0, "touch": 1.0})
        msg = info.value.message
        assert "\n" not in msg, f"{text!r}: one-line message expected, got {msg!r}"
        assert any(
            s in msg for s in ("__import__", "unexpected", "not allowed", "keyword")
        ), f"{text!r}: message should name the offending token: {msg!r}"
    assert not (tmp_path / "x").exists(), "the attack must never be executed"
    with pytest.raises(ExprError, match="unknown function '__import__'"):
        parse("__import__(os)")


REJECTED = [
    ("", "empty expression"),
    ("   ", "empty expression"),
    ("2 ^ 3", "use '**'"),
    ("a.b", "attribute access"),
    ("sin(x).real", "attribute access"),
    ("'abc'", "unexpected character \"'\""),
    ('"abc"', "strings are not allowed"),
    ("sin(1, 2)", "unexpected ','"),
    ("1, 2", "unexpected ','"),
    ("[1]", "unexpected character '['"),
    ("{1: 2}", "unexpected character '{'"),
    ("lambda: 1", "keyword 'lambda'"),
    ("x if y else z", "keyword 'if'"),
    ("True", "keyword 'True'"),
    ("None", "keyword 'None'"),
    ("1 2", "unexpected number '2'"),
    ("x y", "unexpected name 'y'"),
    ("1 + 2)", "unexpected ')'"),
    ("(1 + 2", "missing ')'"),
    ("sin(1 2)", "expected ')' but found number '2'"),
    ("1 +", "unexpected end of expression"),
    ("* 2", "unexpected '*'"),
    ("2x", "invalid number '2x'"),
    ("1e", "invalid number '1e'"),
    ("1.2.3", "invalid number '1.2.3'"),
    ("1e999", "too large"),
    ("sqrt", "function 'sqrt' must be called"),
    ("foo(1)", "unknown function 'foo'"),
    ("pi(2)", "unknown function 'pi'"),
    ("sin()", "unexpected ')'"),
    ("a @ b", "unexpected character '@'"),
    ("a % b", "unexpected character '%'"),
    ("a == b", "unexpected character '='"),
    ("a; b", "unexpected character ';'"),
    ("x # comment", "unexpected character '#'"),
    ("x\\", "unexpected character '\\\\'"),
    ("1 + é", "unexpected character 'é'"),
    ("x" * (MAX_LENGTH + 1), "expression too long"),
    ("(" * (MAX_DEPTH + 1) + "1" + ")" * (MAX_DEPTH + 1), "nested deeper than"),
    ("-" * (MAX_DEPTH + 1) + "1", "nested deeper than"),
    ("2" + "**2" * (MAX_DEPTH + 1), "nested deeper than"),
]


@pytest.mark.parametrize("text,fragment", REJECTED, ids=[t[:30] for t, _ in REJECTED])
def test_rejections(text: str, fragment: str) -> None:
    with pytest.raises(ExprError) as info:
        parse(text)
    msg = info.value.message
    assert fragment in msg, f"{text[:40]!r}: expected {fragment!r} in {msg!r}"
    assert "\n" not in msg, f"{text[:40]!r}: message must be one line"
    assert 0 <= info.value.column <= max(len(text), MAX_LENGTH), f"{text[:40]!r}: column"


def test_limits_are_inclusive() -> None:
    nested = "(" * MAX_DEPTH + "1" + ")" * MAX_DEPTH
    assert evaluate(nested, {}) == 1.0, f"{MAX_DEPTH} nested parentheses are allowed"
    long_ok = "+".join(["1"] * (MAX_LENGTH // 2))
    assert len(long_ok) <= MAX_LENGTH
    assert evaluate(long_ok, {}) == MAX_LENGTH // 2


def test_non_string_input_rejected() -> None:
    with pytest.raises(ExprError, match="expected a string"):
        parse(3)  # type: ignore[arg-type]
