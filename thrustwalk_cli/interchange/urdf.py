"""URDF -> thrustwalk robot, and thrustwalk robot -> planar URDF (SPEC 16).

**Import** (:func:`import_robot`, on a :class:`~thrustwalk_cli.files.urdf_file.Urdf` read by
``files/``). Conventions:

* The sagittal plane is spanned by two axes ``e1`` (forward, thrustwalk x) and ``e2`` (up,
  thrustwalk y) of the URDF root link's frame: ``xz`` (default), ``yz`` or ``xy``. Angles are
  counter-clockwise in the plane, i.e. right-handed about ``n = e1 x e2`` (``-y`` for xz).
  Gravity acts along ``-e2``.
* Poses are computed at the URDF's zero configuration (every joint angle 0). Each fixed
  joint merges its child into its parent: the masses add, the centre of mass is the
  mass-weighted mean and the 3 x 3 inertia tensors (each rotated into the root frame:
  ``R I R^T`` with the link's and the ``<inertial>``'s rotations) add by the parallel-axis
  theorem ``I_c = sum_i [I_i + m_i (|d_i|^2 E - d_i d_i^T)]``. A body keeps its mass, its
  centre of mass projected on the plane and ``n^T I_c n``, its inertia about the plane
  normal. The out-of-plane offsets dropped (``n . c``) are reported: for planar motion about
  ``n`` they change neither the kinetic nor the potential energy.
* Every movable joint is revolute or continuous with its axis ``a`` (in the root frame at the
  zero configuration) along ``+-n``; its sign ``s = a . n``.
* The tree is re-rooted at the stance foot's body. A thrustwalk link frame is parallel to the
  world at the URDF's zero configuration (so q = 0 is the URDF's zero pose); its origin is the
  joint to its thrustwalk parent (the URDF child link's origin), the root's is the stance foot.
  The relative angle of a joint is ``s q_urdf`` when the URDF parent stays the parent, and
  ``-s q_urdf`` where re-rooting reversed the joint.

**Export** (:func:`robot_to_urdf`, :func:`robot_side`): the planar robot as URDF in the x-z
plane, thrustwalk's links as links (a lamina: ``iyy = I``, ``ixx = izz = I/2``), each joint a
revolute joint about ``0 -1 0`` (so the URDF angle is thrustwalk's relative angle) at the
URDF zero pose ``q = 0``; what URDF cannot carry (feet, thrusters, rotors, relabelling,
gravity, the unactuated coordinate) goes into the side file.

One idea in one file (above 600 lines): the mapping between a URDF and a planar robot,
import and export, whose conventions (planes, signs, re-rooting, merged bodies) must be read
together.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .._version import __version__
from ..description.robot import Robot
from ..errors import InputError, Problem, Where, check_instance, locate
from ..files.robot_file import MAX_LINKS, load_robot_text
from ..files.urdf_file import Urdf, UrdfJoint

Vec3 = tuple[float, float, float]

#: the plane's forward and up axes in the URDF root frame
PLANES: dict[str, tuple[Vec3, Vec3]] = {
    "xz": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "yz": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "xy": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
}
AXIS_TOL = 1e-9  # |a x n| above this: the joint axis is not normal to the plane
SNAP = 1e-14  # [SI] round-off of the rotations below this is written as 0
SYMMETRY_TOL = 1e-9  # [m, relative] legs differing more are not mirror images


# ------------------------------------------------------------------------------- the request
@dataclass(frozen=True)
class PointSpec:
    """A point on a URDF link, in that link's frame [m]; ``where``/``key`` locate problems
    (a parameter name, or a side file's locator and key path); ``source`` names it in the
    robot file's comments."""

    link: str
    point: Vec3
    where: Where = "link"
    key: tuple = ()
    source: str = ""


@dataclass(frozen=True)
class ThrusterSpec:
    """A thruster at ``point`` [m] of URDF link ``link`` pushing along ``direction`` (the
    plane's two axes, at the URDF zero pose), fixed in the ``world`` or the ``link``."""

    name: str
    link: str
    point: Vec3
    direction: tuple[float, float]
    frame: str = "world"
    limits: tuple[float, float] = (-1e3, 1e3)
    where: Where = "thrusters"
    key: tuple = ()
    source: str = ""


@dataclass(frozen=True)
class JointSpec:
    """What a side file says of a URDF joint: coordinate name, rotor inertia [kg m^2], gear
    ratio, torque limit [N m], range of the URDF joint angle [rad] (None: not given)."""

    name: str | None = None
    rotor_inertia: float | None = None
    gear_ratio: float | None = None
    torque_limit: float | None = None
    range: tuple[float, float] | None = None
    where: Where = "side"
    key: tuple = ()
    source: str = ""


@dataclass(frozen=True)
class ImportSpec:
    """Everything an import needs besides the URDF (from options and the side file)."""

    stance_foot: PointSpec
    swing_foot: PointSpec
    plane: str = "xz"
    thrusters: tuple[ThrusterSpec, ...] = ()
    unactuated: str | None = None
    unactuated_name: str | None = None
    unactuated_where: Where = "unactuated"
    unactuated_key: tuple = ()
    joints: dict[str, JointSpec] = field(default_factory=dict)
    relabel: dict | None = None  # {"swap": [[a, b]], "R": ..., "b": ...} (URDF link names)
    relabel_where: Where = "side"
    gravity: float = 9.81
    gravity_source: str = "not in a URDF: thrustwalk's default"
    name: str | None = None
    description: str = ""
    command: str = ""
    file: str = "imported.yaml"  # the robot file's name, in messages


@dataclass(frozen=True)
class ImportedRobot:
    """The result of an import: the commented robot YAML, the :class:`Robot` it describes,
    the notes (out-of-plane offsets dropped, merged links, rotors, the relabelling), the
    leg pairs swapped at impact and the URDF links merged into each thrustwalk link."""

    yaml: str
    robot: Robot
    notes: tuple[str, ...]
    swap: tuple[tuple[str, str], ...]
    merged: dict[str, tuple[str, ...]]
    reversed_joints: tuple[str, ...]


# ------------------------------------------------------------------------------ geometry
def _rot(rpy: Sequence[float]) -> np.ndarray:
    """URDF rotation ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    r, p, y = (float(v) for v in rpy)
    if r == p == y == 0.0:
        return np.eye(3)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), \
        math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _snap(x: float) -> float:
    x = float(x)
    return 0.0 if abs(x) < SNAP else x


DIGITS = 14  # significant digits of a written number


def _num(x: float) -> str:
    """A float as YAML reads it back (repr; ``1e-05`` -> ``1.0e-05``), to ``DIGITS``
    significant digits: the frames' arithmetic leaves rounding noise in the last digits of a
    double (0.16000000000000003 for a URDF's 0.16, 0.06000000000000005 for its 0.06), which
    the file does not repeat (a change of at most 5e-14 relative, far below what a URDF's
    numbers say)."""
    s = repr(float(f"{_snap(x):.{DIGITS}g}"))
    if "e" in s:
        mant, exp = s.split("e")
        if "." not in mant:
            mant += ".0"
        s = f"{mant}e{exp}"
    return s


def _vec(v: Sequence[float]) -> str:
    return "[" + ", ".join(_num(x) for x in v) + "]"


_PLAIN = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*")
_YAML_WORDS = {"y", "n", "yes", "no", "on", "off", "true", "false", "null"}


def _name(s: str) -> str:
    """A name as a YAML scalar: plain when safe, else a double-quoted (JSON) string."""
    if _PLAIN.fullmatch(s) and s.lower() not in _YAML_WORDS:
        return s
    return json.dumps(s)


def _safe(text: str, most: int = 60) -> str:
    """Text for a comment: one line, printable, bounded."""
    t = "".join(ch if ch.isprintable() else "?" for ch in str(text))
    return t if len(t) <= most else t[: most - 3] + "..."


# ------------------------------------------------------------------------------- bodies
@dataclass
class _Body:
    """A rigid body: URDF links joined by fixed joints (poses at the zero configuration)."""

    name: str
    top: str
    members: list[str]
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    sources: list = field(default_factory=list)  # (URDF link, its UrdfInertial)
    fixed: list[str] = field(default_factory=list)


class _Importer:
    def __init__(self, urdf: Urdf, spec: ImportSpec):
        self.u = urdf
        self.spec = spec
        if spec.plane not in PLANES:
            raise InputError.param("plane", f"unknown plane {spec.plane!r} (choose from "
                                            f"{', '.join(PLANES)})")
        e1, e2 = (np.array(a) for a in PLANES[spec.plane])
        self.e1, self.e2, self.n = e1, e2, np.cross(e1, e2)
        self.axes = spec.plane[0] + "-" + spec.plane[1]
        self.notes: list[str] = []

    def problem(self, line: int | None, element: str, message: str) -> Problem:
        return self.u.problem(line, element, message)

    def proj(self, v: np.ndarray) -> tuple[float, float]:
        return float(self.e1 @ v), float(self.e2 @ v)

    # -- the URDF tree ----------------------------------------------------------------------
    def tree(self) -> None:
        u = self.u
        problems: list[Problem] = []
        parent_joint: dict[str, UrdfJoint] = {}
        for j in u.joints:
            if j.type not in ("revolute", "continuous", "fixed"):
                why = {"prismatic": "a prismatic joint: thrustwalk's links are joined by "
                                    "revolute joints only",
                       "floating": "a floating joint: thrustwalk pins the stance foot "
                                   "(remove the floating base; the root is found from the "
                                   "stance foot)",
                       "planar": "a planar joint: thrustwalk pins the stance foot (remove "
                                 "the floating base; the root is found from the stance foot)"
                       }.get(j.type, f"unknown joint type {j.type!r} (revolute, continuous "
                                     "or fixed)")
                problems.append(self.problem(j.line, j.element, f'type="{j.type}" is {why}'))
            if j.mimic_line is not None:
                problems.append(self.problem(j.mimic_line, j.element, "<mimic> couples two "
                                             "joints: not supported (every joint is a "
                                             "coordinate)"))
            if j.child in parent_joint:
                first = parent_joint[j.child]
                problems.append(self.problem(j.line, j.element, f"closed loop: link "
                                             f"'{j.child}' is already the child of joint "
                                             f"'{first.name}' (line {first.line}); thrustwalk "
                                             "models trees"))
                continue
            parent_joint[j.child] = j
        if problems:
            raise InputError(problems)
        roots = [lk.name for lk in u.links if lk.name not in parent_joint]
        children: dict[str, list[UrdfJoint]] = {lk.name: [] for lk in u.links}
        for j in u.joints:
            children[j.parent].append(j)
        reached: set[str] = set()
        if roots:
            stack = [roots[0]]
            while stack:
                lk = stack.pop()
                reached.add(lk)
                stack.extend(j.child for j in children[lk])
        if len(roots) != 1 or len(reached) != len(u.links):
            for j in u.joints:  # a joint on a cycle: its ancestors never reach a root
                seen, cur = set(), j.child
                while cur in parent_joint and cur not in seen:
                    seen.add(cur)
                    cur = parent_joint[cur].parent
                if cur in seen:  # cur is on the cycle: name the joint into it
                    jc = parent_joint[cur]
                    raise InputError(self.problem(jc.line, jc.element, f"closed loop through "
                                                  f"link '{cur}': thrustwalk models trees"))
            lk = u.link(roots[1])
            raise InputError(self.problem(lk.line, f'<link name="{lk.name}">', "not connected "
                                          f"to the root link '{roots[0]}' by joints (a URDF "
                                          "is one tree)"))
        self.root = roots[0]
        self.parent_joint = parent_joint
        self.children = children
        # zero-configuration poses in the root frame
        self.R: dict[str, np.ndarray] = {self.root: np.eye(3)}
        self.p: dict[str, np.ndarray] = {self.root: np.zeros(3)}
        order = [self.root]
        for lk in order:
            for j in children[lk]:
                self.R[j.child] = self.R[lk] @ _rot(j.rpy)
                self.p[j.child] = self.p[lk] + self.R[lk] @ np.array(j.xyz)
                order.append(j.child)
        self.order = order
        # every movable joint turns about the plane normal
        self.sign: dict[str, int] = {}
        for j in u.joints:
            if j.type == "fixed":
                continue
            a = self.R[j.child] @ np.array(j.axis)
            if np.linalg.norm(np.cross(a, self.n)) > AXIS_TOL:
                shown = " ".join(f"{x:g}" for x in j.axis)
                world = ", ".join(f"{_snap(x):.3g}" for x in a)
                normal = " ".join(f"{x:g}" for x in self.n)
                what = (f'<axis xyz="{shown}">' if j.axis_line is not None else
                        f"no <axis> (URDF's default {shown})")
                problems.append(self.problem(
                    j.axis_line or j.line, j.element,
                    f"{what} is ({world}) in the root frame, not along the normal "
                    f"({normal}) of the {self.axes} plane: thrustwalk models planar robots "
                    "(the plane may be xz, yz or xy)"))
            self.sign[j.name] = 1 if float(a @ self.n) > 0 else -1
        if problems:
            raise InputError(problems)

    # -- rigid bodies ------------------------------------------------------------------------
    def bodies(self) -> None:
        u = self.u
        top_of: dict[str, str] = {}
        for lk in self.order:
            j = self.parent_joint.get(lk)
            top_of[lk] = top_of[j.parent] if j is not None and j.type == "fixed" else lk
        groups: dict[str, list[str]] = {}
        for lk in self.order:
            groups.setdefault(top_of[lk], []).append(lk)
        problems: list[Problem] = []
        self.body_of: dict[str, _Body] = {}
        self.bodies_: dict[str, _Body] = {}
        for top, members in groups.items():
            massive = [m for m in members if u.link(m).inertial is not None]
            if not massive:
                lk = u.link(top)
                more = (f" (nor do the links fixed to it: {', '.join(members[1:])})"
                        if len(members) > 1 else "")
                problems.append(self.problem(lk.line, f'<link name="{top}">', "no <inertial>"
                                             f"{more}: a moving body needs its mass"))
                continue
            heaviest = max(massive, key=lambda m: u.link(m).inertial.mass)
            body = _Body(heaviest, top, members)
            items = []
            for m in massive:
                ine = u.link(m).inertial
                R = self.R[m] @ _rot(ine.rpy)
                c = self.p[m] + self.R[m] @ np.array(ine.xyz)
                items.append((ine.mass, c, R @ ine.tensor() @ R.T))
                body.sources.append((m, ine))
            M = sum(it[0] for it in items)
            c = sum(it[0] * it[1] for it in items) / M if len(items) > 1 else items[0][1]
            inertia = np.zeros((3, 3))
            for mi, ci, Ii in items:
                d = ci - c
                inertia += Ii + mi * (float(d @ d) * np.eye(3) - np.outer(d, d))
            body.mass, body.com, body.inertia = float(M), c, inertia
            for m in members[1:]:
                j = self.parent_joint[m]
                body.fixed.append(f"{j.name} line {j.line}")
            self.bodies_[body.name] = body
            for m in members:
                self.body_of[m] = body
        if problems:
            raise InputError(problems)
        names = list(self.bodies_)
        if len(names) > MAX_LINKS:
            raise InputError(self.problem(None, "", f"{len(names)} moving bodies after merging "
                                          f"the fixed joints: thrustwalk's limit is "
                                          f"{MAX_LINKS} links"))
        if len(names) < 2:
            raise InputError(self.problem(None, "", "one moving body: a walker needs at least "
                                          "two links joined by a revolute joint"))

    def need_link(self, name: str, where: Where, key: tuple) -> _Body:
        if name not in self.body_of:
            names = [lk.name for lk in self.u.links]
            shown = ", ".join(names[:12]) + (f", ... ({len(names)} links)" if len(names) > 12
                                              else "")
            raise InputError(locate(where, key, f"unknown link {name!r} in "
                                                f"{self.u.file} (links: {shown})"))
        return self.body_of[name]

    def world(self, link: str, point: Sequence[float]) -> np.ndarray:
        return self.p[link] + self.R[link] @ np.array(point, float)

    # -- re-rooting ---------------------------------------------------------------------------
    def reroot(self) -> None:
        s = self.spec
        self.stance = self.need_link(s.stance_foot.link, s.stance_foot.where, s.stance_foot.key)
        self.swing = self.need_link(s.swing_foot.link, s.swing_foot.where, s.swing_foot.key)
        if self.swing is self.stance:
            raise InputError(locate(s.swing_foot.where, s.swing_foot.key, f"the swing foot's "
                                    f"link {s.swing_foot.link!r} is on the stance foot's body "
                                    f"({self.stance.name}): the feet must be on two bodies"))
        edges: dict[str, list[tuple[str, UrdfJoint]]] = {b: [] for b in self.bodies_}
        for j in self.u.joints:
            if j.type == "fixed":
                continue
            a, b = self.body_of[j.parent].name, self.body_of[j.child].name
            edges[a].append((b, j))
            edges[b].append((a, j))
        root = self.stance.name
        self.tw_parent: dict[str, tuple[str, UrdfJoint, bool] | None] = {root: None}
        self.tw_order = [root]

        stack = [root]  # depth first, children in file order
        while stack:
            cur = stack.pop()
            if cur != root:
                self.tw_order.append(cur)
            kids = [(nb, j) for nb, j in edges[cur] if nb not in self.tw_parent]
            for nb, j in kids:
                self.tw_parent[nb] = (cur, j, self.body_of[j.parent].name == cur)
            stack.extend(nb for nb, _ in reversed(kids))
        # the frame origin of each body: the stance foot for the root, else the joint to its
        # thrustwalk parent (the URDF child link's origin)
        self.origin: dict[str, np.ndarray] = {
            root: self.world(s.stance_foot.link, s.stance_foot.point)}
        for b in self.tw_order[1:]:
            _, j, _ = self.tw_parent[b]
            self.origin[b] = self.p[j.child]

    # -- coordinates -----------------------------------------------------------------------
    def coordinates(self) -> None:
        s = self.spec
        for jname, js in s.joints.items():
            if jname not in {j.name for j in self.u.joints}:
                raise InputError(locate(js.where, js.key, f"unknown joint {jname!r} in "
                                        f"{self.u.file}"))
            j = next(j for j in self.u.joints if j.name == jname)
            if j.type == "fixed":
                raise InputError(locate(js.where, js.key, f"joint {jname!r} is fixed (line "
                                        f"{j.line}): it has no coordinate"))
        if s.unactuated is not None:
            self.unact = self.need_link(s.unactuated, s.unactuated_where, s.unactuated_key)
        else:
            self.unact = self.body_of[self.root]
        self.unact_name = s.unactuated_name or f"theta_{self.unact.name}"
        names = [self.joint_spec(self.tw_parent[b][1]).name or self.tw_parent[b][1].name
                 for b in self.tw_order[1:]] + [self.unact_name]
        dup = sorted({x for x in names if names.count(x) > 1})
        if dup:
            raise InputError(locate(s.unactuated_where, s.unactuated_key, f"coordinate name "
                                    f"{dup[0]!r} is used twice (name the unactuated "
                                    "coordinate or the joints in a side file)"))

    def joint_spec(self, j: UrdfJoint) -> JointSpec:
        return self.spec.joints.get(j.name, JointSpec())

    # -- relabelling ----------------------------------------------------------------------------
    def relabel(self) -> tuple[list[tuple[str, str]] | None, dict | None]:
        """The swapped leg pairs: the bodies on the path from the stance body to the swing
        body, paired from both ends (the middle body, e.g. the torso, stays), each pair
        checked to be a mirror image (mass, inertia, segment and centre-of-mass vectors)."""
        s = self.spec
        if s.relabel is not None:
            given = dict(s.relabel)
            if (given.get("swap") is None) == (given.get("R") is None):
                raise InputError(locate(s.relabel_where, ("relabel",), "give exactly one of "
                                        "`swap` or `R`"))
            if given.get("swap") is not None:
                pairs = []
                for i, pair in enumerate(given["swap"]):
                    if len(pair) != 2:
                        raise InputError(locate(s.relabel_where, ("relabel", "swap", i),
                                                "expected a pair of links"))
                    a, b = (self.need_link(x, s.relabel_where, ("relabel", "swap", i)).name
                            for x in pair)
                    pairs.append((a, b))
                return pairs, None
            n = len(self.tw_order)
            R = np.array(given.get("R") or [], float)
            if R.shape != (n, n):
                raise InputError(locate(s.relabel_where, ("relabel", "R"), f"expected a {n} x "
                                        f"{n} matrix ({n} links after merging fixed joints)"))
            if given.get("b") is not None and len(given["b"]) != n:
                raise InputError(locate(s.relabel_where, ("relabel", "b"), f"expected {n} "
                                        "values"))
            return None, given
        path = [self.swing.name]
        while self.tw_parent[path[-1]] is not None:
            path.append(self.tw_parent[path[-1]][0])
        path.reverse()  # stance body ... swing body
        k = len(path)
        pairs = [(path[i], path[k - 1 - i]) for i in range(k // 2)]
        stance_pt = self.origin[path[0]]
        swing_pt = self.world(s.swing_foot.link, s.swing_foot.point)

        def lower(i: int) -> np.ndarray:  # joint toward the foot of path[i]
            if i == 0:
                return stance_pt
            if i == k - 1:
                return swing_pt
            return self.origin[path[i]] if i < k // 2 else self.origin[path[i + 1]]

        def upper(i: int) -> np.ndarray:  # joint toward the hip of path[i]
            return self.origin[path[i + 1]] if i < k // 2 else self.origin[path[i]]

        for i, (a, b) in enumerate(pairs):
            ia, ib = i, k - 1 - i
            A, B = self.bodies_[a], self.bodies_[b]
            checks = [
                ("mass [kg]", A.mass, B.mass),
                ("inertia [kg m^2]", self.n @ A.inertia @ self.n, self.n @ B.inertia @ self.n),
            ]
            for what, pa, pb in (("segment", upper(ia) - lower(ia), upper(ib) - lower(ib)),
                                 ("centre of mass", A.com - lower(ia), B.com - lower(ib))):
                for axis, e in (("x", self.e1), ("y", self.e2)):
                    checks.append((f"{what} {axis} [m]", e @ pa, e @ pb))
            for what, va, vb in checks:
                if abs(va - vb) > SYMMETRY_TOL * max(1.0, abs(va), abs(vb)):
                    raise InputError(self.problem(
                        None, "", f"the legs are not mirror images ({a} and {b}: {what} "
                        f"{va:.6g} vs {vb:.6g}): thrustwalk swaps the legs at impact; give "
                        "`relabel:` in a side file if the swap is meant"))
        if not pairs:
            raise InputError(locate(s.swing_foot.where, s.swing_foot.key, "no leg to swap"))
        return pairs, None

    # -- the robot file ----------------------------------------------------------------------
    def run(self) -> ImportedRobot:
        self.tree()
        self.bodies()
        self.reroot()
        self.coordinates()
        pairs, explicit = self.relabel()
        text = self.write(pairs, explicit)
        robot = load_robot_text(text, self.spec.file)
        merged = {b.name: tuple(b.members) for b in self.bodies_.values()}
        rev = tuple(self.tw_parent[b][1].name for b in self.tw_order[1:]
                    if not self.tw_parent[b][2])
        return ImportedRobot(text, robot, tuple(self.notes), tuple(pairs or ()), merged, rev)

    def write(self, pairs, explicit) -> str:
        s, u = self.spec, self.u
        L: list[str] = []
        c = "#"

        def line(text: str, comment: str = "") -> None:
            L.append(f"{text:<40} {c} {_safe(comment, 200)}" if comment else text)

        out_of_plane = []
        for b in self.tw_order:
            body = self.bodies_[b]
            off = float(self.n @ (body.com - self.origin[self.stance.name]))
            if abs(off) > SNAP:
                out_of_plane.append(f"{b} {off:+.4g} m")
        normal = " ".join(f"{x:g}" for x in self.n)
        L += [f"# Imported from the URDF {_safe(u.file, 120)}",
              f"# (sha256 {u.sha256[:16]}...) by thrustwalk {__version__} import-urdf.",
              f"# Sagittal plane: the {self.axes} plane of the URDF root link "
              f"'{_safe(self.root)}' ({s.plane[0]} -> x, {s.plane[1]} -> y);",
              f"# angles counter-clockwise, i.e. about ({normal}). q = 0 is the URDF's zero",
              "# configuration, where every link frame is parallel to the world frame; a",
              "# link frame's origin is the joint to its parent (the root's: the stance foot).",
              f"# Tree re-rooted at the stance foot's link '{_safe(self.stance.name)}'."
              " Meshes are never read."]
        if s.command:
            L.append(f"# Command: {_safe(s.command, 400)}")
        if out_of_plane:
            note = (f"out-of-plane centre-of-mass offsets dropped (along {normal}, from the "
                    f"stance foot; planar motion about the normal: no energy changes): "
                    + ", ".join(out_of_plane))
            self.notes.append(note)
            L.append("# " + _safe(note, 400))
        line(f"name: {_name(s.name or u.name)}", "<robot name> of the URDF" if not s.name
             else "given")
        desc = s.description or f"imported from URDF {_safe(u.file.rsplit('/', 1)[-1])}"
        line(f"description: {json.dumps(desc)}")
        line(f"gravity: {_num(s.gravity)}", f"[m/s^2] {s.gravity_source}")
        L.append("links:")
        for b in self.tw_order:
            body = self.bodies_[b]
            o = self.origin[b]
            par = self.tw_parent[b]
            ul = u.link(body.top)
            src = f'<link name="{body.top}"> line {ul.line}'
            if len(body.members) > 1:
                src += (f" + fixed {', '.join(body.members[1:])} ("
                        f"{'; '.join(body.fixed)})")
            line(f"  - name: {_name(b)}", src)
            if par is None:
                line("    parent: null", "root: the stance foot's body (pinned)")
            else:
                pb, j, forward = par
                how = "" if forward else ", reversed (re-rooted at the stance foot)"
                line(f"    parent: {_name(pb)}", f"{j.element} line {j.line}{how}")
                jt = self.proj(o - self.origin[pb])
                line(f"    joint: {_vec(jt)}", f"[m] {j.element} <origin> "
                     f"(line {j.origin_line or j.line}) at the URDF zero pose, from the "
                     f"{'stance foot' if self.tw_parent[pb] is None else 'parent joint'}")
            many = len(body.sources) > 1

            def lines_of(attr: str, body=body) -> str:
                return "; ".join(f"{m} line {getattr(ine, attr) or ine.line}"
                                 for m, ine in body.sources)
            line(f"    mass: {_num(body.mass)}", f"[kg] {'sum of ' if many else ''}<mass> of "
                 + lines_of("mass_line"))
            com = self.proj(body.com - o)
            off = float(self.n @ (body.com - o))
            line(f"    com: {_vec(com)}", f"[m] {'mass-weighted ' if many else ''}<inertial>"
                 f"<origin> of {lines_of('origin_line')}"
                 + (f"; {off:+.4g} m along the normal dropped" if abs(off) > SNAP else ""))
            inertia = float(self.n @ body.inertia @ self.n)
            line(f"    inertia: {_num(inertia)}",
                 f"[kg m^2] <inertia> of {lines_of('inertia_line')}"
                 + (", rotated, parallel-axis sum" if many else ", rotated")
                 + ", about the plane normal")
            end, end_src = self.end(b)
            line(f"    end: {_vec(end)}", f"[m] drawing only: {end_src}")
            if par is not None:
                rotor = self.rotor(par[1])
                if rotor:
                    J, G, src = rotor
                    line(f"    rotor: {{inertia: {_num(J)}, gear_ratio: {_num(G)}}}",
                         f"[kg m^2, 1] {src}")
        L.append("coordinates:")
        L.append("  actuated:")
        for b in self.tw_order[1:]:
            pb, j, forward = self.tw_parent[b]
            js = self.joint_spec(j)
            sigma = self.sign[j.name] * (1 if forward else -1)
            name = js.name or j.name
            parts = [f"name: {_name(name)}", f"joint: {_name(b)}"]
            why = [f"{j.element} line {j.line}: angle = {'' if sigma > 0 else '-'}q_urdf"]
            rng, rsrc = self.joint_range(j, js, sigma)
            if rng is not None:
                parts.append(f"range: {_vec(rng)}")
                why.append(rsrc)
            tl, tsrc = self.torque(j, js)
            if tl is not None:
                parts.append(f"torque_limit: {_num(tl)}")
                why.append(tsrc)
            line("    - {" + ", ".join(parts) + "}", "; ".join(why))
        line(f"  unactuated: {{name: {_name(self.unact_name)}, link: {_name(self.unact.name)}}}",
             "absolute angle of " + ("the URDF root link's body" if s.unactuated is None
                                     else f"the body of link {s.unactuated}") + " [rad]")
        L.append("feet:")
        for key, spec, body in (("stance", s.stance_foot, self.stance),
                                ("swing", s.swing_foot, self.swing)):
            pt = self.proj(self.world(spec.link, spec.point) - self.origin[body.name])
            line(f"  {key}: {{link: {_name(body.name)}, point: {_vec(pt)}}}",
                 f"[m] {spec.source or 'given'}: link {spec.link} point "
                 f"{' '.join(f'{x:g}' for x in spec.point)}")
        L.append("relabel:")
        if pairs is not None:
            src = "given" if s.relabel is not None else ("detected: the bodies from the stance "
                                                         "foot to the swing foot, mirrored")
            line("  swap: [" + ", ".join(f"[{_name(a)}, {_name(b)}]" for a, b in pairs) + "]",
                 src)
            if s.relabel is not None and s.relabel.get("b") is not None:
                line(f"  b: {_vec(s.relabel['b'])}", "given")
        else:
            line("  R: [" + ", ".join(_vec(r) for r in explicit["R"]) + "]", "given")
            if explicit.get("b") is not None:
                line(f"  b: {_vec(explicit['b'])}", "given")
        if not s.thrusters:
            L.append("thrusters: []")
        else:
            L.append("thrusters:")
            for t in s.thrusters:
                body = self.need_link(t.link, t.where, t.key)
                pt = self.proj(self.world(t.link, t.point) - self.origin[body.name])
                line(f"  - name: {_name(t.name)}", t.source or "given")
                line(f"    link: {_name(body.name)}", f"URDF link {t.link}")
                line(f"    point: {_vec(pt)}", f"[m] point {' '.join(f'{x:g}' for x in t.point)}"
                                               f" of link {t.link}")
                line(f"    direction: {_vec(t.direction)}", f"in the {self.axes} plane")
                line(f"    frame: {t.frame}")
                line(f"    limits: {_vec(t.limits)}", "[N]")
        return "\n".join(L) + "\n"

    def end(self, b: str) -> tuple[tuple[float, float], str]:
        o = self.origin[b]
        cands = [(self.proj(self.origin[k] - o), f"joint of {k}") for k in self.tw_order
                 if self.tw_parent[k] is not None and self.tw_parent[k][0] == b]
        for key, spec, body in (("stance", self.spec.stance_foot, self.stance),
                                ("swing", self.spec.swing_foot, self.swing)):
            if body.name == b:
                cands.append((self.proj(self.world(spec.link, spec.point) - o),
                              f"the {key} foot"))
        best = max(cands, key=lambda cs: math.hypot(*cs[0]), default=None)
        if best is None or math.hypot(*best[0]) < 1e-9:
            com = self.proj(self.bodies_[b].com - o)
            return (2 * com[0], 2 * com[1]), "twice the centre of mass"
        return best

    def rotor(self, j: UrdfJoint) -> tuple[float, float, str] | None:
        js = self.joint_spec(j)
        red = self.u.reductions.get(j.name)
        if js.rotor_inertia is None:
            if red is not None:
                self.notes.append(f"joint {j.name}: <transmission> reduction {red[0]:g} (line "
                                  f"{red[1]}) but no rotor inertia (URDF has none; give "
                                  f"joints.{j.name}.rotor_inertia in a side file): no rotor")
            return None
        if js.gear_ratio is not None:
            G, gsrc = js.gear_ratio, f"gear ratio from {js.source or 'the side file'}"
        elif red is not None:
            G, gsrc = red[0], f"gear ratio: <transmission> mechanicalReduction line {red[1]}"
        else:
            G, gsrc = 1.0, "gear ratio 1 (none given)"
        return js.rotor_inertia, G, f"rotor inertia from {js.source or 'the side file'}; {gsrc}"

    def joint_range(self, j: UrdfJoint, js: JointSpec, sigma: int):
        if js.range is not None:
            lo, hi = js.range
            src = f"range from {js.source or 'the side file'}"
        elif j.type == "revolute" and j.limit is not None and j.limit.lower is not None \
                and j.limit.upper is not None and j.limit.lower < j.limit.upper:
            lo, hi = j.limit.lower, j.limit.upper
            src = f"range: <limit lower upper> line {j.limit.line}"
        else:
            return None, ""
        a, b = sigma * lo, sigma * hi
        return (min(a, b), max(a, b)), src + ("" if sigma > 0 else " (sign flipped)")

    def torque(self, j: UrdfJoint, js: JointSpec):
        if js.torque_limit is not None:
            return js.torque_limit, f"torque limit from {js.source or 'the side file'}"
        if j.limit is not None and j.limit.effort is not None and j.limit.effort > 0:
            return j.limit.effort, f"torque limit: <limit effort> line {j.limit.line}"
        return None, ""


def import_robot(urdf: Urdf, spec: ImportSpec) -> ImportedRobot:
    """The thrustwalk robot of a URDF (SPEC 16; conventions in the module docstring): the
    commented robot YAML, the :class:`Robot` parsed from it and the notes. Raises
    :class:`InputError` naming the URDF element and line (a prismatic joint, an axis not
    normal to the plane, a closed loop, a moving body without ``<inertial>``), or the
    parameter (an unknown link, legs that are not mirror images)."""
    return _Importer(urdf, spec).run()


# ------------------------------------------------------------------------------ export
def _fmt(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def robot_to_urdf(robot: Robot) -> str:
    """The planar URDF of a thrustwalk robot (x-z plane; see the module docstring): at the
    URDF zero pose every angle of ``robot`` is 0, each actuated coordinate is the revolute
    joint of its name about ``0 -1 0`` (URDF angle = relative angle), with ``<limit>`` from
    ``range`` and ``torque_limit`` (``effort="0"``: no limit; ``continuous`` without a range).
    Link masses [kg], centres of mass (x, 0, y) [m] and inertias (``iyy`` = the planar
    inertia [kg m^2]) as ``<inertial>``; no geometry. Feet, thrusters, rotors and the
    relabelling, which URDF cannot hold, are in :func:`robot_side` (and in comments)."""
    check_instance("robot", robot, Robot, "a Robot (tw.load_robot)")
    coord = {c.link: c for c in robot.coordinates if c.actuated}
    L = ['<?xml version="1.0"?>',
         f"<!-- {_xml_comment(robot.name)}: exported by thrustwalk {__version__} "
         "(planar, x-z plane, joints about 0 -1 0). -->",
         f"<!-- Feet: stance {_xml_comment(robot.stance_foot.link)} "
         f"{robot.stance_foot.point}, swing {_xml_comment(robot.swing_foot.link)} "
         f"{robot.swing_foot.point} (x, z); thrusters, rotors and the relabelling are in the "
         "side file. -->",
         f'<robot name="{_attr(robot.name)}">']
    for lk in robot.links:
        half = lk.inertia / 2
        L += [f'  <link name="{_attr(lk.name)}">',
              "    <inertial>",
              f'      <origin xyz="{_fmt(lk.com[0])} 0 {_fmt(lk.com[1])}" rpy="0 0 0"/>',
              f'      <mass value="{_fmt(lk.mass)}"/>',
              f'      <inertia ixx="{_fmt(half)}" ixy="0" ixz="0" iyy="{_fmt(lk.inertia)}" '
              f'iyz="0" izz="{_fmt(half)}"/>',
              "    </inertial>",
              "  </link>"]
    for lk in robot.links:
        if lk.parent is None:
            continue
        c = coord[lk.name]
        bounded = math.isfinite(c.range[0]) and math.isfinite(c.range[1])
        kind = "revolute" if bounded else "continuous"
        effort = _fmt(c.torque_limit) if math.isfinite(c.torque_limit) else "0"
        L += [f'  <joint name="{_attr(c.name)}" type="{kind}">',
              f'    <parent link="{_attr(lk.parent)}"/>',
              f'    <child link="{_attr(lk.name)}"/>',
              f'    <origin xyz="{_fmt(lk.joint[0])} 0 {_fmt(lk.joint[1])}" rpy="0 0 0"/>',
              '    <axis xyz="0 -1 0"/>']
        if bounded:
            L.append(f'    <limit effort="{effort}" lower="{_fmt(c.range[0])}" '
                     f'upper="{_fmt(c.range[1])}" velocity="0"/>')
        elif math.isfinite(c.torque_limit):
            L.append(f'    <limit effort="{effort}" velocity="0"/>')
        L.append("  </joint>")
    L.append("</robot>")
    return "\n".join(L) + "\n"


def robot_side(robot: Robot) -> str:
    """The side file (YAML) that, with :func:`robot_to_urdf`'s URDF, imports back to
    ``robot``: name, gravity, the feet (x, 0, y), the unactuated coordinate, the reflected
    rotor inertias (``J G^2`` with gear ratio 1: thrustwalk keeps only the product), the
    relabelling as the matrix ``R`` and ``b``, the thrusters."""
    def v3(p):
        return f"[{_num(p[0])}, 0.0, {_num(p[1])}]"
    un = next(c for c in robot.coordinates if not c.actuated)
    L = [f"# Side file of the URDF export of {_safe(robot.name)} (thrustwalk {__version__})",
         f"name: {_name(robot.name)}",
         f"gravity: {_num(robot.gravity)}",
         "plane: xz",
         f"stance_foot: {{link: {_name(robot.stance_foot.link)}, point: "
         f"{v3(robot.stance_foot.point)}}}",
         f"swing_foot: {{link: {_name(robot.swing_foot.link)}, point: "
         f"{v3(robot.swing_foot.point)}}}",
         f"unactuated: {{link: {_name(un.link)}, name: {_name(un.name)}}}"]
    coord = {c.link: c for c in robot.coordinates if c.actuated}
    rotors = [(coord[lk.name].name, lk.rotor_inertia) for lk in robot.links
              if lk.parent is not None and lk.rotor_inertia]
    if rotors:
        L.append("joints:")
        L += [f"  {_name(n)}: {{rotor_inertia: {_num(J)}, gear_ratio: 1.0}}  "
              "# the reflected inertia J G^2" for n, J in rotors]
    L.append("relabel:")
    L.append("  R: [" + ", ".join(_vec(r) for r in robot.relabel_R) + "]")
    L.append(f"  b: {_vec(robot.relabel_b)}")
    if robot.thrusters:
        L.append("thrusters:")
        for t in robot.thrusters:
            L.append(f"  - {{name: {_name(t.name)}, link: {_name(t.link)}, point: "
                     f"{v3(t.point)}, direction: {_vec(t.direction)}, frame: {t.frame}, "
                     f"limits: {_vec(t.limits)}}}")
    return "\n".join(L) + "\n"


def _attr(s: str) -> str:
    return (s.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
            .replace(">", "&gt;"))


def _xml_comment(s: str) -> str:
    return _safe(s).replace("--", "- -")

