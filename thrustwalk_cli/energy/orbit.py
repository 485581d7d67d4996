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
(sign changes on a grid 4 times finer than the nodes, polished by Newton's method) split the
interval, and the interpolant's antiderivative is evaluated at the roots. Two roots closer
than the fine grid's spacing (about ``1/(4 n)`` of the interval) are not separated; their
piece is of that size.

Joint electrical power with a motor: ``P_m / eta_g`` (or ``P_m eta_g`` when negative) plus
``R (u / (G k_t))^2`` (:mod:`.power`); negative electrical power is not recovered (clipped at
0 per joint) unless ``regenerate``. Thrust input power from the thruster's model with the axial
air speed ``V_k = sign(F_k) d_k . p_k'`` through the disk (momentum model).

Cost of transport ``CoT = E / (m g d)`` (``d`` the step length along the ground):
mechanical = (joints' positive work + thrusters' positive work on the walker) / (m g d), total =
(joints' electrical energy + thrusters' input energy) / (m g d), each split into legs and
thrust. A part whose model is missing is None with a reason, never 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.polynomial import chebyshev as C

from ..contact.terms import stance_terms
from ..hzd.quadrature import _cc_weights, _dct_matrix, lobatto
from ..hzd.zero_dynamics import LimitCycle, ZeroDynamics
from ..thrust.schedule import Schedule
from .power import input_power, joint_electrical_power, joule_power

RTOL = 1e-10
MAX_NODES = 1025
FINE = 4  # fine-grid points per node for locating kinks


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
        return float(sum(self.joint_positive_work)) if self.exists else None

    @property
    def thrust_mechanical(self) -> float | None:
        return float(sum(self.thrust_positive_work)) if self.exists else None

    @property
    def legs_electrical(self) -> float | None:
        vals = self.joint_electrical
        return None if not self.exists or any(v is None for v in vals) else float(sum(vals))

    @property
    def thrust_input(self) -> float | None:
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
            return None if e is None else e / T

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
def _fine_matrix(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The fine grid ``x`` (``FINE (n - 1) + 1`` Lobatto points of [-1, 1]) and ``T_k(x)``
    for ``k < n``."""
    M = FINE * (n - 1) + 1
    x = -np.cos(np.pi * np.arange(M) / (M - 1))
    return x, np.cos(np.arccos(x)[:, None] * np.arange(n))


def _abs_and_positive(values: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """``int |f|`` and ``int max(0, f)`` over an interval of half-length ``half`` for rows of
    samples ``values`` (P, n) at ascending Lobatto nodes, piecewise between the roots of each
    row's Chebyshev interpolant (module docstring): with ``F`` its antiderivative (``F(-1) =
    0``), ``s_0`` its sign at the start and ``r_1 < ... < r_p`` its roots,
    ``int |f| = s_0 (sum_i 2 (-1)^(i-1) F(r_i) + (-1)^p F(1))``."""
    P, n = values.shape
    if P == 0:
        return np.zeros(0), np.zeros(0)
    coef = values @ _dct_matrix(n).T  # (P, n) Chebyshev coefficients
    anti = C.chebint(coef, axis=1, lbnd=-1.0)  # (P, n+1)
    der = C.chebder(coef, axis=1)  # (P, n-1)
    xg, Tg = _fine_matrix(n)
    fg = coef @ Tg.T  # (P, M)
    pos = fg >= 0.0
    F1 = anti.sum(axis=1)  # F(1): T_k(1) = 1
    s0 = np.where(pos[:, 0], 1.0, -1.0)
    total_abs = s0 * F1  # no root
    rows, seg = np.nonzero(pos[:, 1:] != pos[:, :-1])
    if rows.size:
        a, b = xg[seg], xg[seg + 1]
        fa, fb = fg[rows, seg], fg[rows, seg + 1]
        x = a - fa * (b - a) / (fb - fa)  # secant start between the fine points
        cr, dr = coef[rows], der[rows]
        for _ in range(3):
            K = np.cos(np.arccos(np.clip(x, -1.0, 1.0))[:, None] * np.arange(n))
            f = np.einsum("rk,rk->r", K, cr)
            d = np.einsum("rk,rk->r", K[:, :n - 1], dr)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(d != 0, f / d, 0.0)
            x = np.clip(x - np.nan_to_num(step), a, b)
        K = np.cos(np.arccos(np.clip(x, -1.0, 1.0))[:, None] * np.arange(n + 1))
        Fr = np.einsum("rk,rk->r", K, anti[rows])
        rank = np.arange(rows.size) - np.searchsorted(rows, rows, side="left")
        count = np.bincount(rows, minlength=P)
        inner = np.zeros(P)
        np.add.at(inner, rows, 2.0 * np.where(rank % 2 == 0, 1.0, -1.0) * Fr)
        total_abs = s0 * (inner + np.where(count % 2 == 0, 1.0, -1.0) * F1)
    return total_abs * half, 0.5 * (total_abs + F1) * half


def orbit_energy(zd: ZeroDynamics, schedule: Schedule, cycles, *, regenerate: bool = False
                 ) -> list[OrbitEnergy]:
    """The step energies of each schedule's periodic orbit (``cycles[i]`` its
    :class:`LimitCycle`), exactly by quadrature on Z (module docstring, SPEC 15)."""
    model, maps = zd.model, zd.maps
    robot = model.robot
    N, m = model.n, model.n_thrusters
    acts = [c for c in robot.coordinates if c.actuated]
    motors = [c.motor for c in acts]
    powers = [t.power for t in robot.thrusters]
    missing = []
    if any(mo is None for mo in motors):
        names = [c.name for c, mo in zip(acts, motors) if mo is None]
        missing.append(f"no motor data for {', '.join(names)}: joint electrical energy not "
                       "computed (a `motor:` per actuated coordinate in the robot file)")
    for t, p in zip(robot.thrusters, powers):
        if p is None:
            missing.append(f"no power model for thruster {t.name}: its input energy not "
                           "computed (a `power:` in the robot file)")
        elif p.kind == "fuel" and p.heating_value is None:
            missing.append(f"thruster {t.name}: a fuel model without `heating_value`: fuel "
                           "mass only, input energy not computed")
    live = [i for i, lc in enumerate(cycles) if lc.exists]
    out: list[OrbitEnergy] = [OrbitEnergy(False, f"no periodic orbit: {lc.reason}")
                              for lc in cycles]
    if not live:
        return out
    sched = schedule.take(np.array(live))
    k = len(live)
    zp = np.array([cycles[i].zeta_plus for i in live])
    s = zd.direction
    kn = np.asarray(sched.knots, float)
    acc = {name: np.zeros((k,) + shape) for name, shape in (
        ("work", (N - 1,)), ("abs", (N - 1,)), ("pos", (N - 1,)), ("el", (N - 1,)),
        ("tw", (m,)), ("tpos", (m,)), ("gen", ()), ("tin", (m,)), ("fuel", (m,)),
        ("time", ()))}
    err = np.zeros(k)
    tin_ok = np.ones((k, m), bool)
    for j in range(len(kn) - 1):
        lo, hi = sorted((kn[j], kn[j + 1]))
        if hi <= lo:
            continue
        half = 0.5 * (hi - lo)
        F = sched.force[:, j, :]  # (k, m)
        Tg = sched.generalized[:, j]  # (k,)
        n = 33
        while True:
            alpha = lobatto(lo, hi, n)
            st = stance_terms(model, maps, alpha)
            zeta = zp[:, None] + zd.V_Z(alpha, sched)  # (k, g)
            zeta = np.maximum(zeta, 0.0)
            u = (st.U0[None] + st.U1[None] * zeta[..., None]
                 + np.einsum("gjm,km->kgj", st.U2, F) + st.UT[None] * Tg[:, None, None])
            phi = maps.Phi(alpha)  # (g, N)
            BFphi = np.einsum("gnm,gn->gm", model.B_F(maps.q_Z(alpha)), phi)  # (g, m)
            k1 = np.abs(st.AT)  # AT = 1 / (e_N^T D Phi) = kappa_1
            adot = k1[None] * np.sqrt(2.0 * zeta)  # |alpha'| (k, g)
            with np.errstate(divide="ignore"):
                inv = 1.0 / adot
            pj = s * u * phi[None, :, :N - 1]  # (k, g, N-1) joint power per |d alpha|
            pt = s * F[:, None, :] * BFphi[None]  # (k, g, m)
            pg = s * Tg[:, None] * phi[None, :, N - 1]
            w = _cc_weights(n) * half
            wc = _cc_weights((n - 1) // 2 + 1) * half

            def quad(v, w=w, wc=wc):
                fine = np.einsum("kg...,g->k...", v, w)
                coarse = np.einsum("kg...,g->k...", v[:, ::2], wc)
                return fine, np.abs(fine - coarse)
            smooth = [quad(pj), quad(pt), quad(pg[..., None])]
            finite = np.all(np.isfinite(inv))
            if finite:
                smooth.append(quad(inv[..., None]))
            e = np.zeros(k)
            for _, er in smooth:
                if er.size:  # a robot without thrusters has no thrust terms
                    e = np.maximum(e, er.reshape(k, -1).max(axis=1))
            scale = max(float(np.max(np.abs(smooth[0][0]))), 1e-300)
            if np.all(e <= RTOL * scale) or n >= MAX_NODES:
                break
            n = 2 * n - 1
        err += e
        acc["work"] += smooth[0][0]
        acc["tw"] += smooth[1][0]
        acc["gen"] += smooth[2][0][:, 0]
        ab, po = _abs_and_positive(pj.transpose(0, 2, 1).reshape(-1, n), half)
        acc["abs"] += ab.reshape(k, N - 1)
        acc["pos"] += po.reshape(k, N - 1)
        _, po = _abs_and_positive(pt.transpose(0, 2, 1).reshape(-1, n), half)
        acc["tpos"] += po.reshape(k, m)
        if not finite:
            tin_ok[:] = False
            continue
        acc["time"] += quad(inv[..., None])[0][:, 0]
        qdot = phi[None] * (s * adot)[..., None]  # (k, g, N)
        for jj, mo in enumerate(motors):
            if mo is None:
                continue
            pe = joint_electrical_power(u[..., jj], qdot[..., jj], mo) if mo.efficiency != 1 \
                else u[..., jj] * qdot[..., jj] + joule_power(u[..., jj], mo)
            pe = pe * inv  # per |d alpha|
            if regenerate:
                acc["el"][:, jj] += quad(pe)[0]
            else:
                acc["el"][:, jj] += _abs_and_positive(pe, half)[1]
        for kk, p in enumerate(powers):
            if p is None:
                continue
            V = np.sign(F[:, kk])[:, None] * BFphi[None, :, kk] * (s * adot)
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
    weight = robot.weight
    for r, i in enumerate(live):
        lc: LimitCycle = cycles[i]
        ins: list[float | None] = []
        fuel: list[float | None] = []
        extra = []
        for kk, p in enumerate(powers):
            fuel.append(float(acc["fuel"][r, kk]) if p is not None and p.kind == "fuel"
                        else None)
            if p is None or (p.kind == "fuel" and p.heating_value is None):
                ins.append(None)
            elif not tin_ok[r, kk]:
                ins.append(None)
                extra.append(f"thruster {robot.thrusters[kk].name}: thrust outside its power "
                             "table's range: input energy not computed")
            else:
                ins.append(float(acc["tin"][r, kk]))
        out[i] = OrbitEnergy(
            True, "energies of the periodic orbit's step (exact quadrature on Z)",
            tuple(map(float, acc["work"][r])), tuple(map(float, acc["pos"][r])),
            tuple(map(float, acc["abs"][r])),
            tuple(None if mo is None else float(acc["el"][r, jj])
                  for jj, mo in enumerate(motors)),
            tuple(map(float, acc["tw"][r])), tuple(map(float, acc["tpos"][r])),
            float(acc["gen"][r]), tuple(ins), tuple(fuel),
            kinetic_start=float(Kp_unit * lc.alpha_dot_plus ** 2),
            kinetic_end=float(Km_unit * lc.alpha_dot_minus ** 2),
            potential_start=Vp, potential_end=Vm, step_time=float(acc["time"][r]),
            distance=zd.step_length, weight=weight, error_estimate=float(err[r]),
            regenerate=regenerate, missing=tuple(missing + extra))
    return out
