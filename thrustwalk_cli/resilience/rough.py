"""Full-order walking on rough ground (SPEC 14): runs until failure for the Monte-Carlo MFPT, and
the one-step map on a mesh for the Markov chain (:mod:`.mfpt` does the mathematics).

**The terrain.** Step ``k`` (1-based) lands ``h_k`` [m] above its stance foot, ``h_k`` i.i.d.
``normal(0, sigma)`` or ``uniform(-w, w)`` with ``w = sqrt(3) sigma`` (``sigma`` is the standard
deviation either way). A trial's heights are
:meth:`~thrustwalk_cli.description.terrain.Terrain.heights` of the terrain of
:func:`trial_terrain`: ``numpy.random.default_rng(seed_t)`` with ``seed_t`` from
``SeedSequence([seed, trial])``, so trial ``t`` walks the same standard draws scaled by ``sigma``
for every sigma and strategy (common random numbers) and a terrain file with ``rough: {seed:
seed_t}`` replays it in ``thrustwalk simulate --terrain``.

**A step** runs on the compiled closed loop (:class:`~thrustwalk_cli.simulation.stepper.
Stepper`): the guard is the swing foot at ``h_k``, the scuff checks before it is armed measure
from the lower of the stance level and the level the swing foot left, a step-down is met past
``s = 1`` up to ``s_max``. It fails with the first of these in time (the push trials' words,
:mod:`.trials`): ``fell`` (the stance leg passes the horizontal, no impact), ``stopped`` (alpha
reverses), ``scuffed`` (an early strike, or the trailing foot does not lift at impact),
``lifted`` (vertical ground force ``<= eps``, or a non-positive impact impulse), ``slipped``
(stance force or impact impulse outside the friction cone ``mu``), ``missed_footing`` (no
touchdown by ``s_max``); ``error`` is a step that could not be computed (no verdict).

**The reduced state** of the chain is the pre-impact one: ``(zeta^-, h)``, the zero dynamics'
``zeta^-`` [kg^2 m^4/s^2] at an impact and the height [m] of the ground it happened on. Once the
outputs have converged within a step (the closed loop drives them to zero; what is left at the
impact is measured and reported, :attr:`StepMap.output_error`), the pre-impact state is on Z
(continued past ``s = 1`` for a step down) at the ``alpha`` where the swing foot is at ``h``
(:meth:`RoughRunner.impact_start`), so ``(zeta^-, h)`` fixes it, the impact map gives the
post-impact state (off Z: the outputs jump) and the next step depends on the state and the next
height only. The ``control`` strategy's QP is given the measured ``zeta^-`` (as in the push
trials). Units SI.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..controller.loop import segment_intervals
from ..description.terrain import Terrain
from ..hzd.zero_dynamics import ZeroDynamics
from ..simulation import kernel as K
from ..simulation.closed_loop import ClosedLoop, SimConfig
from ..simulation.full_order import Start, initial_state
from ..simulation.records import behind_level
from ..simulation.stepper import Stepper, failure_text, first_times, step_record
from .strategy import Realized
from .trials import _failure_outcome

DISTRIBUTIONS = ("normal", "uniform")
FAILURES = ("fell", "stopped", "scuffed", "lifted", "slipped", "missed_footing")
BISECT_TOL = 1e-6  # [m] failure edges of the one-step map located to this


def half_width(distribution: str, sigma: float) -> float:
    """The terrain spread [m] of standard deviation ``sigma`` [m]: ``sigma`` (normal) or the
    half width ``sqrt(3) sigma`` (uniform)."""
    return float(sigma) if distribution == "normal" else math.sqrt(3.0) * float(sigma)


def trial_seed(seed: int, trial: int) -> int:
    """The terrain seed of trial ``trial`` of a run seeded ``seed`` (module docstring)."""
    return int(np.random.SeedSequence([int(seed), int(trial)]).generate_state(1, np.uint32)[0])


def trial_terrain(distribution: str, sigma: float, seed: int, trial: int,
                  s_max: float) -> Terrain:
    """The rough ground of one Monte-Carlo trial (module docstring)."""
    return Terrain(0.0, (), distribution, half_width(distribution, sigma),
                   trial_seed(seed, trial), float(s_max),
                   f"rough ground, {distribution} sigma = {sigma:g} m, trial {trial}")


@dataclass(frozen=True)
class StepOutcome:
    """One step: ``kind`` "" (completed) or a failure/``error``; ``zeta`` the zeta^- of its
    impact [kg^2 m^4/s^2] (None when it failed); ``x`` the post-impact state and ``t`` [s] the
    impact time."""

    kind: str
    reason: str
    zeta: float | None
    x: np.ndarray | None
    t: float
    record: np.ndarray


@dataclass(frozen=True)
class Walk:
    """One run on rough ground: ``steps_completed``; ``outcome`` ``censored`` (every step up to
    the cap), a failure kind or ``error``; ``step`` the failing step and ``height`` [m] its
    ground; ``zeta_range`` min and max of zeta^- over the run [kg^2 m^4/s^2]."""

    steps_completed: int
    outcome: str
    step: int | None
    height: float | None
    reason: str
    zeta_range: tuple[float, float] | None

    @property
    def failed(self) -> bool:
        return self.outcome in FAILURES

    @property
    def attempted(self) -> int:
        """Steps attempted: the completed ones and the one that failed."""
        return self.steps_completed + (1 if self.failed else 0)

    def document(self) -> dict:
        return {"outcome": self.outcome, "steps_completed": self.steps_completed,
                "attempted": self.attempted, "failed_step": self.step,
                "failed_height": self.height, "reason": self.reason,
                "zeta_min": None if self.zeta_range is None else self.zeta_range[0],
                "zeta_max": None if self.zeta_range is None else self.zeta_range[1]}


class RoughRunner:
    """Steps of the compiled closed loop of one strategy on rough ground (module docstring):
    ``s_max`` [1] the missed-footing limit, ``mu`` [1] and ``eps`` [N] the cone and least
    vertical force every step is held to, integrator tolerances ``rtol``, ``atol``."""

    def __init__(self, zd: ZeroDynamics, realized: Realized, *, s_max: float, mu: float,
                 eps: float = 0.0, rtol: float = 1e-9, atol: float = 1e-9):
        self.zd, self.r = zd, realized
        self.model = zd.model
        self.mu, self.eps = float(mu), float(eps)
        self.config = SimConfig(steps=1, rtol=rtol, atol=atol, cone_mu=self.mu,
                                cone_eps=self.eps, max_s=float(s_max))
        self.cl = ClosedLoop(zd, realized.thrust, self.config)
        ts = realized.cycle.step_time if realized.cycle.exists else None
        self.t_max = 10.0 * ts if ts else 10.0
        self.stepper = Stepper(self.cl, self.t_max, dense=False)
        self.seg_int = (segment_intervals(self.cl, realized.knots, zd)
                        if realized.planner is not None else None)
        self.N, self.m, self.nz = self.model.n, self.model.n_thrusters, realized.thrust.n_states
        self._starts: dict[tuple[float, float], np.ndarray | None] = {}
        self._alpha: dict[float, float | None] = {}

    def alpha_at(self, h: float) -> float | None:
        """The ``alpha`` [rad] past ``min_impact_s`` (up to ``s_max``) at which the swing foot on
        Z is at height ``h`` [m] (the gait continued past s = 1 for h < 0); None when it
        never is."""
        from scipy.optimize import brentq

        h = float(h)
        if h in self._alpha:
            return self._alpha[h]
        maps, model = self.zd.maps, self.model

        def height(s: float) -> float:
            q = maps.q_Z(np.array(maps.alpha_i + s * maps.span))
            return float(np.asarray(model.p_swing(q), float)[1]) - h

        from scipy.optimize import minimize_scalar

        s0, s1 = self.config.min_impact_s, self.config.max_s
        top = minimize_scalar(lambda v: -height(v), bounds=(s0, 1.0), method="bounded",
                              options={"xatol": 1e-10})
        s_top = float(top.x) if -top.fun >= height(s0) else s0
        out = None
        if height(s_top) >= 0.0:  # the swing foot gets above h: its first descent through h
            grid = np.linspace(s_top, s1, 41)
            vals = np.array([height(v) for v in grid])
            i = int(np.argmax(vals <= 0.0)) if np.any(vals <= 0.0) else None
            if i is None:  # maybe a dip between the grid points: its lowest point
                low = minimize_scalar(height, bounds=(s_top, s1), method="bounded",
                                      options={"xatol": 1e-10})
                if low.fun <= 0.0:
                    grid = np.linspace(s_top, float(low.x), 41)
                    vals = np.array([height(v) for v in grid])
                    i = int(np.argmax(vals <= 0.0))
            if i is not None and i > 0:
                sv = brentq(height, grid[i - 1], grid[i], xtol=1e-14)
                out = float(maps.alpha_i + sv * maps.span)
        if h == 0.0:
            out = float(maps.alpha_f)
        self._alpha[h] = out
        return out

    def impact_start(self, zeta: float, h: float = 0.0) -> np.ndarray | None:
        """The post-impact state ``[q; q'; z]`` of an impact with ``zeta^- = zeta`` on ground
        ``h`` [m]: the impact map (SPEC 5) applied to the state on Z at :meth:`alpha_at` ``h``
        with ``alpha' = kappa_1 sigma_N``, ``sigma_N^2 / 2 = zeta`` (``h = 0``: the gait's
        ``q^-``, :func:`~thrustwalk_cli.simulation.full_order.initial_state`). None when no
        such impact exists. The last few are kept (a mesh state starts many steps)."""
        key = (float(zeta), float(h))
        if key in self._starts:
            x = self._starts[key]
            return None if x is None else x.copy()
        if len(self._starts) > 256:
            self._starts.clear()
        if h == 0.0:
            x = initial_state(self.zd, self.r.thrust, Start(zeta_minus=float(zeta)))
        else:
            a = self.alpha_at(h)
            x = None
            if a is not None:
                zd = self.zd
                t = zd.terms(np.array([a]))
                sigma = zd.sigma_sign * np.sqrt(2.0 * float(zeta))
                q = zd.maps.q_Z(np.array(a))
                imp = self.model.impact(q, t["Phi"][0] * t["kappa1"][0] * sigma)
                x = np.concatenate([imp.q_plus, imp.dq_plus, self.r.thrust.initial_states()])
        self._starts[key] = x
        return None if x is None else x.copy()

    def step(self, k: int, t: float, x: np.ndarray, zeta: float, h: float,
             behind: float = 0.0) -> StepOutcome:
        """Step ``k`` from the post-impact state ``x`` at ``t`` [s] after an impact of
        ``zeta^- = zeta`` (the controller's measurement) onto ground ``h`` [m] (``behind``:
        module docstring)."""
        r = self.r
        if r.planner is not None:
            plan = r.planner.plan(float(zeta), r.zeta_ref, np.zeros(r.planner.nu))
            per = plan.u.reshape(-1, len(r.driven))
            seg_force = np.zeros((len(self.seg_int), self.m))
            seg_force[:, r.driven] = per[self.seg_int]
            self.stepper.set_thrust(seg_force=seg_force)
        res = self.stepper.step(k, t, x, ground=float(h), behind=float(behind))
        events = []
        first = first_times(res.record)
        if first["low_force"] is not None:
            te, s = first["low_force"]
            events.append((te, 1, "lifted", f"the vertical ground force is <= {self.eps:g} N "
                                            f"from t = {te:.6g} s, s = {s:.4g}"))
        if first["cone_exit"] is not None:
            te, s = first["cone_exit"]
            events.append((te, 2, "slipped", f"the stance force leaves the friction cone "
                                             f"(mu = {self.mu:g}) at t = {te:.6g} s, "
                                             f"s = {s:.4g}"))
        rec = None
        if res.status != K.OK:
            out = res.outcome
            kind, text = failure_text(out, self.config, self.t_max)
            what = _failure_outcome(kind, text)
            if int(out[K.O_STATUS]) == K.FAIL_EVENT and int(out[K.O_EVENT]) == K.EV_OVERSHOOT:
                what, text = "missed_footing", (f"no touchdown on the ground at {h:+.4g} m by "
                                                f"s = {self.config.max_s:g} (s_max) at t = "
                                                f"{out[K.O_T]:.6g} s")
            elif what == "error":
                text = f"the step could not be computed ({kind}): {text}"
            events.append((float(out[K.O_T]), 3, what, text))
        else:
            rec = step_record(res.record, self.N, self.nz, self.m)
            if rec.impulse_friction_ratio > self.mu:
                events.append((rec.t_impact, 4, "slipped", (
                    f"the impact impulse leaves the friction cone (|F^h|/F^v = "
                    f"{rec.impulse_friction_ratio:.4g} > mu = {self.mu:g}) at "
                    f"t = {rec.t_impact:.6g} s")))
        if events:
            _, _, what, why = min(events, key=lambda e: (e[0], e[1]))
            return StepOutcome(what, f"step {k} (ground {h:+.4g} m): {why}", None, None,
                               float(res.outcome[K.O_T]), res.record)
        return StepOutcome("", "", float(rec.zeta_minus), res.x_next, rec.t_impact, res.record)

    def walk(self, heights: Sequence[float], cap: int) -> Walk:
        """From the strategy's fixed point (``zeta^- = zeta_ref`` on Z) over ``heights`` until
        a failure or ``cap`` steps (censored)."""
        r = self.r
        if r.zeta_ref is None:
            return Walk(0, "error", None, None, f"no orbit to start on: {r.cycle.reason}", None)
        zeta = float(r.zeta_ref)
        x, t = self.impact_start(zeta), 0.0
        lo = hi = zeta
        for k in range(1, int(cap) + 1):
            h = float(heights[k - 1])
            res = self.step(k, t, x, zeta, h, behind_level(heights, k))
            if res.kind:
                return Walk(k - 1, res.kind, k, h, res.reason, (lo, hi))
            zeta, x, t = res.zeta, res.x, res.t
            lo, hi = min(lo, zeta), max(hi, zeta)
        return Walk(int(cap), "censored", None, None, f"no failure in {int(cap)} steps (the cap)",
                    (lo, hi))

    def transition(self, zeta: float, h_prev: float, h: float
                   ) -> tuple[str, float | None, float | None]:
        """One step from the impact of ``zeta^- = zeta`` on ground ``h_prev`` [m] onto ground
        ``h`` [m]: ``(kind, zeta^- after, max |y| at that impact [rad])`` (kind "" when it
        completed; ``error`` when no impact on ``h_prev`` exists)."""
        x = self.impact_start(zeta, h_prev)
        if x is None:
            return "error", None, None
        res = self.step(2, 0.0, x, zeta, h, min(0.0, -float(h_prev)))
        if res.kind:
            return res.kind, None, None
        q = np.asarray(step_record(res.record, self.N, self.nz, self.m).q_minus)
        return "", res.zeta, self.output_error(q)

    def output_error(self, q: np.ndarray) -> float:
        """``max |y|`` [rad] of the outputs ``y = (H (q - q_Z(alpha)))_{1..N-1}`` at ``q``."""
        maps = self.zd.maps
        q = np.asarray(q, float)
        alpha = float(maps.c @ q)
        return float(np.max(np.abs((maps.H @ (q - maps.q_Z(np.array(alpha))))[:-1])))


# ----------------------------------------------------------------------------- the mesh
BISECT_TOL = 1e-5  # [m] failure edges of the one-step map located to this


@dataclass(frozen=True)
class StepMap:
    """The one-step map on the mesh of states ``(z[i], hp[j])`` (zeta^- [kg^2 m^4/s^2] of an
    impact on ground ``hp[j]`` [m]): per state the sorted next heights ``h[i][j]`` [m] it was
    evaluated at (the terrain grid ``grid_h`` and the points bracketing each failure edge to
    ``BISECT_TOL``; ``on_grid`` marks the grid's), the zeta^- after the step (NaN: failed); the
    failure kinds at the grid points (counts), the largest output error ``max |y|`` [rad] left
    at an impact over the completed steps (what the reduction to ``(zeta^-, h)`` drops), the
    number of simulations."""

    z: np.ndarray
    hp: np.ndarray
    grid_h: np.ndarray
    h: tuple
    zeta: tuple
    on_grid: tuple
    kinds: dict
    output_error: float
    simulations: int


def build_step_map(runners: RoughRunner | Sequence[RoughRunner], z: np.ndarray,
                   hp: np.ndarray, grid_h: np.ndarray,
                   progress: Callable[[int], None] | None = None) -> StepMap:
    """One full-order step from each mesh state ``(z[i], hp[j])`` onto every height of
    ``grid_h`` [m], each failure edge between grid points located by bisection to
    ``BISECT_TOL`` (``progress(1)`` per ``z[i]``). ``runners``: one per thread (the compiled
    kernel releases the GIL), each taking whole rows of ``z``; the map does not depend on
    how many."""
    from concurrent.futures import ThreadPoolExecutor

    pool = [runners] if isinstance(runners, RoughRunner) else list(runners)
    gset = set(float(v) for v in grid_h)
    rows: list = [None] * len(z)

    def row(runner: RoughRunner, zi: float) -> tuple:
        hr, zr, gr = [], [], []
        kinds: dict[str, int] = {}
        sims, yerr = 0, 0.0
        for hj in np.asarray(hp, float):
            pts: dict[float, float] = {}
            for h in grid_h:
                kind, zn, y = runner.transition(zi, hj, float(h))
                sims += 1
                pts[float(h)] = np.nan if kind else float(zn)
                if kind:
                    kinds[kind] = kinds.get(kind, 0) + 1
                else:
                    yerr = max(yerr, y)
            grid = sorted(pts)
            for a, b in zip(grid[:-1], grid[1:]):
                fa = bool(np.isnan(pts[a]))
                if fa == bool(np.isnan(pts[b])):
                    continue
                lo, hi = a, b
                while hi - lo > BISECT_TOL:
                    mid = 0.5 * (lo + hi)
                    kind, zn, _ = runner.transition(zi, hj, mid)
                    sims += 1
                    pts[mid] = np.nan if kind else float(zn)
                    if bool(kind) == fa:
                        lo = mid
                    else:
                        hi = mid
            order = sorted(pts)
            hr.append(np.array(order))
            zr.append(np.array([pts[v] for v in order]))
            gr.append(np.array([v in gset for v in order]))
        return tuple(hr), tuple(zr), tuple(gr), kinds, sims, yerr

    def share(w: int) -> None:
        for i in range(w, len(z), len(pool)):
            rows[i] = row(pool[w], float(z[i]))
            if progress is not None:
                progress(1)

    if len(pool) == 1:
        share(0)
    else:
        with ThreadPoolExecutor(max_workers=len(pool)) as ex:
            list(ex.map(share, range(len(pool))))
    kinds: dict[str, int] = {}
    for r in rows:
        for k, v in r[3].items():
            kinds[k] = kinds.get(k, 0) + v
    return StepMap(np.asarray(z, float), np.asarray(hp, float), np.asarray(grid_h, float),
                   tuple(r[0] for r in rows), tuple(r[1] for r in rows),
                   tuple(r[2] for r in rows), kinds, float(max(r[5] for r in rows)),
                   int(sum(r[4] for r in rows)))


def visited_range(runner: RoughRunner, zeta: float, heights: Sequence[float]
                  ) -> tuple[float, float]:
    """The range of zeta^- [kg^2 m^4/s^2] a walk from the level impact of ``zeta`` visits on
    the ``heights`` [m] in turn (a failed step restarts it from ``zeta``): where the walker
    spends its time, the range the mesh must cover (what lies beyond it is reported by the
    chain as clipped probability)."""
    lo = hi = z = float(zeta)
    x, t, hp = runner.impact_start(z), 0.0, 0.0
    for k, h in enumerate(heights, start=1):
        res = runner.step(k, t, x, z, float(h), min(0.0, -hp))
        if res.kind:
            z, hp = float(zeta), 0.0
            x, t = runner.impact_start(z), 0.0
            continue
        z, x, t, hp = res.zeta, res.x, res.t, float(h)
        lo, hi = min(lo, z), max(hi, z)
    return lo, hi


def success_interval(runner: RoughRunner, zeta: float, grid_h: Sequence[float]
                     ) -> tuple[float, float] | None:
    """The heights [m] a step from the level impact of ``zeta`` completes on: the ends of the
    run of completed grid heights around 0, each refined by bisection to ``BISECT_TOL``
    towards the failing neighbour; None when none completes."""
    g = np.sort(np.asarray(grid_h, float))
    ok = np.array([not runner.transition(zeta, 0.0, float(h))[0] for h in g])
    if not ok.any():
        return None
    i0 = int(np.argmin(np.abs(g)))
    if not ok[i0]:
        i0 = int(np.flatnonzero(ok)[np.argmin(np.abs(g[ok]))])
    lo_i, hi_i = i0, i0
    while lo_i > 0 and ok[lo_i - 1]:
        lo_i -= 1
    while hi_i < g.size - 1 and ok[hi_i + 1]:
        hi_i += 1
    ends = []
    for i, j in ((lo_i, lo_i - 1), (hi_i, hi_i + 1)):
        if j < 0 or j >= g.size:
            ends.append(float(g[i]))
            continue
        good, bad = float(g[i]), float(g[j])
        while abs(bad - good) > BISECT_TOL:
            mid = 0.5 * (good + bad)
            if runner.transition(zeta, 0.0, mid)[0]:
                bad = mid
            else:
                good = mid
        ends.append(good)
    return ends[0], ends[1]


def _pdf(u: float) -> float:
    """The standard normal density (0 at +-infinity)."""
    return math.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi) if math.isfinite(u) else 0.0


def _cell(distribution: str, spread: float, a: float, b: float) -> tuple[float, float]:
    """Probability [1] of ``a < h < b`` and the conditional mean of ``h`` [m] there, for
    ``normal(0, spread)`` or ``uniform(-spread, spread)``."""
    from scipy.special import ndtr

    if distribution == "normal":
        if spread <= 0:
            return (1.0, 0.0) if a < 0.0 <= b else (0.0, 0.0)
        ua, ub = a / spread, b / spread
        mass = float(ndtr(-ua) - ndtr(-ub)) if ua > 0 else float(ndtr(ub) - ndtr(ua))
        if mass <= 0.0:
            return 0.0, 0.0
        return mass, spread * (_pdf(ua) - _pdf(ub)) / mass
    if spread <= 0:
        return (1.0, 0.0) if a < 0.0 <= b else (0.0, 0.0)
    lo, hi = max(a, -spread), min(b, spread)
    if hi <= lo:
        return 0.0, 0.0
    return (hi - lo) / (2.0 * spread), 0.5 * (lo + hi)


@dataclass(frozen=True)
class Chain:
    """The mesh chain of one sigma: ``Q`` over the states ``(z[i], hp[j])`` (flattened, ``j``
    fastest), the failure probability per state ``fail`` [1], the probability per state of a
    next state beyond the mesh's ends (``clipped``: it was put on the nearest end)."""

    z: np.ndarray
    hp: np.ndarray
    Q: np.ndarray
    fail: np.ndarray
    clipped: np.ndarray

    def weights(self, zeta: float, h: float) -> np.ndarray:
        """The distribution over the states of ``(zeta, h)`` (bilinear weights)."""
        from .mfpt import interpolation_weights

        w = np.zeros(self.z.size * self.hp.size)
        _bilinear(w, self.z, self.hp, np.array([zeta]), np.array([h]), np.ones(1),
                  interpolation_weights)
        return w

    def quasi_stationary(self) -> np.ndarray:
        """The quasi-stationary distribution over the states (the left eigenvector of ``Q``
        for ``lambda_2``, summing to 1): where a walker that has not yet failed is."""
        ev, vec = np.linalg.eig(self.Q.T)
        v = np.abs(np.real(vec[:, int(np.argmax(np.abs(ev)))]))
        return v / v.sum() if v.sum() > 0 else np.full(v.size, 1.0 / v.size)


def _bilinear(row: np.ndarray, z: np.ndarray, hp: np.ndarray, zs: np.ndarray, hs: np.ndarray,
              mass: np.ndarray, weights) -> np.ndarray:
    """Add ``mass`` at the points ``(zs, hs)`` to ``row`` over the grid ``z x hp`` (bilinear;
    a single ``hp`` takes it all); returns the points clipped at the grid's ends."""
    i, ti, ci = weights(z, zs)
    nh = hp.size
    if nh == 1:
        j, tj, cj = np.zeros(zs.size, int), np.zeros(zs.size), np.zeros(zs.size, bool)
        for di, wi in ((0, 1.0 - ti), (1, ti)):
            np.add.at(row, (i + di) * nh, mass * wi)
        return ci
    j, tj, cj = weights(hp, hs)
    for di, wi in ((0, 1.0 - ti), (1, ti)):
        for dj, wj in ((0, 1.0 - tj), (1, tj)):
            np.add.at(row, (i + di) * nh + (j + dj), mass * wi * wj)
    return ci | cj


def transition_matrix(smap: StepMap, distribution: str, sigma: float, z_every: int = 1,
                      h_every: int = 1) -> Chain:
    """The chain's transition matrix for heights of standard deviation ``sigma`` [m] (SPEC 14):
    the row of state ``(z_i, hp_j)`` integrates its one-step map over the next height's
    density cell by cell between the evaluated heights (every ``h_every``-th grid point and
    every bisection point): a cell whose ends completed goes, with its probability, to the
    state ``(zeta^-, h)`` at the cell's conditional mean height ``h`` (``zeta^-`` interpolated
    there), spread bilinearly over the four neighbouring mesh states; a cell whose ends failed
    is failure; a cell across an edge (at most ``BISECT_TOL`` wide) is split at its middle;
    beyond the outer points, the outer point's outcome. ``z_every``, ``h_every``: every
    ``k``-th mesh zeta^- and grid height (the coarser meshes of the refinement; the states'
    heights are then the kept grid heights among ``hp`` and those off the grid)."""
    from .mfpt import interpolation_weights

    spread = half_width(distribution, sigma)
    zi_keep = list(range(0, smap.z.size, z_every))
    keep_grid = set(float(v) for v in smap.grid_h[::h_every])
    on_grid = set(float(v) for v in smap.grid_h)
    hj_keep = [j for j, v in enumerate(smap.hp)
               if float(v) in keep_grid or float(v) not in on_grid] or [0]
    z, hp = smap.z[zi_keep], smap.hp[hj_keep]
    n = z.size * hp.size
    Q = np.zeros((n, n))
    fail = np.zeros(n)
    clipped = np.zeros(n)
    for a_i, i in enumerate(zi_keep):
        for a_j, j in enumerate(hj_keep):
            s_idx = a_i * hp.size + a_j
            h, zn, g = smap.h[i][j], smap.zeta[i][j], smap.on_grid[i][j]
            sel = np.array([(not gi) or float(hv) in keep_grid for hv, gi in zip(h, g)])
            h, zn = h[sel], zn[sel]
            edges = np.concatenate([[-np.inf], h, [np.inf]])
            masses, zs, hs = [], [], []
            for c in range(edges.size - 1):
                a, b = edges[c], edges[c + 1]
                va = zn[c - 1] if c >= 1 else zn[0]
                vb = zn[c] if c < zn.size else zn[-1]
                ha = a if np.isfinite(a) else h[0]
                hb = b if np.isfinite(b) else h[-1]
                pieces = [(a, b, va, vb)]
                if np.isnan(va) != np.isnan(vb):
                    mid = 0.5 * (ha + hb)
                    pieces = [(a, mid, va, va), (mid, b, vb, vb)]
                for pa, pb, ua, ub in pieces:
                    mass, mean = _cell(distribution, spread, pa, pb)
                    if mass <= 0.0:
                        continue
                    if np.isnan(ua):
                        fail[s_idx] += mass
                        continue
                    x = min(max(mean, ha), hb)
                    v = ua if (ua == ub or hb == ha) else ua + (ub - ua) * (x - ha) / (hb - ha)
                    masses.append(mass)
                    zs.append(v)
                    hs.append(x)
            if masses:
                m = np.array(masses)
                clip = _bilinear(Q[s_idx], z, hp, np.array(zs), np.array(hs), m,
                                 interpolation_weights)
                clipped[s_idx] = float(np.sum(m[clip]))
    return Chain(z, hp, Q, fail, clipped)
