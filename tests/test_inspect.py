"""``thrustwalk inspect``: the dynamics at one state, as a table or JSON."""

from __future__ import annotations

import json


def test_inspect_json_keys(tmp_path, cli):
    out = tmp_path / "state.json"
    res = cli("inspect", "three_link", "--q", "0.1,0.2,-0.3", "--dq", "0,1,-1",
              "--thrust", "-10,0", "--json", str(out), "-q")
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    for key in ("q", "dq", "D", "C_dq", "G", "B_F", "swing_foot", "impact", "coordinates",
                "provenance"):
        assert key in doc, key
    assert set(doc["impact"]) >= {"dq_plus", "impulse"}
    assert doc["coordinates"] == ["q1", "q2", "q3"]
    assert len(doc["D"]) == 3 and len(doc["impact"]["dq_plus"]) == 3


def test_inspect_wrong_q_length_is_one_line_exit_2(cli):
    res = cli("inspect", "three_link", "--q", "0.1,0.2")
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "--q" in lines[0] and "expected 3 values" in lines[0]
