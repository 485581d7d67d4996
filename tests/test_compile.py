"""``thrustwalk compile``: the summary of a compiled robot (the model itself: test_model.py)."""

from __future__ import annotations


def test_compile_summary(cli):
    res = cli("compile", "three_link")
    assert res.exit_code == 0, res.output
    assert "total mass" in res.output and "35 kg" in res.output
