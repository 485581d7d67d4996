"""Energy along a full-order run (SPEC 15, 7): the step energies of every completed step of a
simulated run, by quadrature on the run's dense output, after the run (the trajectory itself
is untouched, bit for bit).

Every integrator step of every integration piece of a step carries its 7th-order DOP853
interpolant (the compiled kernel's rows, or SciPy's ``Dop853DenseOutput``); each is integrated
by ``NODES``-point Gauss-Lobatto (exact to degree ``2 NODES - 3``) with the integrands of the
closed loop at the interpolated states (the equations of ``ClosedLoop.details``; for a
compiled run, by the compiled kernel: ``step_stats.energy_nodes`` interpolates and evaluates
the closed loop at every node, a step's first node shared with the end of the step before it
in its piece, the same values as ``ClosedLoop.law`` to rounding; a SciPy run's through
``ClosedLoop.law`` in NumPy):

    joint j, mechanical     u_j q_j'                                 [W]
    thruster k, on walker   F_k d_k . p_k' = F_k (B_F^T q')_k
    generalised mode        T q_N'
    Joule (motor)           R (u_j / (G k_t))^2
    thruster input          P_in(F_k, V_k), V_k = sign(F_k) d_k . p_k'   (energetics.power)
    fuel                    tsfc |F_k|                               [kg/s]

``max(0, .)`` and ``|.|`` (positive and absolute work, clipped electrical power): on an
integrator step where an integrand changes sign between two nodes, its roots are located on the
interpolant (Illinois' regula falsi to rounding) and the step integrated piecewise between
them; ``int |p| = sum |int p|`` over the pieces. The electrical energy takes the gearbox's kink
at ``P_m = 0`` out as :mod:`.orbit` does (``int max(0, P_el) = (1/eta_g - eta_g) int max(0, P_m)
+ int max(0, eta_g P_m + J)``). The quadrature's error is that of the interpolant (the
integration tolerance): the work-energy identity ``Delta K + Delta V = int (u^T q_b' + q'^T
B_F F_T) dt`` holds to it, and a push's jump in energy is reported apart (``push_energy``).

Per step: :class:`RunStepEnergy` (an :class:`~.orbit.OrbitEnergy` with the kinetic energy
after the step's impact and the push's energy); CoT over the step's length along the ground
(the swing foot at impact, slope frame). A part whose model is missing is None with a reason,
never 0. Units SI (J, W, kg, s, m).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .nodes import NODES, Dense, evaluate, evaluate_compiled, kernel_context, lobatto_rule
from .orbit import OrbitEnergy
from .power import input_power, missing_models

ROOT_ITERATIONS = 60


@dataclass(frozen=True)
class RunStepEnergy(OrbitEnergy):
    """The energies of one completed step of a full-order run [J] (SPEC 15): the fields of
    :class:`~.orbit.OrbitEnergy` (``kinetic_start`` at the step's start, ``kinetic_end`` just
    before its impact) with the step's number, the kinetic energy just after its impact
    (relabelled) and the mechanical energy a push added within the step."""

    step: int = 0
    kinetic_after: float | None = None
    push_energy: float = 0.0

    @property
    def impact_loss(self) -> float | None:
        """``K^- - K^+`` [J] of the step's own impact."""
        if self.kinetic_end is None or self.kinetic_after is None:
            return None
        return self.kinetic_end - self.kinetic_after

    @property
    def identity_residual(self) -> float | None:
        """``work + push energy - (E^- - E_start)`` [J] over the step's continuous phase."""
        if self.kinetic_end is None:
            return None
        work = sum(self.joint_work) + sum(self.thrust_work) + self.generalized_work
        return work + self.push_energy - (self.kinetic_end + self.potential_end
                                          - self.kinetic_start - self.potential_start)

    def record(self) -> dict:
        """The JSON block of one step (see :meth:`OrbitEnergy.record`)."""
        if not self.exists:
            return {"exists": False, "reason": self.reason}
        out = super().record()
        out["push_energy"] = self.push_energy
        out.pop("quadrature_error_estimate", None)
        return out


class _Integrands:
    """The integrands of one robot: smooth ones (integrated as they are) and kinked ones
    (whose absolute value is integrated too)."""

    def __init__(self, cl, regenerate: bool):
        robot = cl.model.robot
        self.cl = cl
        self.N, self.nb, self.m = cl.N, cl.nb, cl.m
        self.motors = [c.motor for c in robot.coordinates if c.actuated]
        self.el = [j for j, mo in enumerate(self.motors) if mo is not None]
        self.powers = [t.power for t in robot.thrusters]
        self.regenerate = regenerate

    def kinked(self, d: dict) -> np.ndarray:
        """``u_j q_j'`` (nb), ``F_k d_k . p_k'`` (m) and, clipped electrical power,
        ``eta_g u_j q_j' + J_j`` per motor: (K, columns)."""
        pm = d["u"] * d["dq"][:, :self.nb]
        cols = [pm, d["F"] * d["bt"]]
        if self.el and not self.regenerate:
            eta = np.array([self.motors[j].efficiency for j in self.el])
            cols.append(eta * pm[:, self.el] + self.joule(d))
        return np.concatenate(cols, axis=1)

    def joule(self, d: dict) -> np.ndarray:
        """``R (u / (G k_t))^2`` per motor (K, motors), kept in ``d`` (read twice)."""
        if "joule" not in d:
            if not self.el:
                d["joule"] = np.zeros((d["u"].shape[0], 0))
            else:
                u = d["u"][:, self.el]
                gk = np.array([self.motors[j].G * self.motors[j].k_t for j in self.el])
                R = np.array([self.motors[j].R for j in self.el])
                d["joule"] = R * (u / gk) ** 2
        return d["joule"]

    def smooth(self, d: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Generalised power (K,), thruster input power (K, m; NaN where a table's range is
        left or no model), fuel rate (K, m; 0 without a fuel model)."""
        K, m = d["F"].shape[0], self.m
        pin = np.full((K, m), np.nan)
        fuel = np.zeros((K, m))
        for k, p in enumerate(self.powers):
            if p is None:
                continue
            Fk = d["F"][:, k]
            V = np.sign(Fk) * d["bt"][:, k]
            if p.kind == "fuel":
                fuel[:, k] = p.tsfc * np.abs(Fk)
            if p.kind == "table":
                inside = (Fk >= p.thrust[0]) & (Fk <= p.thrust[-1])
                P = input_power(p, np.clip(Fk, p.thrust[0], p.thrust[-1]), V)
                pin[:, k] = np.where(inside, P, np.nan)
                continue
            P = input_power(p, Fk, V)
            if P is not None:
                pin[:, k] = P
        return d["T"] * d["dq"][:, self.N - 1], pin, fuel


def _abs_integrals(half: np.ndarray, vals: np.ndarray, net: np.ndarray,
                   kernel=None) -> np.ndarray:
    """``int |p|`` per row (R, columns) of the kinked integrands with values ``vals`` (R,
    NODES, columns) at the Gauss-Lobatto nodes of rows of half-width ``half`` and integrals
    ``net`` (R, columns): ``|net|`` where ``p`` keeps its sign at the nodes; else ``p`` is
    its interpolating polynomial on the row (degree ``NODES - 1``, whose integral is the
    Lobatto sum), split at its roots between the nodes (Illinois' regula falsi to rounding)
    and ``int |p| = sum |int p|`` over the pieces, from its antiderivative. ``kernel``: the
    compiled kernel's module, whose ``kink_integrals`` does the root finding and the sums
    (the same operations element by element; a compiled run's), else NumPy."""
    out = np.abs(net)
    sg = vals >= 0.0
    rr, cc = np.nonzero(np.any(sg[:, 1:, :] != sg[:, :-1, :], axis=1))
    if not rr.size:
        return out
    x, _ = lobatto_rule(NODES)
    coef = vals[rr, :, cc] @ _inverse_vandermonde(NODES).T  # (P, NODES) monomials in x
    anti = np.concatenate([np.zeros((len(rr), 1)), coef / np.arange(1, NODES + 1)], axis=1)

    def horner(c, t):
        acc = np.zeros_like(t)
        for j in range(c.shape[1] - 1, -1, -1):
            acc = acc * t + c[:, j]
        return acc

    v = vals[rr, :, cc]  # (P, NODES)
    if kernel is not None:
        total = np.empty(len(rr))
        kernel.kink_integrals(v, coef, anti, x, ROOT_ITERATIONS, total)
        out[rr, cc] = total * half[rr]
        return out
    s = v >= 0.0
    p, g = np.nonzero(s[:, 1:] != s[:, :-1])  # a root in (x_g, x_{g+1}) of polynomial p
    a, b = x[g], x[g + 1]
    fa, fb = v[p, g], v[p, g + 1]
    cp = coef[p]
    root = np.where(fa == 0.0, a, b)
    done = (fa == 0.0) | (fb == 0.0)
    for _ in range(ROOT_ITERATIONS):  # Illinois, bracket [a, b] (either order)
        if done.all():
            break
        xn = b - fb * (b - a) / np.where(fb == fa, 1.0, fb - fa)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        xn = np.where((xn > lo) & (xn < hi), xn, 0.5 * (a + b))
        fx = horner(cp, xn)
        flip = (fx >= 0.0) != (fb >= 0.0)
        keep = ~done
        a = np.where(keep & flip, b, a)
        fa = np.where(keep, np.where(flip, fb, 0.5 * fa), fa)
        b = np.where(keep, xn, b)
        fb = np.where(keep, fx, fb)
        root = np.where(keep, xn, root)
        done |= (fx == 0.0) | (np.abs(b - a) <= 4e-16)
    # sum over the pieces of |A(end) - A(start)|: the roots in order, with the ends
    order = np.lexsort((root, p))
    p, root = p[order], root[order]
    Ar = horner(anti[p], root)
    A1, A0 = horner(anti, np.ones(len(rr))), horner(anti, -np.ones(len(rr)))
    first = np.r_[True, p[1:] != p[:-1]]
    prev = np.where(first, A0[p], np.r_[0.0, Ar[:-1]])
    total = np.zeros(len(rr))
    np.add.at(total, p, np.abs(Ar - prev))
    lastp = np.r_[p[1:] != p[:-1], True]
    total[p[lastp]] += np.abs(A1[p[lastp]] - Ar[lastp])
    out[rr, cc] = total * half[rr]
    return out


@lru_cache(maxsize=4)
def _inverse_vandermonde(n: int) -> np.ndarray:
    """Values at the ``n`` Lobatto nodes -> monomial coefficients in ``x`` of ``[-1, 1]``."""
    x, _ = lobatto_rule(n)
    return np.linalg.inv(np.vander(x, n, increasing=True))


def _per_step(rowint: np.ndarray, owner: np.ndarray, ns: int) -> np.ndarray:
    """The sums over each walking step's rows (``owner``: the step of every row, in
    order) of ``rowint`` (rows, columns): (ns, columns)."""
    starts = np.searchsorted(owner, np.arange(ns))
    if ns and owner.size and np.all(np.diff(np.r_[starts, owner.size]) > 0):
        return np.add.reduceat(rowint, starts, axis=0)
    out = np.zeros((ns, rowint.shape[1]))  # a step without rows: 0
    np.add.at(out, owner, rowint)
    return out


# ----------------------------------------------------------------------------- the run
def run_energy(cl, steps: list[tuple], *, regenerate: bool = False,
               seg_force: list | None = None) -> list[RunStepEnergy]:
    """The energies of completed steps of a full-order run on the closed loop ``cl``:
    ``steps`` a list of ``(step number, pieces, q^-, q'^-)``, ``pieces`` the step's
    integration pieces ``(t0, t1, segment, dense solution)`` in time order (module
    docstring, SPEC 15). ``regenerate``: negative electrical power recovered.

    ``seg_force``: per step the thrust it walked as data, per segment of ``cl`` (segments x
    thrusters) [N], T = 0, instead of ``cl``'s thrust (e.g. a controller's piecewise thrust,
    set step by step): steps of one closed loop with different thrust in one call, each
    step's energies the same as on its own closed loop. The steps may be those of several
    runs (each step's energies are its own; a run's are summed by the caller)."""
    if not steps:
        return []
    model, robot = cl.model, cl.model.robot
    N, nb, m = cl.N, cl.nb, cl.m
    ig = _Integrands(cl, regenerate)
    dense = Dense([s[1] for s in steps])
    ns = len(steps)
    x, w = lobatto_rule(NODES)
    half = 0.5 * (dense.hi - dense.lo)
    t = (0.5 * (dense.lo + dense.hi))[:, None] + half[:, None] * x[None]  # (R, NODES)
    R = t.shape[0]
    rows = np.repeat(np.arange(R), NODES)
    table = None
    if seg_force is not None:  # every step's table, stacked: row -> (its step, its segment)
        nseg = len(cl.breaks) + 1
        table = np.concatenate([np.asarray(f, float).reshape(nseg, m) for f in seg_force])
    d = None
    if dense.compiled:
        d = evaluate_compiled(cl, dense, None if table is None
                               else table[nseg * dense.owner + dense.seg])
    if d is None:
        X = dense.at_nodes(t)
        force = None if table is None else table[nseg * dense.owner[rows] + dense.seg[rows]]
        d = evaluate(cl, X, dense.seg[rows], force)
    W = (half[:, None] * w[None])[..., None]  # weights of every node (R, NODES, 1)
    # every integrand as one table (R, NODES, columns): the kinked ones first, then the
    # generalised power, the thrusters' input power and fuel rate, the Joule losses
    kv = ig.kinked(d)
    gen, pin, fuel = ig.smooth(d)
    cols = [kv, gen[:, None]]
    if m:
        cols += [np.nan_to_num(pin, nan=0.0), fuel]
    if ig.el:
        cols.append(ig.joule(d))
    vals = np.concatenate(cols, axis=1).reshape(R, NODES, -1)
    nk = kv.shape[1]
    rowint = (vals * W).sum(1)  # Gauss-Lobatto on every row (R, columns)
    k_abs_row = _abs_integrals(half, vals[..., :nk], rowint[:, :nk],
                               kernel_context(cl)[0] if dense.compiled else None)
    per_step = _per_step(np.concatenate([rowint, k_abs_row,
                                         (dense.hi - dense.lo)[:, None]], axis=1),
                         dense.owner, ns)
    ne = len(ig.el)
    k_net_step, gen_s = per_step[:, :nk], per_step[:, nk]
    o = nk + 1
    pin_s, fuel_s = per_step[:, o:o + m], per_step[:, o + m:o + 2 * m]
    o += 2 * m
    joule_s = per_step[:, o:o + ne]
    k_abs = per_step[:, o + ne:o + ne + nk]
    time_s = per_step[:, -1]
    pin_bad = np.zeros((ns, m), bool)
    if m:
        np.logical_or.at(pin_bad, dense.owner[rows], np.isnan(pin))
    # energies at the pieces' ends (their jumps: a push), before and after the impact
    first = np.array([p[0] for p in dense.piece_rows])
    last = np.array([p[1] for p in dense.piece_rows])
    owner = np.array(dense.piece_owner)
    Xa = dense.at(first, dense.lo[first])
    Xb = dense.at(last, dense.hi[last])
    Ka_all = 0.5 * np.einsum("ki,kij,kj->k", Xa[:, N:2 * N], model.D(Xa[:, :N]),
                             Xa[:, N:2 * N])
    Va_all = model.V(Xa[:, :N])[..., 0]
    Ea = Ka_all + Va_all
    Eb = model.energy(Xb[:, :N], Xb[:, N:2 * N])
    qm = np.array([s[2] for s in steps], float)
    dqm = np.array([s[3] for s in steps], float)
    Dm = model.D(qm)
    Km = 0.5 * np.einsum("ki,kij,kj->k", dqm, Dm, dqm)
    Vm = model.V(qm)[..., 0]
    imp = model.impact(qm, dqm)
    Kp = 0.5 * np.einsum("ki,kij,kj->k", imp.dq_plus, model.D(imp.q_plus), imp.dq_plus)
    length = model.p_swing(qm)[:, 0]
    missing = missing_models(robot)
    motors, powers = ig.motors, ig.powers
    tin_none = [p is None or (p.kind == "fuel" and p.heating_value is None) for p in powers]
    is_fuel = [p is not None and p.kind == "fuel" for p in powers]
    eta = np.array([motors[j].efficiency for j in ig.el])
    weight = robot.weight
    # per step, the arrays of all steps at once (the same arithmetic as step by step)
    ia_all = np.searchsorted(owner, np.arange(ns)).tolist()  # each step's first piece
    same = owner[1:] == owner[:-1]  # the jumps between pieces within a step: the push
    push_s = np.zeros(ns)
    np.add.at(push_s, owner[1:][same], (Ea[1:] - Eb[:-1])[same])
    pos_all = 0.5 * (k_net_step + k_abs)
    el_all = None
    if ig.el:
        kink = (1.0 / eta - eta) * pos_all[:, :nb][:, ig.el]
        el_all = (kink + eta * k_net_step[:, :nb][:, ig.el] + joule_s if regenerate
                  else kink + pos_all[:, nb + m:]).tolist()
    net_l, pos_l, abs_l = k_net_step.tolist(), pos_all.tolist(), k_abs.tolist()
    pin_l, fuel_l, bad_l = pin_s.tolist(), fuel_s.tolist(), pin_bad.tolist()
    gen_l, time_l, len_l = gen_s.tolist(), time_s.tolist(), length.tolist()
    Ka_l, Va_l, Km_l, Vm_l, Kp_l = (Ka_all.tolist(), Va_all.tolist(), Km.tolist(), Vm.tolist(),
                                    Kp.tolist())
    push_l = push_s.tolist()
    out = []
    for i, (k, _, _, _) in enumerate(steps):
        ia = ia_all[i]
        net, pos, ab = net_l[i], pos_l[i], abs_l[i]
        el: list[float | None] = [None] * nb
        if el_all is not None:
            for jj, v in zip(ig.el, el_all[i]):
                el[jj] = v
        bad = bad_l[i]
        extra = [f"step {k}: thruster {robot.thrusters[kk].name}: thrust outside its power "
                 "table's range: input energy not computed"
                 for kk in range(m) if not tin_none[kk] and bad[kk]]
        out.append(RunStepEnergy(
            True, "energies along the full-order run (Gauss-Lobatto on the dense output)",
            tuple(net[:nb]), tuple(pos[:nb]), tuple(ab[:nb]), tuple(el),
            tuple(net[nb:nb + m]), tuple(pos[nb:nb + m]), gen_l[i],
            tuple(None if tin_none[kk] or bad[kk] else pin_l[i][kk] for kk in range(m)),
            tuple(fuel_l[i][kk] if is_fuel[kk] else None for kk in range(m)),
            kinetic_start=Ka_l[ia], kinetic_end=Km_l[i],
            potential_start=Va_l[ia], potential_end=Vm_l[i],
            step_time=time_l[i], distance=len_l[i], weight=weight,
            error_estimate=None, regenerate=regenerate,
            missing=tuple(missing + extra), step=int(k), kinetic_after=Kp_l[i],
            push_energy=push_l[i]))
    return out


def run_summary(energies: list[RunStepEnergy]) -> dict:
    """The run's summary over its completed steps: totals [J, kg, m, s], mean CoT (the mean of
    the steps' CoT, each part None when any step's is), the CoT of the totals (total energy
    over ``m g`` times the total distance) and average powers [W]."""
    if not energies:
        return {"steps": 0, "reason": "no completed step: no energy"}

    def total(name):
        vals = [getattr(e, name) for e in energies]
        return None if any(v is None for v in vals) else float(sum(vals))

    def mean(key):
        vals = [e.cot()[key] for e in energies]
        return None if any(v is None for v in vals) else float(np.mean(vals))

    parts = ("legs_mechanical", "thrust_mechanical", "legs_electrical", "thrust_input")
    totals = {p: total(p) for p in parts}
    time = float(sum(e.step_time for e in energies))
    dist = float(sum(e.distance for e in energies))
    fuel = [e.fuel_mass for e in energies]
    fuel_total = [None if any(f[k] is None for f in fuel) else float(sum(f[k] for f in fuel))
                  for k in range(len(fuel[0]))]
    weight = energies[0].weight
    lm, tm, le, ti = (totals[p] for p in parts)

    def cot(e):
        return None if e is None or not dist else e / (weight * dist)
    keys = ("mechanical", "mechanical_legs", "mechanical_thrust", "total", "total_legs",
            "total_thrust")
    return {
        "steps": len(energies),
        "time": time, "distance": dist,
        "totals": {**totals, "impact_loss": float(sum(e.impact_loss for e in energies)),
                   "push_energy": float(sum(e.push_energy for e in energies)),
                   "fuel_mass": fuel_total},
        "mean_cot": {k: mean(k) for k in keys},
        "cot_of_totals": {
            "mechanical": cot(None if lm is None else lm + tm), "mechanical_legs": cot(lm),
            "mechanical_thrust": cot(tm),
            "total": cot(None if le is None or ti is None else le + ti), "total_legs": cot(le),
            "total_thrust": cot(ti)},
        "average_power": {p: (None if totals[p] is None or not time else totals[p] / time)
                          for p in parts},
        "max_work_energy_residual": float(max(abs(e.identity_residual) for e in energies)),
        "missing": list(energies[0].missing),
    }


def step_block(e: RunStepEnergy) -> dict:
    """The ``energy`` block of one step entry of a result document: the step's energies,
    costs of transport, average powers, the work-energy residual and the push's energy (the
    models missing and the negative-power convention are the run's, :func:`run_block`)."""
    rec = e.record()
    for key in ("exists", "reason", "missing", "negative_joint_power"):
        rec.pop(key, None)
    return rec


def run_block(energies: list[RunStepEnergy], regenerate: bool = False) -> dict:
    """The ``energy`` block of a run entry: :func:`run_summary` with the quadrature, the
    negative-power convention and the missing models said."""
    out = run_summary(energies)
    out["method"] = (f"{NODES}-point Gauss-Lobatto on every integrator step of the dense "
                     "output; sign changes of u_j q_j', F_k d_k.p_k' and the clipped "
                     "electrical power located on the step's interpolating polynomial")
    out["negative_joint_power"] = ("recovered (regenerate)" if regenerate else
                                   "not recovered: electrical power clipped at 0 per joint")
    return out


def simulation_energy(run, regenerate: bool = False) -> list[RunStepEnergy]:
    """The energies of the completed steps of a full-order ``SimResult`` (both methods),
    computed when first asked for and kept with the run (a failed step has none)."""
    cache = run.__dict__.setdefault("_energy_cache", {})
    if regenerate not in cache:
        by_step: dict[int, list] = {}
        for s in run.segments:
            by_step.setdefault(s.step, []).append((s.t0, s.t1, s.interval, s.sol))
        steps = [(rec.step, by_step[rec.step], rec.q_minus, rec.dq_minus)
                 for rec in run.steps]
        cache[regenerate] = run_energy(run.sim, steps, regenerate=regenerate)
    return cache[regenerate]
