"""``thrustwalk sweep``: sweep files and their errors, points from axes, robot parameters as
axes, resuming, failed points, the outputs, the gait library. The executors (local processes,
Dask) and killed runs: tests/test_sweep_cluster.py."""

from __future__ import annotations

import itertools
import json
import math
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from thrustwalk_cli.errors import InputError
from thrustwalk_cli.studies.documents import col

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((REPO / "sweeps").glob("*.yaml"))


def sweep_file(tmp_path: Path, text: str, name: str = "s.yaml") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


SMALL = """\
name: small
study: limit-cycle
robot: three_link
gait: three_link_walk
grid:
  robot.MT: {values: [8, 12], unit: kg}
  thrust: {start: 0, stop: -20, step: -10}
collect: [speed, zeta_star, walkable]
"""


# ------------------------------------------------------------------------------ files
@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_sweep_file_validates(path, _cache_dir):
    from thrustwalk_cli.studies.sweep import load_sweep

    sweep = load_sweep(path)
    assert len(sweep.tasks) == sweep.spec.count >= 2, path.name
    assert len({t.key for t in sweep.tasks}) == len(sweep.tasks), path.name


def test_the_examples_cover_a_limit_cycle_and_a_simulate_sweep():
    studies = {p.name: p.read_text() for p in EXAMPLES}
    lc = [n for n, t in studies.items() if "study: limit-cycle" in t and "robot.MT" in t
          and "thrust" in t]
    assert lc, "a limit-cycle sweep over thrust and torso mass"
    assert any("study: simulate" in t for t in studies.values())
    readme = (REPO / "README.md").read_text()
    for p in EXAMPLES:
        assert f"sweeps/{p.name}" in readme, f"{p.name} is not in the README"


BAD = [
    ("study: limit-cycle", "study: limit_cycle", "study: must be one of"),
    ("  thrust: {start: 0, stop: -20, step: -10}",
     "  thrus: {start: 0, stop: -20, step: -10}", "unknown axis 'thrus'"),
    ("  robot.MT: {values: [8, 12], unit: kg}", "  robot.MX: {values: [8, 12]}",
     "no parameter 'MX' in the robot three_link"),
    ("  robot.MT: {values: [8, 12], unit: kg}", "  gait.zz: {values: [8, 12]}",
     "no parameter 'zz' in the gait"),
    ("collect: [speed, zeta_star, walkable]", "collect: [speed, zeta_stra]",
     "unknown field 'zeta_stra'"),
    ("  thrust: {start: 0, stop: -20, step: -10}", "  thrust: {start: 0, stop: -20, step: 10}",
     "the step must be non-zero and point from start to stop"),
    ("  thrust: {start: 0, stop: -20, step: -10}", "  thrust: {values: [0, -2000]}",
     "-2000 N is outside the limits"),
    ("grid:\n", "settings: {thruster: hip_z}\ngrid:\n", "settings.thruster"),
    ("grid:\n", "settings: {steps: 5}\ngrid:\n", "unknown key 'steps'"),
    ("  robot.MT: {values: [8, 12], unit: kg}", "  robot.MT: {values: [8, 12], unit: kg}\n"
     "  thrust: [1, 2]", "duplicate key 'thrust'"),
    ("  robot.MT: {values: [8, 12], unit: kg}", "  robot.MT: {values: [8, 12], start: 1}",
     "give `values` or a range"),
    ("  thrust: {start: 0, stop: -20, step: -10}", "  thrust: {values: [0, -10], unit: kN}",
     "'thrust' is in N"),
    ("gait: three_link_walk", "gait: no_such_gait", "no such file and no bundled gait"),
]


@pytest.mark.parametrize("old, new, message", BAD, ids=[m[:30] for _, _, m in BAD])
def test_a_bad_sweep_file_is_refused_before_any_work(cli, tmp_path, old, new, message):
    assert old in SMALL, old
    path = sweep_file(tmp_path, SMALL.replace(old, new, 1))
    out = tmp_path / "out"
    res = cli("sweep", path, "--out", out, "-q")
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert any(message in ln for ln in lines), res.stderr
    assert all(ln.startswith("error: ") for ln in lines), res.stderr
    assert any(ln.startswith(f"error: {path}:") for ln in lines), res.stderr  # file:line
    assert "Traceback" not in res.stderr
    assert not out.exists(), "nothing is written for bad input"


def test_every_problem_is_reported_with_its_line(tmp_path):
    from thrustwalk_cli.studies.sweep import load_sweep

    text = SMALL.replace("collect: [speed, zeta_star, walkable]", "collect: [speed, nope]")
    text = text.replace("robot.MT: {values: [8, 12], unit: kg}", "robot.MX: {values: [8]}")
    path = sweep_file(tmp_path, text)
    with pytest.raises(InputError) as exc:
        load_sweep(path)
    got = sorted(str(p) for p in exc.value.problems)
    lines = text.splitlines()
    assert len(got) == 2, got
    mx = next(i for i, ln in enumerate(lines) if "robot.MX" in ln) + 1
    co = next(i for i, ln in enumerate(lines) if "collect" in ln) + 1
    assert any(g.startswith(f"{path}:{mx}: grid['robot.MX']: no parameter 'MX'") for g in got)
    assert any(g.startswith(f"{path}:{co}: collect[1]: unknown field 'nope'") for g in got)


def test_random_and_zip_problems(tmp_path):
    from thrustwalk_cli.files.sweep_file import load_sweep_file

    text = SMALL + textwrap.dedent("""\
        zip:
          robot.m: {values: [4, 5, 6], unit: kg}
          robot.MH: {values: [14, 15], unit: kg}
        random:
          samples: 4
          seed: 1
          axes:
            robot.L: {distribution: normal, mean: 0.5}
            robot.r: {distribution: log-uniform, low: 0, high: 1}
        """)
    with pytest.raises(InputError) as exc:
        load_sweep_file(sweep_file(tmp_path, text))
    msgs = " | ".join(str(p) for p in exc.value.problems)
    assert "zipped axes need equal lengths (robot.m: 3, robot.MH: 2)" in msgs
    assert "the normal distribution needs `std`" in msgs
    assert "must be > 0 for a log-uniform distribution" in msgs


# ------------------------------------------------------------------------------ points
def test_points_are_grid_times_zip_times_random_in_order(tmp_path, _cache_dir):
    """Against an independent enumeration: itertools.product, zip and the same seeded
    generator drawn axis after axis."""
    from thrustwalk_cli.studies.sweep import load_sweep

    text = textwrap.dedent("""\
        name: order
        study: limit-cycle
        robot: three_link
        grid:
          thrust: {values: [0, -10]}
          robot.MT: {start: 8, stop: 12, num: 3, unit: kg}
        zip:
          robot.m: {values: [4, 6], unit: kg}
          robot.MH: {values: [14, 16], unit: kg}
        random:
          samples: 3
          seed: 11
          axes:
            robot.L: {distribution: uniform, low: 0.4, high: 0.6, unit: m}
            robot.r: {distribution: log-uniform, low: 0.9, high: 1.1, unit: m}
            gait.af: {distribution: normal, mean: 0.27, std: 0.001, unit: rad}
        collect: [speed]
        """)
    sweep = load_sweep(sweep_file(tmp_path, text))
    rng = np.random.default_rng(11)
    L = rng.uniform(0.4, 0.6, 3)
    r = np.exp(rng.uniform(math.log(0.9), math.log(1.1), 3))
    af = rng.normal(0.27, 0.001, 3)
    expected = []
    for F, MT in itertools.product([0.0, -10.0], [8.0, 10.0, 12.0]):
        for m, MH in zip([4.0, 6.0], [14.0, 16.0]):
            for k in range(3):
                expected.append({"thrust": F, "robot.MT": MT, "robot.m": m, "robot.MH": MH,
                                 "robot.L": L[k], "robot.r": r[k], "gait.af": af[k]})
    assert sweep.points == expected
    assert sweep.spec.count == 2 * 3 * 2 * 3


def test_a_sweep_prints_as_one_short_line(tmp_path, _cache_dir):
    """In a notebook ``sweep`` shows its name, study, files, points and axes on one line,
    not the robot and gait files' text (the dataclass repr was 10 kB for an imported robot)."""
    import shutil

    import thrustwalk_cli as tw

    data = Path(__file__).parent / "data"
    for name in ("walker5.yaml", "walker5_walk.yaml"):
        shutil.copy(data / name, tmp_path / name)
    sweep = tw.load_sweep(sweep_file(tmp_path, """\
        name: w5
        study: limit-cycle
        robot: walker5.yaml
        gait: walker5_walk.yaml
        grid:
          thrust: {start: 0, stop: -20, step: -10}
        collect: [speed]
        """))
    text = repr(sweep)
    assert text.startswith("Sweep(name='w5', study='limit-cycle', ")
    assert "points=3" in text and "axes=['thrust']" in text and "walker5_walk.yaml" in text
    assert "\\n" not in text and len(text) < 300, text


def test_continuation_neighbours_form_chains_along_the_last_grid_axis():
    from thrustwalk_cli.description.sweep import Axis, SweepSpec
    from thrustwalk_cli.sweep.points import neighbours

    spec = SweepSpec("n", "design-gait", "r", "", None, None, (), (
        Axis("thrust", "N", "grid", (0.0, -10.0)),
        Axis("target_speed", "m/s", "grid", (0.5, 0.6, 0.7))), ("effort",))
    # points: (0, .5) (0, .6) (0, .7) (-10, .5) (-10, .6) (-10, .7)
    assert neighbours(spec) == [None, 0, 1, 0, 3, 4]


def test_keys_change_with_every_input_and_only_then(tmp_path, _cache_dir):
    from thrustwalk_cli.studies.sweep import load_sweep

    a = load_sweep(sweep_file(tmp_path, SMALL, "a.yaml"))
    b = load_sweep(sweep_file(tmp_path, SMALL.replace("name: small", "name: other")
                              + "description: same points\n", "b.yaml"))
    assert [t.key for t in a.tasks] == [t.key for t in b.tasks]
    assert a.identity == b.identity
    c = load_sweep(sweep_file(tmp_path, SMALL.replace("grid:", "settings: {thruster: torso_back}"
                                                      "\ngrid:"), "c.yaml"))
    assert not {t.key for t in a.tasks} & {t.key for t in c.tasks}
    robot = (REPO / "robots" / "three_link.yaml").read_text().replace("gravity: 9.8",
                                                                       "gravity: 9.81")
    (tmp_path / "r.yaml").write_text(robot)
    d = load_sweep(sweep_file(tmp_path, SMALL.replace("robot: three_link", "robot: r.yaml"),
                              "d.yaml"))
    assert not {t.key for t in a.tasks} & {t.key for t in d.tasks}


# ------------------------------------------------------------------ robot parameters
def test_a_robot_parameter_axis_equals_the_robot_file_with_the_number_edited(tmp_path,
                                                                            _cache_dir):
    """The torso mass MT as an axis gives the numbers of a robot file in which MT was edited
    by hand (to 1e-12): the point's robot is the file's description with the number
    substituted, however its model is compiled."""
    import thrustwalk_cli as tw

    sweep = tw.load_sweep(sweep_file(tmp_path, SMALL))
    res = tw.run_sweep(sweep, workers=1)
    assert res.success and res.done == len(sweep.tasks)
    text = (REPO / "robots" / "three_link.yaml").read_text()
    assert "  MT: 10.0" in text
    for MT in (8.0, 12.0):
        edited = tmp_path / f"three_link_MT{MT:g}.yaml"
        edited.write_text(text.replace("  MT: 10.0", f"  MT: {MT!r}"))
        walker = tw.load_walker(str(edited), "three_link_walk")
        lc = tw.limit_cycle(walker, thrust=[0.0, -10.0, -20.0])
        for F, cyc in zip(lc.thrust, lc.cycles):
            rec = next(r for t, r in zip(sweep.tasks, res.records)
                       if dict(t.values) == {"robot.MT": MT, "thrust": F})
            for name, ref in (("speed", cyc.speed), ("zeta_star", cyc.zeta_star)):
                got = rec["fields"][name]
                assert abs(got - ref) <= 1e-12 * abs(ref), (MT, F, name, got, ref)
            assert rec["document"]["zero_dynamics"]["delta_zero_sq"] == pytest.approx(
                walker.zd.delta_zero_sq, rel=1e-12, abs=0)


def test_gait_parameters_and_gains_reach_the_point(tmp_path, _cache_dir):
    """gait.af replaces the gait file's parameter; kp and kd the controller gains of a
    simulate point (compared with the gait file edited and with simulate called directly)."""
    import thrustwalk_cli as tw

    text = textwrap.dedent("""\
        name: gains
        study: simulate
        robot: three_link
        gait: three_link_walk
        settings: {steps: 2, thrust: -10, method: scipy, rtol: 1.0e-8, atol: 1.0e-8}
        zip:
          kp: {values: [100, 900]}
          kd: {values: [20, 60]}
        collect: [final_zeta_minus, max_abs_output]
        """)
    sweep = tw.load_sweep(sweep_file(tmp_path, text))
    res = tw.run_sweep(sweep, workers=1)
    walker = tw.load_walker("three_link", "three_link_walk")
    from dataclasses import replace

    for t, rec in zip(sweep.tasks, res.records):
        v = dict(t.values)
        g = replace(walker.gait, kp=v["kp"], kd=v["kd"])
        w = replace(walker, gait=g, zd=replace(walker.zd, gait=g))
        ref = tw.simulate(w, steps=2, thrust_model="constant", thrust=[-10.0],
                          method="scipy", rtol=1e-8, atol=1e-8).document()
        assert rec["document"]["settings"]["kp"] == v["kp"]
        assert rec["fields"]["final_zeta_minus"] == ref["runs"][0]["final_zeta_minus"]
    gait_text = (REPO / "gaits" / "three_link_walk.yaml").read_text()
    af = 0.2669090288119819  # 1e-6 rad more: the swing foot stays on the ground
    assert "  af: 0.2669080288119819 " in gait_text
    edited = tmp_path / "walk_af.yaml"
    edited.write_text(gait_text.replace("  af: 0.2669080288119819 ", f"  af: {af!r} ")
                      .replace("robot: three_link", f"robot: {REPO / 'robots/three_link.yaml'}"))
    text2 = SMALL.replace("  robot.MT: {values: [8, 12], unit: kg}\n",
                          f"  gait.af: {{values: [{af!r}], unit: rad}}\n")
    sweep2 = tw.load_sweep(sweep_file(tmp_path, text2, "af.yaml"))
    res2 = tw.run_sweep(sweep2, workers=1)
    lc = tw.limit_cycle(tw.load_walker("three_link", str(edited)), thrust=[0.0, -10.0, -20.0])
    assert [r["fields"]["zeta_star"] for r in res2.records] == [c.zeta_star for c in lc.cycles]


# --------------------------------------------------------------------- running, outputs
@pytest.mark.slow
def test_outputs_of_a_sweep(cli, tmp_path, _cache_dir):
    path = sweep_file(tmp_path, SMALL)
    out = tmp_path / "out"
    res = cli("sweep", path, "--out", out, "--workers", "1")
    assert res.exit_code == 0, res.output + res.stderr
    table = pd.read_csv(out / "results.csv")
    assert list(table.columns) == ["point", "key", "status", "robot_MT_kg", "thrust_N",
                                   col("speed", "m/s"), col("zeta_star", "kg^2 m^4/s^2"),
                                   "walkable", "reason"]
    assert len(table) == 6 and (table["status"] == "ok").all()
    assert list(table["robot_MT_kg"]) == [8, 8, 8, 12, 12, 12]
    assert list(table["thrust_N"]) == [0, -10, -20] * 2
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["schema_version"] == 1 and doc["units"]["thrust"] == "N"
    assert doc["units"]["robot.MT"] == "kg" and doc["units"]["zeta_star"] == "kg^2 m^4/s^2"
    assert doc["counts"] == {"points": 6, "done": 6, "failed": 0, "answered_no": 0,
                             "skipped": 0, "computed": 6, "not_run": 0, "resubmitted": 0}
    assert doc["executor"] == {"kind": "in-process", "workers": 1}
    assert doc["provenance"]["sweep"]["file"] == str(path)
    assert doc["wall_time"] > 0
    keys = sorted(p.stem for p in (out / "points").glob("*.json"))
    assert keys == sorted(table["key"])
    point = json.loads((out / "points" / f"{table['key'][4]}.json").read_text())
    assert point["values"] == {"robot.MT": 12.0, "thrust": -10.0}
    assert point["document"]["cycles"][0]["speed"] == table[col("speed", "m/s")][4]
    assert (out / "heatmap_robot-MT_thrust.png").read_bytes()[:4] == b"\x89PNG"
    assert (out / "heatmap_robot-MT_thrust.pdf").is_file()
    assert (out / ".thrustwalk-sweep.json").is_file()
    # rerun: every point skipped, the same table
    before = (out / "results.csv").read_bytes()
    res = cli("sweep", path, "--out", out, "-q", "--formats", "csv")  # figures: above
    assert res.exit_code == 0 and res.stdout == "", res.output
    assert (out / "results.csv").read_bytes() == before
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["counts"]["skipped"] == 6 and doc["counts"]["computed"] == 0


def test_a_failed_point_is_recorded_and_the_sweep_goes_on(cli, tmp_path, _cache_dir):
    path = sweep_file(tmp_path, SMALL.replace("values: [8, 12]", "values: [8, -1]"))
    out = tmp_path / "out"
    res = cli("sweep", path, "--out", out, "--workers", "1", "-q")
    assert res.exit_code == 0, res.stderr
    assert "3 point(s) failed" in res.stderr
    table = pd.read_csv(out / "results.csv")
    bad = table[table["robot_MT_kg"] == -1]
    assert list(bad["status"]) == ["failed"] * 3
    # (commas in CSV text become ';')
    assert all("three_link.yaml:28: links[1].point_masses[1].mass: must be > 0; got -1" in r
               for r in bad["reason"])
    assert bad[col("speed", "m/s")].isna().all()
    assert (table[table["robot_MT_kg"] == 8]["status"] == "ok").all()
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["counts"]["failed"] == 3 and len(doc["failures"]) == 3
    # a failed point is a result: the rerun (no figures: drawn above) does not compute it again
    res = cli("sweep", path, "--out", out, "--workers", "1", "-q", "--formats", "csv")
    assert json.loads((out / "sweep.json").read_text())["counts"]["computed"] == 0


@pytest.mark.slow
def test_the_sweep_folder_belongs_to_its_sweep(cli, tmp_path, _cache_dir):
    path = sweep_file(tmp_path, SMALL.replace("values: [8, 12]", "values: [8]"))
    out = tmp_path / "out"
    assert cli("sweep", path, "--out", out, "-q", "--workers", "1", "--formats",
               "csv").exit_code == 0  # (a sweep's figures: test_outputs_of_a_sweep)
    other = sweep_file(tmp_path, SMALL.replace("values: [8, 12]", "values: [9]"), "o.yaml")
    res = cli("sweep", other, "--out", out, "-q")
    assert res.exit_code == 2
    assert "holds another sweep ('small' from" in res.stderr
    assert res.stderr.startswith("error: option --out: ")
    res = cli("limit-cycle", "--thrust", "0", "--out", out, "-q")
    assert res.exit_code == 2 and "is a sweep's folder" in res.stderr, res.stderr
    assert (out / "results.csv").is_file() and not (out / "limit_cycles.json").exists()
    lc = tmp_path / "lc"
    assert cli("limit-cycle", "--thrust", "0", "--out", lc, "-q", "--formats",
               "csv").exit_code == 0
    res = cli("sweep", path, "--out", lc, "-q")
    assert res.exit_code == 2 and "is the result folder of a command" in res.stderr
    res = cli("sweep", path, "--out", tmp_path / "s.yaml", "-q")
    assert res.exit_code == 2 and "is a file, not a folder" in res.stderr


def test_a_half_written_point_file_is_never_read(tmp_path, _cache_dir):
    """A killed run leaves at most temporaries (removed) and never a truncated point file;
    a corrupted one (edited by hand) is computed again, with a warning."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.files.output import SweepFolder

    sweep = tw.load_sweep(sweep_file(tmp_path, SMALL))
    out = tmp_path / "out"
    marker = {"identity": sweep.identity, "sweep": "small", "file": "s.yaml", "points": 6}
    folder = SweepFolder(out, marker)
    res = tw.run_sweep(sweep, workers=1, on_point=folder.write_point)
    folder.close()
    (out / "points" / ".abc.json.x1.tmp").write_text('{"key": ')
    first = folder.point_path(sweep.tasks[0].key)
    first.write_text(first.read_text()[:50])
    folder = SweepFolder(out, marker)
    got = folder.finished([t.key for t in sweep.tasks])
    assert not list((out / "points").glob(".*.tmp"))
    assert set(got) == {t.key for t in sweep.tasks[1:]}
    assert len(folder.notes) == 1 and "runs again" in folder.notes[0]
    rerun = tw.run_sweep(sweep, workers=1, finished=got, on_point=folder.write_point)
    folder.close()
    assert rerun.counts.ok == 1 and rerun.counts.skipped == 5
    assert [r["fields"] for r in rerun.records] == [r["fields"] for r in res.records]


@pytest.mark.slow
def test_resume_verifies_every_point_file(cli, tmp_path, _cache_dir, monkeypatch):
    """Issue 30 item 11: a folder in place of a point file, a truncated point file and a
    hand-edited one (same key, another value, the JSON still valid) are each recomputed on
    resume, with a warning naming the point; the folder is moved aside, not deleted; the
    resumed records equal those of the first run (each point computed again from scratch),
    and nothing stops the resume."""
    monkeypatch.chdir(tmp_path)
    path = sweep_file(tmp_path, SMALL)
    out = tmp_path / "out"
    assert cli("sweep", path, "--out", out, "--workers", "1", "-q", "--formats",
               "csv").exit_code == 0  # (a sweep's figures: test_outputs_of_a_sweep)
    table = pd.read_csv(out / "results.csv")
    keys = list(table["key"])
    first = {k: json.loads((out / "points" / f"{k}.json").read_text()) for k in keys}
    folder_point, truncated, edited = (out / "points" / f"{keys[i]}.json" for i in (1, 3, 4))
    folder_point.unlink()
    (folder_point / "inside").mkdir(parents=True)
    truncated.write_text(truncated.read_text()[:-40])
    rec = json.loads(edited.read_text())
    rec["fields"]["zeta_star"] *= 1.5  # same key, another value: a hand edit
    edited.write_text(json.dumps(rec, indent=2))
    res = cli("sweep", path, "--out", out, "--workers", "1", "-q", "--formats", "csv")
    assert res.exit_code == 0, res.stderr
    lines = res.stderr.splitlines()
    assert len(lines) == 3, lines
    assert lines[0].startswith("warning: point 1: ") and "is a folder" in lines[0]
    assert lines[1].startswith("warning: point 3: ") and "truncated" in lines[1]
    assert lines[2].startswith("warning: point 4: ") and "checksum" in lines[2]
    assert all(line.endswith("the point runs again") for line in lines)
    assert (out / "points" / f"{keys[1]}.json.moved-aside" / "inside").is_dir()
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["counts"]["computed"] == 3 and doc["counts"]["skipped"] == 3
    again = {k: json.loads((out / "points" / f"{k}.json").read_text()) for k in keys}
    strip = lambda r: {k: v for k, v in r.items() if k not in ("seconds", "sha256")}  # noqa
    assert [strip(again[k]) for k in keys] == [strip(first[k]) for k in keys]
    assert pd.read_csv(out / "results.csv").equals(table)


def test_a_lost_task_is_never_recorded_and_runs_again(tmp_path):
    """Issue 30 item 3: a point whose task is lost every time (it kills its worker process)
    gets no record (never a failed point) and the run says which; a later run tries it
    again."""
    from thrustwalk_cli.sweep.executors import LocalProcesses
    from thrustwalk_cli.sweep.runner import run_tasks

    tasks = _toy_tasks(8)
    got: dict[str, dict] = {}
    ex = LocalProcesses(2)
    try:
        counts = run_tasks(tasks, _always_crash_5, ex, got, lambda r: None)
    finally:
        ex.close()
    assert counts.lost == [5] and "lost 3 times" in counts.lost_reason
    assert sorted(got) == sorted(t.key for t in tasks if t.index != 5)
    assert [got[t.key]["status"] for t in tasks if t.index != 5] == \
        ["ok", "ok", "ok", "failed", "ok", "ok", "ok"]  # point 3 raises: a failed record
    again: dict[str, dict] = dict(got)
    counts = run_tasks(tasks, _toy_point, ex := LocalProcesses(2), again, lambda r: None)
    ex.close()
    assert counts.ok == 1 and counts.skipped == 7 and again["toy-key-005"]["fields"] == \
        {"y": 25.0}


def _always_crash_5(task) -> dict:
    import os

    if dict(task.values)["x"] == 5.0:
        os._exit(1)
    return _toy_point(task)


def test_a_second_run_into_a_running_sweep_is_refused(tmp_path, _cache_dir):
    import thrustwalk_cli as tw
    from thrustwalk_cli.files.output import SweepFolder

    sweep = tw.load_sweep(sweep_file(tmp_path, SMALL))
    marker = {"identity": sweep.identity, "sweep": "small", "file": "s.yaml", "points": 6}
    first = SweepFolder(tmp_path / "out", marker)
    try:
        with pytest.raises(InputError, match="another thrustwalk sweep is running"):
            SweepFolder(tmp_path / "out", marker)
    finally:
        first.close()
    SweepFolder(tmp_path / "out", marker).close()  # released


def test_workers_and_scheduler_are_checked(cli, tmp_path):
    path = sweep_file(tmp_path, SMALL)
    res = cli("sweep", path, "--out", tmp_path / "o", "--workers", "2", "--scheduler",
              "tcp://127.0.0.1:1")
    assert res.exit_code == 2 and "options --workers/--scheduler: give one" in res.stderr
    res = cli("sweep", path, "--out", tmp_path / "o", "--scheduler", "127.0.0.1:8786")
    assert res.exit_code == 2 and "expected tcp://HOST:PORT" in res.stderr
    res = cli("sweep", path, "--out", tmp_path / "o", "--workers", "0")
    assert res.exit_code == 2 and "option --workers: must be 1..1024" in res.stderr
    assert not (tmp_path / "o").exists()  # checked before the folder exists


def test_a_schedule_axis_equals_the_gait_with_that_schedule(tmp_path, _cache_dir):
    """schedule.j sets interval j's thrust: the limit cycle equals the gait file with that
    thrust: section."""
    import thrustwalk_cli as tw

    text = textwrap.dedent("""\
        name: sched
        study: limit-cycle
        robot: three_link
        settings:
          schedule: {knots: [0, 0.5, 1], values: [0, 0]}
        zip:
          schedule.1: {values: [-10, -20]}
          schedule.2: {values: [5, 0]}
        collect: [zeta_star, speed]
        """)
    sweep = tw.load_sweep(sweep_file(tmp_path, text))
    res = tw.run_sweep(sweep, workers=1)
    gait = (REPO / "gaits" / "three_link_walk.yaml").read_text().replace(
        "robot: three_link", f"robot: {REPO / 'robots/three_link.yaml'}")
    for rec, (a, b) in zip(res.records, [(-10, 5), (-20, 0)]):
        g = tmp_path / f"g{a}.yaml"
        g.write_text(gait + f"thrust: {{knots: [0, 0.5, 1], values: {{hip_x: [{a}, {b}]}}}}\n")
        lc = tw.limit_cycle(tw.load_walker(None, str(g)))
        assert lc.source == "gait"
        assert rec["fields"]["zeta_star"] == lc.cycles[0].zeta_star


@pytest.mark.slow
def test_a_gait_library_with_continuation(cli, tmp_path, _cache_dir):
    """A design-gait sweep over target speed: one gait file per feasible design, library.csv,
    the atlas; each written gait, loaded back, has the fixed point and speed in the table;
    each point after the first is keyed with (and started from) its neighbour."""
    import thrustwalk_cli as tw

    text = textwrap.dedent("""\
        name: lib
        study: design-gait
        robot: three_link
        settings: {clearance: 0, max_iter: 80}
        grid:
          target_speed: {values: [0.8, 0.85]}
        collect: [effort, delta_zero_sq, feasible]
        """)
    path = sweep_file(tmp_path, text)
    sweep = tw.load_sweep(path)
    assert [t.after for t in sweep.tasks] == [None, sweep.tasks[0].key]
    out = tmp_path / "out"
    res = cli("sweep", path, "--out", out, "-q", "--workers", "2")
    assert res.exit_code == 0, res.stderr
    lib = pd.read_csv(out / "library.csv")
    assert len(lib) == 2 and lib["feasible"].all(), lib
    assert list(lib["gait"]) == ["lib_0000", "lib_0001"]
    for _, row in lib.iterrows():
        walker = tw.load_walker(None, str(out / row["file"]))
        assert walker.gait.name == row["gait"]
        lc = tw.limit_cycle(walker, thrust=[0.0]).cycles[0]
        assert lc.zeta_star == pytest.approx(row[col("zeta_star", "kg^2 m^4/s^2")], rel=1e-8)
        assert lc.speed == pytest.approx(row["target_speed_m_s"], rel=2e-3)
    assert (out / "atlas.png").is_file() and (out / "atlas.pdf").is_file()
    points = [json.loads((out / "points" / f"{t.key[:20]}.json").read_text())
              for t in sweep.tasks]
    assert points[0]["next_start"]["zeta_minus"] == pytest.approx(lib.iloc[0][col(
        "zeta_star", "kg^2 m^4/s^2")])


def test_the_registry_and_the_parameter_tables_name_the_same_studies_and_are_documented():
    from thrustwalk_cli.files.sweep_file import STUDY_PARAMETERS, WITHOUT_GAIT
    from thrustwalk_cli.studies.sweep_studies import STUDIES

    assert list(STUDIES) == list(STUDY_PARAMETERS)
    assert {n for n, s in STUDIES.items() if not s.uses_gait} == set(WITHOUT_GAIT)
    files = (REPO / "docs" / "files.md").read_text()
    commands = (REPO / "docs" / "commands.md").read_text()
    for name, study in STUDIES.items():
        section = files.split(f"`settings` of a **{name}** sweep", 1)[1].split("<!--", 1)[0]
        for f in study.fields:
            assert f"`{f}`" in section, (name, f)
        assert f"`{name}`" in commands
    for key in ("kill -9", "dask scheduler", "dask worker", "dask-jobqueue", "SLURMCluster",
                "--tls-ca-file", "tls://", "127.0.0.1", ".thrustwalk-sweep.json"):
        assert key in commands, key


def test_heat_map_cells_are_centred_on_the_values():
    """Cell edges half-way between neighbouring values, half a spacing beyond the ends."""
    from thrustwalk_cli.plots.sweep import _edges

    assert _edges(np.array([0.0, 1.0, 3.0])).tolist() == [-0.5, 0.5, 2.0, 4.0]
    assert _edges(np.array([2.0])).tolist() == [1.5, 2.5]


def test_a_compiled_simulate_sweep_reuses_the_cached_kernel(tmp_path, _cache_dir):
    """Preparing a sweep makes sure the kernel is compiled once; it must load the cached
    kernel, not rebuild it (the entry's file and numba's machine code stay untouched)."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.simulation.stepper import kernel, kernel_status

    kernel()  # compiled (or loaded) before the sweep
    entry = Path(kernel_status()["entry"])
    stamps = {p: p.stat().st_mtime_ns
              for p in [entry, *entry.parent.glob(f"__pycache__/{entry.stem}.*")]}
    assert len(stamps) > 1
    text = textwrap.dedent("""\
        name: compiled
        study: simulate
        robot: three_link
        gait: three_link_walk
        settings: {steps: 2, method: compiled}
        grid:
          thrust: {values: [0, -10]}
        collect: [final_zeta_minus]
        """)
    res = tw.run_sweep(tw.load_sweep(sweep_file(tmp_path, text)), workers=1)
    assert all(r["status"] == "ok" for r in res.records)
    assert kernel_status()["cached"]
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps


# ------------------------------------------------------------------------- the runner
def _toy_tasks(n: int, folder: str = "", study: str = "toy") -> list:
    """``n`` synthetic points (the runner does not look inside them): values x = index."""
    from thrustwalk_cli.sweep.tasks import PointTask

    return [PointTask(i, f"{study}-key-{i:03d}", study, (("x", float(i)),),
                      (("folder", folder),), "robot.yaml", "", None, None) for i in range(n)]


def _toy_point(task) -> dict:
    """A point's record computed from its value alone (x^2); point 3 raises; with a folder
    setting, point 5 kills its worker process the first time it runs (a marker file)."""
    import os

    x = dict(task.values)["x"]
    folder = dict(task.settings)["folder"]
    if x == 5.0 and folder and not os.path.exists(os.path.join(folder, "crashed")):
        open(os.path.join(folder, "crashed"), "w").close()
        os._exit(1)
    if x == 3.0:
        raise ValueError("point 3 cannot be computed")
    return {"key": task.key, "index": task.index, "status": "ok", "reason": "",
            "fields": {"y": x * x}, "document": {"x": x}, "next_start": None, "seconds": 0.0}


def test_chunk_size_rule():
    """ceil(points / (8 workers)), clipped to [1, most]."""
    from thrustwalk_cli.sweep.runner import chunk_size

    assert chunk_size(1953, 2) == 32 and chunk_size(1953, 2, most=200) == 123
    assert chunk_size(100, 2) == 7 and chunk_size(100, 1) == 13
    assert chunk_size(10, 4) == 1 and chunk_size(0, 2) == 1 and chunk_size(5, 2, most=0) == 1


@pytest.mark.parametrize("local", [False, True])
def test_points_in_chunks_get_the_records_of_one_point_per_task(local, counting):
    """13 points, one raising: in chunks of 4 (in this process, or on 2 local worker
    processes) every point is handed over once with the record it gets as a task of its own;
    the raising point's record is failed with its reason, its chunk's other points are ok."""
    from thrustwalk_cli.sweep.executors import InProcess, LocalProcesses
    from thrustwalk_cli.sweep.runner import run_tasks

    tasks = _toy_tasks(13)
    single: dict[str, dict] = {}
    ex = counting(InProcess())
    run_tasks(tasks, _toy_point, ex, single, lambda r: None)
    assert ex.submitted == 13
    assert single["toy-key-003"]["status"] == "failed"
    assert single["toy-key-003"]["reason"] == ("the task could not run (ValueError: point 3 "
                                               "cannot be computed)")
    for chunk in (4, {"toy": 4}):
        ex = counting(LocalProcesses(2) if local else InProcess())
        seen: list[dict] = []
        got: dict[str, dict] = {}
        try:
            counts = run_tasks(tasks, _toy_point, ex, got, seen.append, chunk=chunk)
        finally:
            ex.close()
        assert ex.submitted == 4  # 4 + 4 + 4 + 1
        assert sorted(r["key"] for r in seen) == [t.key for t in tasks]
        assert got == single and counts.ok == 12 and counts.failed == 1
    # a study not named in the mapping runs one point per task
    ex = counting(InProcess())
    run_tasks(tasks, _toy_point, ex, {}, lambda r: None, chunk={"other": 4})
    assert ex.submitted == 13


def test_finished_points_are_left_out_of_the_chunks():
    """A resumed run chunks only the points without a record: none is computed twice."""
    from thrustwalk_cli.sweep.executors import InProcess
    from thrustwalk_cli.sweep.runner import run_tasks

    tasks = _toy_tasks(10)
    done: dict[str, dict] = {}
    run_tasks(tasks, _toy_point, InProcess(), done, lambda r: None)
    partial = {k: v for k, v in done.items() if int(k[-3:]) % 3 == 0}
    seen: list[str] = []
    counts = run_tasks(tasks, _toy_point, InProcess(), partial, lambda r: seen.append(r["key"]),
                       chunk=3)
    assert sorted(seen) == sorted(set(done) - {t.key for t in tasks if t.index % 3 == 0})
    assert counts.skipped == 4 and partial == done


def test_a_chunk_lost_with_its_worker_runs_again_point_by_point(tmp_path):
    """Point 5 kills its worker process once: its chunk (and every task in flight with the
    broken pool) is submitted again point by point; every point is recorded once, as in a run
    without the crash."""
    from thrustwalk_cli.sweep.executors import InProcess, LocalProcesses
    from thrustwalk_cli.sweep.runner import run_tasks

    (tmp_path / "ref").mkdir()
    (tmp_path / "ref" / "crashed").touch()  # the reference never crashes
    ref: dict[str, dict] = {}
    run_tasks(_toy_tasks(20, str(tmp_path / "ref")), _toy_point, InProcess(), ref,
              lambda r: None)
    ex = LocalProcesses(2)
    got: dict[str, dict] = {}
    seen: list[str] = []
    try:
        counts = run_tasks(_toy_tasks(20, str(tmp_path)), _toy_point, ex, got,
                           lambda r: seen.append(r["key"]), chunk=4)
    finally:
        ex.close()
    assert (tmp_path / "crashed").exists() and ex.restarts >= 1
    assert counts.resubmitted >= 4  # at least the crashed chunk's 4 points
    assert sorted(seen) == sorted(ref) and got == ref


def _slow_or_crash(task) -> dict:
    """Point 0 takes 1 s; point 1 kills its worker process the first time it runs (a marker
    file in the folder setting); the others are :func:`_toy_point`."""
    import os

    x = dict(task.values)["x"]
    marker = os.path.join(dict(task.settings)["folder"], "crashed")
    if x == 0.0:
        time.sleep(1.0)
    if x == 1.0 and not os.path.exists(marker):
        open(marker, "w").close()
        time.sleep(0.2)  # point 0 is running on the other worker by now
        os._exit(1)
    return _toy_point(task)


def test_a_dying_worker_loses_only_its_own_task(tmp_path):
    """Two local workers: point 1 kills its worker while point 0 runs on the other. Only
    point 1 runs again (before: the whole pool was broken and restarted, and point 0, in
    flight on a worker that did not die, was lost and computed again too)."""
    from thrustwalk_cli.sweep.executors import LocalProcesses
    from thrustwalk_cli.sweep.runner import run_tasks

    ex = LocalProcesses(2)
    got: dict[str, dict] = {}
    try:
        counts = run_tasks(_toy_tasks(2, str(tmp_path)), _slow_or_crash, ex, got,
                           lambda r: None)
    finally:
        ex.close()
    assert (tmp_path / "crashed").exists()
    assert counts.resubmitted == 1 and ex.restarts == 1 and counts.ok == 2


def _toy_slow(task) -> dict:
    time.sleep(0.005)
    return _toy_point(task)


@pytest.mark.slow
def test_workers_killed_from_outside_again_and_again_never_hang(tmp_path):
    """For 2 s every worker process of the pool is killed as soon as it appears, while the
    runner submits and resubmits: the run ends (within 120 s, else it hung) either with
    every point recorded or lost (never a failed record for a lost worker), or with the
    one error that the workers die as they start. Then the same executor is closed at
    once. (The standard library's process pool could hang here: a submit racing its
    manager thread's clean-up of a broken pool.)"""
    import threading

    import psutil

    from thrustwalk_cli.errors import ComputationError
    from thrustwalk_cli.sweep.executors import LocalProcesses
    from thrustwalk_cli.sweep.runner import run_tasks

    me = psutil.Process()
    before = {c.pid for c in me.children(recursive=True)}
    outcome: dict = {}
    stop = threading.Event()

    def kill() -> None:
        t0 = time.monotonic()
        while not stop.is_set() and time.monotonic() - t0 < 2.0:
            for c in me.children(recursive=True):
                if c.pid not in before:
                    try:
                        c.kill()
                        outcome["killed"] = outcome.get("killed", 0) + 1
                    except psutil.NoSuchProcess:
                        pass
            time.sleep(0.002)

    def run() -> None:
        tasks = _toy_tasks(400)
        got: dict[str, dict] = {}
        try:
            ex = LocalProcesses(2)
        except ComputationError as exc:
            outcome["error"] = str(exc)
            return
        try:
            outcome["counts"] = run_tasks(tasks, _toy_slow, ex, got, lambda r: None, chunk=4)
        except ComputationError as exc:
            outcome["error"] = str(exc)
        finally:
            ex.close()
            outcome["records"] = got

    killer = threading.Thread(target=kill, daemon=True)
    runner = threading.Thread(target=run, daemon=True)
    killer.start()
    runner.start()
    runner.join(120)
    stop.set()
    killer.join(10)
    assert not runner.is_alive(), "the run hung"
    assert outcome.get("killed"), "no worker process was killed"
    if "error" in outcome:
        assert "died as they started" in outcome["error"], outcome["error"]
    else:
        counts, got = outcome["counts"], outcome["records"]
        assert len(got) + len(counts.lost) == 400
        assert all(r["status"] == "ok" for k, r in got.items() if k != "toy-key-003")


@pytest.mark.slow
def test_push_trial_sweep_file_runs_in_chunks_with_the_same_records(counting):
    """``thrustwalk sweep`` of push trials shares engine tasks (trial_chunk) and gives every
    point the record it gets with one point per task."""
    from thrustwalk_cli.studies.sweep import load_sweep, run_sweep
    from thrustwalk_cli.sweep.executors import InProcess

    sweep = load_sweep(Path(__file__).resolve().parents[1] / "sweeps"
                       / "push_trials_thrust.yaml")
    one = counting(InProcess())
    ref = run_sweep(sweep, executor=one, chunk=1)
    auto = counting(InProcess())
    got = run_sweep(sweep, executor=auto)
    n = len(sweep.tasks)
    assert one.submitted == n and auto.submitted < n / 4  # ceil(64 / 8) = 8 trials a task

    def strip(rec):
        return {k: v for k, v in rec.items() if k != "seconds"}

    assert [strip(r) for r in got.records] == [strip(r) for r in ref.records]
    assert {r["fields"]["outcome"] for r in got.records} >= {"recovered", "lifted"}


@pytest.mark.slow  # (this session's additions; CI runs every test)
def test_a_point_whose_study_says_no_gives_its_reason(cli, tmp_path, monkeypatch):
    """A limit-cycle sweep of walker5 (a user's robot, its files beside the sweep file, run
    from that folder): the point at +60 N has no orbit and the one at -80 N leaves the
    contact cone (independently: tw.limit_cycle on the same walker says so); both are
    computed (`ok`), and results.csv's `reason` says why each is not walkable, where a
    walkable point's is empty."""
    import thrustwalk_cli as tw

    data = Path(__file__).resolve().parent / "data"
    for name in ("walker5.yaml", "walker5_thrust.yaml"):
        (tmp_path / name).write_bytes((data / name).read_bytes())
    (tmp_path / "s.yaml").write_text(
        "name: s\nstudy: limit-cycle\nrobot: walker5.yaml\ngait: walker5_thrust.yaml\n"
        "settings:\n  thruster: back\ngrid:\n  thrust: {values: [0, -80, 60]}\n"
        "collect: [walkable]\n")
    monkeypatch.chdir(tmp_path)
    res = cli("sweep", "s.yaml", "--workers", "1", "--out", "o", "--formats", "csv", "-q")
    assert res.exit_code == 0, res.output
    rows = pd.read_csv(tmp_path / "o" / "results.csv").set_index("thrust_N")
    ref = tw.limit_cycle(tw.load_walker("walker5.yaml", "walker5_thrust.yaml"),
                         [0.0, -80.0, 60.0])
    assert list(ref.walkable) == [True, False, False] and not ref.cycles[2].exists
    assert (rows["status"] == "ok").all() and pd.isna(rows.loc[0.0, "reason"])
    assert "contact infeasible" in rows.loc[-80.0, "reason"]
    assert "no periodic orbit" in rows.loc[60.0, "reason"]
    doc = json.loads((tmp_path / "o" / "sweep.json").read_text())
    assert doc["counts"]["answered_no"] == 2 and "2 answered no" in doc["reason"]


def test_a_decimal_range_gives_its_decimal_values(cli, tmp_path, monkeypatch):
    """``--slope``/``--thrust`` ranges and a sweep file's start/stop/step give the decimal
    values they name (independent: Python's float of the decimal text), so that
    ``-0.04:0.02:0.02`` contains a slope of exactly 0 (level ground, SPEC 14), not 3.5e-18,
    and 0.02 rather than 0.019999999999999997; a step that is no short decimal keeps the sums."""
    from thrustwalk_cli.commands.common import parse_values
    from thrustwalk_cli.files.sweep_file import load_sweep_file

    assert parse_values("-0.04:0.02:0.02", "--slope") == [-0.04, -0.02, 0.0, 0.02]
    assert parse_values("0.1:0.35:0.1", "--thrust") == [0.1, 0.2, 0.3]
    third = 1.0 / 3.0
    assert parse_values(f"0:1:{third!r}", "--k") == [i * third for i in range(4)]
    data = Path(__file__).resolve().parent / "data"
    for name in ("walker5.yaml", "walker5_thrust.yaml"):
        (tmp_path / name).write_bytes((data / name).read_bytes())
    (tmp_path / "s.yaml").write_text(
        "name: s\nstudy: limit-cycle\nrobot: walker5.yaml\ngait: walker5_thrust.yaml\n"
        "grid:\n  slope: {start: -0.04, stop: 0.02, step: 0.02}\ncollect: [speed]\n")
    spec, _ = load_sweep_file(tmp_path / "s.yaml")
    (axis,) = spec.axes
    assert list(axis.values) == [float(t) for t in ("-0.04", "-0.02", "0", "0.02")]


@pytest.mark.slow  # (this session's additions; CI runs every test)
def test_an_infeasible_design_point_gives_its_reason(cli, tmp_path, monkeypatch):
    """A design-gait sweep (a gait library) of the compass test robot on flat ground without
    thrust, run from the robot's folder: no gait exists (the hip torque cannot replace the
    energy each impact takes; independently, tw.design_gait with the same settings says
    infeasible). The point is computed (`ok`) and results.csv's `reason` says why there is
    no gait, not an empty cell."""
    import thrustwalk_cli as tw

    data = Path(__file__).resolve().parent / "data"
    (tmp_path / "compass.yaml").write_bytes((data / "compass.yaml").read_bytes())
    (tmp_path / "s.yaml").write_text(
        "name: s\nstudy: design-gait\nrobot: compass.yaml\n"
        "settings: {clearance: 0, starts: 1, max_iter: 20}\n"
        "grid:\n  target_speed: {values: [0.5]}\ncollect: [feasible]\n")
    monkeypatch.chdir(tmp_path)
    ref = tw.design_gait(tw.load_robot("compass.yaml"), speed=0.5, clearance=0.0, starts=1,
                         max_iter=20)
    assert not ref.success
    res = cli("sweep", "s.yaml", "--workers", "1", "--out", "o", "--formats", "csv", "-q")
    assert res.exit_code == 0, res.output
    row = pd.read_csv(tmp_path / "o" / "results.csv").iloc[0]
    assert row["status"] == "ok" and not row["feasible"]
    assert "no feasible gait" in row["reason"]


def test_a_reduced_walk_point_that_does_not_walk_gives_its_reason():
    """The verdict of a reduced-walk point is its document's `walks` (it has no `success`):
    a point computed whose robot does not walk records the document's reason."""
    from thrustwalk_cli.studies.sweep_points import PointResult
    from thrustwalk_cli.studies.sweep_studies import _record

    class Task:
        key, index, study, values, start = "k", 0, "reduced-walk", {}, None

    doc = {"walks": False, "reason": "no stable orbit: the basin is empty"}
    rec = _record(Task(), PointResult(doc, {}), "", 0.0)
    assert rec["status"] == "ok" and rec["reason"] == doc["reason"]
    rec = _record(Task(), PointResult({**doc, "walks": True}, {}), "", 0.0)
    assert rec["reason"] == ""
