"""Push trials and basin trials of the full-order closed loop (SPEC 7, 11, 12).

A trial starts just after an impact on the orbit of its strategy
(:class:`~.strategy.Realized`: ``zeta^- = zeta_ref``) and either

* is pushed in its first step: an impulse ``value * direction`` [N s] at the push point at
  phase ``s`` of the step (:mod:`.push`; ``q' += D^-1 J_p^T P``, the stance foot pinned), or
* starts off the orbit (a basin trial): ``sigma_N^+`` scaled by ``1 + sigma`` (on Z, i.e. a
  start after an impact with ``zeta^- = (1 + sigma)^2 zeta_ref``) and the post-impact rate of
  one output changed by ``rate`` [rad/s] along the direction that leaves ``sigma_N`` unchanged
  (``[J_y; e_N^T D] dq' = [rate e_j; 0]``, ``J_y = H_0 - h_d'(alpha) c``);

then the compiled closed loop (:class:`~thrustwalk_cli.simulation.stepper.Stepper`) walks
``steps`` steps in all (the pushed step is step 1), with the strategy's thrust (``control``:
the SPEC 11 QP at every impact, on the measured zeta^-).

Outcome: the first event in time (each step is simulated; ties go in the order push, stance
force, failure, impact), with the step, the time and the phase s of the step in the reason:

* ``lifted`` / ``slipped``: the push's impulsive ground reaction leaves ``F^v > 0`` / the
  friction cone (SPEC 12, :func:`.push.check_push` on the simulated state at the push, so a
  push the walker never lives to feel is not judged); the stance force first drops to
  ``F^v <= eps`` (or negative: the run stops) / first has ``|F^h|/F^v > mu`` (the time is
  located on the dense output, ``simulation.stepper.first_times``), or the impact impulse
  leaves the cone; an impact whose vertical impulse is not positive is ``lifted``;
* ``stopped``: alpha reverses (the walker stops and falls back);
* ``fell``: the stance leg passes the horizontal, or the swing foot misses the ground;
* ``scuffed``: the swing foot strikes the ground before the guard (an early strike), or the
  trailing foot does not lift off at impact;
* ``error``: the trial could not be computed (integrator or controller failure) — not a
  verdict on the walker, counted apart and reported;
* ``recovered``: every step done and the last one back within ``recovery_tol`` of the orbit:
  ``|zeta^-_M - zeta_ref| <= recovery_tol zeta_ref`` and its outputs settled
  (``max |y| <= output_tol`` over the last step);
* ``unsettled``: every step done, not yet within the tolerance (``converging`` says whether it
  is on its way: outputs settled, ``zeta^-_M`` inside the strategy's reduced basin and closer
  to the orbit than the step before; by SPEC 12 it then converges).

Energy (SPEC 15, ``studies.trial_studies.trial_energies``: this layer keeps per completed step
its dense output and the thrust it walked, ``TrialResult.energy_input``; the studies layer
integrates them, the trials of an engine task together): over the trial's completed steps,
from the dense output (``energetics.run.run_energy``, each step with the thrust it walked):
the joints' positive mechanical work ``sum_j int max(0, u_j q_j') dt``, their electrical
energy (None without a motor model), the thrusters' positive work on the walker and their
input energy (None without a power model), and apart from these the mechanical energy the
push itself added (``push_energy``, the jump of ``K + V`` at the push) [J].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..contact.terms import stance_terms
from ..controller.loop import segment_intervals
from ..controller.step_model import interval_of
from ..hzd.zero_dynamics import ZeroDynamics
from ..simulation import kernel as K
from ..simulation.batch import FIELDS, push_row
from ..simulation.closed_loop import ClosedLoop, SimConfig
from ..simulation.full_order import Start, initial_state
from ..simulation.records import EVENT_REASONS, behind_level, missed_footing
from ..simulation.stepper import Stepper, failure_text, first_times, push_state, step_record
from .push import PushPoint, check_push, stance_impulse, world_to_slope
from .strategy import Realized

OUTCOMES = ("recovered", "unsettled", "fell", "slipped", "lifted", "scuffed", "stopped",
            "error")
FAILED = ("fell", "slipped", "lifted", "scuffed", "stopped")
LAST_PHASE = 1.0 - 1e-6  # a push at phase 1 is applied just before the impact


@dataclass(frozen=True)
class Trial:
    """One trial: a push of signed size ``impulse`` [N s] along the push direction at phase
    ``phase`` [1] of step 1, or a start off the orbit (``sigma`` [1]: relative change of
    sigma_N^+; ``rate`` [rad/s]: change of the transverse output's rate)."""

    impulse: float = 0.0
    phase: float = 0.0
    sigma: float = 0.0
    rate: float = 0.0


@dataclass(frozen=True)
class TrialResult:
    """What a trial did (module docstring for the outcomes). ``step``: the step of the
    outcome (None for recovered/unsettled); per completed step ``zeta_minus`` [kg^2 m^4/s^2];
    ``relative_error`` of the last one against ``zeta_ref`` [1]; ``push``: the push's ground
    reaction check; ``qp``: the controller's statuses by count (control); ``time`` [s] and
    ``phase`` (s of its step) [1] of the event that decided a failed outcome."""

    outcome: str
    step: int | None
    reason: str
    steps_completed: int
    zeta_ref: float | None
    zeta_minus: tuple[float, ...]
    relative_error: float | None
    converging: bool
    speed: float | None
    max_friction_ratio: float | None
    min_vertical_force: float | None
    max_abs_output_last: float | None
    push: dict | None
    pushed: bool
    qp: dict = field(default_factory=dict)
    time: float | None = None
    phase: float | None = None
    #: per completed step ``(closed loop, thrust, (k, pieces, q^-, q'^-))``, ``thrust`` None
    #: (the closed loop's) or the controller's per segment of the closed loop (segments x
    #: thrusters) [N]: what its energies are computed from (``energetics.run.run_energy``)
    energy_input: tuple = field(default=(), repr=False, compare=False)

    @property
    def recovered(self) -> bool:
        return self.outcome == "recovered"

    def fields(self) -> dict:
        """The collectable fields of a push-trial point (SI)."""
        return {"outcome": self.outcome, "recovered": self.recovered,
                "converging": self.converging, "failed_step": self.step,
                "steps_completed": self.steps_completed,
                "final_zeta_minus": self.zeta_minus[-1] if self.zeta_minus else None,
                "relative_error": self.relative_error, "zeta_ref": self.zeta_ref,
                "speed": self.speed, "max_friction_ratio": self.max_friction_ratio,
                "min_vertical_force": self.min_vertical_force,
                "push_friction_ratio": None if self.push is None else self.push["ratio"],
                "push_vertical_impulse": None if self.push is None
                or self.push["reaction"] is None else self.push["reaction"][1]}

    def document(self) -> dict:
        return {"outcome": self.outcome, "step": self.step, "time": self.time,
                "phase": self.phase, "reason": self.reason,
                "steps_completed": self.steps_completed, "zeta_ref": self.zeta_ref,
                "zeta_minus": list(self.zeta_minus), "relative_error": self.relative_error,
                "converging": self.converging, "speed": self.speed,
                "max_friction_ratio": self.max_friction_ratio,
                "min_vertical_force": self.min_vertical_force,
                "max_abs_output_last_step": self.max_abs_output_last, "push": self.push,
                "pushed": self.pushed, "qp": self.qp}


def _failure_outcome(kind: str, text: str) -> str:
    """The outcome of a simulation failure (its kind and wording, ``simulation.records``)."""
    if kind == "fall":
        if text.startswith(EVENT_REASONS["reverse"][1]):
            return "stopped"
        if text.startswith(EVENT_REASONS["horizontal"][1]):
            return "fell"
        return "lifted"  # the vertical ground force becomes (or starts) negative
    if kind == "scuff":
        return "scuffed"
    if kind == "impact":
        return "lifted" if "vertical impulse" in text else "scuffed"
    if kind == "no-impact":
        return "fell"
    return "error"


class TrialRunner:
    """Runs trials of one strategy on one walker (the compiled closed loop is set up once).

    ``steps``: steps per trial (the pushed step included); ``mu`` [1], ``eps`` [N]: the cone
    and least vertical force every step is checked against; ``recovery_tol`` [1] and
    ``output_tol`` [rad]: the recovery test; ``transverse``: index of the actuated coordinate
    whose rate a basin trial perturbs; ``duration`` [s]: the push's duration for the stance
    check (0: impulsive, SPEC 12; > 0: the stance force just before the push over it is
    added to the reaction). ``heights``: the terrain (SPEC 14): step ``k``'s swing foot lands
    ``heights[k - 1]`` [m] above its stance foot (level ground after the list; None: level
    ground), past ``s_max`` without a touchdown the trial ``fell`` (missed footing)."""

    def __init__(self, zd: ZeroDynamics, realized: Realized, point: PushPoint, *,
                 steps: int = 10, mu: float = 0.7, eps: float = 0.0,
                 recovery_tol: float = 0.05, output_tol: float = 1e-3, rtol: float = 1e-9,
                 atol: float = 1e-9, transverse: int = 0, duration: float = 0.0,
                 heights=None, s_max: float | None = None):
        self.zd, self.r, self.point = zd, realized, point
        self.heights = None if heights is None else tuple(  # level ground after the list
            float(h) for h in list(heights)[:int(steps)] + [0.0] * max(0, int(steps) -
                                                                       len(heights)))
        self.model = zd.model
        self.steps, self.mu, self.eps = int(steps), float(mu), float(eps)
        self.recovery_tol, self.output_tol = float(recovery_tol), float(output_tol)
        self.transverse, self.duration = int(transverse), float(duration)
        self.config = SimConfig(steps=1, rtol=rtol, atol=atol, cone_mu=self.mu,
                                cone_eps=self.eps,
                                **({} if s_max is None else {"max_s": float(s_max)}))
        self.cl = ClosedLoop(zd, realized.thrust, self.config)
        ts = realized.cycle.step_time if realized.cycle.exists else None
        self.t_max = 10.0 * ts if ts else 10.0
        self.stepper = Stepper(self.cl, self.t_max, dense=True)  # dense: the energies
        self.seg_int = (segment_intervals(self.cl, realized.knots, zd)
                        if realized.planner is not None else None)

    # -- the start -------------------------------------------------------------------------
    def start_state(self, trial: Trial) -> np.ndarray:
        """The post-impact state ``[q; q'; z]`` of a trial (module docstring)."""
        zd, r = self.zd, self.r
        x = initial_state(zd, r.thrust, Start(zeta_minus=r.zeta_ref * (1.0 + trial.sigma) ** 2))
        if trial.rate:
            N = self.model.n
            q = x[:N]
            alpha = float(zd.maps.c @ q)
            phi = zd.maps.Phi(np.array(alpha))
            Jy = np.hstack([np.eye(N - 1), np.zeros((N - 1, 1))]) - np.outer(phi[:N - 1],
                                                                             zd.maps.c)
            eD = self.model.D(q)[N - 1]
            rhs = np.zeros(N)
            rhs[self.transverse] = trial.rate
            x[N:2 * N] += np.linalg.solve(np.vstack([Jy, eD]), rhs)
        return x

    def push_check(self, trial: Trial, at: tuple[float, np.ndarray] | None = None
                   ) -> tuple[dict | None, str, str]:
        """The stance foot's impulsive reaction to the trial's push (SPEC 12):
        ``(record, outcome, reason)``, outcome ``""`` when it stays pinned. ``at``: the time
        [s] and the simulated state ``[q; q'; z]`` just before the push (what
        :meth:`run` judges; with a duration, the stance force there is counted over it);
        None: the orbit's state at the push's phase (a prediction, before any simulation)."""
        if trial.impulse == 0.0:
            return None, "", ""
        zd, N = self.zd, self.model.n
        P = world_to_slope(self.point.impulse(trial.impulse),
                           float(getattr(self.model, "slope", 0.0)))
        if at is None:
            s = min(trial.phase, LAST_PHASE)
            alpha = zd.alpha_i + s * (zd.alpha_f - zd.alpha_i)
            q, t_push = zd.maps.q_Z(np.array(alpha)), None
        else:
            t_push, x = at
            q = x[:N]
            alpha = float(zd.maps.c @ q)
            s = (alpha - zd.alpha_i) / (zd.alpha_f - zd.alpha_i)
        F = stance_impulse(self.model, q, self.point, P)
        stance = None
        if self.duration > 0:
            stance = self._orbit_force(alpha) if at is None else self._state_force(at[1])
        chk = check_push(F, self.mu, stance, self.duration)
        rec = {"impulse": self.point.impulse(trial.impulse).tolist(),
               "reaction": list(chk.impulse), "ratio": chk.ratio,
               "phase": trial.phase, "phase_applied": s, "time": t_push,
               "state": "orbit (predicted)" if at is None else "simulated",
               "applied": at is not None, "link": self.point.link, "at": self.point.at,
               "duration": self.duration}
        return rec, chk.outcome, chk.reason

    def _state_force(self, x: np.ndarray) -> np.ndarray:
        """The stance force F_1 [N] of the closed loop at the state ``x`` (SPEC 5, 7)."""
        cl, N = self.cl, self.model.n
        s = (float(cl.c @ x[:N]) - cl.ai) / cl.span
        return cl.details(np.asarray(x, float)[None], np.array([cl.segment_of(s)]))["F1"][0]

    def _orbit_force(self, alpha: float) -> np.ndarray:
        """The stance force F_1 [N] of the strategy's orbit at ``alpha`` (SPEC 5)."""
        zd, r = self.zd, self.r
        sched = r.schedule
        a = np.array([alpha])
        zeta = zd.delta_zero_sq * r.zeta_ref + zd.V_Z(a, sched)[0]
        j = int(interval_of(sched.knots, a)[0])
        t = stance_terms(self.model, zd.maps, a)
        F = (np.einsum("gim,m->gi", t.L2, sched.force[0, j]) + t.L1 * zeta[:, None] + t.L0
             + t.LT * sched.generalized[0, j])
        return F[0]

    # -- the run ---------------------------------------------------------------------------
    def run(self, trial: Trial) -> TrialResult:
        r, model = self.r, self.model
        self._walked: list[tuple] = []  # (closed loop, thrust, (k, pieces, q^-, q'^-))
        if r.zeta_ref is None:
            return self._result("error", None, f"no orbit to start on: {r.cycle.reason}", [],
                                None, None, False)
        push = None
        N, m, nz = model.n, model.n_thrusters, r.thrust.n_states
        x = self.start_state(trial)
        row = None
        if trial.impulse != 0.0:
            row = push_row(model, 1, min(trial.phase, LAST_PHASE),
                           self.point.impulse(trial.impulse), self.point.link, self.point.at)
        t, x_true = 0.0, float(r.zeta_ref * (1.0 + trial.sigma) ** 2)
        u_prev = None if r.planner is None else np.zeros(r.planner.nu)
        recs = []
        qp: dict[str, int] = {}
        pushed = False
        for k in range(1, self.steps + 1):
            step_force = None
            if r.planner is not None:
                plan = r.planner.plan(x_true, r.zeta_ref, u_prev)
                qp[plan.status] = qp.get(plan.status, 0) + 1
                per = plan.u.reshape(-1, len(r.driven))
                seg_force = np.zeros((len(self.seg_int), m))
                seg_force[:, r.driven] = per[self.seg_int]
                self.stepper.set_thrust(seg_force=seg_force)
                u_prev = plan.u
                step_force = seg_force
            h = 0.0 if self.heights is None else self.heights[k - 1]
            res = self.stepper.step(k, t, x, push=row if k == 1 else None, ground=h,
                                    behind=behind_level(self.heights, k))
            # the events of this step, in time: (t, tie order, outcome, reason, phase)
            events = []
            if k == 1 and row is not None:
                at = push_state(res.record, N, nz, m)
                if at is not None:
                    pushed = True
                    push, out, why = self.push_check(trial, at)
                    if out:
                        s_p = push["phase_applied"]
                        events.append((at[0], 0, out, f"{why} (the push at t = {at[0]:.6g} "
                                                      f"s, s = {s_p:.4g})", s_p))
                elif push is None:
                    push = {**(self.push_check(trial)[0] or {}), "reaction": None,
                            "ratio": None, "phase_applied": None, "applied": False,
                            "state": "not applied (the step ended before the push)"}
            events += self._cone_events(res.record, res.status == 0)
            rec = None
            if res.status != 0:
                kind, text = failure_text(res.outcome, self.config, self.t_max)
                out = _failure_outcome(kind, text)
                if (self.heights is not None and int(res.outcome[K.O_STATUS]) == K.FAIL_EVENT
                        and int(res.outcome[K.O_EVENT]) == K.EV_OVERSHOOT):
                    out, text = "fell", missed_footing(self.config.max_s, h,
                                                       res.outcome[K.O_T])[1]
                if out == "error":
                    text = f"the trial could not be computed ({kind}): {text}"
                events.append((float(res.outcome[K.O_T]), 3, out, text,
                               float(res.outcome[K.O_S])))
            else:
                rec = step_record(res.record, N, nz, m)
                self._walked.append((self.cl, step_force,
                                     (k, res.pieces, rec.q_minus, rec.dq_minus)))
                if rec.impulse_friction_ratio > self.mu:
                    events.append((rec.t_impact, 4, "slipped", (
                        f"the impact impulse leaves the friction cone (|F_2^h|/F_2^v = "
                        f"{rec.impulse_friction_ratio:.4g} > mu = {self.mu:g}) at "
                        f"t = {rec.t_impact:.6g} s, s = {rec.s_minus:.4g}"), rec.s_minus))
            if events:
                te, _, out, why, se = min(events, key=lambda e: (e[0], e[1]))
                if rec is not None:
                    recs.append(rec)
                return self._result(out, k, f"step {k}: {why}", recs, push, None, pushed,
                                    qp, (te, se))
            pushed = pushed or bool(res.record[FIELDS["pushed"]])
            recs.append(rec)
            x, t, x_true = res.x_next, rec.t_impact, rec.zeta_minus
        if row is not None and not pushed:  # pragma: no cover - the push event always fires
            return self._result("error", 1, "step 1: the push was not applied", recs, push,
                                None, False, qp)
        err = abs(recs[-1].zeta_minus - r.zeta_ref) / r.zeta_ref
        y_last = recs[-1].max_abs_output
        settled = y_last <= self.output_tol
        if err <= self.recovery_tol and settled:
            return self._result("recovered", None, f"back within {self.recovery_tol:g} of the "
                                f"orbit after {self.steps} steps (zeta^- {err:.3g} from it, "
                                f"outputs {y_last:.2g} rad)", recs, push, True, pushed, qp)
        prev = abs(recs[-2].zeta_minus - r.zeta_ref) if len(recs) > 1 else np.inf
        converging = bool(settled and r.basin.contains(recs[-1].zeta_minus)
                          and abs(recs[-1].zeta_minus - r.zeta_ref) < prev)
        what = (f"zeta^- {err:.3g} from the orbit" if not settled or err > self.recovery_tol
                else "")
        if not settled:
            what += f"{', ' if what else ''}outputs {y_last:.2g} rad > {self.output_tol:g}"
        tail = ("; converging (inside the reduced basin, closer each step): more steps would "
                "settle it" if converging else "")
        return self._result("unsettled", None, f"not yet back after {self.steps} steps "
                            f"({what}){tail}", recs, push, converging, pushed, qp)

    def _cone_events(self, raw: np.ndarray, completed: bool
                     ) -> list[tuple[float, int, str, str]]:
        """The first times in a step (completed or not: up to its failure) that the stance
        force dropped to ``F^v <= eps`` (``lifted``) and left the friction cone
        (``slipped``), from the kernel's record (with the step's extreme when it
        completed)."""
        first = first_times(raw)
        out = []
        if first["low_force"] is not None:
            te, s = first["low_force"]
            least = (f"; least {raw[K.R_MINFV]:.4g} N over the step" if completed else "")
            out.append((te, 1, "lifted", f"the vertical ground force is <= {self.eps:g} N "
                                         f"from t = {te:.6g} s, s = {s:.4g}: the stance foot "
                                         f"would lift off{least}", s))
        if first["cone_exit"] is not None:
            te, s = first["cone_exit"]
            fr = raw[K.R_MAXFR]
            most = (f"; largest {fr:.4g} over the step" if completed and fr == fr else "")
            out.append((te, 2, "slipped", f"the stance force leaves the friction cone "
                                          f"(|F^h|/F^v > mu = {self.mu:g}) at t = {te:.6g} "
                                          f"s, s = {s:.4g}{most}", s))
        return out

    def _result(self, outcome: str, step: int | None, reason: str, recs: list, push,
                converging: bool | None, pushed: bool, qp: dict | None = None,
                when: tuple[float, float] | None = None) -> TrialResult:
        zref = self.r.zeta_ref
        zm = tuple(float(rc.zeta_minus) for rc in recs)
        err = abs(zm[-1] - zref) / zref if zm and zref else None
        speed = None
        if recs:
            last = recs[-1]
            speed = float(self.model.p_swing(np.asarray(last.q_minus))[0]) / last.step_time
        fr = [rc.max_friction_ratio for rc in recs if rc.max_friction_ratio is not None]
        return TrialResult(
            outcome, step, reason, len(recs), zref, zm, err,
            bool(outcome == "recovered" or (outcome == "unsettled" and converging)), speed,
            max(fr) if fr else None,
            min(rc.min_vertical_force for rc in recs) if recs else None,
            float(recs[-1].max_abs_output) if recs else None, push, pushed, dict(qp or {}),
            None if when is None else float(when[0]), None if when is None else float(when[1]),
            tuple(getattr(self, "_walked", ())))
