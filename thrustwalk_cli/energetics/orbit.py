"""Energy on the zero-dynamics orbit (SPEC 15): exact, by quadrature, no simulation.

On Z, ``q' = Phi(alpha) alpha'``, the joint torques are affine in ``zeta`` and the thrust
(``u = U0 + U1 zeta + U2 F_T + UT T``, SPEC 5, :func:`~..contact.terms.stance_terms`) and
``dt = d alpha / alpha'``. Every power ``P`` integrates over the step as an integral in alpha
over ``|d alpha|`` (``s = sign(alpha_f - alpha_i) = sign(alpha')``):

    joint j, mechanical     u_j q_j' dt       = s u_j Phi_j d|alpha|                  [J]
    thruster k, on walker   F_k d_k . p_k' dt = s F_k (B_F^T Phi)_k d|alpha|
    generalised mode        T q_N' dt         = s T Phi_N d|alpha|
    Joule, thruster input   P dt              = P / |alpha'| d|alpha|
                            |alpha'| = |kappa_1| sqrt(2 zeta)

The integrands are smooth inside each knot interval of the thrust schedule (the thrust jumps at
the knots), so each interval is integrated on its own Chebyshev-Lobatto nodes (nodes doubled
until the nested error estimate of the smooth integrals is below ``RTOL`` relative).
``max(0, .)`` and ``|.|`` (positive and absolute work, clipped electrical power) are integrated
piecewise between the kinks: the roots of the integrand's Chebyshev interpolant on the interval
split it, and the interpolant's antiderivative is evaluated at the roots. The roots are isolated
between the nodes with a proof (no root, or exactly one, from bounds of the interpolant's
second derivative; gaps without a proof are halved up to ``SPLITS`` times) and polished from
the root of a cubic Hermite interpolant by a Newton step (:func:`.kinks.abs_and_positive`,
one call for all the rows of a knot interval: joints, thrusters, electrical powers). A
thrust's power ``F_k (B_F^T Phi)_k`` is the constant thrust times one function of alpha on a
knot interval: its kinks are those of that function, found once for the whole batch. What
depends on alpha only (the stance terms, ``Phi``, ``B_F^T Phi``, the pieces of ``V_Z`` at the
nodes) is computed once per walker, knots and node count and kept on the ``ZeroDynamics``.

Joint electrical power with a motor: ``P_m / eta_g`` (or ``P_m eta_g`` when negative) plus
the Joule loss ``J = R (u / (G k_t))^2`` (:mod:`.power`); negative electrical power is not
recovered (clipped at 0 per joint) unless ``regenerate``. The gearbox's factor jumps where
``P_m`` changes sign (a kink a Chebyshev interpolant cannot follow), so the energy is written
with smooth integrands only: ``P_el >= 0`` where ``P_m >= 0``, hence

    int max(0, P_el) = (1/eta_g - eta_g) int max(0, P_m) + int max(0, eta_g P_m + J)
    int P_el         = (1/eta_g - eta_g) int max(0, P_m) + eta_g int P_m + int J.

Thrust input power from the thruster's model with the axial air speed ``V_k = sign(F_k) d_k .
p_k'`` through the disk (momentum model).

Cost of transport ``CoT = E / (m g d)`` (``d`` the step length along the ground):
mechanical = (joints' positive work + thrusters' positive work on the walker) / (m g d), total =
(joints' electrical energy + thrusters' input energy) / (m g d), each split into legs and
thrust. A part whose model is missing is None with a reason, never 0.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..contact.terms import stance_terms
from ..hzd.quadrature import _cc_weights, lobatto
from ..hzd.zero_dynamics import ZeroDynamics
from ..thrust.schedule import Schedule
from .kinks import abs_and_positive as _abs_and_positive
from .power import input_power, joule_power, missing_models

RTOL = 1e-10
MAX_NODES = 1025
# nodes at which a knot interval's integrands are first computed (where no call ended
# before): the 33 of the first try are every other one of them (the same nodes, bit for
# bit), and most orbits need the 65 (RABBIT's, the 3-link's, walker5's)
FIRST_NODES = 65


@dataclass(frozen=True)
class OrbitEnergy:
    """Energies of one step of the periodic orbit [J] (SPEC 15); per joint / per thruster
    tuples in the robot's order. ``None`` with a line in ``missing`` where a model is not
    given; everything None (``exists`` false) without an orbit."""

    exists: bool
    reason: str
    joint_work: tuple[float, ...] = ()  # net  int u_j q_j' dt
    joint_positive_work: tuple[float, ...] = ()
    joint_absolute_work: tuple[float, ...] = ()
    joint_electrical: tuple[float | None, ...] = ()
    thrust_work: tuple[float, ...] = ()  # int F_k d_k . p_k' dt on the walker
    thrust_positive_work: tuple[float, ...] = ()
    generalized_work: float = 0.0  # int T q_N' dt (generalised-mode schedules)
    thruster_input: tuple[float | None, ...] = ()
    fuel_mass: tuple[float | None, ...] = ()  # [kg] per step
    kinetic_start: float | None = None  # K^+ (just after impact)
    kinetic_end: float | None = None  # K^- (just before impact)
    potential_start: float | None = None
    potential_end: float | None = None
    step_time: float | None = None  # [s] the step time integrated with the energies
    distance: float | None = None  # [m]
    weight: float | None = None  # [N] m g
    error_estimate: float | None = None  # [J] nested quadrature estimate, largest
    regenerate: bool = False
    missing: tuple[str, ...] = field(default=())

    @classmethod
    def _of(cls, fields: dict) -> OrbitEnergy:
        """The object with these ``fields`` (every one, by name), as the constructor makes
        it: the frozen dataclass's ``__init__`` sets each of its 21 fields through
        ``object.__setattr__`` (4 us an object); a batch of orbits fills ``__dict__`` at
        once (the class has no ``__post_init__`` and no slots)."""
        e = object.__new__(cls)
        e.__dict__.update(fields)
        return e

    # -- derived ------------------------------------------------------------------------
    @property
    def impact_loss(self) -> float | None:
        """Kinetic energy lost at impact ``K^- - K^+`` [J] (>= 0 for a rigid impact)."""
        if self.kinetic_end is None:
            return None
        return self.kinetic_end - self.kinetic_start

    @property
    def identity_residual(self) -> float | None:
        """``joints' work + thrust work - (K^- + V^- - K^+ - V^+)`` [J] over the continuous
        phase (the work-energy identity; 0 up to quadrature)."""
        if self.kinetic_end is None:
            return None
        work = sum(self.joint_work) + sum(self.thrust_work) + self.generalized_work
        return work - (self.kinetic_end + self.potential_end - self.kinetic_start
                       - self.potential_start)

    def _mgd(self, energy: float | None) -> float | None:
        if energy is None or not self.distance:
            return None
        return energy / (self.weight * self.distance)

    @property
    def legs_mechanical(self) -> float | None:
        """The joint motors' positive mechanical work over the step [J] (SPEC 15); None without
        an orbit."""
        return float(sum(self.joint_positive_work)) if self.exists else None

    @property
    def thrust_mechanical(self) -> float | None:
        """The thrusters' positive mechanical work over the step [J] (SPEC 15); None without an
        orbit."""
        return float(sum(self.thrust_positive_work)) if self.exists else None

    @property
    def legs_electrical(self) -> float | None:
        """The joint motors' electrical energy over the step [J] (SPEC 15); None without an orbit
        or a motor model for every joint."""
        vals = self.joint_electrical
        return None if not self.exists or any(v is None for v in vals) else float(sum(vals))

    @property
    def thrust_input(self) -> float | None:
        """The thrusters' input energy over the step by their power models [J] (SPEC 15); None
        without an orbit or a model for every thruster."""
        vals = self.thruster_input
        return None if not self.exists or any(v is None for v in vals) else float(sum(vals))

    def cot(self) -> dict:
        """Costs of transport [1]: mechanical and total, split legs / thrust (None: missing)."""
        lm, tm = self.legs_mechanical, self.thrust_mechanical
        le, ti = self.legs_electrical, self.thrust_input
        return {
            "mechanical": self._mgd(None if lm is None else lm + tm),
            "mechanical_legs": self._mgd(lm),
            "mechanical_thrust": self._mgd(tm),
            "total": self._mgd(None if le is None or ti is None else le + ti),
            "total_legs": self._mgd(le),
            "total_thrust": self._mgd(ti),
        }

    def record(self) -> dict:
        """The JSON block of one case (SI units: J, W, kg, s, m; CoT dimensionless)."""
        if not self.exists:
            return {"exists": False, "reason": self.reason}
        T = self.step_time
        lm, tm, le, ti = (self.legs_mechanical, self.thrust_mechanical, self.legs_electrical,
                          self.thrust_input)

        def power(e):
            return None if e is None or T is None else e / T

        fl = [f for f in self.fuel_mass if f is not None]
        return {
            "exists": True,
            "reason": self.reason,
            "per_step": {
                "joint_work": list(self.joint_work),
                "joint_positive_work": list(self.joint_positive_work),
                "joint_absolute_work": list(self.joint_absolute_work),
                "joint_electrical": list(self.joint_electrical),
                "thrust_work": list(self.thrust_work),
                "thrust_positive_work": list(self.thrust_positive_work),
                "generalized_work": self.generalized_work,
                "thruster_input": list(self.thruster_input),
                "fuel_mass": list(self.fuel_mass),
                "legs_mechanical": lm, "thrust_mechanical": tm,
                "legs_electrical": le, "thrust_input": ti,
                "impact_loss": self.impact_loss,
            },
            "fuel_per_metre": (sum(fl) / self.distance if fl else None),
            "cot": self.cot(),
            "average_power": {"legs_mechanical": power(lm), "thrust_mechanical": power(tm),
                              "legs_electrical": power(le), "thrust_input": power(ti)},
            "work_energy_residual": self.identity_residual,
            "quadrature_error_estimate": self.error_estimate,
            "negative_joint_power": ("recovered (regenerate)" if self.regenerate else
                                     "not recovered: electrical power clipped at 0 per joint"),
            "missing": list(self.missing),
        }


@lru_cache(maxsize=16)
def _weights(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Clenshaw-Curtis weights of ``n`` Lobatto nodes and of the nested ``(n-1)/2 + 1``."""
    return _cc_weights(n), _cc_weights((n - 1) // 2 + 1)


def _nodes(zd: ZeroDynamics, knots: np.ndarray, j: int, n: int) -> dict:
    """What the energy integrands of knot interval ``j`` need at its ``n`` ascending Lobatto
    nodes that does not depend on the thrust values (they depend on alpha only): the stance
    terms' torque rows (SPEC 5), ``s Phi_j`` of the joints, ``s (B_F^T Phi)_k`` of the
    thrusters, ``s Phi_N``, ``|kappa_1|`` and the pieces of ``V_Z`` (``V_0`` and per knot
    interval the increments of ``Gamma`` and ``b_F``, as :meth:`ZeroDynamics.V_Z`); computed
    on first use and kept on ``zd``."""
    cache = zd.__dict__.setdefault("_energy_nodes", {})
    key = (tuple(knots.tolist()), j, n)
    out = cache.get(key)
    if out is not None:
        return out
    if len(cache) > 64:
        cache.clear()
    model, maps = zd.model, zd.maps
    N, m = model.n, model.n_thrusters
    s = zd.direction
    lo, hi = sorted((knots[j], knots[j + 1]))
    alpha = lobatto(lo, hi, n)
    st = stance_terms(model, maps, alpha)
    phi = maps.Phi(alpha)  # (g, N)
    out = cache[key] = {
        "U0": st.U0.T[None], "U1": st.U1.T[None], "UT": st.UT.T[None],
        "U2": st.U2.transpose(2, 1, 0).reshape(m, (N - 1) * len(alpha)),  # m = 0: no thruster
        "pphi": (s * phi[:, :N - 1].T)[None],
        "bt": s * np.einsum("gnm,gn->mg", model.B_F(maps.q_Z(alpha)), phi),  # (m, g)
        "bg": s * phi[:, N - 1],
        "k1": np.abs(st.AT),  # AT = 1 / (e_N^T D Phi) = kappa_1
        "V_Z": _vz_pieces(zd, alpha, knots)}
    return out


def _vz_pieces(zd: ZeroDynamics, alpha: np.ndarray, knots: np.ndarray) -> tuple:
    """The thrust-independent pieces of ``V_Z(alpha)`` (SPEC 3, 4) for a schedule's
    ``knots``, as :meth:`ZeroDynamics.V_Z` computes them: ``V_0(alpha)`` and per knot
    interval the increments of ``Gamma`` and ``b_F`` from the knot to ``alpha`` clipped into
    the interval."""
    klo, khi = np.minimum(knots[:-1], knots[1:]), np.maximum(knots[:-1], knots[1:])
    dG, dB = [], []
    for jj in range(len(knots) - 1):
        a = np.clip(alpha, klo[jj], khi[jj])
        dG.append(zd.Gamma(a) - zd.Gamma(knots[jj]))
        dB.append(zd.B(a) - zd.B(knots[jj]))
    return zd.V0(alpha), dG, dB


def _vz(pieces: tuple, sched: Schedule) -> np.ndarray:
    """``V_Z`` (k, g) of every schedule of the batch from :func:`_vz_pieces`, with the
    operations of :meth:`ZeroDynamics.V_Z` in its order (the same numbers)."""
    V0, dG, dB = pieces
    out = np.broadcast_to(V0, (sched.size,) + V0.shape).copy()
    for jj in range(len(dG)):
        out += np.einsum("...m,km->k...", dG[jj], sched.force[:, jj, :])
        out += sched.generalized[:, jj].reshape((-1,) + (1,) * V0.ndim) * dB[jj]
    return out


def _integrands(zd: ZeroDynamics, sched: Schedule, zp: np.ndarray, j: int, n: int) -> dict:
    """The integrands of knot interval ``j`` at ``n`` Lobatto nodes for the batch (module
    docstring): ``zeta``, the torques ``u`` and the joint powers per ``|d alpha|`` (k, joint,
    g), ``|alpha'|`` and its inverse (k, g), the thrust's and the generalised mode's powers per
    unit thrust (m, g), (g,)."""
    nd = _nodes(zd, np.asarray(sched.knots, float), j, n)
    N, m = zd.model.n, zd.model.n_thrusters
    k = sched.size
    F = sched.force[:, j, :]  # (k, m)
    Tg = sched.generalized[:, j]  # (k,)
    zeta = zp[:, None] + _vz(nd["V_Z"], sched)  # (k, g)
    zeta = np.maximum(zeta, 0.0)
    u = nd["U0"] + nd["U1"] * zeta[:, None, :]
    if m:  # + U2 F
        u = u + (F @ nd["U2"]).reshape(k, N - 1, n)
    u = u + nd["UT"] * Tg[:, None, None]
    adot = nd["k1"][None] * np.sqrt(2.0 * zeta)  # |alpha'| (k, g)
    with np.errstate(divide="ignore"):
        inv = 1.0 / adot
    return {"u": u, "pj": u * nd["pphi"], "bt": nd["bt"], "bg": nd["bg"], "adot": adot,
            "inv": inv}


def orbit_energy(zd: ZeroDynamics, schedule: Schedule, cycles, *, regenerate: bool = False
                 ) -> list[OrbitEnergy]:
    """The step energies of each schedule's periodic orbit (``cycles[i]`` its
    :class:`LimitCycle`), exactly by quadrature on Z (module docstring, SPEC 15).

    What depends on alpha only is computed once per walker, knots and node count
    (:func:`_nodes`); the node count of a knot interval starts where the last call ended
    (kept on ``zd``; ``FIRST_NODES`` on the first call), and the smaller nested counts are
    tried first on subsets of those nodes, so the result is the one the doubling from 33
    nodes gives."""
    model, maps = zd.model, zd.maps
    robot = model.robot
    N, m = model.n, model.n_thrusters
    motors = [c.motor for c in robot.coordinates if c.actuated]
    powers = [t.power for t in robot.thrusters]
    missing = missing_models(robot)
    missing_t = tuple(missing)
    cycles = list(cycles)  # a batch's LimitCycles read once (each read checks its index)
    live = [i for i, lc in enumerate(cycles) if lc.exists]
    out: list[OrbitEnergy | None] = [
        None if lc.exists else OrbitEnergy(False, lc.missing)
        for lc in cycles]
    if not live:
        return out
    sched = schedule.take(np.array(live))
    k = len(live)
    zp = np.array([cycles[i].zeta_plus for i in live])
    kn = np.asarray(sched.knots, float)
    acc = {name: np.zeros((k,) + shape) for name, shape in (
        ("work", (N - 1,)), ("abs", (N - 1,)), ("pos", (N - 1,)), ("el", (N - 1,)),
        ("tw", (m,)), ("tpos", (m,)), ("gen", ()), ("tin", (m,)), ("fuel", (m,)),
        ("time", ()))}
    err = np.zeros(k)
    tin_ok = np.ones((k, m), bool)
    timed = True  # alpha' > 0 at every node: the time-based integrals exist
    el = [jj for jj, mo in enumerate(motors) if mo is not None]
    start = zd.__dict__.setdefault("_energy_node_count", {})
    if len(start) > 256:  # knots that change from call to call (an optimiser's)
        start.clear()
    for j in range(len(kn) - 1):
        lo, hi = sorted((kn[j], kn[j + 1]))
        if hi <= lo:
            continue
        half = 0.5 * (hi - lo)
        F = sched.force[:, j, :]  # (k, m)
        Tg = sched.generalized[:, j]  # (k,)
        aF = np.abs(F)
        skey = (tuple(kn.tolist()), j)
        n, have, full = 33, 0, None
        while True:
            if have < n:  # the integrands at max(n, where the last call ended) nodes
                have = max(n, start.get(skey, FIRST_NODES))
                full = _integrands(zd, sched, zp, j, have)
            step = (have - 1) // (n - 1)  # the n nodes are every step-th of them
            it = {key: v[..., ::step] for key, v in full.items()}
            w, wc = _weights(n)
            w, wc = w * half, wc * half

            def quad(v, w=w, wc=wc):
                fine = v @ w
                return fine, np.abs(fine - v[..., ::2] @ wc)
            work, e_work = quad(it["pj"])  # (k, N-1)
            bt_i, e_bt = quad(it["bt"])  # (m,)
            bg_i, e_bg = quad(it["bg"])
            e = np.maximum(e_work.max(axis=1), np.abs(Tg) * e_bg)
            if m:
                e = np.maximum(e, (aF * e_bt).max(axis=1))
            finite = np.all(np.isfinite(it["inv"]))
            if finite:
                time_i, e_time = quad(it["inv"])
                e = np.maximum(e, e_time)
            scale = max(float(np.max(np.abs(work))), 1e-300)
            if np.all(e <= RTOL * scale) or n >= MAX_NODES:
                break
            n = 2 * n - 1
        start[skey] = n
        u, pj, bt, adot, inv = (np.ascontiguousarray(it[key]) for key in (
            "u", "pj", "bt", "adot", "inv"))
        err += e
        acc["work"] += work
        acc["tw"] += F * bt_i
        acc["gen"] += Tg * bg_i
        # every int |.| and int max(0, .) of the interval in one batch: the joints' powers,
        # the thrusters' per unit thrust and the clipped electrical powers
        parts = [pj.reshape(-1, n), bt]
        if finite and el:  # SPEC 15 with the gearbox's kink at P_m = 0 taken out
            eta = np.array([motors[jj].efficiency for jj in el])[None, :]
            joule = np.stack([joule_power(u[:, jj], motors[jj]) for jj in el], axis=1)
            joule = joule * inv[:, None, :]  # per |d alpha|
            if not regenerate:
                parts.append((eta[..., None] * pj[:, el] + joule).reshape(-1, n))
        ab, po = _abs_and_positive(np.concatenate(parts), half)
        nj = k * (N - 1)
        po_j = po[:nj].reshape(k, N - 1)
        acc["abs"] += ab[:nj].reshape(k, N - 1)
        acc["pos"] += po_j
        if m:  # int max(0, F b) = F int max(0, b) (F > 0), |F| int max(0, -b) (F < 0)
            b_abs, b_pos = ab[nj:nj + m], po[nj:nj + m]
            acc["tpos"] += np.where(F > 0, F * b_pos, aF * (b_abs - b_pos))
        if not finite:
            tin_ok[:] = False
            timed = False
            continue
        acc["time"] += time_i
        if el:  # (module docstring)
            kink = (1.0 / eta - eta) * po_j[:, el]
            if regenerate:
                acc["el"][:, el] += kink + eta * work[:, el] + quad(joule)[0]
            else:
                acc["el"][:, el] += kink + po[nj + m:].reshape(k, len(el))
        for kk, p in enumerate(powers):
            if p is None:
                continue
            V = np.sign(F[:, kk])[:, None] * bt[kk][None] * adot  # s^2 = 1
            Fk = np.broadcast_to(F[:, kk][:, None], V.shape)
            if p.kind == "fuel":
                acc["fuel"][:, kk] += quad(p.tsfc * np.abs(Fk) * inv)[0]
            try:
                P = input_power(p, Fk, V)
            except ValueError:
                tin_ok[:, kk] &= ~np.any((Fk < p.thrust[0]) | (Fk > p.thrust[-1]), axis=1)
                P = input_power(p, np.clip(Fk, p.thrust[0], p.thrust[-1]), V)
            if P is not None:
                acc["tin"][:, kk] += quad(P * inv)[0]
    qm, qp = maps.q_minus, maps.q_plus
    Dm, Dp = model.D(qm), model.D(qp)
    phim, phip = maps.Phi(np.array(zd.alpha_f)), maps.Phi(np.array(zd.alpha_i))
    Vm, Vp = float(model.V(qm)[0]), float(model.V(qp)[0])
    Km_unit, Kp_unit = 0.5 * phim @ Dm @ phim, 0.5 * phip @ Dp @ phip
    weight, distance = robot.weight, zd.step_length
    ad = np.array([[cycles[i].alpha_dot_plus, cycles[i].alpha_dot_minus] for i in live])
    K = (ad**2 * np.array([Kp_unit, Km_unit])).tolist()
    lists = {name: a.tolist() for name, a in acc.items()}
    el_none = [mo is None for mo in motors]
    tin_none = [p is None or (p.kind == "fuel" and p.heating_value is None) for p in powers]
    is_fuel = [p is not None and p.kind == "fuel" for p in powers]
    ok = tin_ok.tolist()
    errs = err.tolist()
    reason = "energies of the periodic orbit's step (exact quadrature on Z)"
    fields = [f.name for f in dataclasses.fields(OrbitEnergy)]
    for r, i in enumerate(live):
        extra = [f"thruster {robot.thrusters[kk].name}: thrust outside its power table's "
                 "range: input energy not computed"
                 for kk in range(m) if timed and not tin_none[kk] and not ok[r][kk]]
        if not timed:
            extra.append("alpha' = 0 at a quadrature node (the walker comes to rest on the "
                         "orbit): step time, electrical, thruster input and fuel not computed")
        el = lists["el"][r]
        tin, fl = lists["tin"][r], lists["fuel"][r]
        out[i] = OrbitEnergy._of(dict(zip(fields, (
            True, reason, tuple(lists["work"][r]), tuple(lists["pos"][r]),
            tuple(lists["abs"][r]),
            tuple(None if el_none[jj] or not timed else el[jj] for jj in range(N - 1)),
            tuple(lists["tw"][r]), tuple(lists["tpos"][r]), lists["gen"][r],
            tuple(None if tin_none[kk] or not ok[r][kk] else tin[kk] for kk in range(m)),
            tuple(fl[kk] if is_fuel[kk] and timed else None for kk in range(m)),
            K[r][0], K[r][1], Vp, Vm, lists["time"][r] if timed else None,
            distance, weight, errs[r], regenerate,
            tuple(missing + extra) if extra else missing_t))))
    return out


def power_profile(zd: ZeroDynamics, schedule: Schedule, cycle, *, samples: int = 201,
                  regenerate: bool = False) -> dict | None:
    """The powers along one step of the periodic orbit ``cycle`` of the first schedule of
    ``schedule`` [W], at ``samples`` values of alpha from ``alpha_i`` to ``alpha_f`` (SPEC 15;
    the integrands of :func:`orbit_energy` in time, not in alpha): with ``alpha' = s |kappa_1|
    sqrt(2 zeta)``,

        joint j          u_j q_j' = u_j Phi_j alpha'                         (N-1 columns)
        thruster k       F_k d_k . p_k' = F_k (B_F^T Phi)_k alpha'           (m columns)
        generalised      T q_N' = T Phi_N alpha'
        joint electrical P_el(u_j, q_j') (motor), clipped at 0 unless ``regenerate``
        thruster input   P_in(F_k, V_k), V_k = sign(F_k) d_k . p_k'  (power model)

    and the time since the start of the step ``time`` [s] (trapezoid in alpha of ``1 /
    |alpha'|``: for plots; the step time itself is :func:`orbit_energy`'s). A column whose
    model is missing (or a table left) is None. None when the orbit does not exist or the
    walker comes to rest on it."""
    from .power import input_power, joint_electrical_power

    if not cycle.exists:
        return None
    model, maps = zd.model, zd.maps
    robot = model.robot
    N, m = model.n, model.n_thrusters
    sched = schedule.take(np.array([0]))
    kn = np.asarray(sched.knots, float)
    # what depends on alpha only, once per walker, knots and samples
    cache = zd.__dict__.setdefault("_profile_terms", {})
    key = (tuple(kn.tolist()), samples)
    if key not in cache:
        if len(cache) > 16:
            cache.clear()
        alpha = np.linspace(zd.alpha_i, zd.alpha_f, samples)
        frac = (alpha - kn[0]) / (kn[-1] - kn[0])
        pk = (kn - kn[0]) / (kn[-1] - kn[0])
        j = np.clip(np.searchsorted(pk, frac, side="right") - 1, 0, len(kn) - 2)
        cache[key] = (alpha, j, stance_terms(model, maps, alpha), _vz_pieces(zd, alpha, kn),
                      maps.Phi(alpha), model.B_F(maps.q_Z(alpha)))
    alpha, j, st, vz, phi, BF = cache[key]
    alpha = alpha.copy()
    F = sched.force[0, j, :]  # (g, m)
    Tg = sched.generalized[0, j]  # (g,)
    zeta = np.maximum(cycle.zeta_plus + _vz(vz, sched)[0], 0.0)
    adot = np.abs(st.AT) * np.sqrt(2.0 * zeta)  # |alpha'|
    if not np.all(adot > 0.0):
        return None
    s = zd.direction
    u = st.U0 + st.U1 * zeta[:, None] + st.UT * Tg[:, None]
    if m:
        u = u + np.einsum("gim,gm->gi", st.U2, F)
    qd = phi * (s * adot)[:, None]  # q' (g, N)
    joint = u * qd[:, :N - 1]
    bt = np.einsum("gnm,gn->gm", BF, qd)  # d_k . p_k' (g, m)
    thrust = F * bt
    inv = 1.0 / adot
    h = np.abs(np.diff(alpha))
    time = np.concatenate([[0.0], np.cumsum(0.5 * h * (inv[1:] + inv[:-1]))])
    acts = [c for c in robot.coordinates if c.actuated]
    el: list = []
    for jj, c in enumerate(acts):
        if c.motor is None:
            el.append(None)
            continue
        p = joint_electrical_power(u[:, jj], qd[:, jj], c.motor)
        el.append(p if regenerate else np.maximum(p, 0.0))
    tin: list = []
    for kk, t in enumerate(robot.thrusters):
        p = t.power
        if p is None:
            tin.append(None)
            continue
        try:
            P = input_power(p, F[:, kk], np.sign(F[:, kk]) * bt[:, kk])
        except ValueError:  # a table's range left
            P = None
        tin.append(P)
    return {"alpha": alpha, "time": time, "joint_mechanical": joint,
            "thrust_mechanical": thrust, "generalized": Tg * qd[:, N - 1],
            "joint_electrical": el, "thruster_input": tin,
            "joint_names": [c.name for c in acts], "thruster_names": list(robot.thruster_names)}
