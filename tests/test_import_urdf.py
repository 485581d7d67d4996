"""``thrustwalk import-urdf`` (SPEC 16): robots from URDF.

Checks against independent computations:

* Pinocchio (``pin``, the test extra) builds its own model from the same URDF (its root is the
  URDF root, with a free-flyer joint); the test maps thrustwalk's coordinates to Pinocchio's
  by hand (below) with the stance foot pinned, and compares D, G, V and the swing foot at
  random states to 1e-10.
* The RABBIT URDF, written from the published numbers (its torso split in two bodies on a
  fixed joint), imports to the bundled ``rabbit`` (the same numbers typed by hand).
* A URDF exported from a thrustwalk robot and imported again gives the same model to 1e-12.
* Bad input: one line naming the URDF element and line, exit 2, nothing written.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
URDF = DATA / "urdf"
RABBIT = URDF / "rabbit.urdf"
ARM = URDF / "walker_arm.urdf"
FOOTBOT = URDF / "footbot.urdf"


def _import(urdf, stance, swing, **kw):
    from thrustwalk_cli.studies.import_urdf import import_urdf

    return import_urdf(urdf, stance, swing, **kw)


def _model(robot):
    from thrustwalk_cli.model.compiler import load_model

    return load_model(robot)


@pytest.fixture(scope="module")
def rabbit_import(_cache_dir):
    res = _import(RABBIT, "left_foot:0,0,0", "right_foot:0,0,0",
                  side=URDF / "rabbit_side.yaml")
    return res, _model(res.robot)


@pytest.fixture(scope="module")
def feet_import(_cache_dir):
    res = _import(FOOTBOT, "left_foot:0,0,-0.06", "right_foot:0,0,-0.06",
                  thrusters=["back:torso:0,0,0.3:1,0"])
    return res, _model(res.robot)


@pytest.fixture(scope="module")
def arm_import(_cache_dir):
    res = _import(ARM, "left_foot:0,0,-0.05", "right_foot:0,0,-0.05",
                  side=URDF / "walker_arm_side.yaml",
                  thrusters=["back:torso:-0.1,0,0.3:-1,0"])
    return res, _model(res.robot)


# ------------------------------------------------------------------------ Pinocchio, by hand
# Planar angles are counter-clockwise in the x-z plane (x forward, z up), i.e. right-handed
# about -y. A revolute joint whose axis points along +y in the world turns its child by
# -q_urdf counter-clockwise, one along -y by +q_urdf. thrustwalk's coordinate of a joint is
# theta_child - theta_parent in its own tree, rooted at the stance foot: between the stance
# foot and the URDF root the parent and child swap (one more sign). So q_urdf = f * q_tw:
#
# rabbit.urdf (stance: left foot; hips about +y, knees about -y in the world):
#   left_knee  -y, reversed: q_tw = -q_urdf  -> f = -1
#   left_hip   +y, reversed: q_tw = +q_urdf  -> f = +1
#   right_hip  +y, forward:  q_tw = -q_urdf  -> f = -1
#   right_knee -y, forward:  q_tw = +q_urdf  -> f = +1
RABBIT_MAP = {"left_knee": ("left_knee", -1), "left_hip": ("left_hip", 1),
              "right_hip": ("right_hip", -1), "right_knee": ("right_knee", 1)}
# walker_arm.urdf (stance: left foot). The right leg's frames are turned by pi about z, so its
# axes "0 -1 0" point along +y in the world; the elbow's "0 -1 0" along -y.
#   left_knee +y reversed: +1; left_hip +y reversed: +1; right_hip +y forward: -1;
#   right_knee +y forward: -1; shoulder (coordinate q_arm) +y forward: -1; elbow -y forward: +1
ARM_MAP = {"left_knee": ("left_knee", 1), "left_hip": ("left_hip", 1),
           "right_hip": ("right_hip", -1), "right_knee": ("right_knee", -1),
           "shoulder": ("q_arm", -1), "elbow": ("elbow", 1)}
# Rotors (side files; URDF has none): the reflected inertia J G^2 on each joint's velocity.
RABBIT_ROTORS = {j: 3.32e-4 * 50 ** 2 for j in RABBIT_MAP}
ARM_ROTORS = {"left_hip": 1e-4 * 100 ** 2, "right_hip": 1e-4 * 100 ** 2,
              "left_knee": 1.2e-4 * 80 ** 2, "right_knee": 1.2e-4 * 80 ** 2}
# footbot.urdf (stance: left foot, every axis +y in unrotated frames): the stance leg's joints
# reversed by the re-rooting (+1), the swing leg's forward (-1); no rotors
FEET_MAP = {f"{side}_{j}": (f"{side}_{j}", 1 if side == "left" else -1)
            for side in ("left", "right") for j in ("ankle", "knee", "hip")}


class PinnedPinocchio:
    """Pinocchio's model of ``urdf`` (free-flyer root = the URDF root, here the torso, whose
    counter-clockwise angle is thrustwalk's q_N) with the stance-foot point held at the
    origin: configuration and velocity as functions of thrustwalk's q and q'."""

    def __init__(self, urdf: Path, joint_map: dict, coords: list[str], rotors: dict,
                 stance: tuple[str, tuple], swing: tuple[str, tuple], gravity: float,
                 root_row: np.ndarray | None = None):
        import pinocchio as pin

        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
        self.model.gravity.linear = np.array([0.0, 0.0, -gravity])
        self.data = self.model.createData()
        self.map = {j: (coords.index(c), f) for j, (c, f) in joint_map.items()}
        self.iN = len(coords) - 1  # q_N is last
        # the URDF root's counter-clockwise angle = root_row @ q (default: q_N itself)
        self.root_row = np.eye(len(coords))[self.iN] if root_row is None else root_row
        self.stance = (self.model.getFrameId(stance[0]), np.array(stance[1], float))
        self.swing = (self.model.getFrameId(swing[0]), np.array(swing[1], float))
        self.arm = np.zeros(self.model.nv)
        for j, a in rotors.items():
            self.arm[self.model.joints[self.model.getJointId(j)].idx_v] = a
        self.g = gravity

    def point(self, frame) -> np.ndarray:
        fid, p = frame
        return self.data.oMf[fid].act(p)

    def configuration(self, q: np.ndarray) -> np.ndarray:
        pin = self.pin
        qp = pin.neutral(self.model)
        rot = pin.utils.rotate("y", -self.root_row @ q)  # counter-clockwise = about -y
        qp[3:7] = pin.Quaternion(rot).coeffs()
        for j, (i, f) in self.map.items():
            jm = self.model.joints[self.model.getJointId(j)]
            a = f * q[i]
            if jm.nq == 2:  # continuous: (cos, sin)
                qp[jm.idx_q:jm.idx_q + 2] = math.cos(a), math.sin(a)
            else:
                qp[jm.idx_q] = a
        pin.framesForwardKinematics(self.model, self.data, qp)
        qp[:3] -= self.point(self.stance)  # the stance foot at the origin
        pin.framesForwardKinematics(self.model, self.data, qp)
        return qp

    def velocity_map(self, q: np.ndarray, qp: np.ndarray) -> np.ndarray:
        """Phi with v = Phi q' (Pinocchio's velocity: the root's linear and angular velocity
        in its own frame, then the joint rates), the stance foot's velocity held at 0."""
        pin = self.pin
        pin.computeJointJacobians(self.model, self.data, qp)
        pin.updateFramePlacements(self.model, self.data)
        fid, p = self.stance
        J = pin.getFrameJacobian(self.model, self.data, fid, pin.LOCAL_WORLD_ALIGNED)
        r = self.data.oMf[fid].rotation @ p
        skew = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
        Jp = J[:3] - skew @ J[3:]  # velocity of the foot point: v_o + w x r
        rot = self.data.oMi[1].rotation
        n = len(q)
        Phi = np.zeros((self.model.nv, n))
        for k in range(n):
            e = np.zeros(n)
            e[k] = 1.0
            v = np.zeros(self.model.nv)
            v[3:6] = rot.T @ np.array([0.0, -self.root_row @ e, 0.0])
            for j, (i, f) in self.map.items():
                v[self.model.joints[self.model.getJointId(j)].idx_v] = f * e[i]
            v[:3] = -np.linalg.solve(Jp[:, :3], Jp[:, 3:] @ v[3:])
            Phi[:, k] = v
        return Phi

    def pinned(self, q: np.ndarray) -> dict:
        """D = Phi^T (M + diag(rotors)) Phi, G = m g dz_com/dq, V, swing foot (x, z)."""
        pin = self.pin
        qp = self.configuration(q)
        Phi = self.velocity_map(q, qp)
        M = pin.crba(self.model, self.data, qp)
        M = np.triu(M) + np.triu(M, 1).T
        Jc = pin.jacobianCenterOfMass(self.model, self.data, qp)
        mass = sum(i.mass for i in self.model.inertias)
        V = pin.computePotentialEnergy(self.model, self.data, qp)
        pin.framesForwardKinematics(self.model, self.data, qp)
        return {"D": Phi.T @ (M + np.diag(self.arm)) @ Phi,
                "G": mass * self.g * (Jc[2] @ Phi), "V": V,
                "swing": self.point(self.swing)[[0, 2]]}


@pytest.mark.parametrize("case", ["rabbit", pytest.param("arm", marks=pytest.mark.slow),
                                  pytest.param("feet", marks=pytest.mark.slow)])
def test_imported_D_and_G_equal_pinocchio(case, request):
    """(The arm walker and the walker with feet are marked slow: compiling 7 links costs
    about 7 s of CPU.) The feet: the stance foot is a link pinned at a point of its sole, the
    ankles are coordinates."""
    pytest.importorskip("pinocchio")
    if case == "rabbit":
        (res, model), path, jmap, rotors = (request.getfixturevalue("rabbit_import"), RABBIT,
                                            RABBIT_MAP, RABBIT_ROTORS)
        stance, swing = ("left_foot", (0, 0, 0)), ("right_foot", (0, 0, 0))
    elif case == "feet":
        (res, model), path, jmap, rotors = (request.getfixturevalue("feet_import"), FOOTBOT,
                                            FEET_MAP, {})
        stance, swing = ("left_foot", (0, 0, -0.06)), ("right_foot", (0, 0, -0.06))
    else:
        (res, model), path, jmap, rotors = (request.getfixturevalue("arm_import"), ARM,
                                            ARM_MAP, ARM_ROTORS)
        stance, swing = ("left_foot", (0, 0, -0.05)), ("right_foot", (0, 0, -0.05))
    robot = res.robot
    ref = PinnedPinocchio(path, jmap, robot.coordinate_names, rotors, stance, swing,
                          robot.gravity)
    rng = np.random.default_rng(7)
    for _ in range(6):
        q = rng.uniform(-1.2, 1.2, robot.n)
        want = ref.pinned(q)
        D = model.D(q)
        assert np.abs(D - want["D"]).max() <= 1e-10 * max(1.0, np.abs(D).max()), case
        assert np.abs(model.G(q) - want["G"]).max() <= 1e-10 * max(1.0, robot.total_mass), case
        assert abs(float(np.ravel(model.V(q))[0]) - want["V"]) <= 1e-10 * robot.total_mass
        assert np.abs(model.p_swing(q) - want["swing"]).max() <= 1e-12
    # the rotors are in: without them Pinocchio's D differs by J G^2 on the joints
    assert case == "feet" or max(rotors.values()) > 0.5


def test_rabbit_urdf_is_the_published_rabbit(rabbit_import, rabbit):
    """The URDF from Chevallereau et al.'s numbers (torso split over a fixed joint, legs 0.1
    m off the plane, gear ratio in the transmissions, rotor inertia in the side file) is the
    bundled RABBIT typed from the same numbers: D, G, B_F, feet, R (coordinates in the same
    order: stance knee, stance hip, swing hip, swing knee, torso angle)."""
    res, model = rabbit_import
    rng = np.random.default_rng(3)
    for _ in range(6):
        q = rng.uniform(-1, 1, 5)
        for f in ("D", "G", "B_F", "p_swing", "p_com"):
            a, b = getattr(model, f)(q), getattr(rabbit, f)(q)
            assert np.abs(a - b).max() <= 1e-12, f
    assert np.array_equal(model.R, rabbit.R)
    assert res.robot.stance_foot.point == (0.0, 0.0)
    assert res.robot.swing_foot.point == pytest.approx((0.0, -0.4), abs=1e-15)
    torso = next(lk for lk in res.robot.links if lk.name == "torso")
    assert torso.mass == 12.0 and torso.inertia == pytest.approx(1.33, abs=1e-14)
    assert torso.com == pytest.approx((0.0, 0.24), abs=1e-15)
    assert res.imported.merged["torso"] == ("torso", "battery", "imu")
    assert res.imported.swap == (("left_tibia", "right_tibia"), ("left_femur", "right_femur"))
    knee = {c.name: c for c in res.robot.coordinates}
    assert knee["left_knee"].range == (0.0, 2.5) and knee["right_knee"].range == (-2.5, 0.0)
    assert knee["left_hip"].torque_limit == 150.0
    assert any("out-of-plane" in n and "torso +0.1 m" in n for n in res.notes)


# ------------------------------------------------------------------------------ round trip
@pytest.mark.parametrize("ref", ["three_link", "rabbit", str(DATA / "walker5.yaml")])
def test_exported_urdf_imports_to_the_same_model(ref, tmp_path):
    from thrustwalk_cli.files.robot_file import load_robot
    from thrustwalk_cli.interchange.urdf import robot_side, robot_to_urdf

    robot = load_robot(ref)
    (tmp_path / "r.urdf").write_text(robot_to_urdf(robot))
    (tmp_path / "side.yaml").write_text(robot_side(robot))
    res = _import(tmp_path / "r.urdf", None, None, side=tmp_path / "side.yaml")
    back = res.robot
    assert back.coordinate_names == robot.coordinate_names
    assert back.link_names == robot.link_names
    a, b = _model(robot), _model(back)
    rng = np.random.default_rng(1)
    for _ in range(6):
        q = rng.uniform(-1, 1, robot.n)
        for f in ("D", "G", "B_F", "p_swing"):
            assert np.abs(getattr(a, f)(q) - getattr(b, f)(q)).max() <= 1e-12, (ref, f)
    assert np.abs(a.R - b.R).max() <= 1e-12 and np.array_equal(a.b, b.b)
    for foot in ("stance_foot", "swing_foot"):
        pa, pb = getattr(robot, foot), getattr(back, foot)
        assert pa.link == pb.link and np.allclose(pa.point, pb.point, rtol=0, atol=1e-12)
    for ca, cb in zip(robot.coordinates, back.coordinates):
        assert (ca.range, ca.torque_limit) == (cb.range, cb.torque_limit)


@pytest.mark.parametrize("ref", ["three_link", "rabbit"])
def test_exported_urdf_is_the_same_robot_for_pinocchio(ref, tmp_path):
    """robot_to_urdf checked by an independent reader: the URDF is rooted at the stance link,
    every joint turns about 0 -1 0 (URDF angle = thrustwalk's relative angle, factor +1); the
    root's angle is q_N minus the relative angles on the path from the root to q_N's link."""
    pytest.importorskip("pinocchio")
    from thrustwalk_cli.files.robot_file import load_robot
    from thrustwalk_cli.interchange.urdf import robot_to_urdf

    robot = load_robot(ref)
    (tmp_path / "r.urdf").write_text(robot_to_urdf(robot))
    act = [c for c in robot.coordinates if c.actuated]
    un = next(c for c in robot.coordinates if not c.actuated)
    names = robot.coordinate_names
    root_row = np.zeros(robot.n)
    root_row[names.index(un.name)] = 1.0
    parent = {lk.name: lk.parent for lk in robot.links}
    of_link = {c.link: c.name for c in act}
    link = un.link
    while parent[link] is not None:  # theta_link - theta_parent = its joint's coordinate
        root_row[names.index(of_link[link])] -= 1.0
        link = parent[link]
    stance = (robot.stance_foot.link, (robot.stance_foot.point[0], 0.0,
                                       robot.stance_foot.point[1]))
    swing = (robot.swing_foot.link, (robot.swing_foot.point[0], 0.0, robot.swing_foot.point[1]))
    ref_model = PinnedPinocchio(tmp_path / "r.urdf", {c.name: (c.name, 1) for c in act},
                                robot.coordinate_names,
                                {c.name: lk.rotor_inertia for c in act for lk in robot.links
                                 if lk.name == c.link}, stance, swing, robot.gravity,
                                root_row)
    model = _model(robot)
    rng = np.random.default_rng(5)
    for _ in range(4):
        q = rng.uniform(-1, 1, robot.n)
        want = ref_model.pinned(q)
        assert np.abs(model.D(q) - want["D"]).max() <= 1e-10 * np.abs(want["D"]).max()
        assert np.abs(model.G(q) - want["G"]).max() <= 1e-10 * robot.total_mass


def test_rotated_inertia_and_merging_by_hand():
    """walker_arm's torso: n^T (R I R^T) n plus the head by the parallel-axis theorem, computed
    here from the URDF's numbers."""
    res = _import(ARM, "left_foot:0,0,-0.05", "right_foot:0,0,-0.05")
    r, p, y = 0.2, 0.3, -0.1
    Rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    Ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    Rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    R = Rz @ Ry @ Rx
    I = np.array([[0.9, 0.01, 0.05], [0.01, 1.1, -0.02], [0.05, -0.02, 0.4]])
    Iyy = (R @ I @ R.T)[1, 1]
    c_t, c_h = np.array([0.02, 0.25]), np.array([0.01 + 0.02, 0.55 + 0.1])  # (x, z)
    c = (15 * c_t + 3 * c_h) / 18
    want = Iyy + 15 * np.sum((c_t - c) ** 2) + 0.012 + 3 * np.sum((c_h - c) ** 2)
    torso = next(lk for lk in res.robot.links if lk.name == "torso")
    assert torso.mass == 18.0
    assert torso.inertia == pytest.approx(want, rel=1e-13)
    # the torso frame's origin is the left hip (0, 0.12, -0.05): com relative to it
    assert torso.com == pytest.approx((c[0], c[1] + 0.05), abs=1e-14)


def test_another_plane_gives_the_same_model():
    """The RABBIT URDF with x and y exchanged everywhere (positions, axes, inertia tensors)
    walks in its y-z plane: imported with plane yz it has the same numbers and relabelling as
    the x-z original (the joint signs flip with the mirrored axes; the planar geometry does
    not)."""
    import re

    text = RABBIT.read_text()
    text = re.sub(r'xyz="(\S+) (\S+) (\S+)"', r'xyz="\2 \1 \3"', text)
    text = re.sub(r'ixx="(\S+)" ixy="(\S+)" ixz="(\S+)" iyy="(\S+)" iyz="(\S+)"',
                  r'ixx="\4" ixy="\2" ixz="\5" iyy="\1" iyz="\3"', text)
    assert 'axis xyz="1 0 0"' in text and 'xyz="0.1 0 0"' in text
    feet = ("left_foot:0,0,0", "right_foot:0,0,0")
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        turned = Path(tmp) / "rabbit_yz.urdf"
        turned.write_text(text)
        a = _import(RABBIT, *feet).robot
        b = _import(turned, *feet, plane="yz").robot
    assert [k for k, _ in b.numbers()] == [k for k, _ in a.numbers()]
    assert np.allclose([v for _, v in b.numbers()], [v for _, v in a.numbers()], rtol=0,
                       atol=1e-15)
    assert b.structure() == a.structure()
    assert [c.range for c in b.coordinates] == [tuple(-x for x in c.range[::-1])
                                                for c in a.coordinates]


# ------------------------------------------------------------------------------ command line
def test_cli_writes_a_commented_robot_that_compiles(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = cli("import-urdf", str(RABBIT), "--stance-foot", "left_foot:0,0,0", "--swing-foot",
              "right_foot:0,0,0", "--side", str(URDF / "rabbit_side.yaml"), "--out",
              "rabbit.yaml")
    assert res.exit_code == 0, res.output
    assert "out-of-plane" in res.stderr and "torso" in res.stdout
    text = Path("rabbit.yaml").read_text()
    # every number names its URDF element and line
    for line in text.splitlines():
        if line.lstrip().startswith(("mass:", "com:", "inertia:", "joint:")):
            assert "line " in line and "#" in line, line
    torso = RABBIT.read_text()
    lines = [_line_of(torso, '<mass value="10.0"/>'), _line_of(torso, '<mass value="2.0"/>')]
    assert f"sum of <mass> of torso line {lines[0]}; battery line {lines[1]}" in text
    red = _line_of(torso, '<actuator name="left_hip_motor">')
    assert f"gear ratio: <transmission> mechanicalReduction line {red}" in text
    assert "# Command: thrustwalk import-urdf" in text
    res = cli("compile", "rabbit.yaml", "--no-kernel", "-q")
    assert res.exit_code == 0, res.output
    # numbers as the URDF gives them (the femur's 0.16 m centre of mass, not the frames'
    # 0.16000000000000003), and the file is the imported robot to 1e-12
    assert not re.search(r"\d\.\d{13,}", text), re.search(r"\S*\d\.\d{13,}\S*", text)
    from thrustwalk_cli.files.robot_file import load_robot

    res = _import(RABBIT, "left_foot:0,0,0", "right_foot:0,0,0", side=URDF / "rabbit_side.yaml")
    written, imported = _model(load_robot("rabbit.yaml")), _model(res.robot)
    q = np.random.default_rng(5).uniform(-1, 1, (6, 5))
    for f in ("D", "G", "p_swing"):
        a, b = getattr(written, f)(q), getattr(imported, f)(q)
        assert np.abs(a - b).max() <= 1e-12 * max(np.abs(b).max(), 1.0), f
    # the walker with feet: the ankle 0.06 m above the sole's contact point, not
    # 0.06000000000000005
    res = cli("import-urdf", str(FOOTBOT), "--stance-foot", "left_foot:0,0,-0.06",
              "--swing-foot", "right_foot:0,0,-0.06", "--out", "footbot.yaml", "-q")
    assert res.exit_code == 0, res.output
    feet = Path("footbot.yaml").read_text()
    assert "joint: [0.0, 0.06]" in feet and not re.search(r"\d\.\d{13,}", feet)


def test_cli_help_has_examples(cli):
    res = cli("import-urdf", "--help")
    assert res.exit_code == 0
    assert "--stance-foot" in res.output and "Example" in res.output


# --------------------------------------------------------------------------------- bad input
def _rabbit_with(old: str, new: str, count: int = 1) -> str:
    text = RABBIT.read_text()
    assert old in text, old
    return text.replace(old, new, count)


def _line_of(text: str, needle: str) -> int:
    return text[: text.index(needle)].count("\n") + 1


FEET = ("--stance-foot", "left_foot:0,0,0", "--swing-foot", "right_foot:0,0,0")

BAD = {
    "axis not normal": (_rabbit_with('<axis xyz="0 -1 0"/>', '<axis xyz="1 0 0"/>'),
                        '<axis xyz="1 0 0"/>', r'<joint name="left_knee">: <axis xyz="1 0 0">'
                        r".* not along the normal"),
    "prismatic": (_rabbit_with('name="left_knee" type="revolute"',
                               'name="left_knee" type="prismatic"'),
                  'name="left_knee" type="prismatic"',
                  r'<joint name="left_knee">: type="prismatic" is a prismatic joint'),
    "closed loop": (_rabbit_with("  <transmission", '  <joint name="loop" type="revolute">\n'
                                 '    <parent link="right_foot"/><child link="left_foot"/>\n'
                                 '    <axis xyz="0 1 0"/>\n  </joint>\n  <transmission'),
                    '<joint name="loop"', r'<joint name="loop">: closed loop: link '
                    r"'left_foot' is already the child of joint 'left_ankle'"),
    "cycle": (_rabbit_with("  <transmission", '  <joint name="loop" type="revolute">\n'
                           '    <parent link="right_foot"/><child link="torso"/>\n'
                           '    <axis xyz="0 1 0"/>\n  </joint>\n  <transmission'),
              '<joint name="loop"', r'<joint name="loop">: closed loop through link '
              r"'torso'"),
    "missing inertial": (_rabbit_with("""<link name="left_femur">
    <inertial>
      <origin xyz="0 0 -0.11" rpy="0 0 0"/>
      <mass value="6.8"/>
      <inertia ixx="0.47" ixy="0" ixz="0" iyy="0.47" iyz="0" izz="0.01"/>
    </inertial>""", '<link name="left_femur">'), '<link name="left_femur">',
                         r'<link name="left_femur">: no <inertial>'),
    "zero mass": (_rabbit_with('<mass value="3.2"/>', '<mass value="0"/>'),
                  '<mass value="0"/>', r'<link name="left_tibia">: <mass value="0">: a link\'s '
                  r"mass must be > 0"),
    "negative mass": (_rabbit_with('<mass value="3.2"/>', '<mass value="-3.2"/>'),
                      '<mass value="-3.2"/>', r'<link name="left_tibia">: <mass value="-3.2">: '
                      r"a link's mass must be > 0"),
    "inertia not positive": (_rabbit_with('ixx="0.47" ixy="0" ixz="0" iyy="0.47"',
                                          'ixx="0.47" ixy="0.9" ixz="0" iyy="0.47"'),
                             'ixy="0.9"', r'<link name="left_femur">: <inertia> is not a rigid '
                             r"body's inertia .* negative principal moment"),
    "triangle inequality": (_rabbit_with('ixx="1.30" ixy="0" ixz="0" iyy="1.30" iyz="0" '
                                         'izz="0.05"', 'ixx="0.1" ixy="0" ixz="0" iyy="1.30" '
                                         'iyz="0" izz="0.05"'), 'ixx="0.1"',
                            r'<link name="torso">: <inertia> is not a rigid body\'s inertia .* '
                            r"triangle inequality"),
    "not XML": (_rabbit_with("</robot>", "</robt>"), "</robt>", r"not well-formed XML"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_urdf_is_one_line_naming_the_element(case, cli, tmp_path, monkeypatch):
    text, needle, pattern = BAD[case]
    monkeypatch.chdir(tmp_path)
    Path("bad.urdf").write_text(text)
    res = cli("import-urdf", "bad.urdf", *FEET, "--out", "out.yaml")
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1, res.stderr
    import re

    line = _line_of(text, needle)
    assert re.match(rf"error: bad\.urdf:{line}: {pattern}", lines[0]), (lines[0], line)
    assert not Path("out.yaml").exists() and "Traceback" not in res.output


@pytest.mark.parametrize("args, pattern", [
    (("--stance-foot", "left_fot:0,0,0", "--swing-foot", "right_foot:0,0,0"),
     r"option --stance-foot: unknown link 'left_fot' in .*rabbit\.urdf \(links: torso, "),
    (("--stance-foot", "left_foot:0,0,0", "--swing-foot", "right_foot:0,0"),
     r"option --swing-foot: the point X,Y,Z \[m\]: expected 3"),
    (("--stance-foot", "left_foot:0,0,0", "--swing-foot", "left_tibia:0,0,0"),
     r"option --swing-foot: the swing foot's link 'left_tibia' is on the stance foot's body"),
    (("--stance-foot", "left_foot:0,0,0"), r"option --swing-foot: required"),
    ((*FEET, "--thruster", "t:nowhere:0,0,0:1,0"), r"option --thruster: unknown link "
                                                   r"'nowhere'"),
    ((*FEET, "--unactuated", "tors"), r"option --unactuated: unknown link 'tors'"),
    ((*FEET, "--plane", "xy"), r"rabbit\.urdf:\d+: <joint name=\"left_hip\">: <axis"),
])
def test_bad_options_are_one_line(args, pattern, cli, tmp_path, monkeypatch):
    import re

    monkeypatch.chdir(tmp_path)
    res = cli("import-urdf", str(RABBIT), *args, "--out", "out.yaml")
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2, res.output
    assert re.search(pattern, lines[0]), lines
    assert not Path("out.yaml").exists()


def test_asymmetric_legs_are_refused_unless_a_relabelling_is_given(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text = RABBIT.read_text()
    i = text.index('<link name="right_tibia">')
    Path("lopsided.urdf").write_text(text[:i] + text[i:].replace('<mass value="3.2"/>',
                                                                 '<mass value="3.3"/>', 1))
    res = cli("import-urdf", "lopsided.urdf", *FEET, "--out", "out.yaml")
    assert res.exit_code == 2 and "not mirror images (left_tibia and right_tibia: mass" \
        in res.stderr, res.stderr
    Path("side.yaml").write_text("relabel: {swap: [[left_foot, right_foot], "
                                 "[left_femur, right_femur]]}\n")
    res = cli("import-urdf", "lopsided.urdf", *FEET, "--side", "side.yaml", "--out", "out.yaml")
    assert res.exit_code == 0, res.stderr
    swap = next(ln for ln in Path("out.yaml").read_text().splitlines() if "swap:" in ln)
    assert swap.startswith("  swap: [[left_tibia, right_tibia], [left_femur, right_femur]]")
    assert swap.endswith("# given")


LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
 <!ENTITY lol5 "&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;">
 <!ENTITY lol6 "&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;">
 <!ENTITY lol7 "&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;">
 <!ENTITY lol8 "&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;">
 <!ENTITY lol9 "&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;">
]>
<robot name="&lol9;"><link name="a"/></robot>
"""
EXTERNAL = """<?xml version="1.0"?>
<!DOCTYPE robot [<!ENTITY secret SYSTEM "file:///etc/passwd">]>
<robot name="x"><link name="&secret;"/></robot>
"""
EXTERNAL_DTD = """<?xml version="1.0"?>
<!DOCTYPE robot SYSTEM "http://example.invalid/robot.dtd">
<robot name="x"><link name="a"/></robot>
"""


@pytest.mark.parametrize("text, pattern", [
    (LAUGHS, r"bad\.urdf:2: a document type declaration .* is refused: a URDF is untrusted XML"),
    (EXTERNAL, r"bad\.urdf:2: a document type declaration"),
    (EXTERNAL_DTD, r"bad\.urdf:2: a document type declaration"),
])
def test_hostile_xml_is_refused_unexpanded(text, pattern, cli, tmp_path, monkeypatch):
    import re
    import resource
    import time

    monkeypatch.chdir(tmp_path)
    Path("bad.urdf").write_text(text)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.process_time()
    res = cli("import-urdf", "bad.urdf", *FEET, "--out", "out.yaml")
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1, res.stderr
    assert re.match("error: " + pattern, lines[0]), lines[0]
    assert time.process_time() - t0 < 5  # nothing was expanded (a bound, not a benchmark)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 50_000  # [kB]
    assert not Path("out.yaml").exists()


def test_a_100_MB_urdf_is_refused_before_reading(cli, tmp_path, monkeypatch):
    from thrustwalk_cli.files.urdf_file import MAX_URDF_MB

    monkeypatch.chdir(tmp_path)
    with open("huge.urdf", "wb") as fh:  # sparse: 100 MB on paper, nothing on disk
        fh.write(b"<robot>")
        fh.truncate(100 * 1024 * 1024)
    assert os.path.getsize("huge.urdf") == 100 * 1024 * 1024
    res = cli("import-urdf", "huge.urdf", *FEET, "--out", "out.yaml")
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1
    assert lines[0] == (f"error: huge.urdf: file of 100 MB: a URDF may have at most "
                        f"{MAX_URDF_MB} MB")
    assert not Path("out.yaml").exists()


def test_meshes_are_never_opened(tmp_path, monkeypatch):
    """The RABBIT URDF names 8 meshes that do not exist: the import reads only the URDF."""
    import builtins
    import io

    opened = []
    real = io.open

    def spy(file, *a, **kw):
        opened.append(str(file))
        return real(file, *a, **kw)

    monkeypatch.setattr(builtins, "open", spy)
    monkeypatch.setattr(io, "open", spy)
    res = _import(RABBIT, "left_foot:0,0,0", "right_foot:0,0,0")
    assert res.urdf.meshes == 8
    assert str(RABBIT) in opened  # the spy sees the reads
    assert not any("mesh" in f or f.endswith((".dae", ".stl")) for f in opened), opened


@pytest.mark.parametrize("side, pattern", [
    ("joints:\n  left_kne: {rotor_inertia: 1.0e-4}\n",
     r"error: side\.yaml:2: joints\.left_kne: unknown joint 'left_kne' in .*rabbit\.urdf"),
    ("joints:\n  left_ankle: {rotor_inertia: 1.0e-4}\n",
     r"error: side\.yaml:2: joints\.left_ankle: joint 'left_ankle' is fixed"),
    ("joints:\n  left_knee: {rotor_inertia: -1}\n",
     r"error: side\.yaml:2: joints\.left_knee\.rotor_inertia: must be >= 0"),
    ("unactuated: {link: tors}\n", r"error: side\.yaml:1: unactuated\.link: unknown link 'tors'"),
    ("relabel: {swap: [[left_foot, right_foot]], R: [[1]]}\n",
     r"error: side\.yaml:1: relabel: give exactly one of `swap` or `R`"),
    (None, r"error: .*three_link\.yaml: this is a robot file, not a URDF side file"),
])
def test_side_file_problems_name_the_side_file_line(side, pattern, cli, tmp_path,
                                                   monkeypatch):
    import re

    monkeypatch.chdir(tmp_path)
    if side is None:
        path = str(Path(__file__).parents[1] / "robots" / "three_link.yaml")
    else:
        Path("side.yaml").write_text(side)
        path = "side.yaml"
    res = cli("import-urdf", str(RABBIT), *FEET, "--side", path, "--out", "out.yaml")
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1, res.stderr
    assert re.match(pattern, lines[0]), lines[0]
    assert not Path("out.yaml").exists()
