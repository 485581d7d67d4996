"""A second opinion from MuJoCo (SPEC 16): the gait's controller on MuJoCo's physics with soft
contact, compared step by step with the rigid-impact model.

The model is :func:`thrustwalk_cli.interchange.mjcf.robot_to_mjcf` (MuJoCo's ``qpos = [x_foot,
z_foot, a]``, thrustwalk's ``q = P a``). ``mujoco`` is imported only here and only when a run
starts (an optional extra: ``pip install 'thrustwalk[mujoco]'``). SI units throughout.

**Labelling.** thrustwalk's pinned coordinates relabel the legs at every impact (SPEC 1,
``q^+ = R q^- + b``). MuJoCo's model does the same: at each touchdown it is re-rooted at the new
stance foot (:meth:`MujocoModel.relabel`: ``q <- R q + b``, the root's slides at that foot's
position and velocity; the same physical state, which needs legs that are mirror images:
:func:`mirror_error`). So the stance foot is always the root's and thrustwalk's state is ``q =
P a``, ``q' = P a'`` of MuJoCo's angles ``a = qpos[2:]``. (MuJoCo's contact leaves out the
Jacobian's rate term ``J' q'``, zero for the root's foot but not for a foot at the end of the
chain, where a stance contact becomes much softer: another reason to re-root.) The stance foot's
own velocity (MuJoCo lets it slip and sink) is not part of ``q'``: ``sigma_N = e_N^T D(q) q'``
(SPEC 3) and ``zeta = sigma_N^2 / 2`` are thrustwalk's definitions at that state.

**Control**, every MuJoCo step (held over the step): the output-zeroing law of ``simulate``
(SPEC 7: input-output linearisation of ``y = H_0 q - h_d(c q)`` with the gait's ``K_p``,
``K_d``, cancelling the thrust on the joints), evaluated through :class:`ControlLaw` (the one
adapter to ``simulation/``) at thrustwalk's state. Its joint torques ``u`` [N m] (and, for a
generalised-thrust schedule, ``T`` [N m] on ``q_N``) act as ``qfrc_applied = P^T [u; T]``:
exactly their virtual work. Thrusters (the dynamics of SPEC 7, integrated over each MuJoCo
step by RK4) push with ``F_k d_k`` at their points, placed by thrustwalk's kinematics from the
stance foot's MuJoCo position, on the link's body (``mj_applyFT``). A push is the force ``P /
timestep`` at the hip (the stance link's end) during one MuJoCo step. MuJoCo steps by
``mj_step1``/``mj_step2``, so the law sees the kinematics of the state it acts on.

**Steps.** Touchdown: the swing foot's first contact with the floor once the guard is armed
(``s > min_impact_s``, as ``simulate``); ``zeta^-`` comes from the state at the contact instant
(linear interpolation between the two MuJoCo steps around the crossing of the foot point with
``z = 0``), then the legs are relabelled. The swing foot's collision is off from its lift-off
until the guard is armed, as thrustwalk's guard ignores a straight-leg foot brushing the
ground at mid-step (the 3-link gait grazes it there): its deepest dip below the ground in that
time is reported (``swing_dip``). The old stance foot keeps its contact until it lifts off
(double support). After a touchdown, the contact needs a few time constants to stop the
walker's fall onto the new foot, so ``alpha' < 0`` counts as a fall only after
``max(5 timeconst, 20 timestep)``.

**What the rigid model cannot see**, per step: foot slip (the stance foot's contact point:
``dx + radius d theta``, rolling removed; net and path length), the highest friction use
``|f_t| / f_n`` of the stance contact after the impact transient, bounce (the stance foot
rising above the ground after its touchdown: highest point, and separations higher than
:data:`LIFT_TOL`), double-support time (touchdown to the old stance foot's lift-off) and the
deepest penetration of a foot into the floor. The rigid model predicts 0 for each.

**Rigid prediction per step**: the reduced cascade of SPEC 3 (rigid impacts, exactly zeroed
outputs, the same thrust model) from the same start: ``zeta^-``, step time, and the speed from
the orbit's step length.
"""

from __future__ import annotations

import importlib
import math
import time
from bisect import bisect_right
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from operator import mul

import numpy as np

from ..errors import ComputationError, InputError
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics
from .mjcf import ContactModel, layout, robot_to_mjcf

INSTALL = "pip install 'thrustwalk[mujoco]'"
MAX_STEPS = 2000  # steps per run
MAX_MJ_STEPS = 50_000_000  # MuJoCo steps per call (all runs; ~1 h of CPU)
LIFT_TOL = 1e-5  # [m] a stance foot higher than this above the ground has left it


def load_mujoco():
    """The ``mujoco`` module, or an :class:`InputError` saying how to install it."""
    try:
        return importlib.import_module("mujoco")
    except ImportError as exc:
        raise InputError(f"this needs MuJoCo, an optional extra that is not installed "
                         f"({exc}): {INSTALL}") from None


def mujoco_version() -> str | None:
    """The installed MuJoCo's version, or None when it is not installed."""
    try:
        return str(load_mujoco().__version__)
    except InputError:
        return None


def compile_mjcf(xml: str):
    """MuJoCo's own compiler on MJCF text: the ``MjModel`` (:class:`ComputationError` when
    MuJoCo refuses it: the export is wrong)."""
    mj = load_mujoco()
    try:
        return mj.MjModel.from_xml_string(xml)
    except Exception as exc:
        raise ComputationError(f"MuJoCo's compiler refused the exported model: {exc}"
                               ) from None


def full_inertia(mj, m, d) -> np.ndarray:
    """MuJoCo's dense joint-space inertia ``M`` (nv x nv) [SI] at ``d``'s state (after
    ``mj_forward``), by ``mj_fullM`` (MuJoCo 3 takes ``(m, dst, qM)``, 4 ``(m, d, dst)``)."""
    M = np.zeros((m.nv, m.nv))
    if hasattr(d, "qM"):
        mj.mj_fullM(m, M, d.qM)
    else:
        mj.mj_fullM(m, d, M)
    return M


# ----------------------------------------------------------------------------- the adapter
class ControlLaw:
    """The one adapter to ``simulation/``: the closed loop of ``simulate`` (SPEC 7) for one
    thrust model, evaluated at a state ``x = [q; q'; z]`` (a list) in thrustwalk's coordinates.

    ``control(x, seg)``: joint torques ``u`` [N m], thrust ``F`` [N] per thruster, generalised
    force ``T`` [N m] on ``q_N``; ``segment(s)``: the alpha segment of ``s`` (schedule knots,
    guard arming); ``armed(seg)``: the guard is armed; ``rates(z)``: the thruster states'
    derivatives."""

    def __init__(self, zd: ZeroDynamics, thrust, min_impact_s: float):
        from ..simulation.closed_loop import ClosedLoop, SimConfig

        cfg = SimConfig(steps=1, min_impact_s=min_impact_s)
        cfg.validate()
        cl = self._cl = ClosedLoop(zd, thrust, cfg)
        self.thrust = thrust
        self.n_states = thrust.n_states
        self._breaks = list(cl.breaks)
        self._armed_after = cl.breaks.index(cl.arm_s)

    def segment(self, s: float) -> int:
        return bisect_right(self._breaks, s)  # ClosedLoop.segment_of without NumPy

    def armed(self, seg: int) -> bool:
        return seg > self._armed_after  # ClosedLoop.guard_armed

    def control(self, x: list, seg: int) -> tuple[list[float], list[float], float]:
        _, u, F, T = self._cl._accel(x, seg, want_u=True)
        return u, F, T

    def rates(self, z: list) -> list[float]:
        return self.thrust.derivatives(z)


def thrust_runs(zd: ZeroDynamics, kind: str, values: list[float] | None,
                thrusters: list[str] | None, *, schedule=None, wn: float = 2.0,
                xi: float = 1.0, tau: float = 0.5, f0: float = 0.0
                ) -> list[tuple[float | None, object]]:
    """``[(value, thrust model), ...]``, one per steady thrust value (one for a piecewise
    schedule), validated as ``simulate`` validates them (:class:`InputError` naming the
    parameter: ``thrust_model``, ``thrust``, ``thruster``, ``f0``, ``wn``, ``xi``, ``tau``)."""
    from ..simulation.closed_loop import SimConfig
    from ..simulation.scenario import make_scenario, thrust_models

    sc = make_scenario(zd, kind, values, thrusters, schedule=schedule, wn=wn, xi=xi, tau=tau,
                       f0=f0, config=SimConfig())
    return thrust_models(zd, sc)


def start_state(zd: ZeroDynamics, thrust, perturb: float = 0.0) -> np.ndarray:
    """``[q; q'; z]`` just after an impact on the predicted orbit (``zeta^-`` scaled by ``1 +
    perturb``), ``simulate``'s start; raises ``NoOrbit`` (an :class:`InputError`)."""
    from ..simulation.full_order import Start, initial_state

    return initial_state(zd, thrust, Start(perturb=perturb))


def no_orbit_error():
    """The exception :func:`start_state` raises when the thrust has no orbit to start on."""
    from ..simulation.full_order import NoOrbit

    return NoOrbit


def predicted_cycle(zd: ZeroDynamics, thrust) -> LimitCycle:
    """The zero-dynamics limit cycle of the thrust (SPEC 3, 4): of the schedule, or of the
    steady thrust of the dynamic models."""
    from ..simulation.closed_loop import predicted_cycle as cycle

    return cycle(zd, thrust)


def rigid_prediction(zd: ZeroDynamics, thrust, x0: np.ndarray, steps: int):
    """The rigid model's prediction from ``x0``: the reduced cascade (SPEC 3) for ``steps``
    steps and the zero-dynamics limit cycle of the thrust (fixed point, step length)."""
    from ..simulation.reduced import simulate_reduced

    cycle = predicted_cycle(zd, thrust)
    N = zd.model.n
    q, dq = x0[:N], x0[N:2 * N]
    sigma = float(zd.model.D(q)[N - 1] @ dq)
    t_max = 10.0 * (cycle.step_time if cycle.exists else 1.0)
    red = simulate_reduced(zd, thrust, steps, float(zd.maps.c @ q), sigma, list(x0[2 * N:]),
                           samples_per_step=60, max_step_time=t_max)
    return red, cycle


# ----------------------------------------------------------------------------- results
@dataclass(frozen=True)
class Push:
    """An impulse ``(px, py)`` [N s] at the end of the stance link (the hip of a
    one-link stance leg, a kneed walker's stance knee) at phase ``s`` of
    step ``step`` (1-based)."""

    step: int
    s: float
    impulse: tuple[float, float]


@dataclass(frozen=True)
class MujocoStep:
    """One step in MuJoCo, from the previous touchdown (or the start) to this one (SI).

    ``zeta_minus`` [kg^2 m^4/s^2], ``sigma_minus`` [kg m^2/s], ``alpha_minus`` [rad],
    ``s_minus``: at the touchdown instant, in thrustwalk's coordinates; ``t_start``,
    ``t_touchdown``, ``step_time`` [s]; ``step_length`` [m]: horizontal distance from the
    previous stance foot's contact point at its touchdown (the start: the origin) to this one;
    ``speed`` [m/s] = step_length / step_time; ``slip`` [m]: net horizontal displacement of the
    stance foot's contact point over the step (rolling removed), ``slip_path`` [m] its path
    length; ``max_friction_ratio``: the highest ``|f_t| / f_n`` of the stance foot's contact
    after the impact transient (None: no contact force then); ``bounce`` [m]: the stance
    foot's highest point above the ground (0: it never left it), ``separations``: how often it
    rose above :data:`LIFT_TOL`; ``double_support`` [s]: touchdown (of the step before) to the
    lift-off of the other foot (None: no lift-off in the step, or the first step, which starts
    after an impact); ``penetration`` [m]: the deepest penetration of a foot into the floor;
    ``swing_dip`` [m]: the deepest dip of the swing foot below the ground while its contact is
    off (before the guard is armed); ``thrust_at_touchdown`` [N] per thruster; ``pushed``: a
    push acted in this step."""

    step: int
    t_start: float
    t_touchdown: float
    step_time: float
    alpha_minus: float
    s_minus: float
    sigma_minus: float
    zeta_minus: float
    step_length: float
    speed: float
    slip: float
    slip_path: float
    max_friction_ratio: float | None
    bounce: float
    separations: int
    double_support: float | None
    penetration: float
    swing_dip: float
    thrust_at_touchdown: tuple[float, ...]
    pushed: bool


@dataclass(frozen=True)
class MujocoRun:
    """One MuJoCo run (one steady thrust value, or the gait's schedule).

    ``success``/``failure``/``reason``: the run completed its steps, or why not: ``fall``
    (alpha reverses, or the stance link passes the horizontal), ``no-impact`` (no touchdown
    by ``s = max_s`` or within 10 predicted step times), ``integrator`` (MuJoCo's state not
    finite, or MuJoCo warned), ``controller`` (the law's decoupling matrix is singular),
    ``no-orbit`` (the thrust has no orbit to start on: nothing ran). ``steps``: the completed
    steps; ``predicted``: the reduced cascade's steps from the same start (rigid impacts);
    ``cycle``: the zero-dynamics limit cycle of the thrust; ``rigid_trajectory``: the cascade's
    samples (t, step, alpha, alpha_dot). ``trajectory``: MuJoCo's samples (t, step, alpha,
    alpha_dot, sigma, stance_height, swing_height, F (n x m)); ``frames``: ``(t, qpos)`` at the
    video's frame rate; ``xml``: the model that ran; ``mj_steps``: MuJoCo steps taken;
    ``wall_time`` [s]: the physics and control loop."""

    value: float | None
    thrust: object = field(repr=False)
    success: bool
    failure: str
    reason: str
    steps: tuple[MujocoStep, ...]
    predicted: tuple = field(default=(), repr=False)
    cycle: LimitCycle | None = field(default=None, repr=False)
    rigid_trajectory: dict = field(default_factory=dict, repr=False)
    trajectory: dict = field(default_factory=dict, repr=False)
    frames: tuple = field(default=(), repr=False)
    xml: str = field(default="", repr=False)
    mj_steps: int = 0
    wall_time: float = 0.0


# ----------------------------------------------------------------------------- the run
class MujocoModel:
    """The MJCF of a robot loaded into MuJoCo (``m``, ``d``), rooted at the stance foot.

    ``set_state(q, q', foot, foot')`` writes thrustwalk's state with the stance foot at
    ``foot`` [m] moving at ``foot'`` [m/s]; :meth:`relabel` re-roots the model at the other
    foot (the same physical configuration and velocities, with the legs' labels exchanged:
    ``q^+ = R q + b``, SPEC 1). ``foot_geom``/``foot_site``: 0 the stance foot (the root's),
    1 the swing foot."""

    def __init__(self, robot, contact: ContactModel, mu: float):
        mj = self.mj = load_mujoco()
        self.robot = robot
        self.xml = robot_to_mjcf(robot, mu=mu, contact=contact)
        self.m = compile_mjcf(self.xml)
        self.d = mj.MjData(self.m)
        self.layout = layout(robot)
        self.N = robot.n
        m = self.m

        def ident(kind, name: str) -> int:
            return int(mj.mj_name2id(m, kind, name))

        geom, site = mj.mjtObj.mjOBJ_GEOM, mj.mjtObj.mjOBJ_SITE
        self.foot_geom = (ident(geom, "foot_stance"), ident(geom, "foot_swing"))
        self.foot_site = (ident(site, "foot_stance"), ident(site, "foot_swing"))
        self.body = [ident(mj.mjtObj.mjOBJ_BODY, n) for n in robot.link_names]
        self._jac = np.zeros((3, m.nv))

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """thrustwalk's ``(q, q')`` [rad, rad/s] of MuJoCo's state."""
        lay, d = self.layout, self.d
        return lay.q_of(d.qpos[2:]), lay.q_of(d.qvel[2:])

    def set_state(self, q, dq, foot=(0.0, 0.0), foot_rate=(0.0, 0.0)) -> None:
        lay, d = self.layout, self.d
        d.qpos[:] = np.concatenate([np.asarray(foot, float), lay.a_of(q)])
        d.qvel[:] = np.concatenate([np.asarray(foot_rate, float), lay.a_of(dq)])

    def relabel(self) -> None:
        """Re-root at the swing foot (after ``mj_step1``/``mj_forward``: its position and
        Jacobian are current): ``q <- R q + b``, ``q' <- R q'``, the root's slides at the swing
        foot's position and velocity. The warm start of the constraint solver is cleared."""
        mj, m, d, robot = self.mj, self.m, self.d, self.robot
        q, dq = self.state()
        sw = self.foot_site[1]
        pos = d.site_xpos[sw]
        mj.mj_jacSite(m, d, self._jac, None, sw)
        vel = self._jac @ d.qvel
        self.set_state(robot.R @ q + robot.b, robot.R @ dq, (pos[0], pos[2]), (vel[0], vel[2]))
        d.qacc_warmstart[:] = 0.0


def mirror_error(model, q: np.ndarray) -> float:
    """How far relabelling ``q`` (SPEC 1) is from the same physical configuration [m]: with
    ``q^+ = R q + b`` the old stance foot must sit at ``-p_2(q)`` from the new one and the
    centre of mass must not move, ``p_com(q^+) = p_com(q) - p_2(q)``. 0 (to round-off) for
    legs that are mirror images; MuJoCo's run re-roots the model at every touchdown and needs
    it."""
    qp = model.relabel(q)
    p2 = model.p_swing(q)
    return float(max(np.abs(model.p_swing(qp) + p2).max(),
                     np.abs(model.p_com(qp) - model.p_com(q) + p2).max()))


MIRROR_TOL = 1e-9  # [m]


def _rk4(f: Callable[[list], list[float]], z: list, h: float) -> list[float]:
    k1 = f(z)
    k2 = f([a + 0.5 * h * b for a, b in zip(z, k1)])
    k3 = f([a + 0.5 * h * b for a, b in zip(z, k2)])
    k4 = f([a + h * b for a, b in zip(z, k3)])
    return [a + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(z, k1, k2, k3, k4)]


def run_mujoco(zd: ZeroDynamics, thrust, value: float | None, *, steps: int,
               contact: ContactModel, mu: float, pushes: Sequence[Push] = (),
               perturb: float = 0.0, min_impact_s: float = 0.75, max_s: float = 1.5,
               samples_per_step: int = 100, fps: float = 0.0, max_frames: int = 1000,
               progress: Callable[[int], None] | None = None) -> MujocoRun:
    """Run ``steps`` steps of the gait's controller on MuJoCo (module docstring), started just
    after an impact on the predicted orbit of ``thrust`` (``zeta^-`` scaled by ``1 +
    perturb``), with friction ``mu`` and the ``contact`` settings. ``fps`` > 0 keeps
    ``(t, qpos)`` frames at that rate for a video (at most ``max_frames``). Never raises on a
    physical failure (a fall, a missed touchdown): the run carries ``success``, ``failure``
    and ``reason``. ``progress(1)`` after every step."""
    if not 1 <= steps <= MAX_STEPS:
        raise InputError.param("steps", f"must be 1..{MAX_STEPS} (got {steps})")
    for p in pushes:
        if not (1 <= p.step <= steps and 0.0 <= p.s < 1.0):
            raise InputError.param("push", f"a push needs a step in 1..{steps} and a phase in "
                                           f"[0, 1) (got step {p.step}, phase {p.s:g})")
    contact.validate()
    model = zd.model
    robot = model.robot
    try:
        x0 = start_state(zd, thrust, perturb)
    except no_orbit_error():
        if progress is not None:
            progress(steps)
        cycle = predicted_cycle(zd, thrust)
        return MujocoRun(value, thrust, False, "no-orbit", f"no orbit to start on for this "
                         f"thrust: {cycle.reason}", (), cycle=cycle)
    N = robot.n
    err = mirror_error(model, x0[:N])
    if not err <= MIRROR_TOL:
        raise InputError(f"robot {robot.name}: relabelling the legs (R, b) moves the robot by "
                         f"{err:.3g} m: its legs are not mirror images, so MuJoCo's model "
                         "cannot change its stance leg at touchdown as thrustwalk's does")
    red, cycle = rigid_prediction(zd, thrust, x0, steps)
    sim = MujocoModel(robot, contact, mu)
    mj, m, d = sim.mj, sim.m, sim.d
    m_thr = model.n_thrusters
    sim.set_state(x0[:N], x0[N:2 * N])
    z = [float(v) for v in x0[2 * N:]]
    law = ControlLaw(zd, thrust, min_impact_s)
    c = zd.maps.c.tolist()
    ai, span, direction = zd.alpha_i, zd.maps.span, zd.direction
    dt = float(m.opt.timestep)
    radius = contact.foot_radius
    t_max = 10.0 * (cycle.step_time if cycle.exists else 1.0)
    settle = max(5.0 * contact.timeconst, 20.0 * dt)
    P = sim.layout.P.tolist()
    PT = sim.layout.P.T.tolist()
    (g_st, g_sw), (s_st, s_sw) = sim.foot_geom, sim.foot_site
    sw_on = True  # the swing foot's collision (the old stance foot is on the ground)
    root = robot.link_index(robot.root.name)
    root_end_y = 4 * root + 3
    A = (robot.T @ sim.layout.P)[root].tolist()  # the stance link's absolute angle on a
    thr_body = [sim.body[robot.link_index(t.link)] for t in robot.thrusters]
    D_s, tp_s, td_s, lp_s = (model.D_s, model.thruster_points_s, model.thruster_dirs_s,
                             model.link_points_s)
    qpos, qvel, qfrc = d.qpos, d.qvel, d.qfrc_applied
    site_xpos, contacts = d.site_xpos, d.contact
    zero3, force, point, f6 = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(6)
    stride = max(1, round((cycle.step_time if cycle.exists else 0.7) / dt / samples_per_step))
    traj: dict[str, list] = {k: [] for k in ("t", "step", "alpha", "alpha_dot", "sigma",
                                             "stance_height", "swing_height", "F")}
    frames: list[tuple[float, list[float]]] = []
    next_frame = 0.0
    out: list[MujocoStep] = []
    k_step, t, t_start, mj_steps = 1, 0.0, 0.0, 0
    prev_td_x = 0.0
    slip = slip_path = bounce = pen = dip = 0.0
    ratio: float | None = None
    seps = 0
    ds_time: float | None = None
    old_down, lifted, pushed = True, False, False
    pending = sorted(pushes, key=lambda p: (p.step, p.s))
    failure, reason = "", ""
    prev = None  # (t, a, a', swing height) of the previous MuJoCo step
    theta_prev = x_prev = None
    warn0 = sum(w.number for w in d.warning)
    t_wall = time.perf_counter()
    while True:
        mj.mj_step1(m, d)
        a, ad = qpos[2:].tolist(), qvel[2:].tolist()
        if not all(map(math.isfinite, a + ad)):
            failure, reason = "integrator", f"step {k_step}: MuJoCo's state is not finite at " \
                                            f"t = {t:.6g} s"
            break
        h_sw = float(site_xpos[s_sw, 2])
        q = [sum(map(mul, row, a)) for row in P]
        s = (sum(map(mul, c, q)) - ai) / span
        seg = law.segment(s)
        # -- touchdown: the swing foot reaches the floor with the guard armed
        if law.armed(seg) and h_sw <= 0.0 and prev is not None and prev[3] > 0.0:
            lam = prev[3] / (prev[3] - h_sw)
            qm = [sum(map(mul, row, [p + lam * (v - p) for p, v in zip(prev[1], a)]))
                  for row in P]
            dqm = [sum(map(mul, row, [p + lam * (v - p) for p, v in zip(prev[2], ad)]))
                   for row in P]
            sig = sum(map(mul, D_s(qm)[(N - 1) * N:], dqm))
            am = sum(map(mul, c, qm))
            t_td = prev[0] + lam * dt
            x_td = float(site_xpos[s_sw, 0])
            length, step_time = x_td - prev_td_x, t_td - t_start
            F_td = law.control(qm + dqm + z, law.segment((am - ai) / span))[1]
            out.append(MujocoStep(
                k_step, t_start, t_td, step_time, am, (am - ai) / span, sig, 0.5 * sig * sig,
                length, length / step_time, slip, slip_path, ratio, bounce, seps,
                ds_time if lifted and k_step > 1 else None, pen, dip,
                tuple(map(float, F_td)), pushed))
            if progress is not None:
                progress(1)
            if k_step >= steps:
                break
            sim.relabel()  # the swing foot is the stance foot (the root) from now on
            mj.mj_step1(m, d)
            a, ad = qpos[2:].tolist(), qvel[2:].tolist()
            h_sw = float(site_xpos[s_sw, 2])
            q = [sum(map(mul, row, a)) for row in P]
            s = (sum(map(mul, c, q)) - ai) / span
            seg = law.segment(s)
            k_step += 1
            t_start, prev_td_x = t_td, x_td
            slip = slip_path = bounce = pen = dip = 0.0
            ratio, seps, ds_time = None, 0, None
            old_down, lifted, pushed = True, False, False
            theta_prev = x_prev = None
        dq = [sum(map(mul, row, ad)) for row in P]
        alpha = sum(map(mul, c, q))
        adot = sum(map(mul, c, dq))
        h_st = float(site_xpos[s_st, 2])
        # -- the swing foot's collision: on until it lifts off, then off until armed
        if old_down and h_sw > 0.0:
            old_down, lifted = False, True
            ds_time = t - t_start
        want = old_down or law.armed(seg)
        if want != sw_on:
            m.geom_contype[g_sw] = 1 if want else 0
            sw_on = want
        if not want and -h_sw > dip:
            dip = -h_sw
        # -- what the rigid model cannot see
        if -h_st > pen:
            pen = -h_st
        if old_down and -h_sw > pen:
            pen = -h_sw
        if h_st > bounce:
            if bounce <= LIFT_TOL < h_st:
                seps += 1
            bounce = h_st
        th = sum(map(mul, A, a))
        x_st = float(qpos[0])
        if theta_prev is not None and h_st <= 0.0:
            dx = (x_st - x_prev) + radius * (th - theta_prev)
            slip += dx
            slip_path += abs(dx)
        theta_prev, x_prev = th, x_st
        # -- failures
        if direction * adot < 0.0 and t - t_start > settle:
            failure, reason = "fall", (f"step {k_step}: alpha reverses (alpha' = 0) at alpha = "
                                       f"{alpha:.6g} rad, t = {t:.6g} s: the walker cannot "
                                       "pass the potential-energy barrier")
            break
        if s > max_s or t - t_start > t_max:
            failure, reason = "no-impact", (f"step {k_step}: no touchdown by s = {s:.4g}, "
                                            f"t = {t:.6g} s")
            break
        if not mj_steps & 15 and lp_s(q)[root_end_y] < 0.0:  # every 16 MuJoCo steps
            failure, reason = "fall", (f"step {k_step}: the stance link passes the horizontal "
                                       f"at t = {t:.6g} s")
            break
        # -- the law, the thrust and the push
        try:
            u, F, T = law.control(q + dq + z, seg)
        except (np.linalg.LinAlgError, ZeroDivisionError):
            failure, reason = "controller", (f"step {k_step}: the controller's decoupling "
                                             f"matrix is singular at t = {t:.6g} s")
            break
        gen = u + [T]
        qfrc[:2] = 0.0
        qfrc[2:] = [sum(map(mul, row, gen)) for row in PT]
        if m_thr and any(F):
            Pt, Dd = tp_s(q), td_s(q)
            fx, fz = float(qpos[0]), float(qpos[1])
            for j in range(m_thr):
                if F[j]:
                    point[0], point[2] = fx + Pt[j], fz + Pt[m_thr + j]
                    force[0], force[2] = F[j] * Dd[j], F[j] * Dd[m_thr + j]
                    mj.mj_applyFT(m, d, force, zero3, point, thr_body[j], qfrc)
        if pending and pending[0].step == k_step and s >= pending[0].s:
            p = pending.pop(0)
            lp = lp_s(q)
            point[0] = float(qpos[0]) + lp[4 * root + 2]
            point[2] = float(qpos[1]) + lp[4 * root + 3]
            force[0], force[2] = p.impulse[0] / dt, p.impulse[1] / dt
            mj.mj_applyFT(m, d, force, zero3, point, sim.body[root], qfrc)
            pushed = True
        if mj_steps % stride == 0:
            for key, v in (("t", t), ("step", k_step), ("alpha", alpha), ("alpha_dot", adot),
                           ("sigma", sum(map(mul, D_s(q)[(N - 1) * N:], dq))),
                           ("stance_height", h_st), ("swing_height", h_sw), ("F", F)):
                traj[key].append(v)
        if fps > 0 and t >= next_frame and len(frames) < max_frames:
            frames.append((t, qpos.tolist()))
            next_frame += 1.0 / fps
        prev = (t, a, ad, h_sw)
        mj.mj_step2(m, d)
        mj_steps += 1
        t += dt
        # -- friction use of the stance contact (forces of the state this step started from)
        if t - t_start > settle and d.ncon:
            g1, g2 = contacts.geom1, contacts.geom2
            for i in range(len(g1)):
                if g1[i] == g_st or g2[i] == g_st:
                    mj.mj_contactForce(m, d, i, f6)
                    if f6[0] > 0.0:
                        r = math.hypot(f6[1], f6[2]) / f6[0]
                        if ratio is None or r > ratio:
                            ratio = r
        if law.n_states:
            z = _rk4(law.rates, z, dt)
        if mj_steps % 512 == 0 and sum(w.number for w in d.warning) > warn0:
            failure, reason = "integrator", (f"step {k_step}: MuJoCo warned (an unstable "
                                             f"state or a full buffer) at t = {t:.6g} s")
            break
    wall = time.perf_counter() - t_wall
    if failure and progress is not None:
        progress(steps - len(out))
    arrays = {k: np.asarray(v, float) for k, v in traj.items() if k != "F"}
    arrays["F"] = np.asarray(traj["F"], float).reshape(len(traj["t"]), m_thr)
    arrays["step"] = arrays["step"].astype(int)
    rt = red.trajectory
    rigid = ({k: np.asarray(rt[k]) for k in ("t", "step", "alpha", "alpha_dot")}
             if rt else {})
    return MujocoRun(value, thrust, not failure, failure,
                     reason or f"completed {len(out)} steps", tuple(out), red.steps, cycle,
                     rigid, arrays, tuple(frames), sim.xml, mj_steps, wall)
