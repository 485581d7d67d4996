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

**The reduced state** of the chain is the *level-equivalent* ``zeta^-``: ``zeta^+ /
delta_zero^2``, with ``zeta^+ = (sigma_N^+)^2 / 2`` just after the impact. It is the ``zeta^-``
of the start on Z (:class:`~thrustwalk_cli.simulation.full_order.Start`) with the same
post-impact angular momentum, and equals ``zeta^-`` on level ground; on a step the impact
happens away from the gait's ``q^-``, so ``zeta^+ != delta_zero^2 zeta^-``, and the label keeps
what the next step's zero dynamics start from. The outputs' post-impact error is dropped: a
chain state restarts on Z (:func:`reduction_residual` measures what that costs). The
``control`` strategy's QP is given this label as its measured ``zeta^-``. Units SI.
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
    """One step: ``kind`` "" (completed) or a failure/``error``; ``label`` the level-equivalent
    zeta^- after it [kg^2 m^4/s^2] (None when it failed); ``x`` the post-impact state and ``t``
    [s] the impact time."""

    kind: str
    reason: str
    label: float | None
    x: np.ndarray | None
    t: float
    record: np.ndarray


@dataclass(frozen=True)
class Walk:
    """One run on rough ground: ``steps_completed``; ``outcome`` ``censored`` (every step up to
    the cap), a failure kind or ``error``; ``step`` the failing step and ``height`` [m] its
    ground; ``labels`` min and max of the level-equivalent zeta^- over the run."""

    steps_completed: int
    outcome: str
    step: int | None
    height: float | None
    reason: str
    label_range: tuple[float, float] | None

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
                "label_min": None if self.label_range is None else self.label_range[0],
                "label_max": None if self.label_range is None else self.label_range[1]}


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
        self.d2 = float(zd.delta_zero_sq)
        self.N, self.m, self.nz = self.model.n, self.model.n_thrusters, realized.thrust.n_states
        self._starts: dict[float, np.ndarray] = {}

    def start(self, label: float) -> np.ndarray:
        """The post-impact state on Z whose (level-equivalent) zeta^- is ``label`` (the last
        few kept: a mesh label starts many steps)."""
        label = float(label)
        x = self._starts.get(label)
        if x is None:
            if len(self._starts) > 64:
                self._starts.clear()
            x = self._starts[label] = initial_state(self.zd, self.r.thrust,
                                                    Start(zeta_minus=label))
        return x.copy()

    def step(self, k: int, t: float, x: np.ndarray, label: float, h: float,
             behind: float = 0.0) -> StepOutcome:
        """Step ``k`` from the post-impact state ``x`` at ``t`` [s] whose label is ``label``
        (the controller's measurement) onto ground ``h`` [m] (``behind``: module docstring)."""
        r = self.r
        if r.planner is not None:
            plan = r.planner.plan(float(label), r.zeta_ref, np.zeros(r.planner.nu))
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
        label_next = 0.5 * rec.sigma_plus ** 2 / self.d2
        return StepOutcome("", "", float(label_next), res.x_next, rec.t_impact, res.record)

    def walk(self, heights: Sequence[float], cap: int) -> Walk:
        """From the strategy's fixed point (``zeta^- = zeta_ref`` on Z) over ``heights`` until
        a failure or ``cap`` steps (censored)."""
        r = self.r
        if r.zeta_ref is None:
            return Walk(0, "error", None, None, f"no orbit to start on: {r.cycle.reason}", None)
        label = float(r.zeta_ref)
        x, t = self.start(label), 0.0
        lo = hi = label
        for k in range(1, int(cap) + 1):
            h = float(heights[k - 1])
            res = self.step(k, t, x, label, h, behind_level(heights, k))
            if res.kind:
                return Walk(k - 1, res.kind, k, h, res.reason, (lo, hi))
            label, x, t = res.label, res.x, res.t
            lo, hi = min(lo, label), max(hi, label)
        return Walk(int(cap), "censored", None, None, f"no failure in {int(cap)} steps (the cap)",
                    (lo, hi))

    def transition(self, label: float, h: float) -> tuple[str, float | None]:
        """One step from the start on Z of ``label`` onto ground ``h`` [m]: ``(kind, label
        after)`` (kind "" when it completed)."""
        res = self.step(1, 0.0, self.start(label), label, h)
        return res.kind, res.label

    def output_error(self, q: np.ndarray) -> float:
        """``max |y|`` [rad] of the outputs ``y = (H (q - q_Z(alpha)))_{1..N-1}`` at ``q``."""
        maps = self.zd.maps
        q = np.asarray(q, float)
        alpha = float(maps.c @ q)
        return float(np.max(np.abs((maps.H @ (q - maps.q_Z(np.array(alpha))))[:-1])))


# ----------------------------------------------------------------------------- the mesh
@dataclass(frozen=True)
class StepMap:
    """The one-step map on a mesh: for each mesh label ``z[i]`` [kg^2 m^4/s^2] the sorted
    heights ``h[i]`` [m] it was evaluated at (the grid ``grid_h``, and the pairs of points
    bracketing each failure edge to ``BISECT_TOL``; ``on_grid[i]`` marks the grid's), the label
    after the step (NaN: failed) and the failure kinds at the grid points (counts)."""

    z: np.ndarray
    grid_h: np.ndarray
    h: tuple[np.ndarray, ...]
    label: tuple[np.ndarray, ...]
    on_grid: tuple[np.ndarray, ...]
    kinds: dict
    simulations: int


def build_step_map(runner: RoughRunner, z: np.ndarray, grid_h: np.ndarray,
                   progress: Callable[[int], None] | None = None) -> StepMap:
    """One full-order step from each mesh label over the heights ``grid_h`` [m], each failure
    edge between grid points located by bisection to ``BISECT_TOL``."""
    hs, labs, grids = [], [], []
    kinds: dict[str, int] = {}
    sims = 0
    for zi in np.asarray(z, float):
        pts: dict[float, float] = {}
        for h in grid_h:
            kind, lab = runner.transition(zi, float(h))
            sims += 1
            pts[float(h)] = np.nan if kind else float(lab)
            if kind:
                kinds[kind] = kinds.get(kind, 0) + 1
        grid = sorted(pts)
        for a, b in zip(grid[:-1], grid[1:]):
            fa, fb = np.isnan(pts[a]), np.isnan(pts[b])
            if fa == fb:
                continue
            lo, hi = a, b
            while hi - lo > BISECT_TOL:
                mid = 0.5 * (lo + hi)
                kind, lab = runner.transition(zi, mid)
                sims += 1
                pts[mid] = np.nan if kind else float(lab)
                if bool(kind) == fa:
                    lo = mid
                else:
                    hi = mid
        order = sorted(pts)
        hs.append(np.array(order))
        labs.append(np.array([pts[h] for h in order]))
        gset = set(float(v) for v in grid_h)
        grids.append(np.array([h in gset for h in order]))
        if progress is not None:
            progress(1)
    return StepMap(np.asarray(z, float), np.asarray(grid_h, float), tuple(hs), tuple(labs),
                   tuple(grids), kinds, sims)


def reachable_range(runner: RoughRunner, label: float, heights: Sequence[float],
                                    most: int = 20) -> tuple[float, float]:
    """The labels [kg^2 m^4/s^2] the walker reaches from ``label`` on the ``heights`` [m]: the
    lowest (highest) label one step takes the current lowest (highest) to, iterated until it
    moves less than 1 % of the range (at most ``most`` times): the fixed points of the
    extreme one-step maps, the range the mesh must cover."""
    lo = hi = float(label)
    for _ in range(most):
        new_lo, new_hi = lo, hi
        for z0, pick in ((lo, min), (hi, max)):
            labs = [lab for h in heights for kind, lab in [runner.transition(z0, float(h))]
                    if not kind]
            if labs:
                if pick is min:
                    new_lo = min(new_lo, min(labs))
                else:
                    new_hi = max(new_hi, max(labs))
        moved = max(lo - new_lo, new_hi - hi)
        lo, hi = new_lo, new_hi
        if moved <= 1e-2 * (hi - lo + 1e-12 * label):
            break
    return lo, hi


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
    lo, hi = max(a, -spread), min(b, spread)
    if spread <= 0:
        return (1.0, 0.0) if a < 0.0 <= b else (0.0, 0.0)
    if hi <= lo:
        return 0.0, 0.0
    return (hi - lo) / (2.0 * spread), 0.5 * (lo + hi)


@dataclass(frozen=True)
class Chain:
    """The mesh chain of one sigma: ``Q`` over the mesh labels ``z``, the failure probability
    per state ``fail`` [1], the probability of a next label beyond the mesh's ends per state
    (``clipped``: it was put on the end point)."""

    z: np.ndarray
    Q: np.ndarray
    fail: np.ndarray
    clipped: np.ndarray

    def quasi_stationary(self) -> np.ndarray:
        """The quasi-stationary distribution over the states (the left eigenvector of ``Q``
        for ``lambda_2``, summing to 1): where a walker that has not yet failed is."""
        ev, vec = np.linalg.eig(self.Q.T)
        v = np.abs(np.real(vec[:, int(np.argmax(np.abs(ev)))]))
        return v / v.sum() if v.sum() > 0 else np.full(v.size, 1.0 / v.size)


def transition_matrix(smap: StepMap, distribution: str, sigma: float, z_every: int = 1,
                      h_every: int = 1) -> Chain:
    """The chain's transition matrix for heights of standard deviation ``sigma`` [m] (SPEC 14):
    row ``i`` integrates the one-step map of ``z[i]`` over the height's density cell by cell
    between the evaluated heights (every ``h_every``-th grid point and every bisection point):
    a cell whose ends completed goes, with its probability, to the label interpolated at the
    cell's conditional mean height, itself spread over the two neighbouring mesh labels
    (linear weights); a cell whose ends failed is failure; a cell across an edge is split at
    its middle (at most ``BISECT_TOL`` wide); beyond the outer points, the outer point's
    outcome. ``z_every``: every ``z_every``-th mesh label (the coarser mesh of the
    refinement)."""
    from .mfpt import interpolation_weights

    spread = half_width(distribution, sigma)
    rows = list(range(0, smap.z.size, z_every))
    z = smap.z[rows]
    n = z.size
    Q = np.zeros((n, n))
    fail = np.zeros(n)
    clipped = np.zeros(n)
    keep_grid = set(float(v) for v in smap.grid_h[::h_every])
    for ii, i in enumerate(rows):
        h, lab, g = smap.h[i], smap.label[i], smap.on_grid[i]
        sel = np.array([(not gi) or float(hv) in keep_grid for hv, gi in zip(h, g)])
        h, lab = h[sel], lab[sel]
        edges = np.concatenate([[-np.inf], h, [np.inf]])
        out_mass, out_lab = [], []
        for c in range(edges.size - 1):
            a, b = edges[c], edges[c + 1]
            la = lab[c - 1] if c >= 1 else lab[0]
            lb = lab[c] if c < lab.size else lab[-1]
            ha = a if np.isfinite(a) else h[0]
            hb = b if np.isfinite(b) else h[-1]
            pieces = []
            if np.isnan(la) == np.isnan(lb):
                pieces.append((a, b, la, lb))
            else:
                mid = 0.5 * (ha + hb)
                pieces += [(a, mid, la, la), (mid, b, lb, lb)]
            for pa, pb, va, vb in pieces:
                mass, mean = _cell(distribution, spread, pa, pb)
                if mass <= 0.0:
                    continue
                if np.isnan(va):
                    fail[ii] += mass
                    continue
                if va == vb or hb == ha:
                    v = va
                else:
                    v = va + (vb - va) * (min(max(mean, ha), hb) - ha) / (hb - ha)
                out_mass.append(mass)
                out_lab.append(v)
        if out_mass:
            j, t, clip = interpolation_weights(z, np.array(out_lab))
            m = np.array(out_mass)
            np.add.at(Q[ii], j, m * (1.0 - t))
            np.add.at(Q[ii], j + 1, m * t)
            clipped[ii] = float(np.sum(m[clip]))
    return Chain(z, Q, fail, clipped)


def reduction_residual(runner: RoughRunner, label: float, heights: Sequence[float]) -> dict:
    """What restarting on Z costs (SPEC 14's residual): from the start of ``label`` one step
    onto each height [m] of ``heights`` (those completed), then one level step from the true
    post-impact state (off Z) and one from the start on Z with the same label. Returns the
    largest relative difference of the labels after that level step [1], the outputs' error
    ``max |y|`` [rad] just after the rough step's impact and at the next impact, and the
    heights used."""
    rel, y_plus, y_next, used = [], [], [], []
    N = runner.N
    for h in heights:
        first = runner.step(1, 0.0, runner.start(label), label, float(h))
        if first.kind:
            continue
        true = runner.step(2, first.t, first.x, first.label, 0.0, min(0.0, -float(h)))
        red = runner.step(2, 0.0, runner.start(first.label), first.label, 0.0)
        if true.kind or red.kind:
            continue
        used.append(float(h))
        rel.append(abs(true.label - red.label) / red.label)
        y_plus.append(runner.output_error(first.x[:N]))
        q_next = np.asarray(step_record(true.record, N, runner.nz, runner.m).q_minus)
        y_next.append(runner.output_error(q_next))
    if not used:
        return {"heights": [], "relative_label_error": None, "output_error_after_impact": None,
                "output_error_next_impact": None,
                "reason": "no step from the fixed point completed on the heights tried"}
    return {"heights": used, "relative_label_error": float(max(rel)),
            "output_error_after_impact": float(max(y_plus)),
            "output_error_next_impact": float(max(y_next)), "reason": ""}
