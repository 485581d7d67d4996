"""The ``mujoco`` study: the gait's controller on MuJoCo's physics with soft contact, step by
step beside the rigid-impact model (SPEC 16). The run is :mod:`thrustwalk_cli.interchange.
mujoco_run` (MuJoCo is imported only there, when a run starts); documents, tables, figure data
and the video are built here. Units: SI (zeta in kg^2 m^4/s^2, sigma in kg m^2/s)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..contact.evaluate import evaluate as contact_evaluate
from ..errors import (
    InputError,
    check_callable,
    check_count,
    check_number,
    check_numbers,
    check_pushes,
    check_text,
    check_texts,
)
from ..hzd.zero_dynamics import limit_cycles
from ..interchange.mjcf import ContactModel, contact_settings
from ..interchange.mujoco_run import (
    MAX_MJ_STEPS,
    MAX_STEPS,
    MujocoRun,
    Push,
    load_mujoco,
    run_mujoco,
    thrust_runs,
)
from ..interchange.mujoco_video import render_frames
from ..thrust.dynamics import canonical
from ..thrust.schedule import Schedule
from ..walker import Walker, check_walker
from .documents import SCHEMA_VERSION, Table, col, gait_record, result_repr, robot_record, units

UNITS = units("time", "thrust", "alpha", "alpha_dot", "sigma_N", "zeta", "step_time",
              "step_length", "speed", "length", "height", "friction_ratio", "wn", "tau",
              "impulse", slip="m", bounce="m", penetration="m", double_support="s",
              timestep="s", timeconst="s", foot_radius="m")
_Z = "kg^2 m^4/s^2"
#: quantities compared per step: (name, unit, rigid-model value when it is a constant)
COMPARED = (("zeta_minus", _Z), ("step_time", "s"), ("step_length", "m"), ("speed", "m/s"),
            ("slip", "m"), ("slip_path", "m"), ("max_friction_ratio", "1"), ("bounce", "m"),
            ("double_support", "s"), ("penetration", "m"))
VIDEO_FPS = 12.0
VIDEO_SIZE = (480, 360)  # [px] width, height


# ----------------------------------------------------------------------------- documents
def _pair(mj, rigid) -> dict:
    """``{"mujoco", "rigid", "difference"}`` (None where a side is missing)."""
    diff = None if mj is None or rigid is None else mj - rigid
    return {"mujoco": mj, "rigid": rigid, "difference": diff}


def _steady(run: MujocoRun) -> dict | None:
    """The last step's zeta^- against the rigid model's (the run's final agreement)."""
    if not run.steps:
        return None
    st = run.steps[-1]
    pr = run.predicted[st.step - 1].zeta_minus if st.step <= len(run.predicted) else None
    return {"step": st.step, "zeta_minus": st.zeta_minus, "rigid_zeta_minus": pr,
            "relative_gap": None if pr is None else (st.zeta_minus - pr) / pr}


@dataclass(frozen=True)
class MujocoResult:
    """MuJoCo runs of one scenario (one per steady thrust value, or the gait's schedule), each
    step beside the rigid-impact model's prediction (SPEC 16).

    ``success``: every run completed its steps. ``status``: ``ok`` (every run completed,
    its last zeta^- within ``zeta_tol`` of the rigid prediction and no step slipped more than
    ``slip_tol``, and the rigid model's orbit contact-feasible at ``mu``), ``warning``
    (completed, but MuJoCo differs from the rigid model by more than that, or the rigid
    orbit's contact fails at ``mu`` (SPEC 5) so that it predicts nothing: ``reason`` says where
    and by how much) or ``failed`` (a run stopped early or had no orbit to start on).
    ``rigid_contact``: the feasibility verdict of each run's orbit at ``mu`` (SPEC 5), for
    the slip it predicts."""

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    runs: tuple[MujocoRun, ...]
    contact: ContactModel
    mu: float
    settings: dict
    rigid_contact: tuple[dict, ...]
    zeta_tol: float = 0.02
    slip_tol: float = 0.01
    mujoco_version: str = ""

    name = "mujoco"

    @property
    def success(self) -> bool:
        """Every MuJoCo run completed (``status`` tells ``ok`` from ``warning``)."""
        return all(r.success for r in self.runs)

    def run_entries(self) -> list[dict]:
        """Per run: status and reason, the last step against the prediction, the rigid
        model's contact verdict at ``mu``, MuJoCo's cost."""
        out = []
        for i, (run, rc) in enumerate(zip(self.runs, self.rigid_contact)):
            st = _steady(run)
            notes = []
            if run.success:
                gap = st["relative_gap"] if st else None
                if gap is not None and abs(gap) > self.zeta_tol:
                    notes.append(f"zeta^- differs from the rigid prediction by "
                                 f"{100 * gap:+.3g} % at step {st['step']} (tolerance "
                                 f"{100 * self.zeta_tol:g} %)")
                slips = [s for s in run.steps if abs(s.slip_path) > self.slip_tol]
                if slips:
                    worst = max(slips, key=lambda s: s.slip_path)
                    notes.append(f"the stance foot slips more than {1e3 * self.slip_tol:g} mm "
                                 f"in {len(slips)} of {len(run.steps)} steps (worst "
                                 f"{1e3 * worst.slip_path:.3g} mm at step {worst.step})")
                if rc.get("feasible") is False:  # agreeing with an invalid prediction is no ok
                    ratios = [s.max_friction_ratio for s in run.steps
                              if s.max_friction_ratio is not None]
                    seen = (f"; MuJoCo's largest stance |f_t|/f_n {max(ratios):.3g}"
                            if ratios else "")
                    notes.append(f"the rigid model's orbit is not contact-feasible at mu = "
                                 f"{rc['mu']:g} ({rc['reason']}), so its prediction does not "
                                 f"hold for this run{seen}")
            status = "failed" if not run.success else ("warning" if notes else "ok")
            reason = run.reason + (": " + "; ".join(notes) if notes else "")
            cyc = run.cycle
            out.append({
                "run": i, "f_ss": run.value, "success": run.success, "status": status,
                "failure": run.failure or None, "reason": reason,
                "steps_completed": len(run.steps), "mujoco_steps": run.mj_steps,
                "wall_time": run.wall_time,
                "predicted": None if cyc is None else {
                    "exists": cyc.exists, "zeta_star": cyc.zeta_star,
                    "step_time": cyc.step_time, "step_length": cyc.step_length,
                    "speed": cyc.speed, "reason": cyc.reason},
                "final": st, "rigid_contact": rc})
        return out

    @property
    def status(self) -> str:
        """``failed`` when a run failed, ``warning`` when one is off the rigid model, else
        ``ok``."""
        runs = self.run_entries()
        if any(r["status"] == "failed" for r in runs):
            return "failed"
        return "warning" if any(r["status"] == "warning" for r in runs) else "ok"

    @property
    def reason(self) -> str:
        """Each run that is not ``ok`` and why, or that every run kept within ``zeta_tol`` of the
        rigid model's zeta^-."""
        bad = [r for r in self.run_entries() if r["status"] != "ok"]
        if not bad:
            return (f"all runs completed within {100 * self.zeta_tol:g} % of the rigid "
                    "model's zeta^-")
        return "; ".join(f"run {r['run']} (F_ss = {r['f_ss']}): {r['reason']}" for r in bad)

    def step_entries(self) -> list[dict]:
        """One entry per MuJoCo step: each quantity as ``{mujoco, rigid, difference}``."""
        out = []
        for i, run in enumerate(self.runs):
            cyc = run.cycle
            L = cyc.step_length if cyc is not None and cyc.exists else None
            rc = self.rigid_contact[i]
            for st in run.steps:
                pr = run.predicted[st.step - 1] if st.step <= len(run.predicted) else None
                T = pr.step_time if pr is not None else None
                rigid = {"zeta_minus": None if pr is None else pr.zeta_minus,
                         "step_time": T, "step_length": L,
                         "speed": None if T is None or L is None else L / T,
                         "slip": 0.0, "slip_path": 0.0,
                         "max_friction_ratio": rc.get("max_friction_ratio"),
                         "bounce": 0.0, "double_support": 0.0, "penetration": 0.0}
                e = {"run": i, "f_ss": run.value, "step": st.step, "t_start": st.t_start,
                     "t_touchdown": st.t_touchdown, "alpha_minus": st.alpha_minus,
                     "s_minus": st.s_minus, "sigma_minus": st.sigma_minus}
                for key, _ in COMPARED:
                    e[key] = _pair(getattr(st, key), rigid[key])
                z = e["zeta_minus"]
                z["relative"] = (None if z["difference"] is None or not z["rigid"] else
                                 z["difference"] / z["rigid"])
                e.update({"separations": st.separations, "swing_dip": st.swing_dip,
                          "thrust_at_touchdown": dict(zip(self.walker.robot.thruster_names,
                                                          st.thrust_at_touchdown)),
                          "pushed": st.pushed})
                out.append(e)
        return out

    def document(self) -> dict:
        """The JSON body of ``mujoco.json``."""
        zd = self.walker.zd
        return {
            "schema_version": SCHEMA_VERSION, "units": UNITS,
            "warnings": list(self.walker.warnings),
            "robot": robot_record(zd), "gait": gait_record(zd),
            "mujoco": {"version": self.mujoco_version, "model_file": "robot.xml",
                       "contact": self.contact.record(), "mu": self.mu,
                       "control": "the output-zeroing law of simulate (SPEC 7) every MuJoCo "
                                  "step, held over the step",
                       "rigid_prediction": "the reduced cascade of SPEC 3 (rigid impacts, "
                                           "exactly zeroed outputs) from the same start"},
            "settings": {**self.settings, "zeta_tolerance": self.zeta_tol,
                         "slip_tolerance": self.slip_tol},
            "success": self.success, "status": self.status, "reason": self.reason,
            "runs": self.run_entries(), "steps": self.step_entries(),
        }

    def tables(self) -> dict[str, Table]:
        """``steps`` (per step: each quantity, the rigid model's and the difference) and
        ``trajectory`` (MuJoCo's samples)."""
        header = ["run", col("f_ss", "N"), "step", col("t_touchdown", "s")]
        for key, unit in COMPARED:
            header += [col(key, unit), col(f"{key}_rigid", unit), col(f"{key}_diff", unit)]
        header += ["zeta_minus_relative_gap", "separations", col("swing_dip", "m"), "pushed"]
        rows = []
        for e in self.step_entries():
            row = [e["run"], e["f_ss"], e["step"], e["t_touchdown"]]
            for key, _ in COMPARED:
                p = e[key]
                row += [p["mujoco"], p["rigid"], p["difference"]]
            row += [e["zeta_minus"]["relative"], e["separations"], e["swing_dip"],
                    int(e["pushed"])]
            rows.append(row)
        steps = Table(header, rows, [
            "thrustwalk mujoco: one row per step; X = MuJoCo, X_rigid = the rigid model's "
            "prediction, X_diff = X - X_rigid (empty: not available)",
            "zeta_minus at the swing foot's touchdown in thrustwalk's coordinates; slip: net "
            "displacement of the stance foot's contact point (rolling removed), slip_path its "
            "path length; bounce: highest rise of the stance foot; double_support: touchdown "
            "to the old stance foot's lift-off; penetration: deepest into the floor"])
        names = self.walker.robot.thruster_names
        th = ["run", col("f_ss", "N"), "step", col("t", "s"), col("alpha", "rad"),
              col("alpha_dot", "rad/s"), col("sigma", "kg m^2/s"),
              col("stance_foot_height", "m"), col("swing_foot_height", "m")] + [
              col(f"thrust_{n}", "N") for n in names]
        trows = []
        for i, run in enumerate(self.runs):
            tr = run.trajectory
            for j in range(tr["t"].size if tr else 0):
                trows.append([i, run.value, int(tr["step"][j]), float(tr["t"][j]),
                              float(tr["alpha"][j]), float(tr["alpha_dot"][j]),
                              float(tr["sigma"][j]), float(tr["stance_height"][j]),
                              float(tr["swing_height"][j])] + tr["F"][j].tolist())
        traj = Table(th, trows, ["thrustwalk mujoco: MuJoCo's samples (every few MuJoCo "
                                 "steps); heights of the foot points above the ground (the "
                                 "floor is one foot radius below z = 0)"])
        return {"steps": steps, "trajectory": traj}

    def attachments(self, doc: dict) -> dict[str, str]:
        """``robot.xml``: the MJCF that ran (the first run's; every run uses the same)."""
        xml = next((r.xml for r in self.runs if r.xml), "")
        return {"robot.xml": xml} if xml else {}

    def figure_data(self) -> dict:
        """Phase portraits (alpha, alpha') of MuJoCo and of the rigid model, per run."""
        runs = []
        for run in self.runs:
            tr, rt = run.trajectory, run.rigid_trajectory
            steps = []
            if tr:
                for k in np.unique(tr["step"]):
                    sel = tr["step"] == k
                    steps.append({"alpha": tr["alpha"][sel], "alpha_dot": tr["alpha_dot"][sel]})
            rigid = []
            if rt:
                for k in np.unique(rt["step"]):
                    sel = rt["step"] == k
                    rigid.append({"alpha": rt["alpha"][sel], "alpha_dot": rt["alpha_dot"][sel]})
            cyc = run.cycle
            runs.append({"value": run.value, "mujoco": steps, "rigid": rigid,
                         "orbit": ({"alpha": cyc.orbit["alpha"],
                                    "alpha_dot": cyc.orbit["alpha_dot"]}
                                   if cyc is not None and cyc.exists else None),
                         "failed": not run.success})
        return {"runs": runs, "contact": self.contact.name, "mu": self.mu}

    def figures(self, titles: bool = False) -> dict:
        """``phase_portraits``: MuJoCo's and the rigid model's (alpha, alpha') side by side."""
        from ..plots.mujoco import phase_portraits

        name = self.walker.name
        return {"phase_portraits": phase_portraits(
            self.figure_data(), title=f"{name}: MuJoCo and the rigid model" if titles else "")}

    def video(self, fps: float = VIDEO_FPS, size: tuple[int, int] = VIDEO_SIZE
              ) -> tuple[bytes | None, str]:
        """A GIF of the last run rendered offscreen by MuJoCo, and a line saying how (or why
        there is none: no frames, or no offscreen OpenGL backend: which were tried)."""
        from ..plots.mujoco import gif

        runs = [r for r in self.runs if r.frames]
        if not runs:
            return None, "no video: no run has frames (kept only when asked for: `fps` > 0)"
        run = runs[-1]
        images, backend, notes = render_frames(self.walker.robot, self.contact, self.mu,
                                               run.frames, width=size[0], height=size[1])
        if backend is None:
            return None, ("no video: no offscreen renderer works here (tried: "
                          + "; ".join(notes or ["nothing to try"]) + ")")
        return gif(images, fps), (f"video rendered offscreen by MuJoCo with {backend} "
                                  f"({len(images)} frames)")


def mujoco_run(walker: Walker, *, steps: int = 20, thrust_model: str | None = None,
               thrust: Sequence[float] | None = None, wn: float = 2.0, xi: float = 1.0,
               tau: float = 0.5, f0: float = 0.0, thruster: Sequence[str] | None = None,
               push: Sequence[tuple[float, float, float, float]] = (),
               mu: float | None = None, contact: str | ContactModel = "default",
               perturb: float = 0.0, min_impact_s: float = 0.75, zeta_tol: float = 0.02,
               slip_tol: float = 0.01, samples: int = 100, fps: float = 0.0,
               progress: Callable[[int], None] | None = None) -> MujocoResult:
    """Run the gait's controller on MuJoCo for ``steps`` steps per steady thrust value ``thrust``
    [N] (default 0; on ``thruster``, default the first) and compare each step with the rigid
    model (SPEC 16; :mod:`thrustwalk_cli.interchange.mujoco_run`).

    Thrust models as ``simulate`` (:mod:`thrustwalk_cli.thrust.dynamics`): ``ideal``
    (``constant`` is its deprecated name), ``first-order`` (``tau`` [s]), ``second-order``
    (``wn`` [rad/s], ``xi``), ``piecewise`` (the gait's ``thrust:`` schedule: the default for
    a gait that has one when no ``thrust`` is given; else ``ideal``).
    ``f0`` [N]: the dynamic models' thrust at t = 0. ``push``: ``(step, phase s, P_x, P_y)``
    [N s] at the hip. ``mu``: friction of the feet and floor (default the gait's).
    ``contact``: a preset (``soft``, ``default``, ``stiff``) or a :class:`ContactModel`
    (:func:`contact_settings`). The start is just after an impact on the predicted orbit
    (``zeta^-`` scaled by ``1 + perturb``). ``zeta_tol`` [1, relative] and ``slip_tol`` [m]:
    a completed run whose last zeta^- differs from the rigid prediction by more, or a step
    whose stance foot slips more, is a ``warning``. ``fps`` > 0 keeps frames for
    :meth:`MujocoResult.video`. Needs MuJoCo (``pip install 'thrustwalk[mujoco]'``):
    :class:`InputError` otherwise."""
    check_walker(walker)
    steps = check_count("steps", steps, le=MAX_STEPS)
    thrust = check_numbers("thrust", thrust, optional=True, min_len=0)
    check_text("thrust_model", thrust_model, optional=True)  # its choices: make_scenario
    wn = check_number("wn", wn, gt=0, unit="rad/s")
    xi = check_number("xi", xi, gt=0)
    tau = check_number("tau", tau, gt=0, unit="s")
    f0 = check_number("f0", f0, unit="N")
    thruster = check_texts("thruster", thruster, optional=True)
    mu = check_number("mu", mu, gt=0, le=10, optional=True)
    if not isinstance(contact, ContactModel):
        check_text("contact", contact)
    perturb = check_number("perturb", perturb, gt=-1)
    min_impact_s = check_number("min_impact_s", min_impact_s)
    zeta_tol = check_number("zeta_tol", zeta_tol, gt=0)
    slip_tol = check_number("slip_tol", slip_tol, gt=0, unit="m")
    samples = check_count("samples", samples, ge=2, le=10_000)
    fps = check_number("fps", fps, ge=0, le=60, unit="1/s")
    check_callable("progress", progress)
    zd = walker.zd
    if not zd.valid:
        raise InputError.param("gait", f"the gait has no walking orbit: {zd.invalid_reason}")
    ct = contact if isinstance(contact, ContactModel) else contact_settings(contact)
    ct.validate()
    mu = zd.gait.mu if mu is None else mu
    values = None if thrust is None else [float(v) for v in thrust]
    if thrust_model is None:
        thrust_model = ("piecewise" if walker.gait.thrust is not None and values is None
                        else "ideal")
    thrust_model = canonical(thrust_model)  # the deprecated `constant` is `ideal`
    if values is None and thrust_model != "piecewise":
        values = [0.0]
    schedule = None
    if thrust_model == "piecewise":
        schedule = walker.gait_schedule()
    runs_in = thrust_runs(zd, thrust_model, values, list(thruster) if thruster else None,
                          schedule=schedule, wn=wn, xi=xi, tau=tau, f0=f0)
    pushes = [Push(int(stp), s, (px, py))
              for stp, s, px, py in check_pushes("push", push, walker.robot, steps)]
    # a bound on the work asked for: MuJoCo steps over every run
    lc_T = [_step_time(zd, th) for _, th in runs_in]
    need = sum(steps * T / ct.timestep for T in lc_T)
    if need > MAX_MJ_STEPS:
        raise InputError.param(("steps", "timestep"), f"about {need:.3g} MuJoCo steps, above "
                                                      f"the limit of {MAX_MJ_STEPS:g} per call")
    version = str(load_mujoco().__version__)  # InputError when the extra is not installed
    runs, rigid = [], []
    for value, th in runs_in:
        runs.append(run_mujoco(zd, th, value, steps=steps, contact=ct, mu=mu, pushes=pushes,
                               perturb=perturb, min_impact_s=min_impact_s,
                               samples_per_step=samples, fps=fps, progress=progress))
        rigid.append(_rigid_contact(walker, th, mu))
    settings = {"thrust_model": thrust_model,
                "thrusters": [walker.robot.thruster_names[j] for j in _driven(walker, thruster)],
                "f_ss": values or [], "wn": wn, "xi": xi, "tau": tau, "f0": f0,
                "steps": steps, "perturb": perturb, "min_impact_s": min_impact_s,
                "pushes": [{"step": p.step, "phase": p.s, "impulse": list(p.impulse),
                            "at": f"{walker.robot.stance_end_text()}, as the force P / "
                                  "timestep during one MuJoCo step"} for p in pushes]}
    return MujocoResult(walker, tuple(runs), ct, mu, settings, tuple(rigid), zeta_tol,
                        slip_tol, version)


def _driven(walker: Walker, thruster: Sequence[str] | None) -> list[int]:
    if not walker.robot.thrusters:
        return []
    return [walker.robot.thruster_index(n) for n in (thruster or [None])]


def _schedule(zd, th) -> Schedule:
    return th.schedule if th.kind == "piecewise" else Schedule.constant(
        zd, np.asarray(th.target, float)[None, :])


def _step_time(zd, th) -> float:
    lc = limit_cycles(zd, _schedule(zd, th))[0]
    return lc.step_time if lc.exists and lc.step_time else 1.0


def _rigid_contact(walker: Walker, th, mu: float) -> dict:
    """The rigid model's contact verdict on the run's orbit (steady thrust) at ``mu``."""
    rep = contact_evaluate(walker.model, walker.zd, _schedule(walker.zd, th), mu=mu,
                           polynomial=False, torque=False, profiles=False)
    case = rep.cases[0]
    return {"mu": mu, "feasible": case.feasible, "reason": case.reason,
            "max_friction_ratio": case.max_friction_ratio,
            "impact_friction_ratio": case.impact_friction_ratio,
            "min_vertical_force": case.min_vertical_force}
