"""`thrustwalk report` on a folder of every kind of result document (small runs, no figures;
the documents whose runs are slow are copied from tests/golden/): every key number and every
verdict beside it is the value at its JSON path (read here with a lookup of its own), and a
number of a case, run or strategy never appears without the verdict of that same item (a
speed of an orbit that lifts its foot was shown bare)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # a folder of every kind of result (about 4 s); CI runs it

DATA = Path(__file__).parent / "data"
GOLDEN = Path(__file__).parent / "golden"
ROBOT, GAIT = DATA / "walker5.yaml", DATA / "walker5_thrust.yaml"

# | quantity | value | `file#path` | verdict | `file#path` |  (the last two empty: no verdict)
ROW = re.compile(r"^\| (.+?) \| (.+?) \| `([^`#]+)#([^`]+)` \| (?:(.+?) \| `([^`#]+)#([^`]+)`"
                 r"|\s*\|\s*) \|$", re.M)
# list items whose numbers carry a verdict: (list, item index) at the start of a path
ITEM = re.compile(r"^(cycles|cases|runs|strategies|schedules)\.(\d+)\.")

SWEEP = """name: w5
study: limit-cycle
robot: three_link
gait: three_link_walk
settings:
  thruster: back
grid:
  thrust: {values: [0, -80]}
collect: [speed, walkable]
"""


def _get(doc, path: str):
    """The value at a dotted path (keys and list indices), written for this test."""
    for part in path.split("."):
        doc = doc[int(part)] if isinstance(doc, list) else doc[part]
    return doc


def _cell(text: str):
    return json.loads(text.replace("\\|", "|"))


@pytest.fixture(scope="module")
def folder(tmp_path_factory, _cache_dir) -> Path:
    """limit-cycle, energy, slope and a limit-cycle sweep of walker5 with walker5_thrust over
    0..-80 N (walkable down to about -50 N), a small rough-ground run of three_link, the golden
    robustness, stability, control and design-gait documents, mujoco when installed; then
    ``report``."""
    import typer.testing

    from thrustwalk_cli.cli import app

    runner = typer.testing.CliRunner()
    top = tmp_path_factory.mktemp("results")

    def run(*args) -> None:
        res = runner.invoke(app, [str(a) for a in args], catch_exceptions=False)
        assert res.exit_code == 0, res.output

    thrust = ["--thrust", "0,-40,-80"]
    run("limit-cycle", ROBOT, GAIT, *thrust, "--formats", "none", "--out", top / "lc", "-q")
    run("energy", ROBOT, GAIT, *thrust, "--formats", "none", "--out", top / "energy", "-q")
    run("slope", ROBOT, GAIT, "--slope", "0,0.1", "--thrust", "0,-80", "--formats", "none",
        "--out", top / "slope", "-q")
    (top / "w5.yaml").write_text(SWEEP)
    run("sweep", top / "w5.yaml", "--robot", ROBOT, "--gait", GAIT, "--workers", "1",
        "--formats", "none", "--out", top / "sweep", "-q")
    run("rough-ground", "three_link", "three_link_walk", "--sigma", "0.002,0.004",
        "--strategy", "none,constant:-20", "--trials", "2", "--cap", "5", "--mesh", "4",
        "--terrain-samples", "4", "--workers", "1", "--formats", "none",
        "--out", top / "rough", "-q")
    try:
        import mujoco  # noqa: F401

        run("mujoco", ROBOT, GAIT, "--steps", "2", "--thrust", "0,-60", "--formats", "none",
            "--no-video", "--out", top / "mujoco", "-q")  # the index reads the JSON only
    except ImportError:
        pass
    for golden, name in (("robustness_three", "robustness.json"),
                         ("stability_three", "stability.json"),
                         ("control_three", "control.json"),
                         ("design_gait_three", "g.report.json")):
        doc = json.loads((GOLDEN / f"{golden}.json").read_text())
        doc["provenance"] = {"command": f"tests/golden/{golden}.json"}
        (top / golden).mkdir()
        (top / golden / name).write_text(json.dumps(doc))
    run("report", top, "-q")
    return top


def _rows(folder: Path) -> list[tuple]:
    return ROW.findall((folder / "index.md").read_text())


def test_every_key_number_and_verdict_is_the_value_at_its_path(folder):
    rows = _rows(folder)
    lines = [ln for ln in (folder / "index.md").read_text().splitlines()
             if ln.startswith("| ") and not ln.startswith("| quantity")]
    assert len(rows) == len(lines) > 60  # every table row parsed
    for label, value, rel, path, verdict, vrel, vpath in rows:
        doc = json.loads((folder / rel).read_text())
        assert _cell(value) == _get(doc, path), (label, rel, path)
        if vpath:
            assert vrel == rel
            assert _cell(verdict) == _get(doc, vpath), (label, rel, vpath)
        # a number of one case / run / strategy comes with the verdict of that same item
        item = ITEM.match(path)
        if item and not rel.endswith("sweep.json"):
            assert vpath.startswith(item.group(0)), (label, rel, path, vpath)


def _speeds(folder: Path, rel: str, lst: str) -> dict[int, str | None]:
    """Item index -> the verdict path beside the speed of that item on the index (None: no
    verdict), from any table layout (a negative index counted from the end)."""
    n = len(json.loads((folder / rel).read_text())[lst])
    out = {}
    for line in (folder / "index.md").read_text().splitlines():
        m = re.match(rf"^\| .+? \| .+? \| `{re.escape(rel)}#{lst}\.(-?\d+)\.speed` \|(.*)$",
                     line)
        if m:
            v = re.search(r"`[^`#]+#([^`]+)`", m.group(2))
            out[int(m.group(1)) % n] = v.group(1) if v else None
    return out


def test_a_non_walkable_last_cycle_shows_its_verdict_and_the_last_walkable_one(folder):
    """walker5_thrust lifts its stance foot at -80 N (the limit-cycle verdict, read from the
    JSON here): its speed is shown only beside 'not walkable: ...'; the last walkable case's
    speed is shown too, beside its 'walkable' verdict. Same for energy's cases."""
    for rel, lst, vkey in (("lc/limit_cycles.json", "cycles", "verdict"),
                           ("energy/energy.json", "cases", "reason")):
        doc = json.loads((folder / rel).read_text())
        walk = [c["walkable"] for c in doc[lst]]
        assert walk[0] and not walk[-1], walk  # the premise of the test
        last, last_ok = len(walk) - 1, max(i for i, w in enumerate(walk) if w)
        speeds = _speeds(folder, rel, lst)
        assert speeds.get(last) == f"{lst}.{last}.{vkey}", (rel, speeds)
        assert doc[lst][last][vkey].startswith("not walkable")
        assert speeds.get(last_ok) == f"{lst}.{last_ok}.{vkey}", (rel, speeds)
        assert doc[lst][last_ok][vkey].startswith("walkable")


def test_the_headline_of_every_document_is_on_the_index(folder):
    paths = {(rel, path) for _, _, rel, path, *_ in _rows(folder)}
    docs = {rel: json.loads((folder / rel).read_text()) for rel, _ in paths}
    want = {
        "energy/energy.json": ["energy.basis"],
        "slope/slope.json": ["walkable_pairs", "steepest.uphill"],
        "sweep/sweep.json": ["counts.points", "counts.done", "counts.failed"],
        "stability_three/stability.json": ["verdict", "cases.0.spectral_radius"],
        "control_three/control.json": ["status", "summary.final_tracking_error"],
        "design_gait_three/g.report.json": ["feasible", "fixed_point.speed"],
        "rough/rough_ground.json": [f"headline.strategies.{k}.sigma" for k in range(2)],
        "robustness_three/robustness.json": [
            f"strategies.{k}.push.summary" for k in
            range(len(docs["robustness_three/robustness.json"]["strategies"]))],
    }
    if (folder / "mujoco").exists():
        want["mujoco/mujoco.json"] = ["runs.0.steps_completed", "runs.1.steps_completed"]
    for rel, ps in want.items():
        for p in ps:
            assert (rel, p) in paths, (rel, p)
    # the energy CoT shown is the basis the document compares
    basis = docs["energy/energy.json"]["energy"]["basis"]
    assert ("energy/energy.json", f"cases.0.energy.cot.{basis}") in paths
