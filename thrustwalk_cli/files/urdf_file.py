"""URDF files and the import side file (SPEC 16): reading untrusted XML safely, with the line
of every element, into plain data; the mechanics of the import are ``interchange/urdf.py``.

A URDF file is untrusted XML. It is refused before parsing when larger than
``MAX_URDF_MB`` megabytes (the size is checked, then at most that many bytes are read), and
parsed by defusedxml's expat SAX reader with document type declarations, entity
declarations and external references all forbidden: no entity is ever expanded (no
"billion laughs") and nothing outside the file is ever opened (no external entity, no
external DTD). Meshes are never loaded: ``<visual>`` and ``<collision>`` are skipped.

Every problem is one line ``file:line: <element name="...">: message``.

The side file (YAML, ``URDF_SIDE_SCHEMA``) carries what a URDF does not: rotor inertias,
gear ratios, torque limits and ranges to override, the unactuated coordinate, feet,
thrusters, the relabelling, gravity.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError, Problem
from .schema import (
    ValidationResult,
    check,
    choice,
    dict_of,
    expect_kind,
    list_of,
    mapping,
    matrix,
    null_or,
    number,
    string,
    vector,
)
from .schema import (
    field as key,
)
from .yamlio import load_yaml

MAX_URDF_MB = 16  # [MB] a URDF beyond this is refused before it is parsed
MAX_ELEMENTS = 200_000  # XML elements in one URDF (a humanoid's URDF has a few thousand)

Vec3 = tuple[float, float, float]


# ------------------------------------------------------------------------------- URDF data
@dataclass(frozen=True)
class UrdfInertial:
    """``<inertial>`` of a link: mass [kg], centre of mass ``xyz`` [m] and the rotation
    ``rpy`` [rad] of the inertia frame in the link frame, inertia tensor about the centre of
    mass in that frame [kg m^2] as ``(ixx, ixy, ixz, iyy, iyz, izz)``; lines of the elements."""

    mass: float
    xyz: Vec3
    rpy: Vec3
    inertia: tuple[float, float, float, float, float, float]
    line: int
    mass_line: int
    origin_line: int | None
    inertia_line: int

    def tensor(self) -> np.ndarray:
        """The 3 x 3 inertia tensor in the inertial frame [kg m^2]."""
        ixx, ixy, ixz, iyy, iyz, izz = self.inertia
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], float)


@dataclass(frozen=True)
class UrdfLink:
    """``<link name>``: its inertial (None when absent) and its line."""

    name: str
    line: int
    inertial: UrdfInertial | None


@dataclass(frozen=True)
class UrdfLimit:
    """``<limit effort lower upper>`` [N m, rad]: None where the attribute is absent."""

    effort: float | None
    lower: float | None
    upper: float | None
    line: int


@dataclass(frozen=True)
class UrdfJoint:
    """``<joint name type>``: parent and child links, origin ``xyz`` [m] / ``rpy`` [rad] of
    the child frame in the parent frame, unit ``axis`` in the child frame, limit; lines."""

    name: str
    type: str
    parent: str
    child: str
    xyz: Vec3
    rpy: Vec3
    axis: Vec3
    limit: UrdfLimit | None
    line: int
    axis_line: int | None
    origin_line: int | None
    mimic_line: int | None = None

    @property
    def element(self) -> str:
        """The joint as messages name it: ``<joint name="NAME">``."""
        return f'<joint name="{self.name}">'


@dataclass(frozen=True)
class Urdf:
    """A parsed URDF: links and joints in file order, the ``mechanicalReduction`` of each
    joint named by a ``<transmission>`` (value, line), the file and its SHA-256."""

    name: str
    file: str
    sha256: str
    links: tuple[UrdfLink, ...]
    joints: tuple[UrdfJoint, ...]
    reductions: dict[str, tuple[float, int]] = field(default_factory=dict)
    meshes: int = 0  # mesh references seen (never loaded)

    def link(self, name: str) -> UrdfLink:
        """The link named ``name`` (it must exist)."""
        return next(lk for lk in self.links if lk.name == name)

    def problem(self, line: int | None, element: str, message: str) -> Problem:
        """``file:line: element: message``."""
        return Problem(self.file, line, element, message)


# ---------------------------------------------------------------------------- safe reading
@dataclass
class _Node:
    tag: str
    attrs: dict[str, str]
    line: int
    children: list[_Node] = field(default_factory=list)
    text: str = ""

    def find(self, tag: str) -> _Node | None:
        return next((c for c in self.children if c.tag == tag), None)

    def findall(self, tag: str) -> list[_Node]:
        return [c for c in self.children if c.tag == tag]


def _read_xml(path: Path) -> tuple[_Node, bytes]:
    """The element tree of the XML file ``path`` with the line of every element; refuses a
    file over ``MAX_URDF_MB`` before parsing and any DTD, entity or external reference."""
    import xml.sax
    import xml.sax.handler

    import defusedxml.sax
    from defusedxml import DefusedXmlException

    file = str(path)
    cap = MAX_URDF_MB * 1024 * 1024
    try:
        size = path.stat().st_size
        if size > cap:
            raise InputError(Problem(file, None, "", f"file of {size / 1048576:.0f} MB: a URDF "
                                                     f"may have at most {MAX_URDF_MB} MB"))
        with path.open("rb") as fh:
            raw = fh.read(cap + 1)  # a file that grew (or a pipe) is capped as well
    except FileNotFoundError:
        raise InputError(Problem(file, None, "", "file not found")) from None
    except IsADirectoryError:
        raise InputError(Problem(file, None, "", "is a directory, not a file")) from None
    except OSError as exc:
        raise InputError(Problem(file, None, "", f"cannot read file: "
                                                 f"{exc.strerror or exc}")) from None
    if len(raw) > cap:
        raise InputError(Problem(file, None, "", f"more than {MAX_URDF_MB} MB: a URDF may have "
                                                 f"at most {MAX_URDF_MB} MB"))

    class Builder(xml.sax.handler.ContentHandler):
        def __init__(self) -> None:
            super().__init__()
            self.stack: list[_Node] = []
            self.root: _Node | None = None
            self.count = 0

        def line(self) -> int:
            return self._locator.getLineNumber() if self._locator is not None else 0

        def startElement(self, name, attrs):  # noqa: N802 (SAX API)
            self.count += 1
            if self.count > MAX_ELEMENTS:
                raise InputError(Problem(file, self.line(), "", f"more than {MAX_ELEMENTS} "
                                                                "XML elements"))
            node = _Node(name, dict(attrs.items()), self.line())
            if self.stack:
                self.stack[-1].children.append(node)
            else:
                self.root = node
            self.stack.append(node)

        def endElement(self, name):  # noqa: N802 (SAX API)
            self.stack.pop()

        def characters(self, content):
            if self.stack and len(self.stack[-1].text) < 1000:
                self.stack[-1].text += content

    handler = Builder()
    try:
        defusedxml.sax.parseString(raw, handler, forbid_dtd=True, forbid_entities=True,
                                   forbid_external=True)
    except xml.sax.SAXParseException as exc:
        raise InputError(Problem(file, exc.getLineNumber(), "",
                                 f"not well-formed XML: {exc.getMessage()}")) from None
    except DefusedXmlException as exc:
        what = {"DTDForbidden": "a document type declaration (<!DOCTYPE ...>)",
                "EntitiesForbidden": "an entity declaration (<!ENTITY ...>)",
                "ExternalReferenceForbidden": "a reference to an external resource"
                }.get(type(exc).__name__, "a forbidden XML construct")
        raise InputError(Problem(file, handler.line() or None, "",
                                 f"{what} is refused: a URDF is untrusted XML, read without "
                                 "DTDs, entities or external references")) from None
    if handler.root is None:
        raise InputError(Problem(file, None, "", "no XML element"))
    return handler.root, raw


# ------------------------------------------------------------------------------ URDF parsing
def _floats(node: _Node, attr: str, n: int, default: tuple | None, problems: list[Problem],
            file: str, element: str) -> tuple | None:
    """Attribute ``attr`` of ``node`` as ``n`` finite floats (``default`` when absent)."""
    text = node.attrs.get(attr)
    if text is None:
        if default is None:
            problems.append(Problem(file, node.line, element, f"<{node.tag}> needs the "
                                                              f"attribute {attr}"))
        return default
    try:
        vals = tuple(float(v) for v in text.split())
    except ValueError:
        vals = ()
    if len(vals) != n or not all(math.isfinite(v) and abs(v) <= 1e9 for v in vals):
        shown = text if len(text) <= 40 else text[:40] + "..."
        problems.append(Problem(file, node.line, element, f"<{node.tag} {attr}=\"{shown}\">: "
                                f"expected {n} finite number{'s' if n > 1 else ''}"))
        return None
    return vals


def _origin(node: _Node | None, problems: list[Problem], file: str, element: str
            ) -> tuple[Vec3, Vec3, int | None]:
    if node is None:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), None
    xyz = _floats(node, "xyz", 3, (0.0, 0.0, 0.0), problems, file, element)
    rpy = _floats(node, "rpy", 3, (0.0, 0.0, 0.0), problems, file, element)
    return xyz or (0.0, 0.0, 0.0), rpy or (0.0, 0.0, 0.0), node.line


def _inertial(node: _Node, problems: list[Problem], file: str, element: str
              ) -> UrdfInertial | None:
    """``<inertial>``: mass > 0 and a physical inertia tensor (positive semi-definite, its
    principal moments satisfying the triangle inequality), else a problem at the element."""
    xyz, rpy, oline = _origin(node.find("origin"), problems, file, element)
    m_node, i_node = node.find("mass"), node.find("inertia")
    if m_node is None or i_node is None:
        missing = "<mass>" if m_node is None else "<inertia>"
        problems.append(Problem(file, node.line, element, f"<inertial> has no {missing}"))
        return None
    mass = _floats(m_node, "value", 1, None, problems, file, element)
    vals = [_floats(i_node, a, 1, None, problems, file, element)
            for a in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")]
    if mass is None or any(v is None for v in vals):
        return None
    if not mass[0] > 0:
        problems.append(Problem(file, m_node.line, element, f"<mass value=\"{mass[0]:g}\">: "
                                "a link's mass must be > 0"))
        return None
    inertial = UrdfInertial(mass[0], xyz, rpy, tuple(v[0] for v in vals), node.line,
                            m_node.line, oline, i_node.line)
    moments = np.linalg.eigvalsh(inertial.tensor())
    scale = max(abs(v[0]) for v in vals) or 1.0
    tol = 1e-9 * scale
    a, b, c = moments
    if a < -tol or a + b < c - tol:
        why = ("has a negative principal moment" if a < -tol
               else "violates the triangle inequality (I1 + I2 >= I3)")
        shown = ", ".join(f"{m:.4g}" for m in moments)
        problems.append(Problem(file, i_node.line, element, f"<inertia> is not a rigid body's "
                                f"inertia (principal moments {shown} kg m^2): it {why}"))
        return None
    return inertial


def load_urdf(path: str | Path) -> Urdf:
    """Read a URDF file safely (see the module docstring) into a :class:`Urdf`; raises
    :class:`InputError` with every problem, each naming its element and line."""
    path = Path(path)
    file = str(path)
    root, raw = _read_xml(path)
    if root.tag != "robot":
        raise InputError(Problem(file, root.line, f"<{root.tag}>", "the root element of a "
                                                                   "URDF is <robot>"))
    problems: list[Problem] = []
    links: list[UrdfLink] = []
    joints: list[UrdfJoint] = []
    reductions: dict[str, tuple[float, int]] = {}
    meshes = 0
    for node in root.children:
        if node.tag in ("link", "joint") and not node.attrs.get("name"):
            problems.append(Problem(file, node.line, f"<{node.tag}>", "needs a name"))
            continue
        if node.tag == "link":
            element = f'<link name="{node.attrs["name"]}">'
            inertial = None
            ins = node.findall("inertial")
            if len(ins) > 1:
                problems.append(Problem(file, ins[1].line, element, "more than one <inertial>"))
            elif ins:
                inertial = _inertial(ins[0], problems, file, element)
            for vis in node.findall("visual") + node.findall("collision"):
                geo = vis.find("geometry")
                meshes += sum(1 for g in (geo.children if geo else ()) if g.tag == "mesh")
            links.append(UrdfLink(node.attrs["name"], node.line, inertial))
        elif node.tag == "joint":
            element = f'<joint name="{node.attrs["name"]}">'
            jtype = node.attrs.get("type", "")
            ends = {}
            for tag in ("parent", "child"):
                sub = node.find(tag)
                if sub is None or not sub.attrs.get("link"):
                    problems.append(Problem(file, node.line, element, f"needs <{tag} link=...>"))
                else:
                    ends[tag] = sub.attrs["link"]
            xyz, rpy, oline = _origin(node.find("origin"), problems, file, element)
            ax = node.find("axis")
            axis = (_floats(ax, "xyz", 3, (1.0, 0.0, 0.0), problems, file, element)
                    if ax is not None else (1.0, 0.0, 0.0))
            if axis is not None and jtype not in ("fixed", "floating", "planar"):
                norm = math.sqrt(sum(a * a for a in axis))
                if norm < 1e-12:
                    problems.append(Problem(file, ax.line if ax is not None else node.line,
                                            element, "<axis> is zero"))
                    axis = None
                else:
                    axis = tuple(a / norm for a in axis)
            lim = node.find("limit")
            limit = None
            if lim is not None:
                got = {a: _floats(lim, a, 1, (math.nan,), problems, file, element)
                       for a in ("effort", "lower", "upper")}
                val = {a: (None if v is None or math.isnan(v[0]) else v[0])
                       for a, v in got.items()}
                limit = UrdfLimit(val["effort"], val["lower"], val["upper"], lim.line)
            mimic = node.find("mimic")
            if len(ends) == 2 and axis is not None:
                joints.append(UrdfJoint(node.attrs["name"], jtype, ends["parent"],
                                        ends["child"], xyz, rpy, axis, limit, node.line,
                                        ax.line if ax is not None else None, oline,
                                        mimic.line if mimic is not None else None))
        elif node.tag == "transmission":
            _transmission(node, reductions, problems, file)
    names = [lk.name for lk in links]
    seen: dict[str, int] = {}
    for lk in links:
        if lk.name in seen:
            problems.append(Problem(file, lk.line, f'<link name="{lk.name}">', "duplicate link "
                                    f"name (first on line {seen[lk.name]})"))
        seen.setdefault(lk.name, lk.line)
    jseen: dict[str, int] = {}
    for j in joints:
        if j.name in jseen:
            problems.append(Problem(file, j.line, j.element, f"duplicate joint name (first on "
                                                             f"line {jseen[j.name]})"))
        jseen.setdefault(j.name, j.line)
        for end in (j.parent, j.child):
            if end not in seen:
                problems.append(Problem(file, j.line, j.element, f"unknown link '{end}' "
                                        f"(links: {_listing(names)})"))
    if not links and not problems:
        problems.append(Problem(file, root.line, "<robot>", "no <link>"))
    if problems:
        raise InputError(problems)
    return Urdf(root.attrs.get("name", path.stem) or path.stem, file,
                hashlib.sha256(raw).hexdigest(), tuple(links), tuple(joints), reductions,
                meshes)


def _listing(names: list[str], most: int = 12) -> str:
    shown = ", ".join(names[:most])
    return shown + (f", ... ({len(names)} in all)" if len(names) > most else "")


def _transmission(node: _Node, reductions: dict[str, tuple[float, int]],
                  problems: list[Problem], file: str) -> None:
    """The ``mechanicalReduction`` of a transmission's joint(s): the ROS format (``<joint>``
    and ``<actuator><mechanicalReduction>``) and the old one (``<mechanicalReduction>`` in
    the transmission)."""
    element = f'<transmission name="{node.attrs.get("name", "")}">'
    red_nodes = [m for a in node.findall("actuator") for m in a.findall("mechanicalReduction")]
    red_nodes += node.findall("mechanicalReduction")
    if not red_nodes:
        return
    rn = red_nodes[0]
    try:
        value = float(rn.text.strip())
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0 and value <= 1e9):
        problems.append(Problem(file, rn.line, element, f"<mechanicalReduction> "
                                f"{rn.text.strip()[:20]!r}: expected a number > 0"))
        return
    for j in node.findall("joint"):
        if j.attrs.get("name"):
            reductions[j.attrs["name"]] = (value, rn.line)


# ------------------------------------------------------------------------------- side file
_FOOT = mapping(
    key("link", string(), "URDF link carrying the foot"),
    key("point", vector(3, "m"), "the foot point in that link's frame (x, y, z)"),
)

_JOINT = mapping(
    key("name", null_or(string()), "name of the joint's coordinate (default: the joint's "
        "name)", default=None),
    key("rotor_inertia", null_or(number("kg m^2", ge=0)), "rotor inertia J of the joint's "
        "motor (URDF has none); the model adds J G^2 on the joint angle", default=None),
    key("gear_ratio", null_or(number("1", gt=0)), "gear ratio G (default: the "
        "`<transmission>`'s `mechanicalReduction`, else 1)", default=None),
    key("torque_limit", null_or(number("N m", gt=0)), "maximum |torque| (default: the "
        "`<limit effort>`)", default=None),
    key("range", null_or(vector(2, "rad")), "[lower, upper] of the URDF joint angle "
        "(default: the `<limit lower upper>` of a revolute joint)", default=None),
)

_SIDE_THRUSTER = mapping(
    key("name", string(), "thruster name"),
    key("link", string(), "URDF link carrying the thruster"),
    key("point", vector(3, "m"), "application point in that link's frame (x, y, z)"),
    key("direction", vector(2), "direction of positive thrust in the plane's two axes (x, z "
        "for the x-z plane), at the URDF's zero configuration"),
    key("frame", choice("world", "link"), "direction fixed in the world or in the link",
        default="world"),
    key("limits", vector(2, "N"), "minimum and maximum thrust", default=[-1e3, 1e3]),
)

URDF_SIDE_SCHEMA = mapping(
    key("name", null_or(string()), "robot name (default: the URDF's `<robot name>`)",
        default=None),
    key("description", string(nonempty=False), "free text for the robot file", default=""),
    key("gravity", number("m/s^2", gt=0), "gravitational acceleration (URDF has none)",
        default=9.81),
    key("plane", null_or(choice("xz", "yz", "xy")), "the sagittal plane: two axes of the URDF "
        "root's frame, forward then up (default xz)", default=None),
    key("stance_foot", null_or(_FOOT), "the stance foot (pinned)", default=None),
    key("swing_foot", null_or(_FOOT), "the swing foot", default=None),
    key("unactuated", null_or(mapping(
        key("link", string(), "URDF link whose absolute angle is q_N (default: the URDF's "
            "root link)"),
        key("name", null_or(string()), "name of q_N (default: theta_LINK)", default=None),
    )), "the unactuated coordinate", default=None),
    key("joints", dict_of(_JOINT, key_name="joint"), "per URDF joint: coordinate name, rotor, "
        "limits", default={}),
    key("relabel", null_or(mapping(
        key("swap", null_or(list_of(list_of(string(), min_len=2))), "link pairs that exchange "
            "roles at impact (URDF link names)", default=None),
        key("R", null_or(matrix()), "explicit N x N relabelling matrix, in the order of "
            "the imported robot's links", default=None),
        key("b", null_or(vector(unit="rad")), "offset in q+ = R q- + b", default=None),
    )), "leg relabelling (default: detected from the mirrored legs)", default=None),
    key("thrusters", list_of(_SIDE_THRUSTER, max_len=16), "thrusters", default=[]),
)


@dataclass(frozen=True)
class UrdfSide:
    """A validated side file: ``data`` (defaults filled in) and ``res`` for locating later
    problems (``where(key_path, message)``)."""

    data: dict
    res: ValidationResult
    file: str

    def where(self, path: tuple, message: str) -> Problem:
        return self.res.problem(path, message)


def load_urdf_side(path: str | Path) -> UrdfSide:
    """Read and validate an import side file (``URDF_SIDE_SCHEMA``); :class:`InputError`
    with every problem (``file:line: key.path: message``)."""
    doc = load_yaml(Path(path))
    if isinstance(doc.data, dict) and {"links", "coordinates"} & set(doc.data):
        expect_kind(doc, "URDF side")  # a robot (or gait) file given as the side file
    res = check(doc, URDF_SIDE_SCHEMA, parameters_path=None)
    res.raise_if_problems()
    return UrdfSide(res.data, res, str(path))
