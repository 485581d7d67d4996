"""Robot descriptions (SPEC section 1): immutable, numeric, free of SymPy.

Conventions (also in the README):

* World frame: x forward, y up, gravity along -y. Units SI (m, kg, s, rad, N).
* Every link has a frame. Its absolute angle ``theta`` is the counter-clockwise rotation of
  the link frame relative to the world frame; a point ``p`` given in link coordinates sits at
  ``origin + Rot(theta) p`` in the world.
* The root link is pinned at the stance foot (a point of the root link). Every other link's
  frame origin is its joint, a point given in its parent's frame.
* Generalised coordinates ``q = [q_b; q_N]``: ``q_b`` are relative joint angles
  ``theta_child - theta_parent`` (one per joint, actuated), ``q_N`` is the absolute angle of
  one link (unactuated). Hence ``theta = T q`` with a constant integer matrix ``T``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

Vec2 = tuple[float, float]
SANE_THRUST_WEIGHTS = 10.0  # [robot weights] bound of a thruster without limits (thrust_bound)
SANE_PUSH_SPEED = 10.0  # [m/s] the largest velocity change of the whole robot by a push


@dataclass(frozen=True)
class Link:
    """A rigid planar link.

    joint: origin of this link's frame in the parent's frame [m] (ignored for the root).
    com: centre of mass in the link frame [m]; mass [kg]; inertia about the COM [kg m^2].
    rotor_inertia: reflected rotor inertia ``J G^2`` on the joint to the parent [kg m^2].
    end: a drawing point (the link's far end) in the link frame [m].
    """

    name: str
    parent: str | None
    joint: Vec2
    mass: float
    com: Vec2
    inertia: float
    end: Vec2 = (0.0, 0.0)
    rotor_inertia: float = 0.0


@dataclass(frozen=True)
class PointRef:
    """A point fixed on a link, in that link's frame [m]."""

    link: str
    point: Vec2


@dataclass(frozen=True)
class Motor:
    """A joint's electric motor (SPEC 15): torque constant ``k_t`` [N m/A], winding
    resistance ``R`` [ohm], gear ratio ``G`` [1] (joint torque ``u = G k_t i``) and gearbox
    efficiency ``efficiency`` in (0, 1] (1: lossless). Used for energy only; the dynamics'
    reflected rotor inertia is the link's ``rotor:``."""

    k_t: float
    R: float
    G: float
    efficiency: float = 1.0


@dataclass(frozen=True)
class ThrusterPower:
    """A thruster's input-power model (SPEC 15), one of ``kind``:

    * ``momentum``: actuator disk of area ``area`` [m^2], air density ``rho`` [kg/m^3],
      figure of merit ``figure_of_merit`` and motor efficiency ``efficiency`` (each in (0, 1]);
    * ``linear``: ``watts_per_newton`` [W/N] times ``|T|``;
    * ``table``: measured ``thrust`` [N] (strictly increasing) -> electrical ``power`` [W],
      interpolated linearly, refused outside its range;
    * ``fuel``: thrust-specific fuel consumption ``tsfc`` [kg/(N s)]; with ``heating_value``
      [J/kg] the fuel's energy is the input energy, without it only the fuel mass is known.
    """

    kind: str
    area: float | None = None
    rho: float = 1.225
    figure_of_merit: float = 1.0
    efficiency: float = 1.0
    watts_per_newton: float | None = None
    thrust: tuple[float, ...] = ()
    power: tuple[float, ...] = ()
    tsfc: float | None = None
    heating_value: float | None = None


@dataclass(frozen=True)
class Thruster:
    """A thruster at ``point`` on ``link`` pushing along unit ``direction``.

    frame: ``"world"`` (direction fixed in the world) or ``"link"`` (rotates with the link).
    limits: (min, max) magnitude [N]; the signed magnitude ``F`` multiplies ``direction``.
    power: its input-power model (:class:`ThrusterPower`, SPEC 15) or None.
    """

    name: str
    link: str
    point: Vec2
    direction: Vec2
    frame: str = "world"
    limits: Vec2 = (-np.inf, np.inf)
    power: ThrusterPower | None = None  # input-power model (SPEC 15); None: not given


@dataclass(frozen=True)
class Coordinate:
    """A generalised coordinate.

    Actuated: relative angle of joint ``link`` (``theta_link - theta_parent``) [rad].
    Unactuated: absolute angle of ``link`` (counter-clockwise from the world frame) [rad].
    range: allowed (min, max) angle [rad]; torque_limit: max |u| [N m] (actuated only).
    motor: the joint's :class:`Motor` (SPEC 15; actuated only) or None.
    Limits constrain gait design and are reported by checks; they do not enter the dynamics.
    """

    name: str
    link: str
    actuated: bool
    range: tuple[float, float] = (-np.inf, np.inf)
    torque_limit: float = np.inf
    motor: Motor | None = None  # the joint's motor (SPEC 15, energy only); None: not given


@dataclass(frozen=True)
class Robot:
    """An immutable robot description; everything a compiler needs, all numbers SI."""

    name: str
    links: tuple[Link, ...]
    coordinates: tuple[Coordinate, ...]
    stance_foot: PointRef
    swing_foot: PointRef
    relabel_R: tuple[tuple[float, ...], ...]
    relabel_b: tuple[float, ...]
    thrusters: tuple[Thruster, ...]
    gravity: float = 9.81
    description: str = ""
    source_file: str = "<memory>"
    source_sha256: str = ""
    parameters: tuple[tuple[str, float], ...] = field(default=())
    key_lines: tuple[tuple[str, int], ...] = field(default=(), compare=False, repr=False)
    #: the named parameters replaced when the file was read (``load_robot``'s
    #: ``parameters``, a sweep's robot-parameter axis) [SI]: with the file, they rebuild this
    #: robot (a controller's plant with scaled parameters, ``files.robot_file.plant_robot``)
    overrides: tuple[tuple[str, float], ...] = field(default=(), compare=False, repr=False)
    #: the file's absolute path when it was read ("" for a robot built in memory):
    #: ``source_file`` is the path as given, which a script changing its working folder
    #: afterwards no longer finds (the plant of ``plant_scale`` reads the file again)
    source_path: str = field(default="", compare=False, repr=False)

    def __repr__(self) -> str:
        """One line: the name, the number of links, the actuated and unactuated coordinates,
        the thrusters and the file (the dataclass repr prints every link and number, which a
        notebook should not; equality is the dataclass's, field by field)."""
        act = [c.name for c in self.coordinates if c.actuated]
        unact = [c.name for c in self.coordinates if not c.actuated]
        return (f"Robot(name={self.name!r}, links={len(self.links)}, actuated={act!r}, "
                f"unactuated={unact!r}, thrusters={self.thruster_names!r}, "
                f"file={self.source_file!r})")

    def line_of(self, path: str) -> int | None:
        """Line of a key path (e.g. ``"coordinates.unactuated"``) in the source file."""
        best = None
        for p, ln in self.key_lines:
            if path == p or path.startswith(p + ".") or path.startswith(p + "["):
                if best is None or len(p) > len(best[0]):
                    best = (p, ln)
        return best[1] if best else None

    # -- derived structure ---------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of links = number of generalised coordinates N."""
        return len(self.links)

    @property
    def link_names(self) -> list[str]:
        """The link names, in file order."""
        return [lk.name for lk in self.links]

    @property
    def coordinate_names(self) -> list[str]:
        """The names of the coordinates, in the order of ``q`` (SPEC 1)."""
        return [c.name for c in self.coordinates]

    @property
    def thruster_names(self) -> list[str]:
        """The thruster names, in the order of the columns of ``B_F`` (SPEC 1)."""
        return [t.name for t in self.thrusters]

    @property
    def root(self) -> Link:
        """The root link (the one without a parent)."""
        return next(lk for lk in self.links if lk.parent is None)

    def link_index(self, name: str) -> int:
        """The position of the link ``name`` in :attr:`link_names` (ValueError: no such link)."""
        return self.link_names.index(name)

    @property
    def stance_leg(self) -> tuple[str, ...]:
        """The stance leg's links from the root: the first half (rounded down, at least one)
        of the link path from the stance foot's link to the swing foot's, the legs of a biped
        mirroring each other about the hip (three_link: the root alone; a kneed walker:
        shank and thigh)."""
        parent = {lk.name: lk.parent for lk in self.links}
        path = [self.swing_foot.link]
        while parent[path[-1]] is not None:
            path.append(parent[path[-1]])
        path.reverse()
        return tuple(path[:max(1, len(path) // 2)])

    def stance_end_text(self) -> str:
        """What the end of the stance link (the default push point, SPEC 12) is on this robot:
        the hip when the stance leg is one link, else the joint to the next stance-leg link
        (a kneed walker's stance knee), never called the hip then."""
        leg = self.stance_leg
        if len(leg) == 1:
            return f"the hip (the end of the stance link {leg[0]})"
        return (f"the end of the stance link {leg[0]}: its joint to {leg[1]} (the stance knee "
                f"of a kneed walker), not the hip")

    def thruster_index(self, name: str | None, param: str = "thruster") -> int:
        """Index of the thruster ``name`` (default: the first). :class:`InputError` on the
        parameter ``thruster`` when the name is unknown, and on ``param`` (the parameter that
        needs a thruster) when the robot has none."""
        names = self.thruster_names
        if not names:
            raise InputError.param(param, f"robot {self.name} has no thruster (`thrusters: []` "
                                          f"in {self.source_file})")
        if name is None:
            return 0
        if name not in names:
            raise InputError.param("thruster", f"unknown thruster {name!r} (robot {self.name} "
                                   f"has: {', '.join(names)})")
        return names.index(name)

    def driven_thruster(self, name: str | None) -> int | None:
        """The thruster that thrust values drive: ``name`` (default: the first), or None for a
        robot without thrusters (then thrust options refer to no thruster; naming one is an
        :class:`InputError` on ``thruster``)."""
        if not self.thrusters:
            if name is not None:
                raise InputError.param("thruster", f"unknown thruster {name!r}: robot "
                                                   f"{self.name} has no thruster")
            return None
        return self.thruster_index(name)

    def check_no_thrust(self, values, param: str = "thrust") -> None:
        """For a robot without thrusters every thrust value [N] must be 0: otherwise an
        :class:`InputError` on ``param`` (one line). A no-op for a robot with thrusters."""
        if self.thrusters:
            return
        bad = [float(v) for v in values if float(v) != 0.0]
        if bad:
            raise InputError.param(param, f"robot {self.name} has no thruster: thrust values "
                                          f"must be 0 (got {bad[0]:g} N)")

    @property
    def total_mass(self) -> float:
        """The sum of the link masses [kg]."""
        return float(sum(lk.mass for lk in self.links))

    def thrust_bound(self, j: int) -> float:
        """The largest |thrust| [N] thruster ``j`` can give: the larger end of its ``limits``,
        or, for a thruster without limits, :data:`SANE_THRUST_WEIGHTS` times the robot's
        weight (a bound beyond that is a typo, not a thruster)."""
        lo, hi = self.thrusters[j].limits
        big = max(abs(lo), abs(hi))
        return float(big) if np.isfinite(big) else SANE_THRUST_WEIGHTS * self.weight

    def check_thrust_bound(self, param: str, value: float, driven) -> None:
        """A thrust bound ``value`` [N] of the thrusters ``driven`` (indices) at most what they
        can give (:meth:`thrust_bound`): :class:`InputError` on ``param`` otherwise."""
        for j in driven:
            big = self.thrust_bound(j)
            if value > big:
                lo, hi = self.thrusters[j].limits
                why = (f"its limits [{lo:g}, {hi:g}] N" if np.isfinite(max(abs(lo), abs(hi)))
                       else f"{SANE_THRUST_WEIGHTS:g} times the robot's weight: it has no "
                            "limits")
                raise InputError.param(param, f"{value:g} N is more than thruster "
                                              f"{self.thrusters[j].name} can give ({big:g} N, "
                                              f"{why})")

    @property
    def weight(self) -> float:
        """The robot's weight m g [N]."""
        return self.total_mass * float(self.gravity)

    def push_bound(self) -> float:
        """The largest push impulse [N s] worth simulating: one that changes the whole robot's
        velocity by :data:`SANE_PUSH_SPEED` m/s (a larger one is a crash, not a push)."""
        return SANE_PUSH_SPEED * self.total_mass

    def check_push(self, param: str, impulse: float) -> None:
        """A push impulse of size ``|impulse|`` [N s] at most :meth:`push_bound`:
        :class:`InputError` on ``param`` otherwise."""
        size, bound = abs(float(impulse)), self.push_bound()
        if size > bound:
            raise InputError.param(param, f"an impulse of {size:g} N s changes the robot's "
                                          f"velocity by {size / self.total_mass:.3g} m/s: at "
                                          f"most {bound:g} N s ({self.total_mass:g} kg x "
                                          f"{SANE_PUSH_SPEED:g} m/s; a larger one is a crash, "
                                          "not a push)")

    def path_from_root(self, name: str) -> list[str]:
        """Link names from the root to ``name`` (inclusive)."""
        parents = {lk.name: lk.parent for lk in self.links}
        path = [name]
        while parents[path[-1]] is not None:
            path.append(parents[path[-1]])
        return path[::-1]

    @property
    def T(self) -> np.ndarray:
        """Constant map ``theta = T q`` from coordinates to absolute link angles (SPEC 1)."""
        return coordinate_map(self.links, self.coordinates)

    @property
    def R(self) -> np.ndarray:
        """The relabelling matrix ``R`` (N x N) of ``q^+ = R q^- + b`` (SPEC 1)."""
        return np.array(self.relabel_R, dtype=float)

    @property
    def b(self) -> np.ndarray:
        """The relabelling offset ``b`` (N,) [rad] of ``q^+ = R q^- + b`` (SPEC 1)."""
        return np.array(self.relabel_b, dtype=float)

    def numbers(self) -> list[tuple[str, float]]:
        """Every physical number the compiled model depends on, as ``(name, value)`` in a
        fixed order that the robot's :meth:`structure` determines: gravity [m/s^2], the total
        mass [kg] (the sum of the link masses, given once so that ``D_u``'s mass block is
        exactly ``total_mass``), per link its joint [m], mass [kg], centre of mass [m],
        inertia [kg m^2], end point [m] and rotor inertia [kg m^2], the foot points [m], and
        per thruster its point [m] and unit direction. These are the compiled model's inputs
        (SPEC 1): robots that differ only in them share one compiled model."""
        out: list[tuple[str, float]] = [("gravity", self.gravity),
                                        ("total_mass", self.total_mass)]

        def vec(name: str, v: Vec2) -> None:
            out.extend(((f"{name}.x", v[0]), (f"{name}.y", v[1])))
        for lk in self.links:
            p = f"links.{lk.name}"
            vec(p + ".joint", lk.joint)
            out.append((p + ".mass", lk.mass))
            vec(p + ".com", lk.com)
            out.append((p + ".inertia", lk.inertia))
            vec(p + ".end", lk.end)
            out.append((p + ".rotor_inertia", lk.rotor_inertia))
        vec("feet.stance", self.stance_foot.point)
        vec("feet.swing", self.swing_foot.point)
        for t in self.thrusters:
            vec(f"thrusters.{t.name}.point", t.point)
            vec(f"thrusters.{t.name}.direction", t.direction)
        return [(k, float(v)) for k, v in out]

    def structure(self) -> dict:
        """What the compiled code depends on besides the values of :meth:`numbers`: names,
        the link tree, the coordinates, the feet's links, the relabelling ``R``, ``b``, the
        thrusters' links and frames, and which numbers are zero (a zero is folded into the
        code, every other number is an input). The model cache key is its hash."""
        return {
            "links": [[lk.name, lk.parent] for lk in self.links],
            "coordinates": [[c.name, c.link, c.actuated] for c in self.coordinates],
            "feet": [self.stance_foot.link, self.swing_foot.link],
            "R": [list(r) for r in self.relabel_R],
            "b": list(self.relabel_b),
            "thrusters": [[t.name, t.link, t.frame] for t in self.thrusters],
            "zero": [name for name, v in self.numbers() if v == 0.0],
        }

    def canonical(self) -> dict:
        """Content that determines the compiled model's numbers: its :meth:`structure` and
        the values of its :meth:`numbers`."""
        return {
            "links": [
                [lk.name, lk.parent, list(lk.joint), lk.mass, list(lk.com), lk.inertia,
                 list(lk.end), lk.rotor_inertia]
                for lk in self.links
            ],
            "coordinates": [[c.name, c.link, c.actuated] for c in self.coordinates],
            "stance_foot": [self.stance_foot.link, list(self.stance_foot.point)],
            "swing_foot": [self.swing_foot.link, list(self.swing_foot.point)],
            "R": [list(r) for r in self.relabel_R],
            "b": list(self.relabel_b),
            "thrusters": [
                [t.name, t.link, list(t.point), list(t.direction), t.frame]
                for t in self.thrusters
            ],
            "gravity": self.gravity,
        }


def coordinate_map(links: tuple[Link, ...], coords: tuple[Coordinate, ...]) -> np.ndarray:
    """Integer matrix ``T`` with ``theta = T q``.

    Each absolute angle is the anchor's absolute angle ``q_N`` plus/minus the relative joint
    angles on the tree path between the anchor link and the link. Raises ``ValueError`` when
    the coordinates are not one relative angle per joint plus one absolute angle.
    """
    names = [lk.name for lk in links]
    parent = {lk.name: lk.parent for lk in links}
    n = len(links)
    act = [c for c in coords if c.actuated]
    unact = [c for c in coords if not c.actuated]
    if len(unact) != 1 or len(act) != n - 1 or len(coords) != n:
        raise ValueError(
            f"need {n - 1} actuated joint angles and 1 absolute angle for {n} links, "
            f"got {len(act)} and {len(unact)}"
        )
    joint_col = {}
    for c in act:
        if parent[c.link] is None:
            raise ValueError(f"'{c.link}' is the root link: it has no joint to a parent")
        if c.link in joint_col:
            raise ValueError(f"joint of '{c.link}' is used by two coordinates")
        joint_col[c.link] = [cc.name for cc in coords].index(c.name)
    anchor = unact[0].link
    anchor_col = [cc.name for cc in coords].index(unact[0].name)

    def root_path(name: str) -> list[str]:
        p = [name]
        while parent[p[-1]] is not None:
            p.append(parent[p[-1]])
        return p

    # theta_x - theta_root = sum of joint angles on the root path of x (excluding root).
    T = np.zeros((n, n))
    anchor_path = root_path(anchor)
    for i, name in enumerate(names):
        T[i, anchor_col] = 1.0
        for lk in root_path(name)[:-1]:
            T[i, joint_col[lk]] += 1.0
        for lk in anchor_path[:-1]:
            T[i, joint_col[lk]] -= 1.0
    return T


def symmetry_relabel(robot_links: tuple[Link, ...], coords: tuple[Coordinate, ...],
                     swaps: list[tuple[str, str]]) -> np.ndarray:
    """Relabelling matrix ``R = T^-1 P T`` from swapped link pairs (SPEC 1).

    After impact the link called ``a`` takes the place (and absolute angle) of link ``b``
    and vice versa; all other links keep their absolute angles.
    """
    names = [lk.name for lk in robot_links]
    n = len(names)
    P = np.eye(n)
    for a, b in swaps:
        ia, ib = names.index(a), names.index(b)
        P[ia, ia] = P[ib, ib] = 0.0
        P[ia, ib] = P[ib, ia] = 1.0
    T = coordinate_map(robot_links, coords)
    R = np.linalg.solve(T, P @ T)
    return np.round(R, 12) + 0.0
