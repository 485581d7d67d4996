"""Robot files: the robot schema table and loading a :class:`Robot` (SPEC 1).

Every problem is reported as ``file:line: key.path: message`` (all of them, not only the
first); the key tables of ``docs/files.md`` are generated from ``ROBOT_SCHEMA``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..description.robot import (
    Coordinate,
    Link,
    Motor,
    PointRef,
    Robot,
    Thruster,
    ThrusterPower,
    coordinate_map,
    symmetry_relabel,
)
from ..errors import InputError, Problem, check_instance, check_number_map, check_path
from .bundled import resolve
from .schema import (
    check,
    choice,
    expect_kind,
    field,
    kind_check,
    list_of,
    mapping,
    matrix,
    null_or,
    number,
    override_parameters,
    parameters,
    string,
    vector,
)
from .yamlio import Document, load_yaml, load_yaml_text

# ----------------------------------------------------------------------------- robot schema
# ----------------------------------------------------------------------------- robot schema
_POINT_MASS = mapping(
    field("mass", number("kg", gt=0), "point mass"),
    field("at", vector(2, "m"), "position in the link frame"),
)


_LINK = mapping(
    field("name", string(), "unique link name"),
    field("parent", null_or(string()), "parent link; null for the root (pinned at the stance "
          "foot)"),
    field("joint", vector(2, "m"), "origin of this link's frame (its joint) in the parent's "
          "frame; ignored for the root", default=[0.0, 0.0]),
    field("mass", number("kg", ge=0), "distributed mass of the link", default=0.0),
    field("com", vector(2, "m"), "centre of mass of `mass`, link frame", default=[0.0, 0.0]),
    field("inertia", number("kg m^2", ge=0), "rotational inertia of `mass` about its centre "
          "of mass", default=0.0),
    field("point_masses", list_of(_POINT_MASS), "extra point masses on the link (combined "
          "with `mass` by the parallel-axis theorem)", default=[]),
    field("end", vector(2, "m"), "far end of the link, for drawing", default=[0.0, 0.0]),
    field("rotor", null_or(mapping(
        field("inertia", number("kg m^2", ge=0), "rotor inertia J"),
        field("gear_ratio", number("1", gt=0), "gear ratio G"),
    )), "motor on the joint to the parent: adds the reflected inertia J G^2 on the joint "
        "angle", default=None),
)


_POINT = mapping(
    field("link", string(), "link name"),
    field("point", vector(2, "m"), "point in the link frame"),
)


_MOTOR = mapping(
    field("torque_constant", number("N m/A", gt=0), "motor torque constant k_t"),
    field("resistance", number("ohm", ge=0), "winding resistance R (Joule loss R i^2)"),
    field("gear_ratio", number("1", gt=0), "gear ratio G: joint torque u = G k_t i",
          default=1.0),
    field("gearbox_efficiency", number("1", gt=0, le=1), "gearbox efficiency (1: lossless)",
          default=1.0),
)


_COORD_ACT = mapping(
    field("name", string(), "coordinate name"),
    field("joint", string(), "child link of the joint: angle = theta_child - theta_parent"),
    field("range", null_or(vector(2, "rad")), "allowed [min, max] joint angle (gait design "
          "and checks; e.g. knees that must not hyperextend)", default=None),
    field("torque_limit", null_or(number("N m", gt=0)), "maximum |torque| of the joint motor",
          default=None),
    field("motor", null_or(_MOTOR), "the joint's electric motor, for energy (SPEC 15); "
          "without it the joint's electrical energy is not computed", default=None),
)


_COORD_UNACT = mapping(
    field("name", string(), "coordinate name"),
    field("link", string(), "link whose absolute angle (counter-clockwise from the world "
          "frame) is q_N"),
)


POWER_KINDS = {  # kind -> (its required keys, its optional keys)
    "momentum": (("area|diameter",), ("air_density", "figure_of_merit", "motor_efficiency")),
    "linear": (("watts_per_newton",), ()),
    "table": (("table",), ()),
    "fuel": (("tsfc",), ("heating_value",)),
}

_POWER = mapping(
    field("kind", choice(*POWER_KINDS), "momentum (actuator disk: hover power |T|^1.5 / "
          "sqrt(2 rho A) / (FM eta), with axial inflow), linear (watts per newton), table "
          "(measured thrust -> electrical power) or fuel (thrust-specific fuel consumption)"),
    field("area", null_or(number("m^2", gt=0)), "momentum: disk area A (or `diameter`)",
          default=None),
    field("diameter", null_or(number("m", gt=0)), "momentum: rotor diameter (A = pi d^2/4)",
          default=None),
    field("air_density", number("kg/m^3", gt=0), "momentum: air density rho", default=1.225),
    field("figure_of_merit", number("1", gt=0, le=1), "momentum: rotor figure of merit FM",
          default=1.0),
    field("motor_efficiency", number("1", gt=0, le=1), "momentum: motor and drive efficiency "
          "eta", default=1.0),
    field("watts_per_newton", null_or(number("W/N", ge=0)), "linear: input power per newton "
          "of |thrust|", default=None),
    field("table", null_or(mapping(
        field("thrust", vector(unit="N", min_len=2), "thrust values, strictly increasing"),
        field("power", vector(unit="W", ge=0), "electrical power at each thrust"),
    )), "table: measured thrust -> electrical power, interpolated linearly, refused outside "
        "its range", default=None),
    field("tsfc", null_or(number("kg/(N s)", gt=0)), "fuel: thrust-specific fuel "
          "consumption (fuel mass rate = tsfc |T|)", default=None),
    field("heating_value", null_or(number("J/kg", gt=0)), "fuel: the fuel's heating value "
          "(input power = heating_value tsfc |T|); without it only the fuel mass is reported",
          default=None),
)


_THRUSTER = mapping(
    field("name", string(), "thruster name"),
    field("link", string(), "link carrying the thruster"),
    field("point", vector(2, "m"), "application point in the link frame"),
    field("direction", vector(2), "direction of positive thrust (normalised on load)"),
    field("frame", choice("world", "link"), "direction fixed in the world or in the link",
          default="world"),
    field("limits", vector(2, "N"), "minimum and maximum thrust", default=[-1e3, 1e3]),
    field("power", null_or(_POWER), "input-power model, for energy (SPEC 15); without it "
          "the thruster's input energy is not computed", default=None),
)


MAX_LINKS = 20  # compiling takes ~35 s at 17 links and grows ~n^3: refuse larger robots
MAX_THRUSTERS = 16

ROBOT_SCHEMA = mapping(
    field("name", string(), "robot name (used for caches and outputs)"),
    field("description", string(nonempty=False), "free text", default=""),
    field("parameters", parameters(), "named numbers usable in any numeric field, e.g. "
          "`r/2`; arithmetic + - * / ** ( ), sin, cos, sqrt, pi", default={}),
    field("gravity", number("m/s^2", gt=0), "gravitational acceleration (along -y)",
          default=9.81),
    field("links", list_of(_LINK, min_len=2, max_len=MAX_LINKS),
          "rigid links forming a tree rooted at the stance foot"),
    field("coordinates", mapping(
        field("actuated", list_of(_COORD_ACT, min_len=1), "q_b: one relative angle per joint, "
              "in order [rad]"),
        field("unactuated", _COORD_UNACT, "q_N: one absolute angle [rad]"),
    ), "generalised coordinates q = [q_b; q_N]"),
    field("feet", mapping(
        field("stance", _POINT, "stance foot: a point of the root link, pinned"),
        field("swing", _POINT, "swing foot: strikes the ground at impact"),
    ), "foot points"),
    field("relabel", mapping(
        field("swap", null_or(list_of(list_of(string(), min_len=2))),
              "link pairs that exchange roles at impact; R follows (R = T^-1 P T)",
              default=None),
        field("R", null_or(matrix()), "explicit N x N relabelling matrix (instead of swap)",
              default=None),
        field("b", null_or(vector(unit="rad")), "offset in q+ = R q- + b", default=None),
    ), "leg relabelling at impact: q+ = R q- + b, q'+ = R q'-"),
    field("thrusters", list_of(_THRUSTER, max_len=MAX_THRUSTERS), "thrusters (may be empty)",
          default=[]),
)


# ----------------------------------------------------------------------------- robots
def _combine(mass: float, com: list[float], inertia: float, points: list[dict]
             ) -> tuple[float, tuple[float, float], float]:
    """Total mass, centre of mass and inertia about it (parallel-axis theorem)."""
    items = [(mass, np.array(com), inertia)] + [(p["mass"], np.array(p["at"]), 0.0)
                                                 for p in points]
    M = sum(m for m, _, _ in items)
    if M <= 0:
        return 0.0, (0.0, 0.0), 0.0
    massive = [it for it in items if it[0] != 0]
    if len(massive) == 1:  # exactly its own centre and inertia (a zero stays zero, whatever
        m, x, i = massive[0]  # the mass: the compiled model's structure depends on zeros)
        return float(m), (float(x[0]), float(x[1])), float(i)
    c = sum(m * x for m, x, _ in items) / M
    I = sum(i + m * float((x - c) @ (x - c)) for m, x, i in items)
    return float(M), (float(c[0]), float(c[1])), float(I)


def load_robot(ref: str, parameters: Mapping[str, float] | None = None, *,
               scale: Mapping[str, float] | None = None) -> Robot:
    """Read, validate and build a :class:`Robot` from a YAML file or bundled name.

    ``parameters``: numbers replacing the file's named ``parameters:`` (e.g. ``{"MT": 12.0}``
    [kg]), exactly as if they were edited into the file (a robot-parameter axis of a sweep;
    kept as the robot's ``overrides``).
    ``scale``: factors for named parameters (``{"MT": 1.1}``: 10 % more torso mass; an
    expression ``e`` becomes ``(e) * factor``), applied after ``parameters`` (a plant that
    differs from a controller's model: ``parameters={"MT": 12.0}, scale={"MT": 1.1}`` is a
    13.2 kg torso)."""
    ref = check_path("ref", ref)
    parameters = check_number_map("parameters", parameters, optional=True)
    scale = check_number_map("scale", scale, optional=True, gt=0)
    path = resolve(ref, "robots")
    doc = load_yaml(path, expect=kind_check("robot", ROBOT_SCHEMA))
    return parse_robot(doc, path, parameters, scale=scale)


def plant_robot(robot: Robot, scale: Mapping[str, float]) -> Robot:
    """``robot`` with the named ``parameters:`` of its file multiplied by ``scale``
    (``{"MT": 1.1}``: 10 % more torso mass [1]): the file read again with the robot's own
    ``overrides`` (the parameters it was loaded with, e.g. ``load_walker(...,
    robot_parameters=...)``) and then the factors (:func:`load_robot`), so the plant is this
    robot scaled, not the file's. :class:`InputError` naming ``plant_scale`` for a name the
    file does not define, for a robot built in memory (no file to scale the parameters of)
    and for a robot its file no longer gives (the file edited since, or the robot changed in
    memory)."""
    check_instance("robot", robot, Robot, "a Robot")
    scale = check_number_map("plant_scale", scale, gt=0)
    how = ("the parameters to scale are those of the robot file: load the robot from its "
           "file (tw.load_robot, tw.load_walker; robot_parameters for other values)")
    if not robot.source_sha256 or robot.source_file == "<memory>":
        raise InputError.param("plant_scale", f"robot {robot.name!r} was built in memory, "
                                              f"not read from a file: {how}")
    try:
        path = (Path(robot.source_path) if robot.source_path
                else resolve(robot.source_file, "robots"))  # the file it was read from
        doc = load_yaml(path, expect=kind_check("robot", ROBOT_SCHEMA))
        overrides = dict(robot.overrides)
        same = parse_robot(doc, path, overrides).canonical() == robot.canonical()
    except InputError as exc:
        raise InputError.param("plant_scale", f"robot {robot.name!r}: its file "
                               f"{robot.source_file} does not read again ({exc})") from None
    if not same:
        raise InputError.param("plant_scale", f"robot {robot.name!r} is not what its file "
                               f"{robot.source_file} gives (the file edited since it was "
                               f"loaded, or the robot changed in memory): {how}")
    return parse_robot(doc, path, overrides, scale=scale)


def load_robot_text(text: str, file: str, parameters: Mapping[str, float] | None = None
                    ) -> Robot:
    """:func:`load_robot` for the YAML text of a robot file (``file`` names it in messages),
    e.g. a robot file's content shipped to a worker process or machine."""
    return parse_robot(load_yaml_text(text, file, expect=kind_check("robot", ROBOT_SCHEMA)),
                       Path(file), parameters)


def parse_robot(doc: Document, path: Path, parameters: Mapping[str, float] | None = None,
                *, scale: Mapping[str, float] | None = None) -> Robot:
    """Validate a parsed robot document (with ``parameters`` replaced, then ``scale``
    applied, see :func:`load_robot`) against ``ROBOT_SCHEMA`` and build the :class:`Robot`
    (every problem at once)."""
    doc = override_parameters(doc, parameters)
    if scale:
        doc = _scaled(doc, dict(scale))
    expect_kind(doc, "robot", ROBOT_SCHEMA)
    res = check(doc, ROBOT_SCHEMA)
    res.raise_if_problems()
    d = res.data
    problems: list[Problem] = []
    names = [lk["name"] for lk in d["links"]]
    for i, n in enumerate(names):
        if names.index(n) != i:
            problems.append(res.problem(("links", i, "name"), f"duplicate link name '{n}'"))
    links = []
    roots = []
    for i, lk in enumerate(d["links"]):
        if lk["parent"] is None:
            roots.append(i)
        elif lk["parent"] not in names:
            problems.append(res.problem(("links", i, "parent"),
                                        f"unknown link '{lk['parent']}'"))
        m, c, I = _combine(lk["mass"], lk["com"], lk["inertia"], lk["point_masses"])
        if m <= 0:
            problems.append(res.problem(("links", i), "link has no mass: give `mass` > 0 or "
                                        "`point_masses`"))
        rotor = lk["rotor"]
        links.append(Link(lk["name"], lk["parent"], tuple(lk["joint"]), m, c, I,
                          tuple(lk["end"]),
                          rotor["inertia"] * rotor["gear_ratio"] ** 2 if rotor else 0.0))
    if len(roots) != 1:
        problems.append(res.problem(("links",), f"exactly one link needs parent: null (the "
                                    f"stance-side root), found {len(roots)}"))
    else:
        parent = {lk.name: lk.parent for lk in links}
        for i, lk in enumerate(links):
            seen, cur = set(), lk.name
            while cur is not None and cur in parent and cur not in seen:
                seen.add(cur)
                cur = parent[cur]
            if cur is not None and cur in seen:
                problems.append(res.problem(("links", i, "parent"),
                                            f"cycle in the link tree through '{lk.name}'"))
                break
    if roots and links[roots[0]].rotor_inertia:
        problems.append(res.problem(("links", roots[0], "rotor"), "the root has no joint"))
    if problems:
        raise InputError(problems)

    def need_link(name: str, path: tuple) -> None:
        if name not in names:
            problems.append(res.problem(path, f"unknown link '{name}' (links: "
                                        f"{', '.join(names)})"))

    co = d["coordinates"]
    coords = []
    for i, c in enumerate(co["actuated"]):
        need_link(c["joint"], ("coordinates", "actuated", i, "joint"))
        rng = tuple(c["range"]) if c["range"] is not None else (-np.inf, np.inf)
        if rng[0] >= rng[1]:
            problems.append(res.problem(("coordinates", "actuated", i, "range"),
                                        "minimum must be below maximum"))
        tl = c["torque_limit"] if c["torque_limit"] is not None else np.inf
        mo = c["motor"]
        motor = None if mo is None else Motor(mo["torque_constant"], mo["resistance"],
                                              mo["gear_ratio"], mo["gearbox_efficiency"])
        coords.append(Coordinate(c["name"], c["joint"], True, rng, tl, motor))
    need_link(co["unactuated"]["link"], ("coordinates", "unactuated", "link"))
    coords.append(Coordinate(co["unactuated"]["name"], co["unactuated"]["link"], False))
    cnames = [c.name for c in coords]
    if len(set(cnames)) != len(cnames):
        problems.append(res.problem(("coordinates",), "coordinate names must be unique"))
    for key in ("stance", "swing"):
        need_link(d["feet"][key]["link"], ("feet", key, "link"))
    tnames = [t["name"] for t in d["thrusters"]]
    for i, t in enumerate(d["thrusters"]):
        if tnames.index(t["name"]) != i:
            problems.append(res.problem(("thrusters", i, "name"),
                                        f"duplicate thruster name '{t['name']}'"))
        need_link(t["link"], ("thrusters", i, "link"))
        if np.hypot(*t["direction"]) < 1e-12:
            problems.append(res.problem(("thrusters", i, "direction"), "direction is zero"))
        if t["limits"][0] > t["limits"][1]:
            problems.append(res.problem(("thrusters", i, "limits"), "minimum > maximum"))
        if t["power"] is not None:
            _check_power(res, doc, ("thrusters", i, "power"), t["power"], problems)
    if problems:
        raise InputError(problems)
    links_t = tuple(links)
    coords_t = tuple(coords)
    root = links[roots[0]].name
    if d["feet"]["stance"]["link"] != root:
        problems.append(res.problem(("feet", "stance", "link"),
                                    f"the stance foot must be on the root link '{root}'"))
    try:
        coordinate_map(links_t, coords_t)
    except ValueError as exc:
        problems.append(res.problem(("coordinates",), str(exc)))
    if problems:
        raise InputError(problems)

    n = len(links)
    rl = d["relabel"]
    if (rl["swap"] is None) == (rl["R"] is None):
        raise InputError(res.problem(("relabel",), "give exactly one of `swap` or `R`"))
    if rl["swap"] is not None:
        pairs = []
        for i, pair in enumerate(rl["swap"]):
            if len(pair) != 2:
                problems.append(res.problem(("relabel", "swap", i), "expected a pair of links"))
                continue
            for nm in pair:
                need_link(nm, ("relabel", "swap", i))
            pairs.append((pair[0], pair[1]))
        if problems:
            raise InputError(problems)
        R = symmetry_relabel(links_t, coords_t, pairs)
    else:
        R = np.array(rl["R"], float)
        if R.shape != (n, n):
            raise InputError(res.problem(("relabel", "R"), f"expected a {n}x{n} matrix"))
    b = np.zeros(n) if rl["b"] is None else np.array(rl["b"], float)
    if b.shape != (n,):
        raise InputError(res.problem(("relabel", "b"), f"expected {n} values"))

    thrusters = []
    for t in d["thrusters"]:
        dvec = np.array(t["direction"], float)
        dvec = dvec / np.hypot(*dvec)
        thrusters.append(Thruster(t["name"], t["link"], tuple(t["point"]),
                                  (float(dvec[0]), float(dvec[1])), t["frame"],
                                  tuple(t["limits"]), _power_model(t["power"])))
    lines = tuple((p, ln) for p, ln in _key_lines(doc))
    return Robot(
        name=d["name"], links=links_t, coordinates=coords_t,
        stance_foot=PointRef(d["feet"]["stance"]["link"], tuple(d["feet"]["stance"]["point"])),
        swing_foot=PointRef(d["feet"]["swing"]["link"], tuple(d["feet"]["swing"]["point"])),
        relabel_R=tuple(map(tuple, R.tolist())), relabel_b=tuple(b.tolist()),
        thrusters=tuple(thrusters), gravity=d["gravity"], description=d["description"],
        source_file=str(path), source_sha256=doc.sha256,
        source_path=os.path.abspath(path),
        parameters=tuple(sorted(res.params.items())), key_lines=lines,
        overrides=tuple(sorted((k, float(v)) for k, v in (parameters or {}).items())),
    )


def _check_power(res, doc: Document, path: tuple, p: dict, problems: list[Problem]) -> None:
    """The keys a thruster's ``power:`` model needs for its ``kind`` (and no key of another
    kind); a table's thrust strictly increasing, as long as its power list."""
    kind = p["kind"]
    required, optional = POWER_KINDS[kind]
    written = set(_raw(doc, path))
    for key in required:
        names = key.split("|")
        given = [n for n in names if p[n] is not None]
        if not given:
            what = " or ".join(f"`{n}`" for n in names)
            problems.append(res.problem(path + (names[0],), f"a {kind} model needs {what}"))
        elif len(given) > 1:
            problems.append(res.problem(path + (given[1],), f"give one of "
                                        f"{' or '.join(f'`{n}`' for n in names)}, not both"))
    own = {n for key in required for n in key.split("|")} | set(optional) | {"kind"}
    for key in sorted(written - own):
        problems.append(res.problem(path + (key,), f"`{key}` is not a key of a {kind} model "
                                    f"(its keys: {', '.join(sorted(own - {'kind'}))})"))
    tab = p["table"]
    if kind == "table" and tab is not None and tab["thrust"] is not None \
            and tab["power"] is not None:
        T = np.asarray(tab["thrust"], float)
        if len(tab["power"]) != len(T):
            problems.append(res.problem(path + ("table", "power"), f"{len(tab['power'])} "
                                        f"values for {len(T)} thrust values"))
        if np.any(np.diff(T) <= 0):
            k = int(np.argmax(np.diff(T) <= 0)) + 1
            problems.append(res.problem(path + ("table", "thrust", k), f"thrust must be "
                                        f"strictly increasing ({T[k]:g} N after {T[k - 1]:g} N)"))


def _raw(doc: Document, path: tuple):
    """The mapping at ``path`` of the document as written (its keys)."""
    node = doc.data
    for key in path:
        node = node[key]
    return node if isinstance(node, dict) else {}


def _power_model(p: dict | None) -> ThrusterPower | None:
    """The :class:`ThrusterPower` of a checked ``power:`` mapping (None: not given)."""
    if p is None:
        return None
    area = p["area"] if p["area"] is not None else (
        np.pi * p["diameter"] ** 2 / 4.0 if p["diameter"] is not None else None)
    tab = p["table"] or {"thrust": (), "power": ()}
    return ThrusterPower(p["kind"], area, p["air_density"], p["figure_of_merit"],
                         p["motor_efficiency"], p["watts_per_newton"],
                         tuple(tab["thrust"]), tuple(tab["power"]), p["tsfc"],
                         p["heating_value"])


def _scaled(doc, scale: dict[str, float]):
    """``doc`` with each named parameter multiplied by its factor (an expression ``e``
    becomes ``(e) * factor``); :class:`InputError` on the parameter ``plant_scale`` for a
    name the file does not define."""
    import copy
    from dataclasses import replace

    params = doc.data.get("parameters") if isinstance(doc.data, dict) else None
    params = params if isinstance(params, dict) else {}
    unknown = [n for n in scale if n not in params]
    if unknown:
        have = ", ".join(params) or "none"
        raise InputError.param("plant_scale", f"unknown robot parameter "
                               f"{', '.join(map(repr, unknown))} (the robot file's "
                               f"parameters: {have})")
    data = copy.deepcopy(doc.data)
    for name, factor in scale.items():
        v = data["parameters"][name]
        data["parameters"][name] = (f"({v}) * {float(factor)!r}" if isinstance(v, str)
                                    else v * float(factor))
    return replace(doc, data=data)


def _key_lines(doc) -> list[tuple[str, int]]:
    """Lines of the top-level sections, for errors raised after loading (compile checks)."""
    out = []
    for key in ("links", "coordinates", "relabel", "feet", "thrusters"):
        ln = doc.line_of((key,))
        if ln is not None:
            out.append((key, ln))
    ln = doc.line_of(("coordinates", "unactuated"))
    if ln is not None:
        out.append(("coordinates.unactuated", ln))
    return out
