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

The robot's numbers (masses, lengths, inertias, gravity: ``Robot.numbers()``) are symbols
``P<i>``, so one compiled model serves every value of them (they are its inputs; zeros are
folded in and belong to the robot's structure). Sums are collected as if those symbols
were numbers (:class:`Folder`), so the code is as short as with the numbers substituted.
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
    #: the robot's numbers as symbols (or folded) and the term collector used on every result
    numbers: Numbers | None = None
    fold: Folder | None = None


def _rot(th: sp.Expr, v: tuple[sp.Expr, sp.Expr]) -> tuple[sp.Expr, sp.Expr]:
    c, s = sp.cos(th), sp.sin(th)
    return (v[0] * c - v[1] * s, v[0] * s + v[1] * c)


def _num(x: float) -> sp.Expr:
    """Exact integers stay integers; other floats become SymPy Floats (53-bit)."""
    return sp.Integer(int(x)) if float(x).is_integer() else sp.Float(x)


class Numbers:
    """The robot's physical numbers (:meth:`Robot.numbers`) as SymPy terms: a zero is the
    integer 0 (folded into the code); any other number is the symbol ``P<i>`` (``i`` its
    position in ``Robot.numbers()``: an input of the compiled model), or, when ``folded``,
    the number itself (a model with the numbers substituted, for comparisons)."""

    def __init__(self, robot: Robot, folded: bool = False):
        self.items = robot.numbers()
        self.index = {name: i for i, (name, _) in enumerate(self.items)}
        self.folded = folded
        self.symbols = [sp.Symbol(f"P{i}", real=True) for i in range(len(self.items))]

    def __call__(self, name: str) -> sp.Expr:
        i = self.index[name]
        v = self.items[i][1]
        if v == 0.0:
            return sp.Integer(0)
        return _num(v) if self.folded else self.symbols[i]

    def vec(self, name: str) -> tuple[sp.Expr, sp.Expr]:
        return (self(name + ".x"), self(name + ".y"))

    @property
    def inputs(self) -> set[sp.Symbol]:
        """The symbols that stand for numbers (empty when folded)."""
        return set() if self.folded else set(self.symbols)


def _is_zero(v: tuple[sp.Expr, sp.Expr]) -> bool:
    return v[0] == 0 and v[1] == 0


class Folder:
    """Collect terms as SymPy collects numeric coefficients, treating expressions in the
    robot's number symbols alone as coefficients: ``a cos(x) + b cos(x)`` becomes
    ``(a + b) cos(x)`` and a coefficient times a sum is distributed over it (as SymPy does
    for a number). With the numbers folded this changes nothing; with numbers as inputs it
    keeps the expressions (and the code) as short as with the numbers substituted."""

    def __init__(self, inputs: set[sp.Symbol]):
        self.P = inputs
        self.memo: dict[sp.Expr, sp.Expr] = {}

    def coefficient(self, e: sp.Expr) -> bool:
        return e.free_symbols <= self.P

    def split(self, term: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
        """``term`` = coefficient * monomial."""
        if self.coefficient(term):
            return term, sp.Integer(1)
        if term.is_Mul:
            c = [a for a in term.args if self.coefficient(a)]
            r = [a for a in term.args if not self.coefficient(a)]
            return sp.Mul(*c), sp.Mul(*r)
        return sp.Integer(1), term

    def __call__(self, e: sp.Expr) -> sp.Expr:
        if not self.P:
            return e
        r = self.memo.get(e)
        if r is None:
            r = self._fold(e)
            self.memo[e] = r
        return r

    def _fold(self, e: sp.Expr) -> sp.Expr:
        if e.is_Atom or self.coefficient(e):
            return e
        if e.is_Add:
            groups: dict[sp.Expr, list[sp.Expr]] = {}
            for a in e.args:
                for t in sp.Add.make_args(self(a)):
                    c, m = self.split(t)
                    groups.setdefault(m, []).append(c)
            return sp.Add(*(sp.Add(*cs) * m for m, cs in groups.items()))
        if e.is_Mul:
            args = [self(a) for a in e.args]
            c = sp.Mul(*[a for a in args if self.coefficient(a)])
            rest = sp.Mul(*[a for a in args if not self.coefficient(a)])
            if rest.is_Add and c != 1:
                return self(sp.Add(*(c * t for t in rest.args), evaluate=False))
            return c * rest
        return e.func(*[self(a) for a in e.args])

    def matrix(self, M: sp.Matrix) -> sp.Matrix:
        return M.applyfunc(self) if self.P else M


def derive(robot: Robot, folded: bool = False) -> Derivation:
    """Derive every symbolic quantity the numeric model needs (SPEC 1). The robot's nonzero
    numbers are the symbols of :class:`Numbers` (the inputs of the compiled model), or the
    numbers themselves when ``folded``."""
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
            if _is_zero(v):
                continue
            px, py = _rot(theta[i], v)
            x, y = x + px, y + py
        return fold.matrix(sp.Matrix([x, y]))

    # -- mass matrix in absolute angles (pinned block), coupling with foot translation --------
    th = list(sp.symbols(f"th0:{n}", real=True))  # placeholder absolute angles
    Dth = sp.zeros(n, n)
    Dthx = sp.zeros(n, 2)  # d(com)/d(theta_i) . e_x, e_y weighted by mass
    for lk in robot.links:
        pre = f"links.{lk.name}"
        terms = [(i, v) for i, v in chain(lk.name, num.vec(pre + ".com")) if not _is_zero(v)]
        m = num(pre + ".mass")
        for i, a in terms:
            # d/dtheta_i Rot(theta_i) a = Rot(theta_i) S a, S = 90 deg rotation.
            rx, ry = _rot(th[i], (-a[1], a[0]))
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
            return fold.matrix(sp.Matrix(_rot(theta[idx[t.link]], d)))
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
