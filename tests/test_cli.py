"""Command line: help texts, exit codes, error lines, limit-cycle outputs."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from thrustwalk_cli._version import __version__
from thrustwalk_cli.cli import COMMANDS, app, invoked_app

REPO = Path(__file__).resolve().parents[1]
ROBOT = (REPO / "robots" / "three_link.yaml").read_text()


def commands() -> list[str]:
    return [m.__name__.rsplit(".", 1)[1].replace("_", "-") for m in COMMANDS]


def test_version(cli):
    res = cli("--version")
    assert res.exit_code == 0 and __version__ in res.output


@pytest.mark.parametrize("command", commands())
def test_every_subcommand_help_has_example_and_units(command, cli):
    res = cli(command, "--help")
    assert res.exit_code == 0, res.output
    assert "Example: thrustwalk " + command in res.output, command
    assert re.search(r"\[(N|m|rad|s|kg m\^2|N m|m/s|rad/s)\]", res.output), command


@pytest.mark.parametrize("command", commands())
def test_a_command_line_builds_only_its_command(command):
    """``main`` hands typer only the named command; its help is the full app's, word for word."""
    from typer.testing import CliRunner

    one = invoked_app([command, "--out", "x"])
    assert [c.name for c in one.registered_commands] == [command]
    assert len(app.registered_commands) == len(COMMANDS)  # the shared app is untouched
    runner = CliRunner()
    full = runner.invoke(app, [command, "--help"], prog_name="thrustwalk")
    lazy = runner.invoke(one, [command, "--help"], prog_name="thrustwalk")
    assert lazy.exit_code == full.exit_code == 0
    assert lazy.output == full.output


@pytest.mark.parametrize("args", [[], ["--help"], ["--version"], ["complie"]])
def test_tool_help_and_unknown_names_keep_every_command(args, monkeypatch):
    monkeypatch.delenv("_THRUSTWALK_COMPLETE", raising=False)
    assert invoked_app(args) is app


def test_shell_completion_keeps_every_command(monkeypatch):
    monkeypatch.setenv("_THRUSTWALK_COMPLETE", "complete_bash")
    assert invoked_app(["compile"]) is app


def test_unknown_command_suggests_the_known_one():
    out = subprocess.run([sys.executable, "-m", "thrustwalk_cli", "complie"],
                         capture_output=True, text=True)
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [
        "error: no such command 'complie'. Did you mean 'compile'? "
        "(see 'python -m thrustwalk_cli --help')"]


@pytest.mark.parametrize("preset", [None, "3"])
def test_command_line_runs_blas_single_threaded_unless_told(preset, monkeypatch):
    from thrustwalk_cli import cli as cli_module

    for var in cli_module.BLAS_THREADS:
        if preset is None:
            monkeypatch.delenv(var, raising=False)
        else:
            monkeypatch.setenv(var, preset)
    monkeypatch.setattr(sys, "argv", ["thrustwalk", "--version"])
    with pytest.raises(SystemExit):
        cli_module.main()
    import os

    for var in cli_module.BLAS_THREADS:
        assert os.environ[var] == (preset or "1")


def test_python_dash_m_entry_point():
    out = subprocess.run([sys.executable, "-m", "thrustwalk_cli", "--version"],
                         capture_output=True, text=True, check=True)
    assert __version__ in out.stdout


@pytest.mark.slow
def test_limit_cycle_outputs(tmp_path, cli):
    res = cli("limit-cycle", "three_link", "three_link_walk", "--thrust", "0:-50:-10,",
              "--out", str(tmp_path))
    assert res.exit_code == 2  # malformed range
    res = cli("limit-cycle", "--thrust", "0,-10,-25,40", "--out", str(tmp_path), "-q")
    assert res.exit_code == 0, res.output
    for name in ("limit_cycles.json", "limit_cycles.csv", "limit_cycles.png",
                 "limit_cycles.pdf", "fixed_point_shift.png", "fixed_point_shift.pdf"):
        assert (tmp_path / name).stat().st_size > 0, name
    assert (tmp_path / "limit_cycles.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "limit_cycles.pdf").read_bytes()[:5] == b"%PDF-"
    text = (tmp_path / "limit_cycles.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text)
    assert set(doc) >= {"provenance", "robot", "gait", "cycles"}
    assert len(doc["provenance"]["robot"]["sha256"]) == 64
    keys = {"thrust", "delta_zero_sq", "zeta_star", "exists", "stable", "reason", "step_time",
            "step_length", "speed", "sigma_minus", "sigma_plus", "alpha_dot_minus",
            "alpha_dot_plus", "min_abs_alpha_dot", "alpha_at_min", "invariance_residual"}
    by_thrust = {c["thrust"]: c for c in doc["cycles"]}
    for c in doc["cycles"]:
        assert keys <= set(c), keys - set(c)
    assert by_thrust[0.0]["exists"] and by_thrust[0.0]["stable"]
    assert by_thrust[-25.0]["speed"] > by_thrust[0.0]["speed"]  # negative thrust speeds up
    # the reported affine law reproduces the computed fixed points
    zdd = doc["zero_dynamics"]
    for F in (0.0, -10.0, -25.0):
        law = zdd["zeta_star_at_zero_thrust"] + zdd["zeta_star_per_newton"] * F
        assert by_thrust[F]["zeta_star"] == pytest.approx(law, rel=1e-12), F
    assert not by_thrust[40.0]["exists"] and by_thrust[40.0]["speed"] is None
    assert by_thrust[40.0]["reason"]
    csv_text = (tmp_path / "limit_cycles.csv").read_text()
    assert "40.0,false,none" in csv_text
    assert csv_text.splitlines()[0].startswith("thrust_N,exists,segment,alpha_rad,")
    prov = doc["provenance"]
    assert prov["command"].startswith("thrustwalk ") and prov["version"] == __version__
    # every numeric value in the JSON is finite
    def walk(v):
        if isinstance(v, float):
            assert math.isfinite(v)
        elif isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, list):
            for x in v:
                walk(x)
    walk(doc)


# --------------------------------------------------------------------------- bad robot files
def _robot(tmp_path: Path, text: str) -> str:
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    return str(p)


BAD_ROBOTS = {
    "missing key": (ROBOT.replace("gravity: 9.8  # [m/s^2]\n", "").replace(
        "feet:\n  stance: {link: stance_leg, point: [0, 0]}\n  swing: {link: swing_leg, "
        "point: [0, -r]}\n", ""), "feet: missing required key"),
    "wrong type": (ROBOT.replace("gravity: 9.8", "gravity: [9.8]"), "gravity: expected"),
    "unknown link": (ROBOT.replace("parent: torso ", "parent: torsoo "),
                     "links[2].parent: unknown link 'torsoo'"),
    "cycle": (ROBOT.replace("  - name: torso\n    parent: stance_leg",
                            "  - name: torso\n    parent: swing_leg"), "cycle"),
    "non-positive mass": (ROBOT.replace("{mass: MH, at: [0, 0]}", "{mass: -15, at: [0, 0]}"),
                          "mass: must be > 0"),
    "invalid coordinates": (ROBOT.replace("{name: q2, joint: swing_leg,",
                                          "{name: q2, joint: torso,"), "coordinates"),
    "bad expression": (ROBOT.replace("at: [0, r/2]", "at: [0, r/2 + x]"), "unknown name 'x'"),
    "unknown key": (ROBOT.replace("gravity: 9.8", "gravity: 9.8\ncolour: red"),
                    "unknown key 'colour'"),
    "bad relabel": (ROBOT.replace("swap: [[stance_leg, swing_leg]]",
                                  "R: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]"),
                    "relabelling does not swap the feet"),
}


@pytest.mark.parametrize("case", sorted(BAD_ROBOTS))
def test_bad_robot_file_one_line_with_location_exit_2(tmp_path, case, cli):
    text, needle = BAD_ROBOTS[case]
    assert text != ROBOT, case
    path = _robot(tmp_path, text)
    res = cli("compile", path)
    assert res.exit_code == 2, (case, res.output)
    assert "Traceback" not in res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert lines, case
    for ln in lines:
        assert re.match(rf"error: {re.escape(path)}(:\d+)?: ", ln), (case, ln)
    assert any(needle in ln for ln in lines), (case, lines)
    assert any(re.match(rf"error: {re.escape(path)}:\d+: ", ln) for ln in lines), (case, lines)


def test_code_injection_rejected_without_execution(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    text = ROBOT.replace("  L: 0.5 ", "  L: \"__import__('os').system('touch x')\" ")
    assert text != ROBOT
    res = cli("compile", _robot(tmp_path, text))
    assert res.exit_code == 2
    assert "parameters.L" in res.output
    assert not (tmp_path / "x").exists()


def test_missing_file_and_unknown_bundled_name(cli):
    res = cli("compile", "no_such_robot")
    assert res.exit_code == 2
    assert "bundled: rabbit, three_link" in res.output


def test_gait_robot_mismatch_and_bad_gait(tmp_path, cli):
    res = cli("limit-cycle", "rabbit", "three_link_walk", "--out",
                              str(tmp_path))
    assert res.exit_code == 2 and "is for robot 'three_link'" in res.output
    gait = (REPO / "gaits" / "three_link_walk.yaml").read_text()
    bad = tmp_path / "g.yaml"
    bad.write_text(gait.replace("robot: three_link", f"robot: {REPO}/robots/three_link.yaml")
                   .replace("c: {q3: -1}", "c: {q1: 1}"))
    res = cli("limit-cycle", "three_link", str(bad), "--out", str(tmp_path / "out"))
    assert res.exit_code == 2 and "alpha.c" in res.output and "unactuated" in res.output
    bad.write_text(gait.replace("q1: [~, ~,", "q1: [0.1, ~,"))
    res = cli("limit-cycle", "three_link", str(bad), "--out", str(tmp_path / "out"))
    assert res.exit_code == 2 and "bezier.coefficients.q1[0]" in res.output


def test_docs_key_tables_match_schema():
    """docs/files.md's key tables are the schema tables (regenerate with `make docs`); the
    README shows the two setup commands and links the references."""
    from thrustwalk_cli.files.schema_docs import render

    files = (REPO / "docs" / "files.md").read_text()
    assert render(files) == files, "docs/files.md key tables are stale: run `make docs`"
    readme = (REPO / "README.md").read_text()
    assert "make demo" in readme and "make test" in readme
    for doc in ("docs/commands.md", "docs/files.md", "docs/architecture.md"):
        assert f"]({doc})" in readme, doc


def test_result_files_are_ordinary_files(tmp_path):
    """Atomic writes go through mkstemp (mode 0600); results must get the usual mode."""
    import os

    from thrustwalk_cli.files import output

    p = output.write_text_atomic(tmp_path / "x.json", "{}")
    umask = os.umask(0)
    os.umask(umask)
    assert p.stat().st_mode & 0o777 == 0o666 & ~umask
    assert [f.name for f in tmp_path.iterdir()] == ["x.json"]  # no temporary left behind


def test_thrust_model_options_are_one_definition(cli, tmp_path, monkeypatch):
    """simulate, control, stability and mujoco take the thrust-model options from one
    definition (commands/options.py): where two commands' defaults agree, the help texts are
    the same words; the defaults that legitimately differ (control's fast thruster) are
    kept and shown by --help. --push is parsed by one parse_push: a malformed value is one
    error line naming the option, exit 2, the same on control and mujoco (user robot, run
    from another folder)."""
    import typer.main

    four = ("simulate", "control", "stability", "mujoco")
    built = typer.main.get_command(app)
    params = {c: {p.opts[0]: p for p in built.commands[c].params
                  if p.opts[0].startswith("--")} for c in four}
    defaults = {"--wn": {"simulate": 2.0, "stability": 2.0, "mujoco": 2.0, "control": 20.0},
                "--xi": dict.fromkeys(four, 1.0),
                "--tau": {"simulate": 0.5, "stability": 0.5, "mujoco": 0.5, "control": 0.05},
                "--f0": {"simulate": 0.0, "mujoco": 0.0},
                "--push": {"control": None, "mujoco": None},
                "--thruster": dict.fromkeys(four)}
    for name, want in defaults.items():
        have = {c: params[c][name] for c in four if name in params[c]}
        assert {c: o.default for c, o in have.items()} == want, name
        for a in have:
            for b in have:
                if want[a] == want[b] and not (name == "--thruster" and {a, b} & {
                        "control", "stability"}):  # what drives it; stability's: only one
                    assert have[a].help == have[b].help, (name, a, b)
            if want[a] is not None:
                assert have[a].show_default is not False, (name, a)  # [default: ...] shown
    for c in ("simulate", "control", "mujoco"):  # control has no --thrust: what drives it
        assert params[c]["--thruster"].multiple
        assert params[c]["--thruster"].help.endswith("(repeat for several; default: the "
                                                     "first).")
    assert not params["stability"]["--thruster"].multiple  # one F_ss on one thruster
    # --thrust-model: the gait's schedule first, else the study's own fallback
    fallback = {"simulate": "second-order", "stability": "second-order", "mujoco": "ideal"}
    helps = {c: params[c]["--thrust-model"].help for c in fallback}
    assert helps["simulate"] == helps["stability"]
    for c, f in fallback.items():
        assert helps[c].endswith(f"default: piecewise for a gait with a thrust: section and "
                                 f"no --thrust, else {f}).")
        assert helps[c].replace(f"else {f})", "") == helps["simulate"].replace(
            "else second-order)", "")
    assert params["control"]["--thrust-model"].default == "ideal"

    monkeypatch.chdir(tmp_path)
    data = Path(__file__).parent / "data"
    robot, gait = (Path(__import__("os").path.relpath(data / f, tmp_path))
                   for f in ("walker5.yaml", "walker5_walk.yaml"))
    said = {}
    for c in ("control", "mujoco"):
        res = cli(c, str(robot), str(gait), "--steps", "3", "--push", "2:0.5",
                  "--out", "o_" + c, "-q")
        lines = res.stderr.strip().splitlines()
        assert res.exit_code == 2 and len(lines) == 1, (c, res.stderr)
        assert "option --push: '2:0.5' is not STEP:PHASE:PX[:PY]" in lines[0], lines
        said[c] = lines[0]
        assert not (tmp_path / ("o_" + c)).exists()
    assert said["control"] == said["mujoco"]


def test_the_thrust_model_option_lists_the_option_table(cli):
    """--thrust-model's help (written without importing numpy) names exactly the thruster
    models of thrust/dynamics.MODELS plus piecewise, on every command that takes it."""
    from thrustwalk_cli.commands.options import THRUST_MODEL_NAMES
    from thrustwalk_cli.thrust.command import thrust_model_names

    assert THRUST_MODEL_NAMES.split(" | ") == list(thrust_model_names())
    for command in ("simulate", "stability", "mujoco", "control"):
        res = cli(command, "--help")
        assert res.exit_code == 0
        text = " ".join(res.output.split())
        for name in thrust_model_names():
            if command == "control" and name == "piecewise":
                continue
            assert name in text, (command, name)


@pytest.mark.slow  # (this session's additions; CI runs every test)
def test_a_gait_file_alone_walks_on_the_robot_it_names(cli, tmp_path, monkeypatch):
    """A gait given alone where the robot goes (a user's gait file, naming its robot file
    relative to itself; a bundled gait's name): the walker is that gait on that robot, the
    same as giving both (independent: the two-argument load), from another folder; a robot
    file alone keeps meaning its bundled gait or an error naming --gait."""
    import thrustwalk_cli as tw

    data = Path(__file__).resolve().parent / "data"
    gait = str(data / "walker5_thrust.yaml")
    monkeypatch.chdir(tmp_path)
    alone, both = tw.load_walker(gait), tw.load_walker(str(data / "walker5.yaml"), gait)
    assert alone.robot == both.robot and alone.gait == both.gait
    assert tw.load_walker("rabbit_walk").robot.name == "rabbit"
    res = cli("limit-cycle", gait, "--thrust", "-10", "--formats", "none", "--out", "a", "-q")
    ref = cli("limit-cycle", str(data / "walker5.yaml"), gait, "--thrust", "-10",
              "--formats", "none", "--out", "b", "-q")
    assert res.exit_code == 0 and ref.exit_code == 0, res.output + ref.output
    a = json.loads((tmp_path / "a" / "limit_cycles.json").read_text())
    b = json.loads((tmp_path / "b" / "limit_cycles.json").read_text())
    assert a["cycles"] == b["cycles"] and a["robot"]["name"] == "walker5"
    res = cli("limit-cycle", str(data / "walker5.yaml"), "--out", "c")
    assert res.exit_code == 2 and "--gait" in res.stderr
