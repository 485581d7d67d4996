"""The ``export-mjcf`` study: a thrustwalk robot as a MuJoCo model (MJCF, SPEC 16), with the
gait's friction and a start on its orbit when a gait is given. The text is
:func:`thrustwalk_cli.interchange.mjcf.robot_to_mjcf`; MuJoCo's own compiler checks it when
MuJoCo is installed (the export itself does not need it)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..description.robot import Robot
from ..errors import InputError
from ..files.robot_file import load_robot
from ..hzd.zero_dynamics import limit_cycles
from ..interchange.mjcf import ContactModel, contact_settings, layout, robot_to_mjcf
from ..interchange.mujoco_run import INSTALL, compile_mjcf, mujoco_version
from ..walker import Walker, load_walker
from .documents import SCHEMA_VERSION

DEFAULT_MU = 0.7  # [1] without a gait: a gait file's default mu


@dataclass(frozen=True)
class ExportResult:
    """The MJCF ``xml`` of ``robot``; ``checked``: MuJoCo's version whose compiler accepted
    it (None: MuJoCo is not installed, the text is unchecked); ``keyframe``: the state of the
    key ``start`` (thrustwalk's q [rad], q' [rad/s]) or None; ``notes``: what the export
    chose (friction, the start)."""

    robot: Robot
    xml: str = field(repr=False)
    mu: float
    contact: ContactModel
    checked: str | None
    keyframe: dict | None
    notes: tuple[str, ...]
    name: str = "export_mjcf"
    success: bool = True
    reason: str = ""

    def document(self) -> dict:
        lay = layout(self.robot)
        return {"schema_version": SCHEMA_VERSION, "success": True, "reason": "",
                "robot": self.robot.name, "mu": self.mu, "contact": self.contact.record(),
                "checked_by_mujoco": self.checked, "keyframe": self.keyframe,
                "bodies": list(lay.bodies), "joints": ["root_x", "root_z", *lay.hinges],
                "coordinate_map": {"q = P a": lay.P.tolist(),
                                   "a": "MuJoCo's qpos[2:] (root_angle, then the hinges)"},
                "notes": list(self.notes)}


def export_mjcf(robot: str | Robot | Walker, gait: str | None = None, *,
                mu: float | None = None, contact: str | ContactModel = "default",
                check: bool = True) -> ExportResult:
    """The MJCF of ``robot`` (a file, a bundled name, a :class:`Robot` or a :class:`Walker`).

    With a gait (``gait``, or a walker): friction ``mu`` defaults to the gait's and the model
    gets the key ``start``: just after an impact on the gait's orbit (its thrust schedule's,
    else zero thrust; none when that orbit does not exist). Without one ``mu`` defaults to
    0.7. ``contact``: a preset or a :class:`ContactModel`. ``check``: compile the text with
    MuJoCo when it is installed (an error there is a bug of the export)."""
    walker = None
    if isinstance(robot, Walker):
        walker = robot
    elif gait is not None:
        if isinstance(robot, Robot):
            raise InputError.param("gait", "with a gait, give the robot as a file or a name "
                                           "(or pass a Walker)")
        walker = load_walker(robot, gait)
    rob = walker.robot if walker is not None else (
        robot if isinstance(robot, Robot) else load_robot(robot))
    ct = contact if isinstance(contact, ContactModel) else contact_settings(contact)
    notes = []
    keyframe = None
    if mu is None:
        mu = walker.gait.mu if walker is not None else DEFAULT_MU
        src = "the gait's" if walker is not None else "no gait: a gait file's default"
        notes.append(f"friction mu = {mu:g} ({src})")
    if walker is not None:
        zd = walker.zd
        if walker.gait.thrust is not None:
            sched = walker.gait.thrust.resolve(zd, zd.model.robot, walker.where, pad=True)[0]
            what = "the gait's thrust schedule"
        else:
            sched, what = None, "zero thrust"
        lc = (None if not zd.valid else zd.nominal_cycle() if sched is None else
              limit_cycles(zd, sched)[0])
        if lc is not None and lc.exists:
            t = zd.terms(np.array([zd.alpha_f]))
            dq_minus = t["Phi"][0] * t["kappa1"][0] * lc.sigma_minus
            imp = zd.model.impact(zd.maps.q_minus, dq_minus)
            keyframe = {"q": imp.q_plus.tolist(), "dq": imp.dq_plus.tolist(),
                        "zeta_minus": lc.zeta_star, "orbit": what}
            notes.append(f"key 'start': just after an impact on the orbit of {what} "
                         f"(zeta* = {lc.zeta_star:.6g} kg^2 m^4/s^2); the motors and thrusters "
                         "are not driven: the model falls without a controller")
        else:
            notes.append(f"no key 'start': no orbit for {what} "
                         f"({lc.reason if lc is not None else zd.invalid_reason})")
    xml = robot_to_mjcf(rob, mu=mu, contact=ct,
                        keyframe=None if keyframe is None else (keyframe["q"], keyframe["dq"]),
                        notes=notes)
    checked = None
    if check:
        version = mujoco_version()
        if version is not None:
            compile_mjcf(xml)
            checked = version
        else:
            notes.append(f"not checked by MuJoCo's compiler (MuJoCo is not installed: "
                         f"{INSTALL})")
    return ExportResult(rob, xml, float(mu), ct, checked, keyframe, tuple(notes))
