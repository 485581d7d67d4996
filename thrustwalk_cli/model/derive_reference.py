"""The reference derivation of the dynamics (SPEC 1; the derivation before issue 26): every
quantity in ``q`` by SymPy, ``C`` and ``C_u`` from the Christoffel symbols of ``D`` and ``D_u``
(cost N^4 to N^5), and its tape programs with the bias terms in absolute angles
(:func:`bias_theta`). What :func:`thrustwalk_cli.model.compiler.folded_model` compiles, the
reference the tests compare :func:`.derive.derive` with. Imports SymPy; only the compiler
imports it.
"""

from __future__ import annotations

import sympy as sp

from ..description.robot import Robot
from .derive import Derivation, Folder, Numbers, is_zero, rot


def derive_reference(robot: Robot, folded: bool = False) -> Derivation:
    """The reference derivation (the one before issue 26): every quantity in ``q`` by
    SymPy, ``C`` and ``C_u`` from the Christoffel symbols of ``D`` and ``D_u`` in ``q``
    (SPEC 1), the tape's bias terms by :func:`bias_theta`. The robot's nonzero numbers are
    the symbols of :class:`Numbers`, or the numbers themselves when ``folded`` (what
    :func:`thrustwalk_cli.model.compiler.folded_model` compiles: the reference the tests
    compare :func:`derive` with). Its cost grows as N^4 to N^5 (16 links: minutes)."""
    n = robot.n
    names = robot.link_names
    num = Numbers(robot, folded)
    fold = Folder(num.inputs)
    q = list(sp.symbols(f"q0:{n}", real=True))
    dq = list(sp.symbols(f"dq0:{n}", real=True))
    dxy = list(sp.symbols("dx1 dy1", real=True))
    F = list(sp.symbols(f"F0:{max(len(robot.thrusters), 1)}", real=True))
    T = sp.Matrix(robot.T.astype(int).tolist())
    theta = list(T * sp.Matrix(q))
    idx = {nm: i for i, nm in enumerate(names)}

    # Constant vectors v_ij: point of link j = foot + sum_i Rot(theta_i) v_ij.
    sf = num.vec("feet.stance")

    def chain(link: str, local: tuple[sp.Expr, sp.Expr]) -> list[tuple[int, tuple]]:
        """[(i, v_i)] such that the world point = foot + sum Rot(theta_i) v_i (pinned)."""
        path = robot.path_from_root(link)
        terms: dict[int, list[sp.Expr]] = {}
        for a, b in zip(path[:-1], path[1:]):
            j = num.vec(f"links.{b}.joint")
            v = terms.setdefault(idx[a], [sp.Integer(0), sp.Integer(0)])
            v[0] += j[0]
            v[1] += j[1]
        v = terms.setdefault(idx[link], [sp.Integer(0), sp.Integer(0)])
        v[0] += local[0]
        v[1] += local[1]
        root = terms.setdefault(idx[path[0]], [sp.Integer(0), sp.Integer(0)])
        root[0] -= sf[0]
        root[1] -= sf[1]
        return [(i, (v[0], v[1])) for i, v in terms.items()]

    def point(link: str, local: tuple[sp.Expr, sp.Expr]) -> sp.Matrix:
        x, y = sp.Integer(0), sp.Integer(0)
        for i, v in chain(link, local):
            if is_zero(v):
                continue
            px, py = rot(theta[i], v)
            x, y = x + px, y + py
        return fold.matrix(sp.Matrix([x, y]))

    # -- mass matrix in absolute angles (pinned block), coupling with foot translation --------
    th = list(sp.symbols(f"th0:{n}", real=True))  # placeholder absolute angles
    Dth = sp.zeros(n, n)
    Dthx = sp.zeros(n, 2)  # d(com)/d(theta_i) . e_x, e_y weighted by mass
    for lk in robot.links:
        pre = f"links.{lk.name}"
        terms = [(i, v) for i, v in chain(lk.name, num.vec(pre + ".com")) if not is_zero(v)]
        m = num(pre + ".mass")
        for i, a in terms:
            # d/dtheta_i Rot(theta_i) a = Rot(theta_i) S a, S = 90 deg rotation.
            rx, ry = rot(th[i], (-a[1], a[0]))
            Dthx[i, 0] += m * rx
            Dthx[i, 1] += m * ry
            for k, b in terms:
                if k < i:
                    continue
                dot = sp.expand(m * (a[0] * b[0] + a[1] * b[1]))
                cross = sp.expand(m * (a[0] * b[1] - a[1] * b[0]))
                if i == k:
                    val = dot
                else:
                    phi = th[k] - th[i]
                    val = dot * sp.cos(phi) - cross * sp.sin(phi)
                Dth[i, k] += val
                if k != i:
                    Dth[k, i] += val
        Dth[idx[lk.name], idx[lk.name]] += num(pre + ".inertia")
        J = num(pre + ".rotor_inertia")
        if J != 0 and lk.parent is not None:
            c, p = idx[lk.name], idx[lk.parent]
            Dth[c, c] += J
            Dth[p, p] += J
            Dth[c, p] -= J
            Dth[p, c] -= J
    Dth, Dthx = fold.matrix(Dth), fold.matrix(Dthx)
    sub = dict(zip(th, theta))
    D_theta, Dx_theta = Dth, Dthx
    Dth = Dth.subs(sub)
    Dthx = Dthx.subs(sub)
    D = fold.matrix(T.T * Dth * T)
    Dqx = fold.matrix(T.T * Dthx)  # n x 2 coupling block in q
    mtot = num("total_mass")
    Du = sp.zeros(n + 2, n + 2)
    Du[:n, :n] = D
    Du[:n, n:] = Dqx
    Du[n:, :n] = Dqx.T
    Du[n, n] = Du[n + 1, n + 1] = mtot

    # -- potential, gravity vector ----------------------------------------------------------
    g = num("gravity")
    com_terms = [(num(f"links.{lk.name}.mass"), point(lk.name, num.vec(f"links.{lk.name}.com")))
                 for lk in robot.links]
    V = fold(sum((m * g * p[1] for m, p in com_terms), sp.Integer(0)))
    G = fold.matrix(sp.Matrix([sp.diff(V, qi) for qi in q]))
    Gu = sp.Matrix(list(G) + [0, mtot * g])
    com = fold.matrix(sum((m * p for m, p in com_terms), sp.zeros(2, 1)) / mtot)

    # -- Coriolis from Christoffel symbols ---------------------------------------------------
    def christoffel(M: sp.Matrix, coords: list[sp.Symbol], rates: list[sp.Symbol]) -> sp.Matrix:
        m_ = len(coords)
        dM = [fold.matrix(M.diff(c)) if c in q else sp.zeros(m_, m_) for c in coords]
        Cm = sp.zeros(m_, m_)
        for k in range(m_):
            for j in range(m_):
                acc = sp.Integer(0)
                for i in range(m_):
                    gam = fold((dM[i][k, j] + dM[j][k, i] - dM[k][i, j]) / 2)
                    if gam != 0:
                        acc += gam * rates[i]
                Cm[k, j] = acc
        return Cm

    C = christoffel(D, q, dq)
    h = fold.matrix(C * sp.Matrix(dq) + G)
    xy = list(sp.symbols("x1 y1", real=True))
    Cu = christoffel(Du, q + xy, dq + dxy)
    hu = fold.matrix(Cu * sp.Matrix(dq + dxy) + Gu)

    # -- thrusters ---------------------------------------------------------------------------
    def direction(t) -> sp.Matrix:
        d = num.vec(f"thrusters.{t.name}.direction")
        if t.frame == "link":
            return fold.matrix(sp.Matrix(rot(theta[idx[t.link]], d)))
        return sp.Matrix(d)

    BF_cols, BFu_cols, tpts = [], [], []
    for t in robot.thrusters:
        p = point(t.link, num.vec(f"thrusters.{t.name}.point"))
        J = p.jacobian(q)
        d = direction(t)
        BF_cols.append(fold.matrix(J.T * d))
        BFu_cols.append(fold.matrix(sp.Matrix(list(J.T * d) + list(d))))
        tpts.append(p)
    m_t = len(robot.thrusters)
    BF = sp.Matrix.hstack(*BF_cols) if m_t else sp.zeros(n, 0)
    BFu = sp.Matrix.hstack(*BFu_cols) if m_t else sp.zeros(n + 2, 0)
    thr_dir = sp.Matrix.hstack(*[direction(t) for t in robot.thrusters]) if m_t else \
        sp.zeros(2, 0)
    thr_pts = sp.Matrix.hstack(*tpts) if m_t else sp.zeros(2, 0)

    # -- swing foot ---------------------------------------------------------------------------
    p2 = point(robot.swing_foot.link, num.vec("feet.swing"))
    E2 = p2.jacobian(q)
    E2u = sp.Matrix.hstack(E2, sp.eye(2))

    # -- drawing points: each link's frame origin and end point ------------------------------
    pts = []
    for lk in robot.links:
        if lk.parent is None:
            o = point(lk.name, (sp.Integer(0), sp.Integer(0)))
        else:
            o = point(lk.parent, num.vec(f"links.{lk.name}.joint"))
        e = point(lk.name, num.vec(f"links.{lk.name}.end"))
        pts += [o[0], o[1], e[0], e[1]]

    exprs = {
        "D": D,
        "C": fold.matrix(C),
        "G": G,
        "h": h,
        "V": sp.Matrix([V]),
        "B_F": BF,
        "D_u": Du,
        "h_u": hu,
        "C_u": fold.matrix(Cu),
        "B_Fu": BFu,
        "p_swing": p2,
        "E_swing": fold.matrix(E2),
        "E_swing_u": fold.matrix(E2u),
        "p_com": com,
        "J_com": fold.matrix(com.jacobian(q)),
        "thruster_points": thr_pts,
        "thruster_dirs": thr_dir,
        "link_points": sp.Matrix(pts),
        "link_points_J": fold.matrix(sp.Matrix(pts).jacobian(q)),
    }
    return Derivation(q=q, dq=dq, dxy=dxy, F=F, exprs=exprs, theta=th, D_theta=D_theta,
                      Dx_theta=Dx_theta, T=T, mg=mtot * g, numbers=num, fold=fold)


def bias_theta(der: Derivation) -> tuple[sp.Matrix, sp.Matrix]:
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
    fold = der.fold or Folder(set())
    dD = [fold.matrix(Dth.diff(a)) for a in th]
    c = []
    for k in range(n):
        acc = sp.Integer(0)
        for i in range(n):
            for j in range(n):
                g = fold(dD[i][k, j] + dD[j][k, i] - dD[k][i, j])
                if g != 0:
                    acc += g * dth[i] * dth[j] / 2
        c.append(fold(acc))
    foot = [fold(sum((sp.diff(Dx[i, r], th[i]) * dth[i] ** 2 for i in range(n)),
                     sp.Integer(0))) for r in range(2)]
    sub = dict(zip(th, list(T * sp.Matrix(der.q))))
    sub.update(zip(dth, list(T * sp.Matrix(der.dq))))
    h = fold.matrix(T.T * sp.Matrix(c).subs(sub) + der.exprs["G"])
    ground = fold.matrix(sp.Matrix([foot[0].subs(sub), foot[1].subs(sub) + der.mg]))
    return h, ground


def reference_programs(der: Derivation) -> dict[str, tuple[int, list[sp.Expr]]]:
    """The expressions of every tape program (the table of :mod:`thrustwalk_cli.model.tape`):
    name -> (number of inputs read, flat row-major outputs). Inputs are ``q`` then ``q'``.
    The bias ``h`` and the ground-force bias rows come from :func:`bias_theta` (shorter
    than the Christoffel sums in ``q`` of the generated functions; the tests compare the
    two)."""
    n = len(der.q)
    e = der.exprs
    flat = lambda M: list(M) if M.shape[0] * M.shape[1] else []  # noqa: E731
    h, h_foot = bias_theta(der)
    accel = flat(e["D"]) + flat(h) + flat(e["B_F"])
    ground = flat(e["D_u"][n:n + 2, :n]) + flat(h_foot) + flat(e["B_Fu"][n:n + 2, :])
    foot_vy = (der.fold or Folder(set()))(
        sum((e["E_swing"][1, j] * der.dq[j] for j in range(n)), sp.Integer(0)))
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


def tape_programs(der: Derivation) -> dict[str, tuple[int, list[sp.Expr]]]:
    """The expressions of every tape program (the table of :mod:`thrustwalk_cli.model.tape`):
    name -> (number of inputs read, flat row-major outputs; inputs ``q`` then ``q'``). For
    :func:`derive` they are expressions in its definitions (``Derivation.defs``)."""
    if der.programs is not None:
        return der.programs
    return reference_programs(der)
