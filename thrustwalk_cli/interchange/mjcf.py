"""thrustwalk robot -> MuJoCo MJCF (SPEC 16): the planar robot as a MuJoCo model.

Plain text generation: nothing here imports ``mujoco`` (the export works without it; the
MuJoCo run of :mod:`thrustwalk_cli.interchange.mujoco_run` loads the same text).

Conventions (SI units):

* The plane is MuJoCo's x-z plane: thrustwalk's ``(x, y)`` is MuJoCo's ``(x, z)``, gravity
  ``(0, 0, -g)``. A counter-clockwise thrustwalk angle is a rotation about ``-y``, so every
  hinge has ``axis="0 -1 0"`` and its MuJoCo angle is thrustwalk's angle (as in the URDF
  export).
* One body per link, in the robot's tree, rooted at the robot's root link (the stance leg of
  thrustwalk's labelling). Body frames are parallel to thrustwalk's link frames (at zero joint
  angles every frame is parallel to the world, as in thrustwalk); the root body's frame origin
  is the stance-foot point (the link frame translated by ``-foot``), so its two slide joints
  ``root_x`` (along x) and ``root_z`` (along z) are the stance foot's position and its hinge
  ``root_angle`` is the root link's absolute angle. Every other body's hinge, named after the
  actuated coordinate of that joint, is the relative angle ``theta_child - theta_parent``, as
  in thrustwalk: MuJoCo's ``qpos = [x_foot, z_foot, a]`` with ``a = [theta_root; joint angles]``
  and thrustwalk's ``q = P a`` (:class:`MjcfLayout`, ``P = T^-1 A`` an integer matrix).
* Each body carries an ``<inertial>`` (mass [kg], centre of mass [m], ``diaginertia = (I/2, I,
  I/2)``: the planar inertia about the plane normal is ``iyy``, the two out-of-plane values
  (a lamina's) never act in planar motion); ``inertiafromgeom="false"``: the capsules that draw
  the links have no mass. A reflected rotor inertia is the hinge's ``armature`` (it adds
  ``J`` to the joint's relative rate, as thrustwalk's ``rotor_inertia``). A zero planar inertia
  (a point mass) is written as ``INERTIA_FLOOR`` (MuJoCo refuses a moving body without
  inertia); it changes the inertia matrix by at most that much.
* Feet: a sphere of radius ``foot_radius`` centred on each foot point (``foot_stance``,
  ``foot_swing``; sites of the same names), friction ``mu``; the floor is a plane one radius
  below ``z = 0``, so a foot point at thrustwalk's ground height ``0`` touches it. A sphere
  rolls: the contact point lies one radius below the foot point and a rotation ``d theta`` of
  the stance link moves the foot point by ``radius * d theta`` without slip. Only feet and
  floor collide (``contype``/``conaffinity``); the link capsules are drawings.
* Thrusters: a site per thruster at its point, and a ``<general>`` actuator on that site whose
  gear is the unit direction (``ctrl`` = thrust [N]): in the site's frame for a ``link``
  thruster, in the world (``refsite="world"``) for a ``world`` thruster. Joint motors (gear 1,
  ``ctrlrange`` from ``torque_limit``) drive the actuated hinges. The MuJoCo run applies the
  controller's torques and the thrust through ``qfrc_applied`` instead (generalised forces of
  thrustwalk's model, also a generalised thrust on ``q_N``) and leaves these actuators at zero.
* Contact and integration: ``solref``, ``solimp``, timestep, integrator and cone from a
  :class:`ContactModel` (presets :data:`CONTACT_PRESETS`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from .._version import __version__
from ..description.robot import Robot
from ..errors import InputError, check_instance, check_number, check_numbers

#: [kg m^2] the planar inertia written for a link whose inertia is zero (point masses)
INERTIA_FLOOR = 1e-12
ROOT_JOINTS = ("root_x", "root_z", "root_angle")
INTEGRATORS = ("implicitfast", "Euler")  # what mj_step1/mj_step2 integrate (not RK4)
CONES = ("elliptic", "pyramidal")


@dataclass(frozen=True)
class ContactModel:
    """MuJoCo's soft contact and integration settings (SPEC 16).

    ``solref = (timeconst [s], dampratio [1])``: the contact behaves as a mass-spring-damper
    with that time constant and damping ratio (smaller: stiffer); ``solimp = (d0, dwidth,
    width [m], midpoint, power)``: the impedance, from ``d0`` at zero penetration to ``dwidth``
    at ``width``. ``timestep`` [s]; ``integrator``; ``cone`` (friction cone) with ``impratio``
    (the ratio of frictional to normal impedance: > 1 makes friction stiffer, less creep);
    ``foot_radius`` [m] of the feet's spheres. MuJoCo needs ``timeconst >= 2 timestep``
    (otherwise it silently stiffens less than asked): :meth:`validate` refuses it.
    """

    name: str = "default"
    timeconst: float = 0.005
    dampratio: float = 1.0
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    timestep: float = 5e-4
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    impratio: float = 10.0
    foot_radius: float = 1e-4

    @property
    def solref(self) -> tuple[float, float]:
        """MuJoCo's ``solref``: ``(timeconst [s], dampratio [1])`` (SPEC 16)."""
        return (self.timeconst, self.dampratio)

    def validate(self) -> None:
        """Raise :class:`InputError` naming every setting out of range (timestep, solref, solimp,
        integrator, cone, impratio, foot_radius); return None when all are valid."""
        problems = []
        if not 1e-6 <= self.timestep <= 0.01:
            problems.append(("timestep", f"must lie in [1e-6, 0.01] s (got {self.timestep:g})"))
        elif not self.timeconst >= 2.0 * self.timestep:
            problems.append(("solref", f"MuJoCo needs a contact time constant of at least "
                                          f"2 timesteps ({2 * self.timestep:g} s; got "
                                          f"{self.timeconst:g} s)"))
        if not 0 < self.dampratio <= 10:
            problems.append(("solref", f"the damping ratio must lie in (0, 10] (got "
                                       f"{self.dampratio:g})"))
        d0, dw, width, mid, power = self.solimp
        if not (0 < d0 < 1 and 0 < dw < 1 and width > 0 and 0 < mid < 1 and power >= 1):
            problems.append(("solimp", "needs 0 < d0, dwidth < 1, width > 0 m, 0 < midpoint "
                                       "< 1, power >= 1"))
        if self.integrator not in INTEGRATORS:
            problems.append(("integrator", f"unknown integrator {self.integrator!r} (choose "
                                           f"from {', '.join(INTEGRATORS)})"))
        if self.cone not in CONES:
            problems.append(("cone", f"unknown cone {self.cone!r} (choose from "
                                     f"{', '.join(CONES)})"))
        if not 1.0 <= self.impratio <= 1e3:
            problems.append(("impratio", f"must lie in [1, 1000] (got {self.impratio:g})"))
        if not 1e-5 <= self.foot_radius <= 0.1:
            problems.append(("foot_radius", f"must lie in [1e-5, 0.1] m (got "
                                            f"{self.foot_radius:g})"))
        if problems:
            raise InputError([InputError.param(n, m).problems[0] for n, m in problems])

    def record(self) -> dict:
        """Plain numbers for documents (SI)."""
        return {"preset": self.name, "solref": list(self.solref), "solimp": list(self.solimp),
                "timestep": self.timestep, "integrator": self.integrator, "cone": self.cone,
                "impratio": self.impratio, "foot_radius": self.foot_radius}


#: ``--contact`` presets: MuJoCo's own default contact (soft), a stiffer one (default) and a
#: stiff one with a small timestep (the rigid-impact limit the checks use)
CONTACT_PRESETS: dict[str, ContactModel] = {
    "soft": ContactModel("soft", timeconst=0.02, dampratio=1.0,
                         solimp=(0.9, 0.95, 0.001, 0.5, 2.0), timestep=2e-3),
    "default": ContactModel("default"),
    "stiff": ContactModel("stiff", timeconst=0.001, dampratio=1.0,
                          solimp=(0.99, 0.999, 0.0005, 0.5, 2.0), timestep=1e-4),
}


def contact_settings(preset: str = "default", *, timestep: float | None = None,
                     solref: Sequence[float] | None = None,
                     solimp: Sequence[float] | None = None, integrator: str | None = None,
                     foot_radius: float | None = None, impratio: float | None = None,
                     cone: str | None = None) -> ContactModel:
    """A :data:`CONTACT_PRESETS` entry (``soft``, ``default``, ``stiff``) with the given
    settings replaced (``solref = (timeconst [s], dampratio)``, ``solimp = (d0, dwidth, width
    [m][, midpoint, power])``, ``timestep`` [s], ``foot_radius`` [m]); validated."""
    if preset not in CONTACT_PRESETS:
        raise InputError.param("contact", f"unknown preset {preset!r} (choose from "
                                          f"{', '.join(CONTACT_PRESETS)})")
    ct = CONTACT_PRESETS[preset]
    changes: dict = {}
    if solref is not None:
        if len(solref) != 2:
            raise InputError.param("solref", "expected TIMECONST,DAMPRATIO (e.g. 0.005,1)")
        changes.update(timeconst=float(solref[0]), dampratio=float(solref[1]))
    if solimp is not None:
        if len(solimp) not in (3, 5):
            raise InputError.param("solimp", "expected D0,DWIDTH,WIDTH[,MIDPOINT,POWER] (e.g. "
                                             "0.95,0.99,0.001)")
        v = [float(x) for x in solimp] + ([0.5, 2.0] if len(solimp) == 3 else [])
        changes["solimp"] = tuple(v)
    for key, val in (("timestep", timestep), ("integrator", integrator),
                     ("foot_radius", foot_radius), ("impratio", impratio), ("cone", cone)):
        if val is not None:
            changes[key] = float(val) if isinstance(val, (int, float)) else val
    if changes:
        ct = replace(ct, name=f"{preset} (changed: {', '.join(sorted(changes))})", **changes)
    ct.validate()
    return ct



@dataclass(frozen=True)
class MjcfLayout:
    """How the MJCF's coordinates map to thrustwalk's (see the module docstring).

    ``bodies``: link names in the MJCF's body order (depth first from the root; MuJoCo's dof
    order). ``hinges``: the joint name of each body (``root_angle`` for the root).
    ``P``: ``q = P a`` with ``a = qpos[2:]`` (N x N, integer); ``P_inv`` its inverse.
    ``qpos = [x_foot, z_foot, a]`` and ``qvel = [x_foot', z_foot', a']`` with the stance foot of
    thrustwalk's labelling (the root's) pinned at ``(x_foot, z_foot)``.
    """

    bodies: tuple[str, ...]
    hinges: tuple[str, ...]
    P: np.ndarray = field(repr=False)
    P_inv: np.ndarray = field(repr=False)

    def q_of(self, a: np.ndarray) -> np.ndarray:
        """thrustwalk's ``q`` [rad] from MuJoCo's angles ``a = qpos[2:]``."""
        return np.asarray(a, float) @ self.P.T

    def a_of(self, q: np.ndarray) -> np.ndarray:
        """MuJoCo's angles ``a`` from thrustwalk's ``q`` [rad] (also rates)."""
        return np.asarray(q, float) @ self.P_inv.T

    def unpinned_map(self) -> np.ndarray:
        """``J`` ((N+2) x (N+2)) with ``qvel = J q_u'``, ``q_u = [q; x_1; y_1]``: MuJoCo's
        joint-space inertia ``M`` maps to thrustwalk's ``D_u = J^T M J`` (SPEC 1)."""
        n = self.P.shape[0]
        J = np.zeros((n + 2, n + 2))
        J[0, n] = J[1, n + 1] = 1.0
        J[2:, :n] = self.P_inv
        return J


def layout(robot: Robot) -> MjcfLayout:
    """The body order and the coordinate map of :func:`robot_to_mjcf` for ``robot``."""
    children: dict[str | None, list[str]] = {}
    for lk in robot.links:
        children.setdefault(lk.parent, []).append(lk.name)
    order: list[str] = []
    stack = [robot.root.name]
    while stack:  # depth first, children in the robot file's order
        name = stack.pop()
        order.append(name)
        stack.extend(reversed(children.get(name, [])))
    coord = {c.link: c.name for c in robot.coordinates if c.actuated}
    hinges = tuple(ROOT_JOINTS[2] if lk == robot.root.name else coord[lk] for lk in order)
    parent = {lk.name: lk.parent for lk in robot.links}
    n = robot.n
    A = np.zeros((n, n))  # theta (robot link order) = A a
    pos = {name: i for i, name in enumerate(order)}
    for i, lk in enumerate(robot.links):
        name = lk.name
        while name is not None:
            A[i, pos[name]] = 1.0
            name = parent[name]
    P = np.round(np.linalg.solve(robot.T, A), 12) + 0.0
    P_inv = np.round(np.linalg.inv(P), 12) + 0.0
    return MjcfLayout(tuple(order), hinges, P, P_inv)


def _f(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def _v(*xs: float) -> str:
    return " ".join(_f(x) for x in xs)


def _comment(s: str) -> str:
    return escape(s).replace("--", "- -")


def robot_to_mjcf(robot: Robot, *, mu: float = 1.0, contact: ContactModel | None = None,
                  keyframe: tuple[Sequence[float], Sequence[float]] | None = None,
                  notes: Sequence[str] = ()) -> str:
    """The MJCF text of the planar ``robot`` (conventions in the module docstring).

    ``mu`` [1]: the feet's and the floor's sliding friction; ``contact``: solref, solimp,
    timestep, integrator, cone, foot radius (default :data:`CONTACT_PRESETS` ``default``);
    ``keyframe``: thrustwalk's ``(q, q')`` [rad, rad/s] of a state with the stance foot at the
    origin, written as the key ``start`` (e.g. just after an impact on the predicted orbit);
    ``notes``: lines for the header comment."""
    check_instance("robot", robot, Robot, "a Robot (tw.load_robot)")
    mu = check_number("mu", mu, gt=0, le=10)
    contact = check_instance("contact", contact or CONTACT_PRESETS["default"], ContactModel,
                             "a ContactModel (contact_settings)")
    contact.validate()
    if keyframe is not None:
        if not (isinstance(keyframe, tuple) and len(keyframe) == 2):
            raise InputError.param("keyframe", "must be a pair (q, dq)")
        n = len(robot.coordinates)
        keyframe = (check_numbers("keyframe", keyframe[0], min_len=n, max_len=n),
                    check_numbers("keyframe", keyframe[1], min_len=n, max_len=n))
    if isinstance(notes, (str, bytes)) or not hasattr(notes, "__iter__") or any(
            not isinstance(t, str) for t in notes):
        raise InputError.param("notes", "must be a sequence of texts")
    lay = layout(robot)
    names = set(lay.hinges[1:]) | set(robot.link_names) | set(robot.thruster_names)
    clash = sorted(names & {*ROOT_JOINTS, "world", "floor", "foot_stance", "foot_swing"})
    if clash:
        raise InputError(f"robot {robot.name}: the name {clash[0]!r} is one the MJCF export "
                         "uses itself (rename the link, coordinate or thruster)")
    r = contact.foot_radius
    links = {lk.name: lk for lk in robot.links}
    kids: dict[str, list[str]] = {}
    for lk in robot.links:
        if lk.parent is not None:
            kids.setdefault(lk.parent, []).append(lk.name)
    root = robot.root.name
    foot = np.asarray(robot.stance_foot.point, float)
    coord = {c.link: c for c in robot.coordinates if c.actuated}
    solref = f'solref="{_v(*contact.solref)}" solimp="{_v(*contact.solimp)}"'
    fr = f'friction="{_v(mu, 0.0, 0.0)}"'
    extent = max(1.0, float(np.abs([p for lk in robot.links for p in (*lk.joint, *lk.end)]
                                   ).max()) * 2)
    L = ['<?xml version="1.0"?>',
         f"<!-- {_comment(robot.name)}: exported by thrustwalk {__version__} (SPEC 16). "
         "Planar: the x-z plane, hinges about 0 -1 0 (the MuJoCo angle is thrustwalk's "
         "counter-clockwise angle), the root's slides are the stance foot's position. -->",
         f"<!-- Contact preset {_comment(contact.name)}: solref {_v(*contact.solref)}, "
         f"solimp {_v(*contact.solimp)}, timestep {_f(contact.timestep)} s, friction mu "
         f"{_f(mu)}, feet spheres of radius {_f(r)} m (the floor is one radius below z = 0). "
         "-->"]
    L += [f"<!-- {_comment(n)} -->" for n in notes]
    L += [f"<mujoco model={quoteattr(robot.name)}>",
          '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
          f'  <option timestep="{_f(contact.timestep)}" gravity="0 0 {_f(-robot.gravity)}" '
          f'integrator="{contact.integrator}" cone="{contact.cone}" '
          f'impratio="{_f(contact.impratio)}"/>',
          f'  <statistic extent="{_f(extent)}" center="0 0 {_f(extent / 4)}"/>',
          '  <visual><global offwidth="1280" offheight="960"/></visual>',
          "  <default>",
          '    <geom contype="0" conaffinity="0" rgba="0.35 0.45 0.7 1"/>',
          '    <joint limited="false" damping="0"/>',
          "  </default>",
          "  <asset>",
          '    <texture name="grid" type="2d" builtin="checker" width="512" height="512" '
          'rgb1="0.85 0.85 0.85" rgb2="0.7 0.7 0.7"/>',
          '    <material name="grid" texture="grid" texrepeat="8 8" reflectance="0"/>',
          "  </asset>",
          "  <worldbody>",
          '    <light name="sun" pos="0 -4 6" dir="0 0.5 -1" directional="true"/>',
          f'    <geom name="floor" type="plane" pos="0 0 {_f(-r)}" size="0 0 0.05" '
          f'material="grid" contype="0" conaffinity="1" condim="3" {fr} {solref}/>',
          '    <site name="world" pos="0 0 0" size="0.005" rgba="0 0 0 0"/>']

    def body(name: str, depth: int) -> None:
        lk = links[name]
        ind = "  " * depth
        off = foot if name == root else np.zeros(2)  # the root's frame sits at the foot
        if name == root:
            pos = (0.0, 0.0)
        else:
            j = np.asarray(lk.joint, float) - (foot if lk.parent == root else 0.0)
            pos = (j[0], j[1])
        L.append(f"{ind}<body name={quoteattr(name)} pos=\"{_v(pos[0], 0, pos[1])}\">")
        if name == root:
            L.extend([f'{ind}  <joint name="root_x" type="slide" axis="1 0 0"/>',
                      f'{ind}  <joint name="root_z" type="slide" axis="0 0 1"/>',
                      f'{ind}  <joint name="root_angle" type="hinge" axis="0 -1 0"/>'])
        else:
            c = coord[name]
            arm = f' armature="{_f(lk.rotor_inertia)}"' if lk.rotor_inertia else ""
            L.append(f"{ind}  <joint name={quoteattr(c.name)} type=\"hinge\" axis=\"0 -1 0\""
                     f"{arm}/>")
        inertia = lk.inertia if lk.inertia > 0 else INERTIA_FLOOR
        com = np.asarray(lk.com, float) - off
        L.append(f'{ind}  <inertial pos="{_v(com[0], 0, com[1])}" mass="{_f(lk.mass)}" '
                 f'diaginertia="{_v(inertia / 2, inertia, inertia / 2)}"/>')
        a = -off
        b = np.asarray(lk.end, float) - off
        if np.hypot(*(b - a)) > 1e-9:
            L.append(f'{ind}  <geom name={quoteattr(name + "_link")} type="capsule" '
                     f'size="0.02" fromto="{_v(a[0], 0, a[1], b[0], 0, b[1])}"/>')
        for tag, ref in (("stance", robot.stance_foot), ("swing", robot.swing_foot)):
            if ref.link == name:
                p = np.asarray(ref.point, float) - off
                L.append(f'{ind}  <geom name="foot_{tag}" type="sphere" size="{_f(r)}" '
                         f'pos="{_v(p[0], 0, p[1])}" contype="1" conaffinity="0" condim="3" '
                         f'{fr} {solref} rgba="0.8 0.3 0.2 1"/>')
                L.append(f'{ind}  <site name="foot_{tag}" pos="{_v(p[0], 0, p[1])}" '
                         f'size="{_f(r)}" rgba="0 0 0 0"/>')
        for t in robot.thrusters:
            if t.link == name:
                p = np.asarray(t.point, float) - off
                L.append(f"{ind}  <site name={quoteattr(t.name)} pos=\"{_v(p[0], 0, p[1])}\" "
                         f'size="0.02" rgba="0.95 0.6 0.1 1"/>')
        for k in kids.get(name, []):
            body(k, depth + 1)
        L.append(f"{ind}</body>")

    body(root, 2)
    L.append("  </worldbody>")
    L.append("  <actuator>")
    for c in robot.coordinates:
        if not c.actuated:
            continue
        lim = (f' ctrlrange="{_v(-c.torque_limit, c.torque_limit)}"'
               if np.isfinite(c.torque_limit) else "")
        L.append(f"    <motor name={quoteattr(c.name)} joint={quoteattr(c.name)} "
                 f'gear="1"{lim}/>')
    for t in robot.thrusters:
        d = t.direction
        ref = ' refsite="world"' if t.frame == "world" else ""
        lo, hi = t.limits
        lim = f' ctrlrange="{_v(lo, hi)}"' if np.isfinite(lo) and np.isfinite(hi) else ""
        L.append(f"    <general name={quoteattr(t.name)} site={quoteattr(t.name)}{ref} "
                 f'gear="{_v(d[0], 0, d[1], 0, 0, 0)}"{lim}/>')
    L.append("  </actuator>")
    if keyframe is not None:
        q, dq = (np.asarray(v, float) for v in keyframe)
        qpos = np.concatenate([[0.0, 0.0], lay.a_of(q)])
        qvel = np.concatenate([[0.0, 0.0], lay.a_of(dq)])
        L += ["  <keyframe>",
              f'    <key name="start" qpos="{_v(*qpos)}" qvel="{_v(*qvel)}"/>',
              "  </keyframe>"]
    L.append("</mujoco>")
    return "\n".join(L) + "\n"
