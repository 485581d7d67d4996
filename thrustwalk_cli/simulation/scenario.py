"""Scenarios of the full-order simulation: one thrust model swept over steady values, each
run compared step by step with the zero-dynamics prediction (SPEC 3, 7).

A scenario is one thrust model and a sweep of ``F_ss`` values [N] (one full-order run per
value, each with the reduced cascade of SPEC 3 run from the same initial state). Every step of
the full-order run is compared with the zero-dynamics prediction:

* thrust a function of alpha (constant, piecewise): ``zeta^-_pred = zeta_start + V_Z(alpha_f)``
  (SPEC 3, closed form, from the simulated post-impact value);
* thrust a function of time (first-/second-order): one step of the reduced cascade from the
  simulated post-impact ``(alpha, sigma_N, thruster state)``.

Units: SI (zeta in kg^2 m^4/s^2, sigma in kg m^2/s). The documents written from the outcomes
are built in :mod:`thrustwalk_cli.studies.simulate`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, param_problem
from ..hzd.zero_dynamics import ZeroDynamics
from ..thrust.command import given_dynamics
from ..thrust.dynamics import ThrusterDynamics, canonical
from ..thrust.schedule import Schedule
from .closed_loop import (
    ThrustModel,
    check_thruster_rate,
    predicted_cycle,
    thrust_model_names,
    zeta_star_at,
)
from .full_order import NoOrbit, SimConfig, SimResult, Start, initial_state, simulate
from .reduced import ReducedModel, ReducedResult, predict_step, simulate_reduced


@dataclass(frozen=True)
class Scenario:
    """What to simulate: thrust model ``kind`` driven at each of ``values`` [N] on the
    thrusters ``thrusters`` (indices), ``wn`` [rad/s], ``xi`` [1], ``tau`` [s], initial
    thrust ``f0`` [N]; ``schedule``: the piecewise schedule (``kind == "piecewise"``);
    ``reduced_only`` skips the full-order model (the fast preview). ``impact_s_tol`` [1] and
    ``zeta_tol`` [1, relative]: a full-order step whose impact is farther than this from s = 1,
    or whose zeta^- differs from the zero-dynamics prediction by more, is reported as a
    deviation (:func:`deviations`). ``heights``: a terrain (SPEC 14), the height [m] each step
    lands on (``full_order.simulate``); None: level ground."""

    kind: str
    values: tuple[float, ...]
    thrusters: tuple[int, ...]
    wn: float = 2.0
    xi: float = 1.0
    tau: float = 0.5
    f0: float = 0.0
    start: Start = Start()
    config: SimConfig = SimConfig()
    reduced_only: bool = False
    schedule: Schedule | None = None
    impact_s_tol: float = 1e-3
    zeta_tol: float = 1e-3
    heights: tuple[float, ...] | None = None
    dynamics: ThrusterDynamics | None = None  # given as an object: its kind is a label


@dataclass(frozen=True)
class Outcome:
    """One run: the sweep value (None for piecewise), its thrust model, the full-order result
    (None for ``reduced_only``), the reduced cascade and the per-step comparison.
    ``no_orbit``: why the run could not start (its thrust has no periodic orbit to start on);
    then ``full`` and ``reduced`` are None."""

    value: float | None
    thrust: ThrustModel
    full: SimResult | None
    reduced: ReducedResult | None
    comparison: tuple[dict, ...]
    no_orbit: str | None = None

    @property
    def primary(self) -> SimResult | ReducedResult | None:
        """The full-order result, else the reduced one (None when the run did not start)."""
        return self.full if self.full is not None else self.reduced

    @property
    def success(self) -> bool:
        """The run started and completed every step."""
        return self.primary is not None and self.primary.success


def make_scenario(zd: ZeroDynamics, kind: str, values: list[float] | None,
                  thrusters: list[str] | None, *, schedule: Schedule | None = None,
                  **kw) -> Scenario:
    """Validate parameters into a :class:`Scenario`; :class:`InputError` names the parameter
    (``thrust_model``, ``thrust`` for ``values``, ``thruster``, ``f0``, ``wn``, ``xi``, ``tau``).
    For a robot without thrusters ``values`` and ``f0`` must be 0 (no thruster is driven).
    ``schedule``: the piecewise schedule (from the gait's ``thrust:`` section), required for
    ``kind == "piecewise"``."""
    robot = zd.model.robot
    problems = []
    dynamics = given_dynamics(kind, zd.model.n_thrusters)
    kind = dynamics.kind if dynamics is not None else canonical(kind)  # `constant` is `ideal`
    if dynamics is None and kind not in thrust_model_names():
        raise InputError.param("thrust_model", f"unknown model {kind!r} (choose from "
                               f"{', '.join(thrust_model_names())})")
    if kind == "piecewise":
        if values is not None:
            raise InputError.param("thrust", "not used with the piecewise thrust model (the "
                                   "schedule comes from the gait's thrust: section)")
        if thrusters:
            raise InputError.param("thruster", "not used with the piecewise thrust model")
        if schedule is None:
            raise InputError.param("thrust_model", "piecewise thrust needs a schedule")
        idx: tuple[int, ...] = ()
        values = []
    elif not robot.thrusters:  # thrust options refer to no thruster: only 0 is possible
        if thrusters:
            robot.driven_thruster(thrusters[0])
        robot.check_no_thrust(values or [], "thrust")
        robot.check_no_thrust([kw.get("f0", 0.0)], "f0")
        idx = ()
    else:
        names = thrusters or [None]
        idx = tuple(robot.thruster_index(n) for n in names)
        if len(set(idx)) != len(idx):
            raise InputError.param("thruster", "a thruster is named twice")
        for j in idx:
            lo, hi = robot.thrusters[j].limits
            for v in list(values or []) + [kw.get("f0", 0.0)]:
                if not lo <= v <= hi:
                    problems.append(param_problem(
                        ("thrust", "f0"), f"{v:g} N is outside the limits [{lo:g}, {hi:g}] N of "
                        f"thruster {robot.thruster_names[j]}"))
    for key, unit in (("wn", "rad/s"), ("xi", ""), ("tau", "s"), ("impact_s_tol", ""),
                      ("zeta_tol", "")):
        if key in kw and not kw[key] > 0:
            problems.append(param_problem(key, f"must be > 0{' ' + unit if unit else ''} "
                                               f"(got {kw[key]:g})"))
    if problems:
        raise InputError(sorted(set(problems), key=str))
    if dynamics is None:
        check_thruster_rate(kind, kw.get("wn", 2.0), kw.get("xi", 1.0), kw.get("tau", 0.5),
                            zd.model.n_thrusters)
    kw["config"].validate()
    return Scenario(kind, tuple(values), idx, schedule=schedule, dynamics=dynamics, **kw)


def thrust_models(zd: ZeroDynamics, sc: Scenario) -> list[tuple[float | None, ThrustModel]]:
    """One :class:`ThrustModel` per sweep value (a single one for piecewise)."""
    m = zd.model.n_thrusters
    if sc.kind == "piecewise":
        return [(None, ThrustModel("piecewise", np.zeros(m), schedule=sc.schedule))]
    out = []
    for v in sc.values:
        target = np.zeros(m)
        f0 = np.zeros(m)
        target[list(sc.thrusters)] = v
        f0[list(sc.thrusters)] = sc.f0
        out.append((v, ThrustModel(sc.kind, target, wn=sc.wn, xi=sc.xi, tau=sc.tau,
                                   initial=f0, dynamics=sc.dynamics)))
    return out


def run_scenario(zd: ZeroDynamics, sc: Scenario,
                 progress: Callable[[int], None] | None = None) -> list[Outcome]:
    """Run every sweep value (full order unless ``reduced_only``, plus the cascade).
    ``progress(1)`` after every step of the primary model. A value without a periodic orbit
    to start on is an :class:`Outcome` with ``no_orbit`` set; the other values still run."""
    rm = ReducedModel(zd)
    cfg = sc.config
    N = zd.model.n
    out = []
    for value, th in thrust_models(zd, sc):
        try:
            x0 = initial_state(zd, th, sc.start)
        except NoOrbit as exc:
            out.append(Outcome(value, th, None, None, (), no_orbit=str(exc)))
            if progress is not None:
                progress(cfg.steps)
            continue
        D0 = np.array(zd.model.D_s(x0[:N].tolist())).reshape(N, N)
        a0, s0 = float(zd.maps.c @ x0[:N]), float(D0[N - 1] @ x0[N:2 * N])
        pred = predicted_cycle(zd, th)
        t_max = cfg.max_step_time or (10.0 * pred.step_time if pred.exists else 10.0)
        full = None
        if not sc.reduced_only:
            full = simulate(zd, th, cfg, sc.start, progress, sc.heights)
        red = simulate_reduced(zd, th, cfg.steps, a0, s0, x0[2 * N:].tolist(), rtol=cfg.rtol,
                               atol=cfg.atol, method=cfg.integrator,
                               samples_per_step=cfg.samples_per_step, max_step_time=t_max,
                               progress=progress if sc.reduced_only else None, model=rm,
                               trajectory=sc.reduced_only)
        comp = tuple(compare_steps(zd, th, full, red, rm)) if full is not None else ()
        out.append(Outcome(value, th, full, red, comp))
    return out


def compare_steps(zd: ZeroDynamics, th: ThrustModel, full: SimResult, red: ReducedResult,
                  rm: ReducedModel) -> list[dict]:
    """Zero-dynamics prediction of every full-order step (see the module docstring)."""
    V = _V_f(zd, th)
    pred = full.prediction
    ref_q = ref_dq = None
    if pred.exists:
        t = zd.terms(np.array([zd.alpha_f]))
        ref_q = zd.maps.q_minus
        ref_dq = t["Phi"][0] * t["kappa1"][0] * pred.sigma_minus
    out = []
    for st in full.steps:
        if th.time_dependent:
            zp = predict_step(zd, th, st.alpha_start, st.sigma_start, list(st.z_start),
                              rtol=full.config.rtol, atol=full.config.atol, model=rm)
            method = "reduced cascade over one step from the simulated post-impact state"
            zs = zeta_star_at(zd, np.array(st.thrust_at_impact))
        else:
            zp = st.zeta_start + V
            method = "zeta^+ (simulated) + V_Z(alpha_f)"
            zs = pred.zeta_star
        rs = red.steps[st.step - 1] if st.step <= len(red.steps) else None
        rec = {
            "method": method,
            "zeta_minus": zp,
            "relative_error": None if zp is None else (st.zeta_minus - zp) / zp,
            "zeta_star": zs if zs is not None and zs > 0 else None,
            "reduced_zeta_minus": rs.zeta_minus if rs else None,
            "reduced_relative_error": ((st.zeta_minus - rs.zeta_minus) / rs.zeta_minus
                                       if rs else None),
            "reduced_step_time": rs.step_time if rs else None,
        }
        if ref_q is not None:
            rec["orbit_distance"] = {
                "q": float(np.abs(np.array(st.q_minus) - ref_q).max()),
                "dq": float(np.abs(np.array(st.dq_minus) - ref_dq).max())}
        else:
            rec["orbit_distance"] = None
        out.append(rec)
    return out


def deviations(oc: Outcome, sc: Scenario) -> list[str]:
    """Where a completed full-order run leaves the zero-dynamics prediction (SPEC 7), one line
    per kind: impacts farther than ``sc.impact_s_tol`` from s = 1 (the swing foot did not
    strike where the gait ends: a grazing or missed touchdown, then a strike on the
    extrapolated constraints) and steps whose zeta^- differs from the prediction by more than
    ``sc.zeta_tol`` relative. Empty when the run follows the prediction."""
    if oc.full is None:
        return []
    out = []
    late = [st for st in oc.full.steps if abs(st.s_minus - 1.0) > sc.impact_s_tol]
    if late:
        worst = max(late, key=lambda st: abs(st.s_minus - 1.0))
        why = ("the terrain's step heights move the touchdown (the reduced map no longer "
               "applies exactly)" if sc.heights is not None and any(sc.heights) else
               "the swing foot did not strike where the gait ends (a grazing or missed "
               "touchdown)")
        out.append(f"{_steps(late)}: impact away from s = 1 (worst s = {worst.s_minus:.6g} "
                   f"at step {worst.step}; tolerance {sc.impact_s_tol:g}): {why}")
    off = [(st, c) for st, c in zip(oc.full.steps, oc.comparison)
           if c["relative_error"] is not None and abs(c["relative_error"]) > sc.zeta_tol]
    if off:
        st, c = max(off, key=lambda p: abs(p[1]["relative_error"]))
        out.append(f"{_steps([p[0] for p in off])}: zeta^- off the zero-dynamics prediction "
                   f"(worst {100 * c['relative_error']:+.4g} % at step {st.step}: "
                   f"{st.zeta_minus:.6g} vs {c['zeta_minus']:.6g} kg^2 m^4/s^2; tolerance "
                   f"{100 * sc.zeta_tol:g} %)")
    return out


def _steps(steps) -> str:
    n = [st.step for st in steps]
    return f"step {n[0]}" if len(n) == 1 else f"{len(n)} steps ({n[0]} to {n[-1]})"


def _V_f(zd: ZeroDynamics, th: ThrustModel) -> float:
    sched = th.schedule if th.piecewise else Schedule.constant(
        zd, np.asarray(th.target, float)[None, :])
    return float(zd.V_Z(np.array(zd.alpha_f), sched)[0])
