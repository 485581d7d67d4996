"""``thrustwalk energy`` (issue 28, SPEC 15): the cost of transport over constant thrust, the
gait library's Pareto comparison, design-gait's energy block, missing models and bad input.

Independent checks: the CoT against E / (m g d) from the limit-cycle command's energy block
of the same thrust (another command, another document); the mechanical balance of a steady
orbit (joints' net work + thrust work = the impact loss K^- - K^+, from the model's D at q^-
and q^+ and its impact map); the cheapest strategy against the two curves interpolated here
from the CSV files; the design's CoT against limit-cycle on the written gait.
"""

from __future__ import annotations

import csv
import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

import thrustwalk_cli as tw

DATA = Path(__file__).resolve().parent / "data"
W5, W5T = DATA / "walker5.yaml", DATA / "walker5_thrust.yaml"
MOTOR = "motor: {torque_constant: 0.05, resistance: 0.6, gear_ratio: 100, gearbox_efficiency: 0.9}"
POWER = "power: {kind: momentum, diameter: 0.35, figure_of_merit: 0.7, motor_efficiency: 0.9}"


def _powered_walker5(folder: Path) -> Path:
    """A COPY of walker5 with a motor on every joint and a rotor model on its thruster."""
    text = W5.read_text()
    for name in ("q_sk", "q_sh", "q_wh", "q_wk"):
        line = next(ln for ln in text.splitlines() if f"{{name: {name}," in ln)
        text = text.replace(line, line[:-1] + ", " + MOTOR + "}")
    text = text.replace("limits: [-100, 100]}", f"limits: [-100, 100], {POWER}}}")
    path = folder / "walker5_powered.yaml"
    path.write_text(text)
    return path


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _num(text: str) -> float | None:
    return None if text == "" else float(text)


@pytest.mark.slow
def test_cot_is_the_limit_cycle_energy_over_mgd_and_the_orbit_balances(cli, tmp_path,
                                                                       monkeypatch):
    """Per thrust: the CoTs equal E / (m g d) from limit-cycle's energy block of the same
    thrust; joints' net work + thrust work = K^- - K^+ (steady orbit on level ground: K and V
    return), K^+ through the model's impact map."""
    monkeypatch.chdir(tmp_path)
    robot = _powered_walker5(tmp_path).name
    thrust = "0,-20,-40"
    r = cli("energy", robot, str(W5T), "--thrust", thrust, "--out", "e", "-q")
    assert r.exit_code == 0, r.output
    r = cli("limit-cycle", robot, str(W5T), "--thrust", thrust, "--formats", "csv", "--out",
            "lc", "-q")
    assert r.exit_code == 0, r.output
    doc = json.loads(Path("e/energy.json").read_text())
    lc = json.loads(Path("lc/limit_cycles.json").read_text())
    rows = _rows(Path("e/energy.csv"))
    walker = tw.load_walker(robot, str(W5T))
    model, maps, zd = walker.model, walker.zd.maps, walker.zd
    mg = walker.robot.total_mass * 9.81
    assert doc["energy"]["basis"] == "total" and not doc["energy"]["missing"]
    for case, row, ref in zip(doc["cases"], rows, lc["cycles"]):
        assert case["thrust"] == ref["thrust"] == float(row["thrust_N"])
        assert case["walkable"] and row["verdict"] == "walkable"
        e = ref["energy"]["per_step"]
        d = ref["step_length"]
        mech = (e["legs_mechanical"] + e["thrust_mechanical"]) / (mg * d)
        total = (e["legs_electrical"] + e["thrust_input"]) / (mg * d)
        for got in (case["energy"]["cot"], {k: _num(row[f"cot_{k}"]) for k in
                                            ("mechanical", "total")}):
            assert got["mechanical"] == pytest.approx(mech, rel=1e-12)
            assert got["total"] == pytest.approx(total, rel=1e-12)
        assert _num(row["speed_m_s"]) == pytest.approx(ref["speed"], rel=1e-12)
        # the balance over one step of the steady orbit
        dq_minus = maps.Phi(np.array(zd.alpha_f)) * ref["alpha_dot_minus"]
        imp = model.impact(maps.q_minus, dq_minus)
        K_minus = 0.5 * dq_minus @ model.D(maps.q_minus) @ dq_minus
        K_plus = 0.5 * imp.dq_plus @ model.D(imp.q_plus) @ imp.dq_plus
        work = _num(row["joint_net_work_J"]) + _num(row["thrust_work_J"])
        assert K_minus - K_plus > 0
        assert work == pytest.approx(K_minus - K_plus, rel=1e-8)
        assert _num(row["impact_loss_J"]) == pytest.approx(K_minus - K_plus, rel=1e-9)
    # the headline: the extreme thrust against the nominal, with the computed numbers
    c0, c1 = doc["cases"][0], doc["cases"][-1]
    assert doc["nominal_thrust"] == 0.0 and doc["extreme_thrust"] == -40.0
    assert doc["headline"].startswith(
        f"thrust -40 N raises speed from {c0['speed']:.3g} to {c1['speed']:.3g} m/s at total "
        f"CoT {c0['energy']['cot']['total']:.3g} -> {c1['energy']['cot']['total']:.3g}")
    for fig in ("cot_speed", "power_step"):
        assert Path(f"e/{fig}.png").is_file() and Path(f"e/{fig}.pdf").is_file()


@pytest.mark.slow
def test_a_robot_without_motor_or_power_data_says_so(cli, tmp_path, monkeypatch):
    """walker5 has no motor: nor power: the total CoT is None in the JSON with the reason,
    empty in the CSV with a note line, and said on the console; the mechanical CoT is there."""
    monkeypatch.chdir(tmp_path)
    r = cli("energy", str(W5), str(W5T), "--thrust", "0,-20", "--out", "e")
    assert r.exit_code == 0, r.output
    doc = json.loads(Path("e/energy.json").read_text())
    missing = doc["energy"]["missing"]
    assert any(m.startswith("no motor data for q_sk, q_sh, q_wh, q_wk") for m in missing)
    assert any(m.startswith("no power model for thruster back") for m in missing)
    assert doc["energy"]["basis"] == "mechanical"
    assert doc["energy"]["basis_reason"].startswith("the total CoT is missing")
    for case in doc["cases"]:
        cot = case["energy"]["cot"]
        assert cot["total"] is None and cot["total_legs"] is None
        assert cot["total_thrust"] is None and cot["mechanical"] > 0
        assert case["energy"]["per_step"]["thruster_input"] == [None]
    for row in _rows(Path("e/energy.csv")):
        assert row["cot_total"] == "" and row["joint_electrical_J"] == ""
        assert row["thruster_input_J"] == "" and float(row["cot_mechanical"]) > 0
    notes = doc["tables"]["energy.csv"]["notes"]
    assert any(n.startswith("empty total cells: no motor data") for n in notes)
    out = " ".join(r.stdout.split())
    assert "no motor data for q_sk, q_sh, q_wh, q_wk: joint electrical energy not computed" \
        in out
    assert "no power model for thruster back" in out
    assert "total CoT not computed" in doc["headline"]


@pytest.mark.slow
def test_an_orbit_without_energies_says_why(cli, tmp_path, monkeypatch):
    """A thrust value whose orbit does not exist: energies None with the reason, empty
    cells, never NaN or 0; the case still has its row."""
    monkeypatch.chdir(tmp_path)
    r = cli("energy", str(W5), str(W5T), "--thrust", "0,60", "--out", "e", "-q")
    assert r.exit_code == 0, r.output
    doc = json.loads(Path("e/energy.json").read_text())
    bad = doc["cases"][1]
    assert bad["verdict"] == "no orbit" and bad["energy"] is None
    assert bad["energy_reason"].startswith("no periodic orbit")
    row = _rows(Path("e/energy.csv"))[1]
    assert row["speed_m_s"] == "" and row["cot_mechanical"] == ""
    assert row["reason"].startswith("no periodic orbit")


LIBRARY = """\
    name: lib
    study: design-gait
    robot: three_link
    settings: {clearance: 0, max_iter: 80, starts: 1}
    grid:
      target_speed: {values: [0.75, 0.85, 0.95]}
    collect: [effort, feasible]
    """


@pytest.mark.slow
def test_the_cheapest_strategy_is_the_least_of_the_two_interpolated_curves(cli, tmp_path,
                                                                         monkeypatch):
    """A 3-gait library of the bundled 3-link walker (design-gait sweep, 0.75 to 0.95 m/s)
    against three_link_walk pushed by thrust: at each speed of pareto.csv the cheapest is the
    least of the two curves interpolated here from energy.csv and library_energy.csv."""
    monkeypatch.chdir(tmp_path)
    Path("lib.yaml").write_text(textwrap.dedent(LIBRARY))
    r = cli("sweep", "lib.yaml", "--out", "lib", "--workers", "1", "--formats", "csv", "-q")
    assert r.exit_code == 0, r.output
    r = cli("energy", "three_link", "three_link_walk", "--thrust", "6:-8:-1", "--library", "lib",
            "--out", "e")
    assert r.exit_code == 0, r.output
    doc = json.loads(Path("e/energy.json").read_text())
    basis = doc["library"]["basis"]
    assert basis == "total"  # the bundled robot's illustrative motors and rotors

    def curve(rows):
        pts = sorted((float(r["speed_m_s"]), float(r[f"cot_{basis}"])) for r in rows
                     if r["walkable"] == "true" and r[f"cot_{basis}"] != "")
        return np.array([p[0] for p in pts]), np.array([p[1] for p in pts])

    xa, ya = curve(_rows(Path("e/library_energy.csv")))
    xb, yb = curve(_rows(Path("e/energy.csv")))
    assert len(xa) == 3 and len(xb) >= 5
    pareto = _rows(Path("e/pareto.csv"))
    compared = 0
    for row in pareto:
        v = float(row["speed_m_s"])
        a = np.interp(v, xa, ya) if xa[0] <= v <= xa[-1] else None
        b = np.interp(v, xb, yb) if xb[0] <= v <= xb[-1] else None
        assert (row["compared"] == "true") == (a is not None and b is not None)
        if a is not None and b is not None:
            compared += 1
            assert float(row[f"cot_{basis}_designed"]) == pytest.approx(a, rel=1e-12)
            assert float(row[f"cot_{basis}_thrust"]) == pytest.approx(b, rel=1e-12)
            assert row["cheapest"] == ("designed gait" if a < b else "gait + thrust")
        else:
            assert row["cheapest"] == ("designed gait" if b is None else "gait + thrust")
    assert compared >= 3
    head = doc["library"]["headline"]
    assert ("thrust pays" in head) or ("a gait designed for the speed is cheaper" in head)
    assert head in " ".join(r.stdout.split())  # the summary's last line
    assert Path("e/pareto.png").is_file() and Path("e/pareto.pdf").is_file()
    # the library gaits' CoT are limit-cycle's at zero thrust of the same gait file
    g = doc["library"]["gaits"][0]
    lc = tw.limit_cycle(tw.load_walker(None, g["file"]), thrust=[0.0])
    assert g["energy"]["cot"]["total"] == pytest.approx(lc.energy[0].cot()["total"], rel=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["missing", "result-folder", "other-sweep", "file"])
def test_library_that_is_not_a_library_is_one_line_exit_2_nothing_written(cli, tmp_path,
                                                                          monkeypatch, kind):
    monkeypatch.chdir(tmp_path)
    if kind == "result-folder":  # a command's result folder, not a sweep
        assert cli("limit-cycle", str(W5), str(W5T), "--thrust", "0", "--out", "lib",
                   "--formats", "csv", "-q").exit_code == 0  # (its figures play no part)
    elif kind == "other-sweep":
        for name in ("walker5.yaml", "walker5_thrust.yaml"):
            (tmp_path / name).write_bytes((DATA / name).read_bytes())
        Path("s.yaml").write_text("name: s\nstudy: limit-cycle\nrobot: walker5.yaml\ngait: "
                                  "walker5_thrust.yaml\ngrid:\n  thrust: {values: [0]}\n"
                                  "collect: [speed]\n")
        assert cli("sweep", "s.yaml", "--out", "lib", "--workers", "1", "-q").exit_code == 0
    elif kind == "file":
        Path("lib").write_text("x")
    before = sorted(p.name for p in tmp_path.iterdir())
    r = cli("energy", str(W5), str(W5T), "--thrust", "0", "--library", "lib", "--out", "e")
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: option --library: "), r.stderr
    expect = {"missing": "lib is not a folder", "file": "lib is not a folder",
              "result-folder": "lib is not a gait library: no sweep marker",
              "other-sweep": "lib is not a gait library: it holds a limit-cycle sweep"}[kind]
    assert expect in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


@pytest.mark.parametrize("value", ["nan", "0,nan", "-inf"])
def test_thrust_that_is_not_a_number_is_one_line_exit_2(cli, tmp_path, monkeypatch, value):
    monkeypatch.chdir(tmp_path)
    r = cli("energy", str(W5), str(W5T), "--thrust", value, "--out", "e")
    assert r.exit_code == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: option --thrust: "), r.stderr
    assert not Path("e").exists()


@pytest.mark.slow
def test_python_energy_is_the_document_the_command_writes(cli, tmp_path, monkeypatch):
    """tw.energy(...) renders the document the command writes; tw.energy stays the study
    once the energy models are imported (no subpackage shadows it)."""
    import thrustwalk_cli.energetics.orbit  # noqa: F401 - the import that used to shadow it
    from thrustwalk_cli.files.output import jsonable

    monkeypatch.chdir(tmp_path)
    walker = tw.load_walker(str(W5), str(W5T))
    res = tw.energy(walker, thrust=[0.0, -10.0])
    assert isinstance(res, tw.EnergyResult) and res.success
    assert set(res.tables()) == {"energy"} and set(res.figures()) == {"cot_speed", "power_step"}
    assert cli("energy", str(W5), str(W5T), "--thrust", "0,-10", "--out", "e",
               "-q").exit_code == 0
    written = json.loads(Path("e/energy.json").read_text())
    mine = json.loads(json.dumps(jsonable(res.document())))
    assert {k: v for k, v in written.items() if k not in ("provenance", "tables")} == mine


def test_no_public_name_is_a_subpackage_or_module_of_the_package():
    """A subpackage named like a public function becomes the package's attribute once
    imported and shadows it (tw.energy was shadowed by energy/ until it became energetics/)."""
    root = Path(tw.__file__).parent
    clash = [n for n in tw.__all__ if (root / n).is_dir() or (root / f"{n}.py").is_file()]
    assert not clash, clash


@pytest.mark.slow
def test_design_gait_reports_the_designed_gaits_cot(cli, tmp_path, monkeypatch):
    """The design-gait report's energy block: the CoT of the written gait, as limit-cycle
    computes it on that gait file at the design's thrust (an independent path)."""
    monkeypatch.chdir(tmp_path)
    r = cli("design-gait", "three_link", "--target-speed", "0.8", "--clearance", "0",
            "--starts", "1", "--max-iter", "80", "--formats", "none", "--out", "g", "--name", "w")
    assert r.exit_code == 0, r.output
    rep = json.loads(Path("g/w.report.json").read_text())
    en = rep["energy"]
    assert en["exists"] and en["thrust"] == [0.0, 0.0] and not en["missing"]
    r2 = cli("limit-cycle", "three_link", "g/w.yaml", "--thrust", "0", "--formats", "csv",
             "--out", "lc", "-q")
    assert r2.exit_code == 0, r2.output
    lc = json.loads(Path("lc/limit_cycles.json").read_text())["cycles"][0]
    e = lc["energy"]["per_step"]
    mgd = rep["energy"]["weight"] * lc["step_length"]
    assert en["cot"]["mechanical"] == pytest.approx(
        (e["legs_mechanical"] + e["thrust_mechanical"]) / mgd, rel=1e-9)
    assert en["cot"]["total"] == pytest.approx((e["legs_electrical"] + e["thrust_input"]) / mgd,
                                               rel=1e-9)
    row = next(ln for ln in r.stdout.splitlines() if "CoT total [1]" in ln)
    assert f"{en['cot']['total']:.5g}" in row


class _Point:
    """A stand-in for a walkable orbit with energies (what the Pareto comparison reads)."""

    walkable = True
    energy = True

    def __init__(self, speed: float, cot: float):
        self._v, self._c = speed, cot

    def speed(self) -> float:
        return self._v

    def cot(self) -> dict:
        return {"total": self._c}


def test_pareto_says_where_thrust_pays_and_when_the_ranges_do_not_overlap():
    """Hand-made curves: designed gaits at 0.6, 0.8, 1.0 m/s (CoT 0.2, 0.4, 1.0); the gait with
    thrust at 0.6, 0.9 m/s (CoT 0.3, 0.6): by hand, designed is cheaper at 0.6 (0.2 < 0.3) and
    0.8 (0.4 < 0.5), thrust at 0.9 (0.6 < 0.7); 1.0 only designed. Disjoint ranges: said."""
    from thrustwalk_cli.studies.energy import pareto_headline, pareto_rows

    designed = [_Point(0.6, 0.2), _Point(0.8, 0.4), _Point(1.0, 1.0)]
    pushed = [_Point(0.6, 0.3), _Point(0.9, 0.6)]
    rows = pareto_rows(designed, pushed, "total")
    assert [(r["speed"], r["cheapest"], r["compared"]) for r in rows] == [
        (0.6, "designed gait", True), (0.8, "designed gait", True),
        (0.9, "gait + thrust", True), (1.0, "designed gait", False)]
    assert rows[1]["gait + thrust"] == pytest.approx(0.5)
    assert rows[2]["designed gait"] == pytest.approx(0.7)
    head = pareto_headline(rows, designed, pushed, "total", "g")
    assert head == ("a gait designed for the speed is cheaper from 0.6 to 0.8 m/s (total CoT "
                    "0.3-0.5 with thrust vs 0.2-0.4 designed); thrust pays at 0.9 m/s (total "
                    "CoT 0.6 with thrust vs 0.7 designed); only the designed gaits reach 1 m/s")
    apart = [_Point(1.2, 0.5), _Point(1.4, 0.8)]
    rows = pareto_rows(designed, apart, "total")
    assert not any(r["compared"] for r in rows)
    assert pareto_headline(rows, designed, apart, "total", "g") == (
        "no common speed: the designed gaits walk at 0.6-1 m/s, g with thrust at 1.2-1.4 m/s "
        "(the ranges do not overlap)")


@pytest.mark.slow  # (this session's additions; CI runs every test)
def test_the_headline_speaks_of_walkable_gaits_only(_cache_dir):
    """walker5 (a user's robot): at -80 N its orbit lifts the stance foot (not walkable,
    independently: limit_cycle's verdict), so the energy headline's extreme is -40 N, the
    farthest walkable thrust, not -80 N; with no walkable value at all, the headline says the
    orbits are no gaits."""
    import thrustwalk_cli as tw

    data = Path(__file__).resolve().parent / "data"
    w = tw.load_walker(str(data / "walker5.yaml"), str(data / "walker5_thrust.yaml"))
    assert list(tw.limit_cycle(w, [0.0, -40.0, -80.0]).walkable) == [True, True, False]
    res = tw.energy(w, [0.0, -40.0, -80.0])
    assert res.headline.startswith("thrust -40 N") and "-80" not in res.headline
    assert "-80" not in res.reason
    bad = tw.energy(w, [-80.0, -100.0])
    assert not any(c.walkable for c in bad.cases)
    assert "no thrust value is walkable" in bad.headline
