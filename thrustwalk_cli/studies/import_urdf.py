"""The ``import-urdf`` study: a robot YAML from a URDF file and an optional side file
(SPEC 16). Reading is ``files/urdf_file.py``; the mechanics are ``interchange/urdf.py``."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..description.robot import Robot
from ..errors import InputError, check_path, check_text
from ..files.urdf_file import Urdf, UrdfSide, load_urdf, load_urdf_side
from ..interchange.urdf import (
    PLANES,
    ImportedRobot,
    ImportSpec,
    JointSpec,
    PointSpec,
    ThrusterSpec,
    import_robot,
)
from .documents import SCHEMA_VERSION

PointArg = str | tuple[str, Sequence[float]]
MAX_THRUSTER_OPTIONS = 16


@dataclass(frozen=True)
class ImportResult:
    """An imported robot: ``yaml`` (the commented robot file), ``robot`` (the
    :class:`Robot` it describes), ``notes`` (offsets dropped, transmissions without a rotor
    inertia), the leg pairs swapped at impact and the URDF links merged into each link."""

    imported: ImportedRobot
    urdf: Urdf
    side: str | None = None
    name: str = "import_urdf"
    success: bool = True
    reason: str = ""

    @property
    def robot(self) -> Robot:
        """The imported :class:`Robot` (SPEC 16)."""
        return self.imported.robot

    @property
    def yaml(self) -> str:
        """The commented robot YAML, each number naming its URDF element and line (SPEC 16)."""
        return self.imported.yaml

    @property
    def notes(self) -> tuple[str, ...]:
        """One line per remark of the import (merged fixed joints, out-of-plane parts dropped,
        ...)."""
        return self.imported.notes

    def __repr__(self) -> str:
        r = self.robot
        return (f"ImportResult(robot={r.name!r}, links={r.link_names!r}, "
                f"coordinates={r.coordinate_names!r}, notes={len(self.notes)})")

    def document(self) -> dict:
        """A summary (links with their URDF links, coordinates, swap, notes; SI units)."""
        r = self.robot
        return {"schema_version": SCHEMA_VERSION, "success": True, "reason": "",
                "urdf": {"file": self.urdf.file, "sha256": self.urdf.sha256},
                "side_file": self.side, "robot": r.name,
                "links": [{"name": lk.name, "parent": lk.parent, "mass": lk.mass,
                           "urdf_links": list(self.imported.merged[lk.name])}
                          for lk in r.links],
                "coordinates": r.coordinate_names,
                "reversed_joints": list(self.imported.reversed_joints),
                "swap": [list(p) for p in self.imported.swap],
                "total_mass": r.total_mass, "notes": list(self.notes),
                "units": {"mass": "kg", "total_mass": "kg"}}

    def tables(self) -> dict:
        """No CSV table (``{}``)."""
        return {}

    def figures(self, titles: bool = False) -> dict:
        """No figure (``{}``)."""
        return {}


def _floats(text: str, n: int, param: str, what: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != n or not all(math.isfinite(v) and abs(v) <= 1e6 for v in vals):
        raise InputError.param(param, f"{what}: expected {n} comma-separated finite numbers, "
                                      f"got {text!r}")
    return vals


def _point(value: PointArg, param: str) -> PointSpec:
    """``"LINK:X,Y,Z"`` (or ``(link, (x, y, z))``): a point [m] in a URDF link's frame."""
    if isinstance(value, str):
        link, sep, xyz = value.rpartition(":")
        if not sep or not link:
            raise InputError.param(param, f"expected LINK:X,Y,Z (a URDF link and a point in its "
                                          f"frame [m]), got {value!r}")
        pt = _floats(xyz, 3, param, "the point X,Y,Z [m]")
    else:
        link, xyz = value
        pt = tuple(float(v) for v in xyz)
        if len(pt) != 3:
            raise InputError.param(param, "expected a point (x, y, z) [m]")
    return PointSpec(link, pt, param, (), f"given as {param}")


def _thruster(text: str, param: str) -> ThrusterSpec:
    """``NAME:LINK:X,Y,Z:DX,DZ[:world|link]``."""
    parts = text.split(":")
    if len(parts) not in (4, 5) or not parts[0] or not parts[1]:
        raise InputError.param(param, f"expected NAME:LINK:X,Y,Z:DX,DZ[:world|link], got "
                                      f"{text!r}")
    frame = parts[4] if len(parts) == 5 else "world"
    if frame not in ("world", "link"):
        raise InputError.param(param, f"frame {frame!r}: choose world or link")
    point = _floats(parts[2], 3, param, "the point X,Y,Z [m]")
    d = _floats(parts[3], 2, param, "the direction DX,DZ")
    if math.hypot(*d) < 1e-12:
        raise InputError.param(param, f"thruster {parts[0]}: the direction is zero")
    return ThrusterSpec(parts[0], parts[1], point, d, frame, (-1e3, 1e3), param, (),
                        f"given as {param}")


def import_urdf(urdf: str | Path, stance_foot: PointArg | None = None,
                swing_foot: PointArg | None = None, *, plane: str | None = None,
                thrusters: Sequence[str | ThrusterSpec] = (), side: str | Path | None = None,
                unactuated: str | None = None, name: str | None = None,
                out: str | Path = "robot.yaml", command: str = "") -> ImportResult:
    """A thrustwalk robot from the URDF file ``urdf`` (SPEC 16; conventions in
    :mod:`thrustwalk_cli.interchange.urdf`).

    ``stance_foot``/``swing_foot``: ``"LINK:X,Y,Z"`` (a URDF link and a point in its frame
    [m]); ``plane``: ``xz`` (default), ``yz`` or ``xy`` of the URDF root's frame; thrusters:
    ``"NAME:LINK:X,Y,Z:DX,DZ[:world|link]"`` (direction in the plane's two axes);
    ``side``: a side file (rotor inertias, limits, names, relabelling, feet, thrusters,
    gravity; ``docs/files.md``); ``unactuated``: the URDF link whose absolute angle is q_N
    (default: the URDF root's). Options override the side file. ``out`` names the robot file
    in messages; nothing is written here (``result.yaml`` is the file's text).
    Raises :class:`InputError` naming the URDF element and line or the parameter."""
    urdf = check_path("urdf", urdf)
    if not Path(urdf).is_file():
        raise InputError.param("urdf", f"{urdf}: no such file")
    side = check_path("side", side, optional=True)
    for param, value in (("stance_foot", stance_foot), ("swing_foot", swing_foot)):
        if not (value is None or isinstance(value, str) or (
                isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], str))):
            raise InputError.param(param, f"must be 'LINK:X,Y,Z' or (LINK, (X, Y, Z)), got "
                                          f"{type(value).__name__} {value!r:.40}")
    check_text("plane", plane, optional=True)
    if isinstance(thrusters, (str, bytes)) or not hasattr(thrusters, "__iter__") or any(
            not isinstance(t, (str, ThrusterSpec)) for t in thrusters):
        raise InputError.param("thrusters", "must be a sequence of "
                                            "'NAME:LINK:X,Y,Z:DX,DZ[:world|link]' texts")
    thrusters = list(thrusters)
    check_text("unactuated", unactuated, optional=True)
    check_text("name", name, optional=True)
    check_path("out", out)
    u = load_urdf(urdf)
    sd: UrdfSide | None = load_urdf_side(side) if side is not None else None
    d = sd.data if sd is not None else {}

    def from_side(key: str) -> PointSpec | None:
        f = d.get(key)
        if f is None:
            return None
        return PointSpec(f["link"], tuple(f["point"]), sd.where, (key, "link"),
                         f"side file {sd.file} line {sd.res.line_of((key,))}")

    feet = []
    for param, value in (("stance_foot", stance_foot), ("swing_foot", swing_foot)):
        spec = _point(value, param) if value is not None else from_side(param)
        if spec is None:
            raise InputError.param(param, "required: LINK:X,Y,Z (a URDF link and a point in "
                                          f"its frame [m]), or `{param}:` in the side file")
        feet.append(spec)
    chosen_plane = plane or d.get("plane") or "xz"
    if chosen_plane not in PLANES:
        raise InputError.param("plane", f"unknown plane {chosen_plane!r} (choose from "
                                        f"{', '.join(PLANES)})")
    specs: list[ThrusterSpec] = []
    for i, t in enumerate(d.get("thrusters") or []):
        specs.append(ThrusterSpec(t["name"], t["link"], tuple(t["point"]), tuple(t["direction"]),
                                  t["frame"], tuple(t["limits"]), sd.where,
                                  ("thrusters", i, "link"),
                                  f"side file {sd.file} line "
                                  f"{sd.res.line_of(('thrusters', i))}"))
    if len(thrusters) > MAX_THRUSTER_OPTIONS:
        raise InputError.param("thrusters", f"{len(thrusters)} thrusters: the limit is "
                                            f"{MAX_THRUSTER_OPTIONS}")
    for t in thrusters:
        specs.append(t if isinstance(t, ThrusterSpec) else _thruster(t, "thrusters"))
    tnames = [t.name for t in specs]
    dup = sorted({n for n in tnames if tnames.count(n) > 1})
    if dup:
        raise InputError.param("thrusters", f"thruster {dup[0]!r} is given twice")
    if len(specs) > MAX_THRUSTER_OPTIONS:
        raise InputError.param("thrusters", f"{len(specs)} thrusters: the limit is "
                                            f"{MAX_THRUSTER_OPTIONS}")
    joints = {}
    for jname, js in (d.get("joints") or {}).items():
        rng = tuple(js["range"]) if js["range"] is not None else None
        if rng is not None and not rng[0] < rng[1]:
            raise InputError(sd.where(("joints", jname, "range"), "lower must be below upper"))
        joints[jname] = JointSpec(js["name"], js["rotor_inertia"], js["gear_ratio"],
                                  js["torque_limit"], rng, sd.where, ("joints", jname),
                                  f"side file line {sd.res.line_of(('joints', jname))}")
    un = d.get("unactuated")
    if unactuated is not None:
        un_link, un_where, un_key = unactuated, "unactuated", ()
    elif un is not None:
        un_link, un_where, un_key = un["link"], sd.where, ("unactuated", "link")
    else:
        un_link, un_where, un_key = None, "unactuated", ()
    gravity_src = ("not in a URDF: thrustwalk's default" if sd is None or "gravity" not in
                   (sd.res.doc.data or {}) else f"side file line "
                   f"{sd.res.line_of(('gravity',))}")
    spec = ImportSpec(
        stance_foot=feet[0], swing_foot=feet[1], plane=chosen_plane, thrusters=tuple(specs),
        unactuated=un_link, unactuated_name=(un or {}).get("name"), unactuated_where=un_where,
        unactuated_key=un_key, joints=joints, relabel=d.get("relabel"),
        relabel_where=sd.where if sd is not None else "side",
        gravity=d.get("gravity", 9.81), gravity_source=gravity_src,
        name=name or d.get("name"), description=d.get("description") or "",
        command=command, file=str(out))
    return ImportResult(import_robot(u, spec), u, None if side is None else str(side))
