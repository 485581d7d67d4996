"""What the console tables show where a value is missing: one mark, the em dash, in every
command's table (limit-cycle, energy, feasibility on the user robot walker5), never "-" or
"n/a"; the JSON says null."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

DATA = Path(__file__).parent / "data"
DASH = "—"


def _rows(text: str) -> list[list[str]]:
    """The body rows of the rich table(s) in ``text``, as lists of stripped cells."""
    return [[c.strip() for c in ln.strip().strip("│").split("│")]
            for ln in text.splitlines() if ln.startswith("│")]


@pytest.mark.parametrize("command", ["limit-cycle", "energy", "feasibility"])
def test_a_missing_value_is_an_em_dash_in_every_table(command, cli, tmp_path, monkeypatch):
    """walker5 gives no motor data and no thruster power model (read from its YAML file):
    the total cost of transport is missing at every thrust; at +100 N of its backward-pointing
    torso thruster (its limit) the gait has no orbit (the verdict says so): every number of
    that row is missing. Each missing cell is the em dash; no cell is "-", "n/a" or "None"."""
    robot = yaml.safe_load((DATA / "walker5.yaml").read_text())
    assert not any("motor" in c for c in robot["coordinates"]["actuated"])
    assert not any("power" in t for t in robot["thrusters"])
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "200")  # a table, not the narrow terminal's lines
    res = cli(command, str(DATA / "walker5.yaml"), str(DATA / "walker5_walk.yaml"),
              "--thrust", "0,100", "--formats", "none", "--out", "out", "--json", "doc.json")
    assert res.exit_code == 0, res.output
    rows = _rows(res.stdout)
    assert len(rows) == 2, res.stdout
    cells = [c for r in rows for c in r]
    assert not {"-", "n/a", "N/A", "None", "nan", ""} & set(cells), rows
    zero, pushed = rows
    assert zero[0] == "0" and DASH not in zero[1:3], zero
    assert pushed[0] == "100"
    numbers = pushed[1:-1] if command != "feasibility" else pushed[2:]
    assert numbers and all(c == DASH for c in numbers), pushed
    doc = json.loads((tmp_path / "doc.json").read_text())
    if command == "limit-cycle":
        assert "no orbit" in pushed[-1] and doc["cycles"][1]["zeta_star"] is None
        assert zero[-2] == DASH and doc["cycles"][0]["energy"]["cot"]["total"] is None
    elif command == "energy":
        assert "no orbit" in pushed[-1] and doc["cases"][1]["energy"] is None
        assert zero[3] == DASH and doc["cases"][0]["energy"]["cot"]["total"] is None
    else:
        assert pushed[1] == "INFEASIBLE" and doc["cases"][1]["min_vertical_force"] is None


def test_a_table_shows_none_as_the_em_dash(capsys):
    """show_table, the one table printer of the commands, shows a None cell as the em dash."""
    from thrustwalk_cli.commands.common import show_table

    show_table("t", [("a", True), ("b", False)], [[1.5, None], [None, "x"]])
    rows = _rows(capsys.readouterr().out)
    assert rows == [["1.5", DASH], [DASH, "x"]]
