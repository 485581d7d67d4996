"""The one gait-file writer (files/gait_file.gait_text): what it writes reads back as the
same gait, bit for bit, through the reader every command uses; design-gait, optimize and
the gait-library sweep all write through it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.files.gait_file import (
    bind_gait,
    gait_text,
    load_gait,
    load_gait_text,
    robot_reference,
)
from thrustwalk_cli.files.robot_file import load_robot

DATA = Path(__file__).parent / "data"


def _read_back(text: str, file: Path, robot):
    gait, source = load_gait_text(text, str(file))
    return bind_gait(gait, source, robot), source


@pytest.mark.parametrize("robot_ref,gait_ref", [
    ("rabbit", "rabbit_walk"),
    (str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml")),
])
def test_gait_text_reads_back_bit_for_bit(robot_ref, gait_ref, tmp_path):
    robot = load_robot(robot_ref)
    written, source = load_gait(gait_ref)
    gait = bind_gait(written, source, robot)
    # awkward numbers: not representable in few digits, integers, negative zero avoided
    rng = np.random.default_rng(3)
    A = tuple(tuple(float(v) for v in row + rng.normal(0, 1e-3, len(row)) / 3.0)
              for row in np.array(gait.A))
    gait = replace(gait, A=A, kp=401.0, kd=np.float64(40) / 3.0, mu=0.65)
    out = tmp_path / "sub" / "g.yaml"
    ref = robot_reference(robot, robot_ref, out)
    thrusters = robot.thruster_names
    thrust = None
    if thrusters:
        thrust = ("force", [0.0, 1 / 3, 1.0], {thrusters[0]: [-10.0 / 3, 2.5]}, "N")
    text = gait_text(gait, robot, robot_ref=ref, description="a test: gait # not a comment",
                     header=["x: y", "two\nlines"], invariance="given", thrust=thrust)
    out.parent.mkdir()
    back, _ = _read_back(text, out, robot)
    assert back.c == gait.c and back.alpha_f == gait.alpha_f
    assert back.A == gait.A  # every coefficient bit for bit
    assert (back.kp, back.kd, back.mu) == (gait.kp, gait.kd, gait.mu)
    assert back.invariance == "given"
    if thrust is not None:
        assert back.thrust is not None
        assert back.thrust.mode == "force" and list(back.thrust.knots) == [0.0, 1 / 3, 1.0]
        assert dict(back.thrust.values)[thrusters[0]] == (-10.0 / 3, 2.5)
    # invariance: auto writes columns 0 and 1 as ~, and the reader accepts it
    auto = gait_text(gait, robot, robot_ref=ref, description="d", invariance="auto")
    assert all(line.split(": ", 1)[1].startswith("[~, ~, ")
               for line in auto.splitlines() if line.startswith("    ") and "[" in line)
    back2, _ = _read_back(auto, out, robot)
    assert back2.invariance == "auto"
    assert [r[2:] for r in back2.A] == [r[2:] for r in gait.A]


def test_robot_reference(tmp_path):
    robot = load_robot("rabbit")
    assert robot_reference(robot) == "rabbit"  # the bundled robot, by name
    assert robot_reference(robot, "rabbit", tmp_path / "g.yaml") == "rabbit"
    user = load_robot(str(DATA / "walker5.yaml"))
    assert robot_reference(user) == str((DATA / "walker5.yaml").resolve())
    rel = robot_reference(user, str(DATA / "walker5.yaml"), tmp_path / "a" / "g.yaml")
    assert (tmp_path / "a" / rel).resolve() == (DATA / "walker5.yaml").resolve()


def test_names_that_look_like_yaml_read_back(tmp_path):
    robot = load_robot("rabbit")
    written, source = load_gait("rabbit_walk")
    gait = replace(bind_gait(written, source, robot), name="walk: fast # v2")
    out = tmp_path / "g.yaml"
    text = gait_text(gait, robot, robot_ref="rabbit", description="'quoted' {braces}: x\ny")
    back, src = _read_back(text, out, robot)
    assert back.name == "walk: fast # v2"
