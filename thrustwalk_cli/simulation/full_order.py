"""Full-order closed-loop hybrid simulation with thruster dynamics (SPEC section 7).

The stance phase is the closed loop of :mod:`closed_loop` (input-output linearisation of
``y = H_0 q - h_d(c q)``, ``y'' = -K_p y - K_d y'``, thrust models). Hybrid execution: the
guard is the swing-foot height crossing zero downward once the step is past ``s =
min_impact_s`` (0.75 by default, at least 0.5: past the middle of the step; before it the swing
foot may touch the ground, and a dip deeper than ``scuff_tol`` is a scuff, an early strike); the
impact map and relabelling of :meth:`CompiledModel.impact` (SPEC 5, 1) give the next step;
thruster states are continuous across impacts. Failures stop the run and are reported in
``SimResult.reason``: integrator failure, swing-foot scuff, stance leg past horizontal, alpha
reversing, negative vertical ground force, an infeasible impact, or no impact. SI units.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from ..errors import InputError
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics
from .closed_loop import (
    ClosedLoop,
    SimConfig,
    ThrustModel,
    predicted_cycle,
    zeta_star_at,
)
from .records import EVENT_REASONS as _EVENT_REASONS
from .records import Segment, StepRecord, behind_level, missed_footing


@dataclass(frozen=True)
class Start:
    """Initial condition: on Z just after an impact whose pre-impact value is
    ``zeta^- = (1 + perturb) zeta_minus`` [kg^2 m^4/s^2], or an explicit state ``(q, dq)``
    [rad, rad/s]. ``zeta_minus`` None: the predicted fixed point of the thrust at t = 0
    (``orbit="predicted"``: F_ss for constant thrust, the initial thrust of the dynamic
    models, the schedule for piecewise) or of zero thrust (``orbit="nominal"``)."""

    zeta_minus: float | None = None
    perturb: float = 0.0
    q: np.ndarray | None = None
    dq: np.ndarray | None = None
    orbit: str = "predicted"


class NoOrbit(InputError):
    """The start asked for (the predicted orbit) does not exist for this thrust: no periodic
    orbit, so no run. An :class:`InputError` for a single run; a scenario of several steady
    thrust values reports it as that value's result and runs the others."""


# ----------------------------------------------------------------------------- results
@dataclass(frozen=True)
class SimResult:
    """A full-order run. ``success`` false means the run stopped early; ``failure`` is one of
    ``fall``, ``scuff``, ``impact``, ``no-impact``, ``integrator``, ``controller`` (and on a
    terrain ``missed_footing``) and ``reason``
    says what happened, where and when. ``steps`` holds every completed step."""

    success: bool
    reason: str
    failure: str
    thrust: ThrustModel
    config: SimConfig
    steps: tuple[StepRecord, ...]
    prediction: LimitCycle
    trajectory: Mapping[str, np.ndarray] = field(repr=False)  # a Trajectory: sampled when read
    segments: tuple[Segment, ...] = field(repr=False)
    nfev: int = 0
    wall_time: float = 0.0
    sim: object = field(default=None, repr=False)

    def sample(self, step: int, times: np.ndarray) -> dict[str, np.ndarray]:
        """Dense state and details (``q``, ``dq``, ``ddq``, ``u``, ``y``, ``F``, ``F1``, ...) at
        ``times`` inside step ``step`` (1-based, end points included) [SI]."""
        segs = [s for s in self.segments if s.step == step]
        if not segs:
            raise ValueError(f"step {step} was not simulated")
        times = np.asarray(times, float)
        X = np.empty((times.size, segs[0].sol(segs[0].t0).size))
        iv = np.empty(times.size, int)
        for j, s in enumerate(segs):
            last = j == len(segs) - 1
            sel = (times >= s.t0) & ((times <= s.t1) if last else (times < s.t1))
            if j == 0:
                sel |= times < s.t0
            if last:
                sel |= times > s.t1
            if sel.any():
                X[sel] = s.sol(times[sel]).T
                iv[sel] = s.interval
        return self.sim.details(X, iv)

    def phase_curves(self, per_step: int, tol: float = 2e-3, levels: int = 8
                     ) -> list[list[dict[str, np.ndarray]]]:
        """The phase-plane curve ``(alpha, alpha')`` [rad, rad/s] of every simulated step, one
        curve per integration piece of the step (a push's jump between them), for a phase
        portrait: the dense output at the ``per_step`` uniform times of the step and the
        integrator's own steps, then every gap halved where its chord misses the curve's
        middle by more than ``tol`` of the piece's extent in either coordinate, up to
        ``levels`` times, so that a fast stretch (alpha' rising steeply just before impact)
        is drawn as the curve it is, not as a chord of uniform samples. ``alpha = c q`` and
        ``alpha' = c q'`` are linear in the state (SPEC 2)."""
        c = np.asarray(self.sim.c, float)
        N = c.size
        out = []
        for k in sorted({s.step for s in self.segments}):  # as the trajectory's steps
            segs = [s for s in self.segments if s.step == k]
            uniform = np.linspace(segs[0].t0, segs[-1].t1, per_step)
            curves = []
            for s in segs:
                nodes = np.asarray(s.sol.ts, float)
                t = np.unique(np.concatenate([
                    [s.t0, s.t1], uniform[(uniform > s.t0) & (uniform < s.t1)],
                    nodes[(nodes > s.t0) & (nodes < s.t1)]]))

                def ab(tt, s=s):
                    X = np.asarray(s.sol(tt), float).T
                    return X[:, :N] @ c, X[:, N:2 * N] @ c
                a, d = ab(t)
                for _ in range(levels):
                    sa, sd = max(np.ptp(a), 1e-12), max(np.ptp(d), 1e-12)
                    gaps = _bent(a / sa, d / sd, tol)  # the gaps whose chord may miss
                    if not gaps.size:
                        break
                    tm = 0.5 * (t[gaps] + t[gaps + 1])
                    am, dm = ab(tm)
                    ea = np.abs(am - 0.5 * (a[gaps] + a[gaps + 1])) / sa
                    ed = np.abs(dm - 0.5 * (d[gaps] + d[gaps + 1])) / sd
                    bad = np.maximum(ea, ed) > tol
                    if not bad.any():
                        break
                    tm, am, dm = tm[bad], am[bad], dm[bad]
                    order = np.argsort(np.concatenate([t, tm]), kind="stable")
                    t = np.concatenate([t, tm])[order]
                    a = np.concatenate([a, am])[order]
                    d = np.concatenate([d, dm])[order]
                curves.append({"alpha": a, "alpha_dot": d})
            out.append(curves)
        return out


def _bent(x: np.ndarray, y: np.ndarray, tol: float) -> np.ndarray:
    """The gaps of the polyline ``(x, y)`` (scaled coordinates) whose chord may miss the curve
    by more than ``tol``: a chord of length ``h`` across a curve that turns by ``theta`` over
    it misses its middle by about ``theta h / 8``, and the turn is estimated by the angles
    between the chord and its neighbours (a gap with no neighbour is always checked)."""
    dx, dy = np.diff(x), np.diff(y)
    h = np.hypot(dx, dy)
    if h.size < 2:
        return np.arange(h.size)
    turn = np.abs(np.angle((dx[1:] + 1j * dy[1:]) * (dx[:-1] - 1j * dy[:-1])))  # at inner points
    theta = np.maximum(np.r_[np.inf, turn], np.r_[turn, np.inf])  # each gap's larger neighbour
    return np.flatnonzero(theta * h / 8.0 > 0.5 * tol)


class _Stop(Exception):
    def __init__(self, failure: str, reason: str):
        super().__init__(reason)
        self.failure, self.reason = failure, reason


def _dip(cl: ClosedLoop, sol, lows, seg: int, t0: float, t1: float):
    """The first lowest point of the swing foot in ``[t0, t1]`` that is below the ground:
    with the guard armed (deeper than ``ground_tol``) the downward crossing before it,
    located on the dense solution by brentq, is the strike: ``("guard", t)``; before the
    guard is armed a dip deeper than ``scuff_tol`` is ``("scuff", t)``. None otherwise."""
    armed = cl.guard_armed(seg)
    limit = -cl.config.ground_tol if armed else -cl.config.scuff_tol
    ground = cl.ground if armed else cl.behind  # armed: the ground where the foot lands

    def height(tt):
        return cl.swing_height(sol.sol(tt)) - ground
    for tm in lows:
        if tm > t1 or height(tm) >= limit:
            continue
        if not armed:
            return "scuff", float(tm)
        grid = np.linspace(t0, tm, 65)
        h = np.array([height(tt) for tt in grid])
        idx = np.nonzero((h[:-1] > 0) & (h[1:] <= 0))[0]
        if idx.size == 0:  # already below the ground when the guard was armed
            return "scuff", float(t0)
        i = int(idx[0])
        return "guard", float(brentq(height, grid[i], grid[i + 1], xtol=1e-14,
                                     rtol=4 * np.finfo(float).eps))
    return None


def initial_state(zd: ZeroDynamics, thrust: ThrustModel, start: Start) -> np.ndarray:
    """``x0 = [q; q'; z]``: the impact map (SPEC 5) applied to the pre-impact state on Z with
    ``zeta^- = (1 + perturb) zeta_minus``, or the explicit state of ``start``."""
    model = zd.model
    N = model.n
    z0 = thrust.initial_states()
    if start.q is not None:
        q, dq = np.asarray(start.q, float), np.asarray(start.dq, float)
        if q.shape != (N,) or dq.shape != (N,):
            raise InputError.param(("q0", "dq0"), f"expected {N} values each "
                             f"({', '.join(model.robot.coordinate_names)})")
        return np.concatenate([q, dq, z0])
    zm = start.zeta_minus
    if start.orbit not in ("predicted", "nominal"):
        raise InputError.param("start", f"unknown orbit {start.orbit!r} (predicted, nominal)")
    if zm is None and start.orbit == "nominal":
        zm = zd.fixed_point()  # of zero thrust
        if not zm > 0:
            raise InputError(f"cannot start on the nominal orbit: no fixed point without "
                             f"thrust (zeta* = {zm:.6g}); give `zeta0` or `q0`/`dq0`")
    if zm is None:
        if thrust.time_dependent:
            F0 = np.zeros(thrust.m) if thrust.initial is None else thrust.initial
        else:
            F0 = thrust.target
        if thrust.piecewise:
            lc = predicted_cycle(zd, thrust)
            if not lc.exists:
                raise NoOrbit(f"cannot start on the predicted orbit: {lc.reason}")
            zm = lc.zeta_star
        else:
            zm = zeta_star_at(zd, np.asarray(F0, float))
            if not zm > 0:
                raise NoOrbit(f"cannot start on the predicted orbit: no fixed point for the "
                                 f"initial thrust (zeta* = {zm:.6g}); use `start` nominal, "
                                 f"`zeta0` or `q0`/`dq0`")
    zm = zm * (1.0 + start.perturb)
    if not zm > 0:
        raise InputError.param("perturb", f"the start needs zeta^- > 0 (got {zm:.6g})")
    t = zd.terms(np.array([zd.alpha_f]))
    sigma = zd.sigma_sign * np.sqrt(2.0 * zm)
    dq_minus = t["Phi"][0] * t["kappa1"][0] * sigma
    imp = model.impact(zd.maps.q_minus, dq_minus)
    return np.concatenate([imp.q_plus, imp.dq_plus, z0])


def simulate(zd: ZeroDynamics, thrust: ThrustModel, config: SimConfig = SimConfig(),
             start: Start = Start(), progress: Callable[[int], None] | None = None,
             heights: Sequence[float] | None = None) -> SimResult:
    """Simulate ``config.steps`` steps of the closed-loop hybrid system (SPEC 7), with the
    compiled kernel (``config.method == "compiled"``) or ``solve_ivp`` (``"scipy"``, the
    reference): same equations, events and records; zeta^- agrees to the tolerance.

    ``heights``: a terrain (SPEC 14), at least ``config.steps`` values: the swing foot of step
    ``k`` lands ``heights[k - 1]`` [m] above its stance foot (normal to the slope): the guard
    is the swing foot reaching that height once armed; a step-down is met past ``s = 1`` on
    the Bezier polynomials continued, until ``config.max_s`` (past it: ``missed_footing``).
    Each record carries its ``terrain_height``. None: level ground.

    ``progress(1)`` is called after every completed step. Never raises on a physical failure:
    the result carries ``success``, ``failure`` and ``reason``.
    """
    config.validate()
    t_wall = time.perf_counter()
    cl = ClosedLoop(zd, thrust, config)
    pred = predicted_cycle(zd, thrust)
    x = initial_state(zd, thrust, start)
    t_max = config.max_step_time or (10.0 * pred.step_time if pred.exists else 10.0)
    if config.method == "compiled":
        from .stepper import run_steps

        recs, segs, failure, reason, nfev = run_steps(cl, x, t_max, config.steps, progress,
                                                      heights)
        traj = Trajectory(cl, segs, config.samples_per_step)
        if not failure:
            reason = f"completed {len(recs)} steps"
        return SimResult(not failure, reason, failure, thrust, config, tuple(recs), pred, traj,
                         tuple(segs), nfev, time.perf_counter() - t_wall, cl)
    steps: list[StepRecord] = []
    segments: list[Segment] = []
    t = 0.0
    failure, reason = "", ""
    for k in range(1, config.steps + 1):
        cl.ground = 0.0 if heights is None else float(heights[k - 1])
        cl.behind = behind_level(heights, k)
        try:
            rec, x, t = _one_step(cl, k, t, x, t_max, segments, heights is not None)
        except _Stop as stop:
            failure, reason = stop.failure, f"step {k}: {stop.reason}"
            break
        steps.append(rec)
        if progress is not None:
            progress(1)
    traj = Trajectory(cl, segments, config.samples_per_step)
    ok = not failure
    if ok:
        reason = f"completed {len(steps)} steps"
    return SimResult(ok, reason, failure, thrust, config, tuple(steps), pred, traj,
                     tuple(segments), cl.nfev, time.perf_counter() - t_wall, cl)


def _one_step(cl: ClosedLoop, k: int, t0: float, x0: np.ndarray, t_max: float,
              segments: list[Segment], terrain: bool = False
              ) -> tuple[StepRecord, np.ndarray, float]:
    """Integrate one step (segment by segment) up to the guard, then apply the impact
    (``terrain``: the run is on a terrain, an overshoot is a missed footing)."""
    N, cfg = cl.N, cl.config
    nfev0 = cl.nfev
    s0 = (float(cl.c @ x0[:N]) - cl.ai) / cl.span
    seg = cl.segment_of(s0)
    start_segments = len(segments)
    # states outside every event's domain at the start
    d0 = cl.details(x0[None], np.array([seg]))
    if d0["F1"][0, 1] < 0:
        raise _Stop("fall", f"the vertical ground force is negative at the start of the step "
                            f"({d0['F1'][0, 1]:.4g} N)")
    h0 = cl.swing_height(x0) - cl.behind
    if h0 < -cfg.scuff_tol:  # no event can see a foot that starts below the ground and rises
        raise _Stop("scuff", f"the swing foot starts the step {-h0:.4g} m below the ground "
                             f"(s = {s0:.4g})")
    t, x = t0, x0
    rising = cl.foot_velocity(x) >= 0.0
    while True:
        evs = cl.events(seg, rising)
        names = [name for name, _ in evs]
        try:
            sol = solve_ivp(cl.rhs, (t, t0 + t_max), x, method=cfg.integrator, rtol=cfg.rtol,
                            atol=cfg.atol, events=[f for _, f in evs], dense_output=True,
                            args=(seg,))
        except np.linalg.LinAlgError:
            raise _Stop("controller", f"the decoupling matrix is singular near t = {t:.6g} s "
                                      "(input-output linearisation undefined)") from None
        t1, x1 = float(sol.t[-1]), sol.y[:, -1].copy()
        fired = [nm for (nm, f), te in zip(evs, sol.t_events)
                 if f.terminal and len(te) and te[-1] == t1]
        name = fired[0] if fired else ""
        # the swing foot's lowest points: a dip below the ground between two integrator
        # steps is a strike (armed guard) or a scuff (before the guard); it comes first
        lows = sol.t_events[names.index("foot_min")] if "foot_min" in names else ()
        dip = _dip(cl, sol, lows, seg, t, t1)
        if dip is not None:
            name, t1 = dip
            x1 = sol.sol(t1)
        elif sol.status == -1:
            if sol.sol is not None and t1 > t:
                segments.append(Segment(k, t, t1, seg, sol.sol))
            s1 = (float(cl.c @ x1[:N]) - cl.ai) / cl.span
            if cl.guard_armed(seg) and s1 > 1.0:  # past the gait's end: physics, not the tool
                raise _Stop("no-impact", f"the swing foot did not strike the ground by the end "
                                         f"of the step (s = 1; a grazing or missed touchdown): "
                                         f"on the extrapolated constraints the integrator "
                                         f"{cfg.integrator} failed at s = {s1:.4g}, t = {t1:.6g} s "
                                         f"({sol.message})")
            raise _Stop("integrator", f"integrator {cfg.integrator} failed at t = {t1:.6g} s: "
                                      f"{sol.message}")
        if t1 > t:
            segments.append(Segment(k, t, t1, seg, sol.sol))
        t, x = t1, x1
        if name in ("foot_min", "foot_max"):  # an extremum above the ground: watch the next
            rising = name == "foot_min"
            continue
        if name == "":
            raise _Stop("no-impact", f"no impact within {t_max:.4g} s (alpha = "
                                     f"{cl.c @ x1[:N]:.6g} rad)")
        if name == "break":
            seg += 1
            # the events of the next segment watch the swing foot's next extremum from here:
            # a foot already moving down when the guard is armed must be watched for its
            # lowest point (a shallow dip below the ground at a slow touchdown lies between
            # two integrator steps and is found only there), not for an apex it has passed
            rising = cl.foot_velocity(x) >= 0.0
            continue
        if name == "guard":
            break
        if name == "overshoot" and terrain:
            raise _Stop(*missed_footing(cfg.max_s, cl.ground, t))
        failure, text = _EVENT_REASONS[name]
        s = (float(cl.c @ x[:N]) - cl.ai) / cl.span
        raise _Stop(failure, f"{text} at t = {t:.6g} s, s = {s:.4g}")
    s_minus = (float(cl.c @ x[:N]) - cl.ai) / cl.span
    if s_minus < cfg.min_impact_s:
        raise _Stop("scuff", f"the swing foot strikes the ground at s = {s_minus:.4g}, before "
                             f"s = {cfg.min_impact_s:g} (a scuff, not the end of the step; "
                             "threshold `min_impact_s`)")
    rec, x_next = _impact_and_record(cl, k, t0, t, x0, x, seg, segments[start_segments:],
                                     cl.nfev - nfev0)
    return rec, x_next, t


def _impact_and_record(cl: ClosedLoop, k, t0, t1, x0, x, seg, segs, nfev):
    """Impact map (SPEC 5), its checks, and the step's statistics from the dense solution."""
    N, model = cl.N, cl.model
    q, dq, z = x[:N], x[N:2 * N], x[2 * N:]
    imp = model.impact(q, dq)
    Fx, Fy = (float(v) for v in imp.impulse)
    lift = float(imp.dq_u_plus[N + 1])
    if Fy <= 0:
        raise _Stop("impact", f"impact infeasible: vertical impulse {Fy:.4g} N s <= 0 at "
                              f"t = {t1:.6g} s")
    if lift <= 0:
        raise _Stop("impact", f"impact infeasible: the trailing foot does not lift off (vertical "
                              f"velocity {lift:.4g} m/s) at t = {t1:.6g} s")
    # statistics on the solver's own nodes plus a uniform grid of the step
    ts, Xs, ivs = [], [], []
    grid = np.linspace(t0, t1, 201)
    for s in segs:
        tt = np.concatenate([s.sol.ts, grid, [s.t0, s.t1]])
        tt = np.unique(tt[(tt >= s.t0) & (tt <= s.t1)])
        ts.append(tt)
        Xs.append(s.sol(tt).T)
        ivs.append(np.full(tt.size, s.interval))
    d = cl.details(np.vstack(Xs), np.concatenate(ivs))
    F1 = d["F1"]
    low, exit_ = _first_exits(cl, segs, ts, F1)
    pos = F1[:, 1] > 0
    ratio = np.abs(F1[pos, 0]) / F1[pos, 1]
    D_minus = np.array(model.D_s(list(q))).reshape(N, N)
    sigma_minus = float(D_minus[N - 1] @ dq)
    D_plus = np.array(model.D_s(list(imp.q_plus))).reshape(N, N)
    sigma_plus = float(D_plus[N - 1] @ imp.dq_plus)
    D0 = np.array(model.D_s(list(x0[:N]))).reshape(N, N)
    sigma0 = float(D0[N - 1] @ x0[N:2 * N])
    Fi = cl.force(z, seg)
    rec = StepRecord(
        step=k, t_start=t0, t_impact=t1, step_time=t1 - t0,
        alpha_start=float(cl.c @ x0[:N]), z_start=tuple(map(float, x0[2 * N:])),
        alpha_minus=float(cl.c @ q), s_minus=(float(cl.c @ q) - cl.ai) / cl.span,
        sigma_start=sigma0, zeta_start=0.5 * sigma0**2,
        sigma_minus=sigma_minus, zeta_minus=0.5 * sigma_minus**2,
        sigma_plus=sigma_plus, zeta_plus=0.5 * sigma_plus**2,
        impulse=(Fx, Fy), impulse_friction_ratio=abs(Fx) / Fy,
        trailing_foot_lift_velocity=lift,
        thrust_at_impact=tuple(float(v) for v in Fi),
        min_vertical_force=float(F1[:, 1].min()),
        max_friction_ratio=float(ratio.max()) if pos.all() else None,
        max_abs_output=float(np.abs(d["y"]).max()),
        max_abs_output_rate=float(np.abs(d["dy"]).max()),
        max_abs_torque=float(np.abs(d["u"]).max()),
        torque_saturated=bool(d["saturated"].any()),
        energy_minus=float(model.energy(q, dq)),
        energy_plus=float(model.energy(imp.q_plus, imp.dq_plus)),
        q_minus=tuple(map(float, q)), dq_minus=tuple(map(float, dq)), nfev=nfev,
        low_force_at=low, cone_exit_at=exit_, terrain_height=cl.ground,
    )
    return rec, np.concatenate([imp.q_plus, imp.dq_plus, z])


def _violated(F1: np.ndarray, which: int, mu: float, eps: float) -> np.ndarray:
    """Where the stance force rows ``F1`` (k, 2) [N] violate one cone condition: 0:
    ``F^v <= eps``; 1: ``|F^h| > mu F^v`` with ``F^v > 0``."""
    fh, fv = F1[:, 0], F1[:, 1]
    if which == 0:
        return fv <= eps
    return (fv > 0) & (np.abs(fh) > mu * fv)


def _first_exits(cl: ClosedLoop, segs, ts, F1):
    """``(t [s], s [1])`` of the first sample of a step (the statistics' states ``ts`` per
    segment, their forces ``F1``) that violates ``F_1^v > cone_eps`` and of the first that
    violates ``|F_1^h| <= cone_mu F_1^v``, each located by bisection on the dense solution
    between it and the segment's sample before it (as the compiled kernel's
    ``step_stats``); None where none does."""
    cfg = cl.config
    mu = np.inf if cfg.cone_mu is None else cfg.cone_mu
    out = []
    for which in (0, 1):
        bad = _violated(F1, which, mu, cfg.cone_eps)
        best = None
        k = 0
        for j, tt in enumerate(ts):
            idx = np.nonzero(bad[k:k + tt.size])[0]
            if idx.size and (best is None or tt[idx[0]] < best[0]):
                best = (float(tt[idx[0]]), j, int(idx[0]))
            k += tt.size
        if best is None:
            out.append(None)
            continue
        te, j, i = best
        s, tt = segs[j], ts[j]
        if i > 0:
            a, b = float(tt[i - 1]), te
            for _ in range(200):
                if b - a <= 4 * np.finfo(float).eps * abs(b) + 1e-15:
                    break
                mid = 0.5 * (a + b)
                f = cl.details(s.sol(mid)[None], np.array([s.interval]))["F1"]
                if _violated(f, which, mu, cfg.cone_eps)[0]:
                    b = mid
                else:
                    a = mid
            te = b
        x = s.sol(te)
        out.append((te, (float(cl.c @ x[:cl.N]) - cl.ai) / cl.span))
    return out[0], out[1]


class Trajectory(Mapping):
    """The sampled time histories of a run (:func:`_trajectory`: ``per_step`` uniform samples
    of every step with their details), computed when first read: a caller that wants only the
    steps (a sweep's point, a Python user reading ``steps``) never pays for them. Reads as a
    ``dict`` of arrays; empty (false) when the run has no segment. ``rows``: the number of
    samples, known without computing them."""

    def __init__(self, cl: ClosedLoop, segments: list[Segment], per_step: int):
        self._args = (cl, list(segments), int(per_step))
        self._data: dict[str, np.ndarray] | None = None
        self.rows = len({s.step for s in segments}) * int(per_step)

    def _built(self) -> dict[str, np.ndarray]:
        if self._data is None:
            self._data = _trajectory(*self._args)
            self._args = None
        return self._data

    def __getitem__(self, key: str) -> np.ndarray:
        return self._built()[key]

    def __iter__(self):
        return iter(self._built())

    def __len__(self) -> int:
        return len(self._built()) if self.rows else 0

    def __bool__(self) -> bool:
        return self.rows > 0

    def __eq__(self, other) -> bool:
        return dict(self) == other if isinstance(other, Mapping) else NotImplemented

    __hash__ = None


def _trajectory(cl: ClosedLoop, segments: list[Segment], per_step: int) -> dict:
    """Uniform samples of every step (end points included) with the stance-foot position.

    The states of all steps are gathered first and evaluated by one :meth:`ClosedLoop.details`
    call (row by row the same arithmetic as one call per step)."""
    if not segments:
        return {}
    from .stepper import DenseSolution

    steps = sorted({s.step for s in segments})
    parts, iv, T, K = [], [], [], []
    for k in steps:
        segs = [s for s in segments if s.step == k]
        times = np.linspace(segs[0].t0, segs[-1].t1, per_step)
        for j, s in enumerate(segs):
            last = j == len(segs) - 1
            sel = (times >= s.t0) & ((times <= s.t1) if last else (times < s.t1))
            if sel.any():
                parts.append((s.sol, times[sel]))
                iv.append(np.full(int(sel.sum()), s.interval))
        T.append(times)
        K.append(np.full(times.size, k))
    if all(isinstance(sol, DenseSolution) for sol, _ in parts):  # the compiled kernel's
        X = dense_rows(parts)
    else:
        X = np.vstack([sol(tt).T for sol, tt in parts])
    out = cl.details(X, np.concatenate(iv))
    out["t"] = np.concatenate(T)
    out["step"] = np.concatenate(K)
    # the stance foot moves to the swing foot's position at the end of every step
    ends = np.cumsum([t.size for t in T]) - 1
    advance = cl.model.p_swing(out["q"][ends])[:, 0]  # each step's swing foot, all at once
    feet, foot = [], 0.0
    for a, times in zip(advance.tolist(), T):
        feet.append(np.full(times.size, foot))
        foot += a
    out["foot_x"] = np.concatenate(feet)
    return out


def dense_rows(parts: list[tuple]) -> np.ndarray:
    """The states (K, n) of several dense solutions of the compiled kernel
    (:class:`~thrustwalk_cli.simulation.stepper.DenseSolution`) at their times: ``parts`` is a
    list of ``(solution, times)``; the rows follow in order. The same operations as
    ``DenseSolution.__call__`` (so equal to it bit for bit), done once for all pieces. (Kept
    out of ``stepper.py``: that file is part of the kernel's fingerprint.)"""
    if not parts:
        return np.zeros((0, 0))
    n = parts[0][0].n
    rows, ks, ts, lo, hi = [], [], [], [], []
    off = 0
    for sol, tt in parts:
        tt = np.atleast_1d(np.asarray(tt, float))
        ks.append(np.searchsorted(sol.ts, tt, side="left") - 1)
        lo.append(np.full(tt.size, off))  # each piece's rows: [off, off + rows - 1]
        hi.append(np.full(tt.size, off + sol.t_old.size - 1))
        rows.append(sol.rows)
        ts.append(tt)
        off += sol.rows.shape[0]
    R = np.concatenate(rows) if len(rows) > 1 else rows[0]
    lo = np.concatenate(lo)
    k = np.minimum(np.maximum(np.concatenate(ks) + lo, lo), np.concatenate(hi))
    tt = np.concatenate(ts)
    t_old, t_new = R[:, 0], R[:, 1]
    F = R[:, 2 + n:].reshape(-1, 7, n)
    h = t_new[k] - t_old[k]
    x = ((tt - t_old[k]) / h)[:, None]
    y = np.zeros((tt.size, n))
    for i, j in enumerate(range(6, -1, -1)):
        y += F[k, j]
        y *= x if i % 2 == 0 else 1.0 - x
    y += R[k, 2:2 + n]
    return y
