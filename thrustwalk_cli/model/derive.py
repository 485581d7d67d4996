"""Symbolic derivation of the pinned and unpinned dynamics (SPEC section 1). Imports SymPy.

Only the compiler imports this module; a cached model never does.

Derivation strategy (see shared/PERF_NOTES.md): positions are written in absolute link
angles ``theta``; every point of link ``j`` is ``p_foot + sum_{i in path(j)} Rot(theta_i) v_ij``
with constant vectors ``v_ij``. Then, without any ``simplify``,

    D_theta[i, k] = sum_j m_j v_ij . Rot(theta_k - theta_i) v_kj + delta_ik I_i
    a . Rot(phi) b = (a . b) cos(phi) - (a x b) sin(phi)

and the relative-coordinate quantities follow from the constant map ``theta = T q``:
``D = T^T D_theta T``, ``G = T^T G_theta``. ``C`` comes from the Christoffel symbols of ``D``
in ``q`` (so ``D' - 2C`` is skew-symmetric by construction).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from ..description.robot import Robot


@dataclass
class Derivation:
    """Symbolic results. ``q``/``dq`` are the N generalised coordinates and rates;
    ``dxy`` the stance-foot velocity of the unpinned model (q_u = [q; x_1; y_1])."""

    q: list[sp.Symbol]
    dq: list[sp.Symbol]
    dxy: list[sp.Symbol]
    F: list[sp.Symbol]
    exprs: dict[str, sp.Matrix]
    #: absolute link angles theta = T q (placeholders), the pinned inertia matrix D_theta and
    #: the foot-coupling block D_theta,x in them (before substituting theta = T q), T, the
    #: total mass and g: the tape's bias terms are derived from these (tape_programs)
    theta: list[sp.Symbol] = field(default_factory=list)
    D_theta: sp.Matrix | None = None
    Dx_theta: sp.Matrix | None = None
    T: sp.Matrix | None = None
    mg: sp.Expr = sp.Integer(0)


def _rot(th: sp.Expr, v: tuple[float, float]) -> tuple[sp.Expr, sp.Expr]:
    c, s = sp.cos(th), sp.sin(th)
    return (v[0] * c - v[1] * s, v[0] * s + v[1] * c)


def _num(x: float) -> sp.Expr:
    """Exact integers stay integers; other floats become SymPy Floats (53-bit)."""
    return sp.Integer(int(x)) if float(x).is_integer() else sp.Float(x)


def derive(robot: Robot) -> Derivation:
    """Derive every symbolic quantity the numeric model needs (SPEC 1)."""
    n = robot.n
    names = robot.link_names
    q = list(sp.symbols(f"q0:{n}", real=True))
    dq = list(sp.symbols(f"dq0:{n}", real=True))
    dxy = list(sp.symbols("dx1 dy1", real=True))
    F = list(sp.symbols(f"F0:{max(len(robot.thrusters), 1)}", real=True))
    T = sp.Matrix(robot.T.astype(int).tolist())
    theta = list(T * sp.Matrix(q))
    links = {lk.name: lk for lk in robot.links}
    idx = {nm: i for i, nm in enumerate(names)}

    # Constant vectors v_ij: point of link j = foot + sum_i Rot(theta_i) v_ij.
    sf = robot.stance_foot.point

    def chain(link: str, local: tuple[float, float]) -> list[tuple[int, tuple[float, float]]]:
        """[(i, v_i)] such that the world point = foot + sum Rot(theta_i) v_i (pinned)."""
        path = robot.path_from_root(link)
        terms: dict[int, list[float]] = {}
        for a, b in zip(path[:-1], path[1:]):
            j = links[b].joint
            v = terms.setdefault(idx[a], [0.0, 0.0])
            v[0] += j[0]
            v[1] += j[1]
        v = terms.setdefault(idx[link], [0.0, 0.0])
        v[0] += local[0]
        v[1] += local[1]
        root = terms.setdefault(idx[path[0]], [0.0, 0.0])
        root[0] -= sf[0]
        root[1] -= sf[1]
        return [(i, (float(v[0]), float(v[1]))) for i, v in terms.items()]

    def point(link: str, local: tuple[float, float]) -> sp.Matrix:
        x, y = sp.Integer(0), sp.Integer(0)
        for i, v in chain(link, local):
            if v == (0.0, 0.0):
                continue
            px, py = _rot(theta[i], (_num(v[0]), _num(v[1])))
            x, y = x + px, y + py
        return sp.Matrix([x, y])

    # -- mass matrix in absolute angles (pinned block), coupling with foot translation --------
    th = list(sp.symbols(f"th0:{n}", real=True))  # placeholder absolute angles
    Dth = sp.zeros(n, n)
    Dthx = sp.zeros(n, 2)  # d(com)/d(theta_i) . e_x, e_y weighted by mass
    for lk in robot.links:
        terms = [(i, v) for i, v in chain(lk.name, lk.com) if v != (0.0, 0.0)]
        m = lk.mass
        for i, a in terms:
            # d/dtheta_i Rot(theta_i) a = Rot(theta_i) S a, S = 90 deg rotation.
            sa = (-a[1], a[0])
            rx, ry = _rot(th[i], (_num(sa[0]), _num(sa[1])))
            Dthx[i, 0] += _num(m) * rx
            Dthx[i, 1] += _num(m) * ry
            for k, b in terms:
                if k < i:
                    continue
                dot = a[0] * b[0] + a[1] * b[1]
                cross = a[0] * b[1] - a[1] * b[0]
                if i == k:
                    val = _num(m * dot)
                else:
                    phi = th[k] - th[i]
                    val = _num(m * dot) * sp.cos(phi) - _num(m * cross) * sp.sin(phi)
                Dth[i, k] += val
                if k != i:
                    Dth[k, i] += val
        Dth[idx[lk.name], idx[lk.name]] += _num(lk.inertia)
        if lk.rotor_inertia and lk.parent is not None:
            c, p = idx[lk.name], idx[lk.parent]
            J = _num(lk.rotor_inertia)
            Dth[c, c] += J
            Dth[p, p] += J
            Dth[c, p] -= J
            Dth[p, c] -= J
    sub = dict(zip(th, theta))
    D_theta, Dx_theta = Dth, Dthx
    Dth = Dth.subs(sub)
    Dthx = Dthx.subs(sub)
    D = T.T * Dth * T
    Dqx = T.T * Dthx  # n x 2 coupling block in q
    mtot = _num(robot.total_mass)
    Du = sp.zeros(n + 2, n + 2)
    Du[:n, :n] = D
    Du[:n, n:] = Dqx
    Du[n:, :n] = Dqx.T
    Du[n, n] = Du[n + 1, n + 1] = mtot

    # -- potential, gravity vector ----------------------------------------------------------
    g = _num(robot.gravity)
    com_terms = [(lk.mass, point(lk.name, lk.com)) for lk in robot.links]
    V = sum((_num(m) * g * p[1] for m, p in com_terms), sp.Integer(0))
    G = sp.Matrix([sp.diff(V, qi) for qi in q])
    Gu = sp.Matrix(list(G) + [0, mtot * g])
    com = sum((_num(m) * p for m, p in com_terms), sp.zeros(2, 1)) / mtot

    # -- Coriolis from Christoffel symbols ---------------------------------------------------
    def christoffel(M: sp.Matrix, coords: list[sp.Symbol], rates: list[sp.Symbol]) -> sp.Matrix:
        m_ = len(coords)
        dM = [M.diff(c) if c in q else sp.zeros(m_, m_) for c in coords]
        Cm = sp.zeros(m_, m_)
        for k in range(m_):
            for j in range(m_):
                acc = sp.Integer(0)
                for i in range(m_):
                    gam = (dM[i][k, j] + dM[j][k, i] - dM[k][i, j]) / 2
                    if gam != 0:
                        acc += gam * rates[i]
                Cm[k, j] = acc
        return Cm

    C = christoffel(D, q, dq)
    h = C * sp.Matrix(dq) + G
    xy = list(sp.symbols("x1 y1", real=True))
    Cu = christoffel(Du, q + xy, dq + dxy)
    hu = Cu * sp.Matrix(dq + dxy) + Gu

    # -- thrusters ---------------------------------------------------------------------------
    BF_cols, BFu_cols, tpts = [], [], []
    for t in robot.thrusters:
        p = point(t.link, t.point)
        J = p.jacobian(q)
        if t.frame == "link":
            d = sp.Matrix(_rot(theta[idx[t.link]], (_num(t.direction[0]), _num(t.direction[1]))))
        else:
            d = sp.Matrix([_num(t.direction[0]), _num(t.direction[1])])
        BF_cols.append(J.T * d)
        BFu_cols.append(sp.Matrix(list(J.T * d) + list(d)))
        tpts.append(p)
    m_t = len(robot.thrusters)
    BF = sp.Matrix.hstack(*BF_cols) if m_t else sp.zeros(n, 0)
    BFu = sp.Matrix.hstack(*BFu_cols) if m_t else sp.zeros(n + 2, 0)
    thr_dir = sp.Matrix.hstack(*[
        sp.Matrix(_rot(theta[idx[t.link]], (_num(t.direction[0]), _num(t.direction[1]))))
        if t.frame == "link" else sp.Matrix([_num(t.direction[0]), _num(t.direction[1])])
        for t in robot.thrusters
    ]) if m_t else sp.zeros(2, 0)
    thr_pts = sp.Matrix.hstack(*tpts) if m_t else sp.zeros(2, 0)

    # -- swing foot ---------------------------------------------------------------------------
    p2 = point(robot.swing_foot.link, robot.swing_foot.point)
    E2 = p2.jacobian(q)
    E2u = sp.Matrix.hstack(E2, sp.eye(2))

    # -- drawing points: each link's frame origin and end point ------------------------------
    pts = []
    for lk in robot.links:
        if lk.parent is None:
            o = point(lk.name, (0.0, 0.0))
        else:
            o = point(lk.parent, lk.joint)
        e = point(lk.name, lk.end)
        pts += [o[0], o[1], e[0], e[1]]

    exprs = {
        "D": D,
        "C": C,
        "G": G,
        "h": h,
        "V": sp.Matrix([V]),
        "B_F": BF,
        "D_u": Du,
        "h_u": hu,
        "C_u": Cu,
        "B_Fu": BFu,
        "p_swing": p2,
        "E_swing": E2,
        "E_swing_u": E2u,
        "p_com": com,
        "J_com": com.jacobian(q),
        "thruster_points": thr_pts,
        "thruster_dirs": thr_dir,
        "link_points": sp.Matrix(pts),
        "link_points_J": sp.Matrix(pts).jacobian(q),
    }
    return Derivation(q=q, dq=dq, dxy=dxy, F=F, exprs=exprs, theta=th, D_theta=D_theta,
                      Dx_theta=Dx_theta, T=T, mg=mtot * g)


def _bias_theta(der: Derivation) -> tuple[sp.Matrix, sp.Matrix]:
    """The bias terms in absolute angles, a second derivation of ``h`` (SPEC 1) for the tape.

    With ``theta = T q`` (T constant) the Lagrangian in ``q`` has ``D = T^T D_theta T``, so
    ``C q' = T^T c_theta(theta, theta')`` with ``c_theta,k = sum_ij Gamma_kij theta_i'
    theta_j'``, the Christoffel symbols of ``D_theta`` (whose entries depend on differences
    of single angles, so they are short); ``h = T^T c_theta + G`` [N m]. The foot rows of the
    unpinned bias at rest (``q_u' = [q'; 0; 0]``) are ``d/dt(D_theta,x^T) theta'``; row i of
    ``D_theta,x`` depends on ``theta_i`` alone, so they are ``sum_i dD_theta,x[i]/dtheta_i
    theta_i'^2``, plus ``(0, m g)`` [N].
    """
    n = len(der.q)
    th, T = der.theta, der.T
    dth = list(sp.symbols(f"dth0:{n}", real=True))
    Dth, Dx = der.D_theta, der.Dx_theta
    dD = [Dth.diff(a) for a in th]
    c = []
    for k in range(n):
        acc = sp.Integer(0)
        for i in range(n):
            for j in range(n):
                g = dD[i][k, j] + dD[j][k, i] - dD[k][i, j]
                if g != 0:
                    acc += g * dth[i] * dth[j] / 2
        c.append(acc)
    foot = [sum((sp.diff(Dx[i, r], th[i]) * dth[i] ** 2 for i in range(n)), sp.Integer(0))
            for r in range(2)]
    sub = dict(zip(th, list(T * sp.Matrix(der.q))))
    sub.update(zip(dth, list(T * sp.Matrix(der.dq))))
    h = T.T * sp.Matrix(c).subs(sub) + der.exprs["G"]
    ground = sp.Matrix([foot[0].subs(sub), foot[1].subs(sub) + der.mg])
    return h, ground


def tape_programs(der: Derivation) -> dict[str, tuple[int, list[sp.Expr]]]:
    """The expressions of every tape program (the table of :mod:`thrustwalk_cli.model.tape`):
    name -> (number of inputs read, flat row-major outputs). Inputs are ``q`` then ``q'``.
    The bias ``h`` and the ground-force bias rows come from :func:`_bias_theta` (shorter
    than the Christoffel sums in ``q`` of the generated functions; the tests compare the
    two)."""
    n = len(der.q)
    e = der.exprs
    flat = lambda M: list(M) if M.shape[0] * M.shape[1] else []  # noqa: E731
    h, h_foot = _bias_theta(der)
    accel = flat(e["D"]) + flat(h) + flat(e["B_F"])
    ground = flat(e["D_u"][n:n + 2, :n]) + flat(h_foot) + flat(e["B_Fu"][n:n + 2, :])
    foot_vy = sum((e["E_swing"][1, j] * der.dq[j] for j in range(n)), sp.Integer(0))
    return {
        "accel": (2 * n, accel),
        "force": (2 * n, accel + ground),
        "height": (n, flat(e["p_swing"])),
        "footvel": (2 * n, [foot_vy]),
        "links": (n, flat(e["link_points"])),
        "impact": (n, flat(e["D_u"]) + flat(e["E_swing_u"])),
        "energy": (n, flat(e["D"]) + flat(e["V"])),
        "push": (n, flat(e["D"]) + flat(e["link_points_J"])),
    }
