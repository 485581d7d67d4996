"""Verdicts a user can trust and outputs that fit their tools: a corpus of user mistakes with
the exact first line of each message, invalid gaits never called good, the gait's own thrust
used by default, plain CSV files, documents with units, tables that never split a number."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
GAIT = (REPO / "gaits" / "three_link_walk.yaml").read_text()


def _write(tmp_path: Path, name: str, text: str) -> str:
    path = tmp_path / f"{name}.yaml"
    path.write_text(text.replace("name: three_link_walk", f"name: {name}"))
    return str(path)


def _degrees(text: str) -> str:
    """The gait as a user who typed degrees would write it."""
    head, body = text.split("bezier:", 1)
    body = re.sub(r"-?\d+\.\d+", lambda m: f"{math.degrees(float(m.group(0))):.2f}", body)
    return head.replace("af: 0.2669080288119819", "af: 15.29") + "bezier:" + body


def _line_of(path: str, key: str) -> int:
    """1-based line of the first line that starts with ``key`` (after indentation)."""
    for i, line in enumerate(Path(path).read_text().splitlines(), 1):
        if line.strip().startswith(key):
            return i
    raise AssertionError(key)


def _position_residual() -> float:
    """max |a_0 - H_0 q^+| of NOT_INVARIANT, by hand: q^- from the last Bezier column and
    alpha_f (q1 = theta_torso - theta_stance, q2 = theta_swing - theta_torso, q3 = theta_stance
    = -alpha_f), then the legs swap their absolute angles and the torso keeps its own."""
    q1, q2, q3 = 0.039547914228207505, 0.49426814341686387, -0.2669080288119819
    th_stance, th_torso, th_swing = q3, q3 + q1, q3 + q1 + q2
    q1p, q2p = th_torso - th_swing, th_stance - th_torso  # the new stance leg is the old swing
    return max(abs(0.2 - q1p), abs(0.3 - q2p))


NOT_INVARIANT = (GAIT.replace("invariance: auto", "invariance: given")
                 .replace("[~, ~, -0.428", "[0.2, -0.1, -0.428")
                 .replace("[~, ~, 0.1187", "[0.3, 0.2, 0.1187"))
SCUFFING = GAIT.replace("0.2445021030062819, 0.4729868829529832",
                        "0.1045021030062819, 0.3729868829529832")
THRUSTED = GAIT + ("thrust:   # designed constant thrust [N]\n  mode: force\n  knots: [0, 1]\n"
                   "  fractions: true\n  values: {hip_x: [-12.5], torso_back: [0.0]}\n")


# ---------------------------------------------------------------------- the mistakes corpus
@pytest.mark.slow
def test_corpus_of_user_mistakes_first_lines(tmp_path, cli):
    deg = _write(tmp_path, "degrees", _degrees(GAIT))
    flip = _write(tmp_path, "flipped", GAIT.replace("c: {q3: -1}", "c: {q3: 1}"))
    ni = _write(tmp_path, "not_invariant", NOT_INVARIANT)
    cases = [
        (["limit-cycle", "three_link", deg], 2,
         f"error: {deg}:{_line_of(deg, 'final:')}: alpha.final: the swing foot is 0.004013 m "
         "above the ground at impact; angles are in radians (15.29 > pi)"),
        (["limit-cycle", "three_link", flip], 2,
         f"error: {flip}:{_line_of(flip, 'final:')}: alpha.final: the swing foot is 0.2684 m "
         "above the ground at impact: alpha_f = c q^- must be reached with the swing foot on "
         "the ground (check the sign of alpha.c and alpha.final)"),
        (["limit-cycle", "three_link", ni], 0,
         f"warning: the gait is not hybrid-invariant (impact residuals: position "
         f"{_position_residual():.3g} rad, velocity 3.79, tolerance 1e-08): after impact the "
         "walker leaves the zero-dynamics manifold, so no zero-dynamics orbit is a walking "
         "orbit; `invariance: auto` in the gait file computes columns 0 and 1 so that it is"),
        (["limit-cycle", "rabbit", "three_link_walk"], 2,
         f"error: {REPO / 'gaits' / 'three_link_walk.yaml'}:{_line_of(str(REPO / 'gaits' / 'three_link_walk.yaml'), 'robot:')}: "  # noqa: E501
         "robot: gait 'three_link_walk' is for robot 'three_link', not 'rabbit'"),
        (["limit-cycle", "--thrust", "0:-50:10"], 2,
         "error: option --thrust: the step must be non-zero and point from start to stop "
         "(got '0:-50:10'; use e.g. 0:-50:-10 or 0,-10)"),
    ]
    for args, code, first in cases:
        res = cli(*args, "--out", tmp_path / "out", "--formats", "csv", "-q")
        assert res.exit_code == code, (args, res.output)
        assert res.stderr.splitlines()[0] == first, (args, res.stderr)
        assert "Traceback" not in res.output


def test_degrees_below_the_ground_point_at_the_coefficient(tmp_path):
    """A gait in degrees whose foot ends under the ground names the first value beyond pi."""
    from thrustwalk_cli.errors import InputError
    from thrustwalk_cli.walker import load_walker

    text = _degrees(GAIT).replace("af: 15.29", "af: 0.2669080288119819")
    path = _write(tmp_path, "deg2", text)
    with pytest.raises(InputError) as exc:
        load_walker("three_link", path)
    msg = str(exc.value)
    assert "bezier.coefficients.q1[2]" in msg and "angles are in radians (-24.55 > pi)" in msg


# ------------------------------------------------------------------ never call invalid good
@pytest.mark.slow
def test_not_invariant_gait_has_no_walking_orbit_anywhere(tmp_path, cli):
    ni = _write(tmp_path, "not_invariant", NOT_INVARIANT)
    res = cli("limit-cycle", "three_link", ni, "--thrust", "0,-10", "--out", tmp_path / "lc",
              "--formats", "csv", "-q")
    assert res.exit_code == 0
    doc = json.loads((tmp_path / "lc" / "limit_cycles.json").read_text())
    assert not doc["success"] and doc["zero_dynamics"]["hybrid_invariant"] is False
    for c in doc["cycles"]:
        assert not c["exists"] and not c["walkable"] and "invariance: auto" in c["reason"]
    res = cli("feasibility", "three_link", ni, "--thrust", "0", "--out", tmp_path / "fe",
              "--formats", "none", "-q")
    fe = json.loads((tmp_path / "fe" / "feasibility.json").read_text())
    assert fe["verdict"] == "infeasible" and "hybrid-invariant" in fe["cases"][0]["reason"]


@pytest.mark.slow
def test_scuffing_is_part_of_every_verdict(tmp_path, cli):
    sc = _write(tmp_path, "scuffing", SCUFFING)
    cli("limit-cycle", "three_link", sc, "--thrust", "0", "--out", tmp_path / "lc",
        "--formats", "csv", "-q")
    lc = json.loads((tmp_path / "lc" / "limit_cycles.json").read_text())
    c = lc["cycles"][0]
    assert c["exists"] and c["stable"] and not c["walkable"]
    assert c["verdict"].startswith("not walkable: the swing foot goes 1.494 mm below")
    assert lc["swing_foot"]["scuffs"] and lc["swing_foot"]["deepest"] < -1e-3
    cli("feasibility", "three_link", sc, "--thrust", "0", "--out", tmp_path / "fe",
        "--formats", "md", "-q")
    fe = json.loads((tmp_path / "fe" / "feasibility.json").read_text())
    assert not fe["cases"][0]["feasible"] and "scuffing" in fe["cases"][0]["reason"]
    md = (tmp_path / "fe" / "feasibility.md").read_text()
    assert "**Infeasible:** the swing foot goes" in md and "not part of the verdict" not in md


WALKER5 = REPO / "tests" / "data" / "walker5.yaml"
WALKER5_WALK = REPO / "tests" / "data" / "walker5_walk.yaml"


@pytest.mark.slow
def test_walkable_means_contact_feasible_on_a_users_robot(tmp_path, cli, monkeypatch):
    """Issue 24 item 2: on a user's 5-link knee walker, limit-cycle called every thrust from 0
    to -12 N walkable while feasibility said infeasible from -2 N (friction ratio 0.83) and
    lifted from -6 N. Now the two commands give the same verdict case by case, and the
    limit-cycle numbers are the feasibility command's."""
    monkeypatch.chdir(tmp_path)
    args = [WALKER5, WALKER5_WALK, "--thrust", "0:-12:-2", "--formats", "none"]
    assert cli("limit-cycle", *args, "--out", "lc", "-q").exit_code == 0
    assert cli("feasibility", *args, "--out", "fe", "-q").exit_code == 0
    lc = json.loads((tmp_path / "lc" / "limit_cycles.json").read_text())
    fe = json.loads((tmp_path / "fe" / "feasibility.json").read_text())
    assert lc["contact"]["mu"] == fe["mu"] == 0.7
    for c, f in zip(lc["cycles"], fe["cases"], strict=True):
        assert c["thrust"] == f["thrust"]
        assert c["exists"] and c["stable"], c["thrust"]  # the orbit is fine everywhere
        assert c["walkable"] == f["feasible"], c["thrust"]
        assert c["contact"]["feasible"] == f["feasible"]
        for key in ("min_vertical_force", "max_friction_ratio"):
            assert c["contact"][key] == f[key], (c["thrust"], key)
        if not c["walkable"]:
            assert c["verdict"].startswith("not walkable: stable orbit, contact infeasible")
    walkable = [c["thrust"] for c in lc["cycles"] if c["walkable"]]
    assert walkable == [0.0], walkable  # slips from -2 N, lifts from -6 N
    by = {c["thrust"]: c for c in lc["cycles"]}
    assert by[-2.0]["contact"]["max_friction_ratio"] > 0.7
    assert by[-6.0]["contact"]["min_vertical_force"] < 0 and not lc["success"]
    res = cli("limit-cycle", *args, "--out", "lc2")
    assert "-6 to -12 N (4 cases): not walkable" in " ".join(res.stdout.split())
    assert "thrustwalk feasibility" in res.stdout
    # a friction coefficient that makes -2 N feasible: the verdicts move together
    res = cli("limit-cycle", *args, "--mu", "1.2", "--out", "lc3", "-q")
    lc3 = json.loads((tmp_path / "lc3" / "limit_cycles.json").read_text())
    assert [c["walkable"] for c in lc3["cycles"][:2]] == [True, True]


def test_walkable_in_a_limit_cycle_sweep_is_the_feasibility_verdict(tmp_path, cli):
    sweep = tmp_path / "s.yaml"
    sweep.write_text("name: s\nstudy: limit-cycle\nrobot: walker5.yaml\ngait: walk.yaml\n"
                     "grid:\n  thrust: {values: [0, -2, -6]}\n"
                     "collect: [walkable, contact_feasible, max_friction_ratio]\n")
    # files outside the sweep file's folder are named on the command line (issue 30)
    res = cli("sweep", sweep, "--out", tmp_path / "out", "-q", "--workers", "1",
              "--robot", WALKER5, "--gait", WALKER5_WALK)
    assert res.exit_code == 0, res.output
    import csv

    rows = list(csv.DictReader((tmp_path / "out" / "results.csv").open()))
    assert [r["walkable"] for r in rows] == ["true", "false", "false"], rows


@pytest.mark.slow
def test_simulate_never_plain_ok_when_the_cone_is_left(tmp_path, cli):
    res = cli("simulate", "--steps", "2", "--thrust", "0", "--thrust-model", "constant",
              "--mu", "0.3", "--samples", "10", "--formats", "csv", "--out", tmp_path, "-q")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "simulation.json").read_text())
    run = doc["runs"][0]
    assert run["success"] and run["status"] == "warning" and "(slips at steps 1-2" in run["reason"]
    assert "warning: run 0 (F_ss = 0.0): completed" in res.stderr
    assert "warning: run 0 (F_ss = 0.0): warning:" not in res.stderr
    import re

    cone = [w for w in run["warnings"] if "friction cone" in w]
    assert cone
    for w in cone:  # each part named left the cone (ratio > mu), and only those
        parts = re.findall(r"(stance|impact) ([0-9.]+)", w)
        assert parts and all(float(v) > 0.3 for _, v in parts), w
    assert "(slips at steps 1-2" in res.stderr
    res = cli("simulate", "--steps", "2", "--thrust", "0", "--thrust-model", "constant",
              "--samples", "10", "--formats", "csv", "--out", tmp_path / "b", "-q")
    assert json.loads((tmp_path / "b" / "simulation.json").read_text())["runs"][0][
        "status"] == "ok"


@pytest.mark.slow
def test_animate_with_nothing_to_animate_writes_results_and_says_so(tmp_path, cli):
    res = cli("simulate", "--reduced", "--steps", "1", "--thrust", "0", "--animate",
              "--samples", "5", "--out", tmp_path, "-q")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "simulation.json").exists() and not (tmp_path / "walker.gif").exists()
    assert "warning: nothing to animate" in res.stderr


# -------------------------------------------------------------- the gait's thrust by default
@pytest.mark.slow
def test_gait_thrust_is_the_default_everywhere(tmp_path, cli, walker3):
    g = _write(tmp_path, "thrusted", THRUSTED)
    res = cli("limit-cycle", "three_link", g, "--formats", "csv", "--out", tmp_path / "lc")
    assert "the gait's own thrust: schedule is analysed" in res.stderr
    lc = json.loads((tmp_path / "lc" / "limit_cycles.json").read_text())
    assert lc["source"] == "gait" and lc["thruster"] == "hip_x"
    assert [c["thrust"] for c in lc["cycles"]] == [-12.5]
    from thrustwalk_cli.studies.limit_cycle import limit_cycle

    ref = limit_cycle(walker3, [-12.5]).cycles[0]  # the same thrust, given explicitly
    assert lc["cycles"][0]["zeta_star"] == pytest.approx(ref.zeta_star, rel=1e-12)
    cli("feasibility", "three_link", g, "--formats", "none", "--out", tmp_path / "fe", "-q")
    fe = json.loads((tmp_path / "fe" / "feasibility.json").read_text())
    assert fe["mode"] == "schedule" and fe["cases"][0]["thrust"]["values"] == {"hip_x": [-12.5]}
    assert fe["cases"][0]["zeta_star"] == pytest.approx(ref.zeta_star, rel=1e-12)
    res = cli("simulate", "three_link", g, "--steps", "2", "--samples", "10", "--formats",
              "csv", "--out", tmp_path / "si", "-q")
    si = json.loads((tmp_path / "si" / "simulation.json").read_text())
    assert si["settings"]["thrust_model"] == "piecewise"
    assert si["steps"][0]["zeta_minus"] == pytest.approx(ref.zeta_star, rel=1e-7)
    cli("shape", "three_link", g, "--k", "0,10", "--formats", "csv", "--out", tmp_path / "sh",
        "-q")
    sh = json.loads((tmp_path / "sh" / "shape.json").read_text())
    assert sh["base_thrust"]["force"]["hip_x"] == -12.5
    assert sh["nominal"]["zeta_star"] == pytest.approx(ref.zeta_star, rel=1e-9)
    k0 = sh["schedules"][0]
    assert k0["k"] == 0.0 and k0["zeta_star"]["shaped"] == pytest.approx(ref.zeta_star, rel=1e-9)
    assert k0["shift"]["true_fixed_point_shift"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.slow
def test_robot_alone_picks_its_bundled_gait(tmp_path, cli):
    res = cli("limit-cycle", "rabbit", "--thrust", "0", "--formats", "csv", "--out", tmp_path,
              "-q")
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "limit_cycles.json").read_text())["gait"]["name"] == \
        "rabbit_walk"


# --------------------------------------------------------------------------- outputs that fit
@pytest.fixture(scope="module")
def outputs(tmp_path_factory, cli):
    """One run of every command that writes files, into one folder per command (its JSON
    and CSV files: the tests of this module read no figure)."""
    root = tmp_path_factory.mktemp("outputs")
    runs = {
        "limit_cycle": ["limit-cycle", "--thrust", "0,-20,40"],
        "shape": ["shape", "--k", "0,20"],
        "feasibility": ["feasibility", "--thrust", "0,-20"],
        "optimize": ["optimize", "--target-zeta", "1500", "--knots", "0,0.5,1"],
        "simulate": ["simulate", "--steps", "2", "--thrust", "0,-10", "--samples", "20"],
    }
    for name, args in runs.items():
        res = cli(*args, "--out", root / name, "--formats",
                  "none" if name in ("feasibility", "optimize") else "csv", "-q")
        assert res.exit_code == 0, (name, res.output)
    res = cli("inspect", "three_link", "--q", "0.1,0.2,-0.3", "--dq", "0,1,-1", "--json",
              root / "inspect.json", "-q")
    assert res.exit_code == 0, res.output
    return root


@pytest.mark.slow
def test_every_csv_loads_with_pandas_and_numpy_without_options(outputs):
    import pandas as pd

    csvs = sorted(outputs.rglob("*.csv"))
    assert len(csvs) >= 4
    unit_suffix = re.compile(r"_(N|Nm|Ns|rad|rad_s|s|m|m_s|J|kg2m4_s2|kgm2_s)$")
    for path in csvs:
        frame = pd.read_csv(path)
        arr = np.genfromtxt(path, names=True, delimiter=",", dtype=None, encoding="utf-8")
        assert len(frame) == arr.shape[0] > 0, path.name
        assert list(frame.columns) == path.read_text().splitlines()[0].split(","), path.name
        named = [c for c in frame.columns if unit_suffix.search(c)]
        assert named, (path.name, list(frame.columns))
        doc = json.loads(next(path.parent.glob("*.json")).read_text())
        assert doc["tables"][path.name]["columns"] == list(frame.columns)


UNIT_WORDS = {"N", "m", "s", "rad", "kg", "J", "1"}


@pytest.mark.slow
def test_every_json_has_units_and_a_schema_version(outputs):
    from thrustwalk_cli.studies.documents import UNITS

    canonical = set(UNITS.values())
    docs = sorted(outputs.rglob("*.json"))
    assert len(docs) >= 6
    for path in docs:
        if path.name == ".thrustwalk-run.json":  # the folder's manifest, not a result
            continue
        doc = json.loads(path.read_text())
        assert doc["schema_version"] == 1, path
        assert doc["units"], path
        for key, unit in doc["units"].items():
            spelled = unit in canonical or set(re.findall(r"[A-Za-z]+", unit)) <= UNIT_WORDS
            assert spelled and " / " not in unit and "per" not in unit, (path.name, key, unit)


@pytest.mark.slow
def test_json_to_stdout_is_the_document(tmp_path, cli):
    res = cli("limit-cycle", "--thrust", "0", "--formats", "csv", "--out", tmp_path, "--json",
              "-")
    assert res.exit_code == 0
    piped = json.loads(res.stdout)
    written = json.loads((tmp_path / "limit_cycles.json").read_text())
    assert piped == written


def test_out_naming_a_file_is_one_line_exit_2(tmp_path, cli):
    target = tmp_path / "taken"
    target.write_text("x")
    for cmd in (["limit-cycle"], ["feasibility"], ["simulate", "--steps", "1"]):
        res = cli(*cmd, "--out", target, "-q")
        assert res.exit_code == 2, (cmd, res.output)
        assert res.stderr.strip() == f"error: option --out: {target} is a file, not a folder"
    assert target.read_text() == "x"


def test_max_output_refuses_huge_sweeps_before_any_work(tmp_path, cli):
    res = cli("limit-cycle", "--thrust", "0:-9.999:-0.001", "--max-output", "100", "--out",
              tmp_path, "-q")
    assert res.exit_code == 2
    assert res.stderr.startswith("error: option --max-output: 10000 thrust values make a CSV")
    res = cli("shape", "--k", "0:9999:1", "--max-output", "1", "--out", tmp_path, "-q")
    assert res.exit_code == 2
    assert res.stderr.startswith("error: option --max-output: 10000 values of k make a CSV")
    assert not list(tmp_path.iterdir())


@pytest.mark.slow
def test_tables_never_split_a_number(tmp_path, cli, monkeypatch):
    """At a narrow terminal every number of the table is still whole on its line."""
    monkeypatch.setenv("COLUMNS", "50")
    res = cli("limit-cycle", "--thrust", "0,-12.345678,40", "--formats", "csv", "--out",
              tmp_path)
    assert res.exit_code == 0
    doc = json.loads((tmp_path / "limit_cycles.json").read_text())
    from thrustwalk_cli.studies.documents import fmt

    for c in doc["cycles"]:
        for key in ("thrust", "zeta_star", "step_time", "speed"):
            if c[key] is not None:
                assert fmt(c[key]) in res.stdout, (key, fmt(c[key]))
    assert "[kg^2 m^4/s^2]" in res.stdout  # headers carry units


@pytest.mark.slow
def test_progress_lines_when_standard_error_is_not_a_terminal(tmp_path, cli):
    res = cli("simulate", "--steps", "2", "--thrust", "0", "--samples", "10", "--formats", "csv",
              "--out", tmp_path)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("simulating steps:")]
    assert [ln.split(" (")[0] for ln in lines] == ["simulating steps: 1/2",
                                                    "simulating steps: 2/2"]
    assert all("eta" in ln for ln in lines)


def test_progress_in_a_log_is_a_line_per_tenth_not_per_unit(capsys):
    """Standard error not a terminal: 1,000 units write the first, every tenth and the last,
    each with the counts and an ETA."""
    from thrustwalk_cli.commands.common import progress

    with progress("trials", 1000, quiet=False) as advance:
        for _ in range(1000):
            advance()
    lines = capsys.readouterr().err.splitlines()
    counts = [int(ln.split(": ")[1].split("/")[0]) for ln in lines]
    assert counts[0] == 1 and counts[-1] == 1000
    assert set(range(100, 1001, 100)) <= set(counts) and len(lines) <= 11 + 2
    assert all("eta" in ln for ln in lines)


@pytest.mark.slow
def test_help_cites_no_internal_document_and_completion_is_on(cli):
    from thrustwalk_cli.cli import COMMANDS

    assert "--install-completion" in cli("--help").output
    for module in COMMANDS:
        name = module.__name__.rsplit(".", 1)[1].replace("_", "-")
        text = cli(name, "--help").output
        assert "SPEC" not in text, name


def test_inspect_warns_on_angles_beyond_pi_and_prints_a_table(cli):
    res = cli("inspect", "three_link", "--q", "0.1,4.0,-0.3")
    assert res.exit_code == 0
    assert "warning: q2 = 4 is beyond +-pi: angles are in radians" in res.stderr
    assert "potential energy" in res.stdout and "[[" not in res.stdout


@pytest.mark.slow
def test_shape_is_not_a_success_when_a_shaped_schedule_has_no_orbit(tmp_path, cli):
    """k = -500 N m (generalized) stops the walker before the end of the step: the study says
    so in the JSON (success false, the reason naming the schedule) and on standard error, and
    still writes the orbits it has."""
    res = cli("shape", "--k", "0,-500", "--formats", "csv", "--out", tmp_path, "-q")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "shape.json").read_text())
    assert doc["success"] is False
    assert doc["reason"].startswith("no stable shaped orbit for 1 of 2 schedule(s) (k = -500)")
    assert "walker stops" in doc["reason"]
    assert "warning: no stable shaped orbit for 1 of 2" in res.stderr
    assert (tmp_path / "shape.csv").exists()
    ok = cli("shape", "--k", "0,10", "--formats", "csv", "--out", tmp_path / "ok", "-q")
    assert json.loads((tmp_path / "ok" / "shape.json").read_text())["success"] is True, ok.output


def test_bundled_gait_headers_record_commands_that_run_today():
    """Issue 24 item 10: the header of gaits/rabbit_walk.yaml recorded a removed option. Every
    option on a bundled gait's `command:` line is an option of today's design-gait, and the
    positional argument is the robot the gait names."""
    import shlex

    from typer.main import get_command

    from thrustwalk_cli.cli import app

    cmd = get_command(app).commands["design-gait"]
    options = {o for p in cmd.params for o in getattr(p, "opts", [])}
    for path in sorted((REPO / "gaits").glob("*.yaml")):
        line = next(ln for ln in path.read_text().splitlines() if ln.startswith("# command:"))
        words = shlex.split(line.removeprefix("# command:"))
        assert words[:2] == ["thrustwalk", "design-gait"], path.name
        flags = [w for w in words if w.startswith("-")]
        assert flags and set(flags) <= options, (path.name, set(flags) - options)
        robot = next(ln for ln in path.read_text().splitlines() if ln.startswith("robot:"))
        assert words[2] == robot.split(":", 1)[1].strip(), path.name


def test_repr_of_a_walker_and_results_is_one_short_line(walker3):
    import thrustwalk_cli as tw

    objects = [walker3, walker3.zd, tw.limit_cycle(walker3, thrust=[0, -10]),
               tw.feasibility(walker3, thrust=[0])]
    for obj in objects:
        text = repr(obj)
        assert "\n" not in text and len(text) < 400, (type(obj).__name__, len(text))
    assert repr(walker3).startswith("Walker(robot='three_link', gait='three_link_walk'")
    lc = objects[2]
    assert repr(lc) == f"LimitCycleResult(success=True, reason={lc.reason!r})"


def test_repr_of_a_robot_and_a_gait_is_one_short_line():
    """Robot and Gait print one line (name, links, coordinates, thrusters, file; name, robot,
    file, alpha_f, order), checked against the YAML files read by PyYAML, not the hundreds of
    characters of every link and Bezier coefficient; equality stays the dataclass's, field by
    field, and the fields are intact."""
    import dataclasses

    import yaml

    from thrustwalk_cli.walker import load_walker

    data = Path(__file__).parent / "data"
    for gait_file in ("walker5_walk.yaml", "walker5_thrust.yaml"):
        w = load_walker(str(data / "walker5.yaml"), str(data / gait_file))
        ry = yaml.safe_load((data / "walker5.yaml").read_text())
        gy = yaml.safe_load((data / gait_file).read_text())
        act = [c["name"] for c in ry["coordinates"]["actuated"]]
        text = repr(w.robot)
        assert "\n" not in text and len(text) < 200, text
        assert text == (f"Robot(name={ry['name']!r}, links={len(ry['links'])}, actuated={act!r}, "
                        f"unactuated={[ry['coordinates']['unactuated']['name']]!r}, "
                        f"thrusters={[t['name'] for t in ry['thrusters']]!r}, "
                        f"file={str(data / 'walker5.yaml')!r})"), text
        text = repr(w.gait)
        order = len(next(iter(gy["bezier"]["coefficients"].values()))) - 1
        assert "\n" not in text and len(text) < 200, text
        assert text.startswith(f"Gait(name={gy['name']!r}, robot='walker5', "
                               f"file={str(data / gait_file)!r}, alpha_f="), text
        assert text.endswith(f", order={order})"), text
        af = float(re.search(r"alpha_f=([-0-9.e]+)", text).group(1))
        assert af == pytest.approx(float(gy["parameters"]["af"]), rel=1e-5)
        # equality and the fields: the dataclass's
        again = load_walker(str(data / "walker5.yaml"), str(data / gait_file))
        assert again.robot == w.robot and again.gait == w.gait
        assert dataclasses.replace(w.gait, kp=1.0) != w.gait
        assert dataclasses.replace(w.robot, gravity=9.0) != w.robot
        assert len(dataclasses.fields(w.robot)) == 16 and w.robot.links[0].name == "stance_shin"
        assert w.gait.A and w.gait.order == order


def test_result_tables_convert_to_pandas_in_one_call(walker3):
    import pandas

    import thrustwalk_cli as tw

    table = tw.limit_cycle(walker3, thrust=[0, -10]).tables()["limit_cycles"]
    frame = table.to_pandas()
    assert list(frame.columns) == table.header and len(frame) == len(table.rows)
    assert frame.equals(pandas.DataFrame(table.to_dict()))
    assert frame["zeta_kg2m4_s2"].dtype == float


@pytest.mark.parametrize("args, line", [
    # (a gait alone walks on its own robot: tests/test_cli.py; beside a gait it is refused)
    (["limit-cycle", "{gait}", "{gait}", "--out", "{out}"],
     "this is a gait file, not a robot file"),
    (["limit-cycle", "three_link", "{robot}", "--out", "{out}"],
     "this is a robot file, not a gait file"),
    (["sweep", "{gait}", "--out", "{out}"], "this is a gait file, not a sweep file"),
])
def test_a_file_of_another_kind_is_named_as_such(tmp_path, cli, args, line):
    fill = {"gait": str(WALKER5_WALK), "robot": str(WALKER5), "out": str(tmp_path / "o")}
    res = cli(*[a.format(**fill) for a in args])
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and line in res.stderr, res.stderr
    assert "unknown key" not in res.stderr and not (tmp_path / "o").exists()


def test_a_range_without_its_step_is_refused(tmp_path, cli):
    res = cli("limit-cycle", "--thrust", "0:-50", "--out", tmp_path / "o")
    assert res.exit_code == 2 and not (tmp_path / "o").exists()
    assert "option --thrust: a range needs its step, start:stop:step" in res.stderr


def test_formats_none_says_what_was_written(tmp_path, cli):
    res = cli("limit-cycle", "--thrust", "0", "--formats", "none", "--out", tmp_path / "o")
    assert res.exit_code == 0
    assert [p.name for p in (tmp_path / "o").glob("[!.]*")] == ["limit_cycles.json"]
    said = " ".join(res.stdout.split())
    assert f"wrote {tmp_path / 'o'}: limit_cycles.json (no figures)" in said
    assert "CSV" not in said


def test_a_sweep_collecting_status_has_one_column_per_name(tmp_path, cli):
    sweep = tmp_path / "s.yaml"
    sweep.write_text("name: s\nstudy: simulate\nrobot: three_link\ngait: three_link_walk\n"
                     "settings: {steps: 1}\ngrid:\n  thrust: {values: [0, -10]}\n"
                     "collect: [status, steps_completed]\n")
    res = cli("sweep", sweep, "--out", tmp_path / "out", "-q", "--workers", "1")
    assert res.exit_code == 0, res.output
    header = (tmp_path / "out" / "results.csv").read_text().splitlines()
    header = next(h for h in header if not h.startswith("#")).split(",")
    assert len(header) == len(set(header)), header
    assert "status" in header and "simulate_status" in header


def test_a_first_simulation_says_it_compiles_the_kernel(tmp_path, cli, monkeypatch):
    """Issue 24 item 7: the first simulate on a machine was silent for 1.5-2 minutes (the
    one-time kernel compile). A command that needs the kernel says so before it starts and
    shows the time passing; with the kernel cached it says nothing."""
    import thrustwalk_cli.simulation.stepper as stepper
    import thrustwalk_cli.studies.compile as study

    state = {"cached": False, "compiled": 0}
    real = study.compile_kernel

    def fake_compile(*, rebuild=False):  # the real kernel, as if compiled now
        state["compiled"] += 1
        rec = real()
        state["cached"] = True
        return {**rec, "cache_hit": False, "seconds": 31.5}

    monkeypatch.setattr(stepper, "kernel_status",
                        lambda: {"cached": state["cached"], "compile_seconds": None,
                                 "entry": ""})
    monkeypatch.setattr(study, "compile_kernel", fake_compile)
    args = ["simulate", "--steps", "1", "--thrust", "0", "--thrust-model", "constant",
            "--formats", "none"]
    res = cli(*args, "--out", tmp_path / "a")
    assert res.exit_code == 0, res.output
    first = res.stderr.splitlines()[0]
    assert first.startswith("compiling the simulation kernel once for this machine (~30 s")
    assert "compiled the simulation kernel in 31.5 s" in res.stderr
    assert state["compiled"] == 1
    res = cli(*args, "--out", tmp_path / "b")  # now cached: not a word
    assert res.exit_code == 0 and "kernel" not in res.stderr and state["compiled"] == 1
    state["cached"] = False
    res = cli(*args, "--out", tmp_path / "c", "-q")  # quiet: compiled, silently
    assert res.exit_code == 0 and res.stderr == "" and state["compiled"] == 2
