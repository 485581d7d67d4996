"""Symbolic derivation of the pinned and unpinned dynamics (SPEC section 1). Imports SymPy.

Only the compiler imports this module; a cached model never does.

Derivation strategy (see shared/PERF_NOTES.md): positions are written in absolute link
angles ``theta``; every point of link ``j`` is ``p_foot + sum_{i in path(j)} Rot(theta_i) v_ij``
with constant vectors ``v_ij``. Then, without any ``simplify``,

    D_theta[i, k] = sum_j m_j v_ij . Rot(theta_k - theta_i) v_kj + delta_ik I_i
    a . Rot(phi) b = (a . b) cos(phi) - (a x b) sin(phi)

and the relative-coordinate quantities follow from the constant map ``theta = T q``:
``D = T^T D_theta T``, ``G = T^T G_theta``. :func:`derive` (what the compiler uses) takes the
Coriolis terms in closed form, ``C_theta = W diag(theta')`` with ``W = dD_theta/dtheta``
entrywise (the Christoffel symbols of ``D_theta``, so ``D' - 2C`` is skew-symmetric), and
returns its results as sums of short definitions (cost about N^3, no simplification, no
``cse``). The derivation before issue 26 (:mod:`.derive_reference`) takes ``C`` from the
Christoffel symbols of ``D`` in ``q`` by SymPy (cost N^4 to N^5); the tests compare the two.

The robot's numbers (masses, lengths, inertias, gravity: ``Robot.numbers()``) are symbols
``P<i>``, so one compiled model serves every value of them (they are its inputs; zeros are
folded in and belong to the robot's structure). :func:`derive` hoists every coefficient in
them as it is made (:class:`Hoist`); the reference derivation collects sums as if those
symbols were numbers (:class:`Folder`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import sympy as sp

from ..description.robot import Robot
from .codegen import Hoist


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
    #: :func:`derive` only: the definitions (symbol -> expression, in order: each reads
    #: inputs, coefficients and earlier definitions) that ``exprs`` and ``programs`` are
    #: written in; the tape programs; the coefficients of the robot's numbers (``k<j>``)
    defs: dict[sp.Symbol, sp.Expr] = field(default_factory=dict)
    programs: dict[str, tuple[int, list[sp.Expr]]] | None = None
    hoist: Hoist | None = None


def rot(th: sp.Expr, v: tuple[sp.Expr, sp.Expr]) -> tuple[sp.Expr, sp.Expr]:
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


def is_zero(v: tuple[sp.Expr, sp.Expr]) -> bool:
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


class _Staged:
    """Definitions for :func:`derive`: ``define`` binds an expression to a new symbol (a
    temporary of the generated code and a register of the tape), ``coef`` turns an
    expression in the robot's numbers into a coefficient (:class:`Hoist`: computed once
    per set of numbers), ``sincos`` gives the sine and cosine of an integer combination of
    the coordinates (each combination defined once)."""

    def __init__(self, q: list[sp.Symbol], hoist: Hoist):
        self.q = q
        self.hoist = hoist
        self.defs: dict[sp.Symbol, sp.Expr] = {}
        self.trig: dict[tuple, tuple[sp.Expr, sp.Expr]] = {}
        self.angles: dict[tuple, sp.Expr] = {}

    def define(self, name: str, e: sp.Expr) -> sp.Expr:
        if e.is_Atom:
            return e
        s = sp.Symbol(name, real=True)
        self.defs[s] = e
        return s

    def coef(self, e: sp.Expr) -> sp.Expr:
        """A coefficient as such (a number, or one hoisted symbol even when negative: a
        product is then one multiplication, no negation)."""
        return e if e.is_Number else self.hoist(e)

    def sincos(self, row) -> tuple[sp.Expr, sp.Expr]:
        """``(sin a, cos a)`` of ``a = sum_j row[j] q_j`` (integer ``row``)."""
        combo = tuple((j, int(c)) for j, c in enumerate(row) if c)
        if not combo:
            return sp.Integer(0), sp.Integer(1)
        sign = 1
        if combo[0][1] < 0:
            combo, sign = tuple((j, -c) for j, c in combo), -1
        r = self.trig.get(combo)
        if r is None:
            a = self.angle(combo)
            i = len(self.trig)
            r = (self.define(f"zs{i}", sp.sin(a)), self.define(f"zc{i}", sp.cos(a)))
            self.trig[combo] = r
        return sign * r[0], r[1]

    def angle(self, combo: tuple) -> sp.Expr:
        """``sum c q_j`` over ``combo`` = ((j, c), ...): a definition (shared by the sine and
        the cosine), built on the one of ``combo[:-1]``."""
        if len(combo) == 1 and combo[0][1] == 1:
            return self.q[combo[0][0]]
        r = self.angles.get(combo)
        if r is None:
            j, c = combo[-1]
            head = self.angle(combo[:-1]) if len(combo) > 1 else sp.Integer(0)
            r = self.define(f"za{len(self.angles)}", head + c * self.q[j])
            self.angles[combo] = r
        return r


def derive(robot: Robot, folded: bool = False,
           progress: Callable[[str], None] | None = None) -> Derivation:
    """Derive every quantity of the numeric model (SPEC 1) in absolute link angles
    ``theta = T q`` and map them to ``q`` by the constant integer matrix ``T``.

    With ``v_ij`` the constant vectors of the reference derivation (a point of link ``j`` is
    ``foot + sum_i Rot(theta_i) v_ij``), ``a_i = sum_j m_j v_ij`` [kg m] and, for ``i < k``,
    ``c_ik = sum_j m_j v_ij . v_kj``, ``s_ik = sum_j m_j v_ij x v_kj`` [kg m^2]:

    * ``D_theta[i, k] = c_ik cos(theta_k - theta_i) - s_ik sin(theta_k - theta_i)`` (+ the
      constant inertias and rotor terms), ``D = T^T D_theta T`` [kg m^2];
    * ``W[i, k] = dD_theta[i, k]/dtheta_k`` (antisymmetric); the Christoffel symbols of
      ``D_theta`` reduce to ``C_theta = W diag(theta')``, so
      ``C = T^T W diag(T q') T`` and ``h = C q' + G = T^T (W theta'^2 + G_theta)`` with
      ``G_theta,i = g (Rot(theta_i) S a_i)_y`` [N m] (``S``: the 90-degree rotation);
    * unpinned (``q_u = [q; x_1; y_1]``): ``D_u``'s coupling block ``T^T X`` with rows
      ``X_i = Rot(theta_i) S a_i`` [kg m], ``C_u``'s foot rows ``-Rot(theta_i) a_i theta_i'``
      mapped by ``T`` (its foot columns are zero), ``h_u = [h; sum_i -Rot(theta_i) a_i
      theta_i'^2 + (0, m g)]`` [N];
    * a point's Jacobian ``dp/dq = sum_i (Rot(theta_i) S v_i) T[i, :]``.

    These equal the Lagrange/Christoffel derivation of :mod:`.derive_reference` exactly
    (the tests compare the two to 1e-12). Every nonlinear piece is a short definition
    (``Derivation.defs``, emitted once per generated function that needs it and once per
    tape program); the results are integer combinations of them, so the cost grows about
    as N^3 and no simplification or common-subexpression search is needed. Coefficients
    in the robot's numbers are hoisted (:class:`Hoist`) as they are made. ``progress``
    is called with a short label after each part."""
    n = robot.n
    names = robot.link_names
    idx = {nm: i for i, nm in enumerate(names)}
    num = Numbers(robot, folded)
    hoist = Hoist(num.inputs)
    q = list(sp.symbols(f"q0:{n}", real=True))
    dq = list(sp.symbols(f"dq0:{n}", real=True))
    dxy = list(sp.symbols("dx1 dy1", real=True))
    F = list(sp.symbols(f"F0:{max(len(robot.thrusters), 1)}", real=True))
    Ti = robot.T.astype(int)
    Tl = Ti.tolist()  # Python integers for products with SymPy terms
    st = _Staged(q, hoist)
    k, define = st.coef, st.define
    done = progress or (lambda what: None)
    Z = sp.Integer(0)
    sf = num.vec("feet.stance")

    def chain(link: str, local) -> list[tuple[int, tuple[sp.Expr, sp.Expr]]]:
        """[(i, v_i)]: the world point = foot + sum Rot(theta_i) v_i (pinned); zeros out."""
        path = robot.path_from_root(link)
        terms: dict[int, list[list[sp.Expr]]] = {}
        for a, b in zip(path[:-1], path[1:]):
            j = num.vec(f"links.{b}.joint")
            v = terms.setdefault(idx[a], [[], []])
            v[0].append(j[0])
            v[1].append(j[1])
        v = terms.setdefault(idx[link], [[], []])
        v[0].append(local[0])
        v[1].append(local[1])
        root = terms.setdefault(idx[path[0]], [[], []])
        root[0].append(-sf[0])
        root[1].append(-sf[1])
        out = [(i, (sp.Add(*v[0]), sp.Add(*v[1]))) for i, v in terms.items()]
        return [(i, v) for i, v in out if not is_zero(v)]

    angle = [st.sincos(Ti[i]) for i in range(n)]  # (sin, cos) of theta_i, made when used

    def rot(i: int, v) -> tuple[sp.Expr, sp.Expr]:
        """``Rot(theta_i) v`` with hoisted coefficients."""
        s, c = angle[i]
        return (k(v[0]) * c - k(v[1]) * s, k(v[0]) * s + k(v[1]) * c)

    def rot_s(i: int, v) -> tuple[sp.Expr, sp.Expr]:
        """``Rot(theta_i) S v = d/dtheta_i Rot(theta_i) v``."""
        return rot(i, (-v[1], v[0]))

    # -- the map T as sums over the link tree --------------------------------------------------
    # Seen from the anchor (the link whose absolute angle is q_N), joint j separates the
    # links beyond it, F_j, from the anchor: T[i, j] = sigma_j for i in F_j, else 0 (sigma_j
    # = -1 where the joint's child is on the anchor's side), and T[i, N] = 1. So
    # (T^T x)_j = sigma_j S_j with S_j = x_far(j) + the S of the joints beyond far(j): one
    # add per link instead of one per nonzero of T.
    anchor = next(c.link for c in robot.coordinates if not c.actuated)
    ucol = next(j for j, c in enumerate(robot.coordinates) if not c.actuated)
    col = {c.link: j for j, c in enumerate(robot.coordinates) if c.actuated}
    joints: dict[str, list[tuple[int, str]]] = {nm: [] for nm in names}  # link -> (j, other)
    for lk in robot.links:
        if lk.parent is not None:
            joints[lk.name].append((col[lk.name], lk.parent))
            joints[lk.parent].append((col[lk.name], lk.name))
    far: dict[int, int] = {}  # joint column -> the link beyond it
    near: dict[int, int] = {}  # joint column -> the link on the anchor's side
    order = [anchor]  # links, each after its neighbour nearer the anchor
    for a in order:
        for j, b in joints[a]:
            if j not in far:
                far[j], near[j] = idx[b], idx[a]
                order.append(b)
    sigma = {j: 1 if col.get(names[f]) == j else -1 for j, f in far.items()}
    beyond = {j: [jj for jj, _ in joints[names[f]] if jj != j] for j, f in far.items()}
    joint_order = sorted(far, key=lambda j: -order.index(names[far[j]]))  # farthest first
    F: dict[int, set[int]] = {}
    for j in joint_order:
        F[j] = {far[j]}.union(*(F[jj] for jj in beyond[j]))
    if any(Tl[i][j] != (sigma[j] if i in F[j] else 0) for j in far for i in range(n)) or \
            any(Tl[i][ucol] != 1 for i in range(n)):  # pragma: no cover
        raise ValueError("derive: T is not the map of the link tree (coordinate_map)")

    def through_T(cols: dict[int, sp.Expr], tag: str, signed: bool = True
                  ) -> list[sp.Expr]:
        """``[sum_i T[i, a] x_i for a]`` of ``x = cols`` (a row vector in theta), by the
        partial sums ``S_j`` (definitions ``zS<tag>_<j>``); without the signs ``sigma_a``
        unless ``signed``."""
        S: dict[int, sp.Expr] = {}
        for j in joint_order:
            S[j] = define(f"zS{tag}_{j}", sp.Add(cols.get(far[j], Z),
                                                  *(S[jj] for jj in beyond[j])))
        out = [(sigma[a] if signed else 1) * S[a] if a != ucol else Z for a in range(n)]
        out[ucol] = sp.Add(cols.get(idx[anchor], Z), *(S[j] for j, _ in joints[anchor]))
        return out

    def through_T2(M: dict[tuple[int, int], sp.Expr], tag: str) -> list[list[sp.Expr]]:
        """``T^T M T`` (as rows): the rows of ``M T`` by :func:`through_T`, then its
        columns, the signs applied once at the end."""
        rows = {}
        for i in range(n):
            r = through_T({kk: e for (ii, kk), e in M.items() if ii == i}, f"{tag}{i}_",
                          signed=False)
            rows[i] = [define(f"zR{tag}{i}", e) if b == ucol else e for b, e in enumerate(r)]
        cols = [through_T({i: rows[i][b] for i in range(n)}, f"{tag}c{b}_")
                for b in range(n)]
        return [[(sigma[b] if b != ucol else 1) * cols[b][a] for b in range(n)]
                for a in range(n)]

    # -- rates: theta' = T q', along the link tree from the anchor (one add per link) -------
    rate: dict[int, sp.Expr] = {idx[anchor]: dq[ucol]}
    for j in sorted(far, key=lambda j: order.index(names[far[j]])):  # nearest first
        rate[far[j]] = define(f"zv{far[j]}", rate[near[j]] + sigma[j] * dq[j])
    sq = {i: define(f"zq{i}", rate[i] ** 2) for i in range(n)}

    # -- mass distribution: a_i, c_ik, s_ik and the constants of D_theta ----------------------
    a_vec: dict[int, list[list[sp.Expr]]] = {}
    cpair: dict[tuple[int, int], list[sp.Expr]] = {}
    spair: dict[tuple[int, int], list[sp.Expr]] = {}
    const: dict[tuple[int, int], list[sp.Expr]] = {}
    for lk in robot.links:
        pre = f"links.{lk.name}"
        m = num(pre + ".mass")
        terms = chain(lk.name, num.vec(pre + ".com")) if m != 0 else []
        for i, v in terms:
            acc = a_vec.setdefault(i, [[], []])
            acc[0].append(m * v[0])
            acc[1].append(m * v[1])
            for kk, w in terms:
                if kk < i:
                    continue
                dot = m * (v[0] * w[0] + v[1] * w[1])
                if kk == i:
                    const.setdefault((i, i), []).append(dot)
                else:
                    cpair.setdefault((i, kk), []).append(dot)
                    spair.setdefault((i, kk), []).append(m * (v[0] * w[1] - v[1] * w[0]))
        i = idx[lk.name]
        const.setdefault((i, i), []).append(num(pre + ".inertia"))
        J = num(pre + ".rotor_inertia")
        if J != 0 and lk.parent is not None:
            c, p = idx[lk.name], idx[lk.parent]
            const.setdefault((c, c), []).append(J)
            const.setdefault((p, p), []).append(J)
            const.setdefault((min(c, p), max(c, p)), []).append(-J)
    avec = {i: (sp.Add(*v[0]), sp.Add(*v[1])) for i, v in a_vec.items()}
    avec = {i: v for i, v in avec.items() if not is_zero(v)}
    done("mass distribution")

    # -- D_theta's varying entries and W ------------------------------------------------------
    dvar: dict[tuple[int, int], sp.Expr] = {}
    wvar: dict[tuple[int, int], sp.Expr] = {}
    for (i, kk) in sorted(set(cpair) | set(spair)):
        c = sp.Add(*cpair.get((i, kk), []))
        s = sp.Add(*spair.get((i, kk), []))
        if c == 0 and s == 0:
            continue
        sn, cs = st.sincos(Ti[kk] - Ti[i])
        dvar[i, kk] = define(f"zd{i}_{kk}", k(c) * cs + k(-s) * sn)
        wvar[i, kk] = define(f"zW{i}_{kk}", k(-c) * sn + k(-s) * cs)
    Dc = {key: sp.Add(*v) for key, v in const.items()}

    def D_const(a: int, b: int) -> sp.Expr:
        cst = []
        for (i, kk), e in Dc.items():
            t = Tl[i][a] * Tl[kk][b] + (Tl[kk][a] * Tl[i][b] if i != kk else 0)
            if t and e != 0:
                cst.append(t * e)
        return k(sp.Add(*cst))
    Dv = through_T2({**dvar, **{(kk, i): x for (i, kk), x in dvar.items()}}, "D")
    D = sp.zeros(n, n)
    for a in range(n):
        for b in range(a, n):
            D[a, b] = D[b, a] = D_const(a, b) + Dv[a][b]
    done("mass matrix")

    # -- gravity, potential, centre of mass, the unpinned coupling --------------------------
    g = num("gravity")
    mtot = num("total_mass")
    X = {i: tuple(define(f"zX{i}_{r}", e) for r, e in enumerate(rot_s(i, v)))
         for i, v in avec.items()}
    Gth = {i: k(g * v[0]) * angle[i][1] - k(g * v[1]) * angle[i][0] for i, v in avec.items()}
    G = sp.Matrix(through_T(Gth, "G"))
    V = sp.Matrix([sp.Add(*(k(g * v[0]) * angle[i][0] + k(g * v[1]) * angle[i][1]
                            for i, v in avec.items()))])
    com = [sp.Add(*(rot(i, (v[0] / mtot, v[1] / mtot))[r] for i, v in avec.items()))
           for r in range(2)]
    Dqx = [through_T({i: x[r] for i, x in X.items()}, f"X{r}") for r in range(2)]  # [r][a]
    inv_m = k(1 / mtot)
    J_com = sp.Matrix(2, n, lambda r, a: inv_m * Dqx[r][a])
    Du = sp.zeros(n + 2, n + 2)
    Du[:n, :n] = D
    for r in range(2):
        for a in range(n):
            Du[a, n + r] = Du[n + r, a] = Dqx[r][a]
    Du[n, n] = Du[n + 1, n + 1] = k(mtot)
    done("gravity and centre of mass")

    # -- Coriolis: h = T^T (W theta'^2 + G_theta), C = T^T W diag(theta') T -------------------
    def W(i: int, j: int) -> sp.Expr:
        if (i, j) in wvar:
            return wvar[i, j]
        return -wvar[j, i] if (j, i) in wvar else Z

    bias = {i: define(f"ze{i}", sp.Add(*(W(i, j) * sq[j] for j in range(n)), Gth.get(i, Z)))
            for i in range(n)}
    h = sp.Matrix(through_T(bias, "h"))
    C = sp.Matrix(through_T2({(i, j): W(i, j) * rate[j] for i in range(n) for j in range(n)
                              if W(i, j) != 0}, "C"))
    # foot rows: U_i = -Rot(theta_i) a_i = (-X_i,y, X_i,x)
    U = {i: (-x[1], x[0]) for i, x in X.items()}
    foot_bias = [sp.Add(*(u[r] * sq[i] for i, u in U.items())) for r in range(2)]
    foot_bias[1] = foot_bias[1] + k(mtot * g)
    Cu = sp.zeros(n + 2, n + 2)
    Cu[:n, :n] = C
    for r in range(2):
        Cu[n + r, :n] = sp.Matrix([through_T({i: u[r] * rate[i] for i, u in U.items()},
                                             f"U{r}")])
    hu = sp.Matrix(list(h) + foot_bias)
    done("Coriolis and gravity terms")

    # -- points and their Jacobians ------------------------------------------------------------
    def point(link: str, local, tag: str):
        """(p (2 expressions), dp/dq (2 x n), {i: dp/dtheta_i}) of a point of ``link``."""
        terms = chain(link, local)
        p = [sp.Add(*(rot(i, v)[r] for i, v in terms)) for r in range(2)]
        cols = {i: tuple(define(f"zj{tag}_{i}_{r}", e) for r, e in enumerate(rot_s(i, v)))
                for i, v in terms}
        J = [through_T({i: c[r] for i, c in cols.items()}, f"j{tag}{r}") for r in range(2)]
        return p, J, cols

    p2, E2, E2cols = point(robot.swing_foot.link, num.vec("feet.swing"), "f")
    E2m = sp.Matrix(E2)
    E2u = sp.Matrix.hstack(E2m, sp.eye(2))
    foot_vy = sp.Add(*(c[1] * rate[i] for i, c in E2cols.items()))
    pts, ptsJ = [], []
    for j, lk in enumerate(robot.links):
        if lk.parent is None:
            o = point(lk.name, (Z, Z), f"o{j}")
        else:
            o = point(lk.parent, num.vec(f"links.{lk.name}.joint"), f"o{j}")
        e = point(lk.name, num.vec(f"links.{lk.name}.end"), f"e{j}")
        pts += o[0] + e[0]
        ptsJ += o[1] + e[1]
    done("kinematics")

    # -- thrusters -------------------------------------------------------------------------------
    BF_cols, dirs, tpts = [], [], []
    for t_i, t in enumerate(robot.thrusters):
        d = num.vec(f"thrusters.{t.name}.direction")
        L = idx[t.link]
        p, _, _ = point(t.link, num.vec(f"thrusters.{t.name}.point"), f"t{t_i}")
        tpts.append(p)
        col_terms: dict[int, sp.Expr] = {}
        for i, v in chain(t.link, num.vec(f"thrusters.{t.name}.point")):
            if t.frame == "link":  # (S v) . Rot(theta_L - theta_i) d
                sn, cs = st.sincos(Ti[L] - Ti[i])
                e = k(v[0] * d[1] - v[1] * d[0]) * cs + k(v[1] * d[1] + v[0] * d[0]) * sn
            else:  # (Rot(theta_i) S v) . d
                sn, cs = angle[i]
                e = k(v[0] * d[1] - v[1] * d[0]) * cs - k(v[0] * d[0] + v[1] * d[1]) * sn
            col_terms[i] = define(f"zb{t_i}_{i}", e)
        BF_cols.append(through_T(col_terms, f"b{t_i}"))
        dirs.append(list(rot(L, d)) if t.frame == "link" else [k(d[0]), k(d[1])])
    m_t = len(robot.thrusters)
    BF = sp.Matrix(n, m_t, lambda a, c: BF_cols[c][a]) if m_t else sp.zeros(n, 0)
    thr_dir = sp.Matrix(2, m_t, lambda r, c: dirs[c][r]) if m_t else sp.zeros(2, 0)
    thr_pts = sp.Matrix(2, m_t, lambda r, c: tpts[c][r]) if m_t else sp.zeros(2, 0)
    BFu = sp.Matrix.vstack(BF, thr_dir)
    done("thrusters")

    exprs = {
        "D": D, "C": C, "G": G, "h": h, "V": V, "B_F": BF, "D_u": Du, "h_u": hu, "C_u": Cu,
        "B_Fu": BFu, "p_swing": sp.Matrix(p2), "E_swing": E2m, "E_swing_u": E2u,
        "p_com": sp.Matrix(com), "J_com": J_com, "thruster_points": thr_pts,
        "thruster_dirs": thr_dir, "link_points": sp.Matrix(pts),
        "link_points_J": sp.Matrix(ptsJ),
    }
    flat = lambda M: list(M) if M.shape[0] * M.shape[1] else []  # noqa: E731
    accel = flat(D) + flat(h) + flat(BF)
    ground = flat(Du[n:n + 2, :n]) + foot_bias + flat(thr_dir)
    programs = {
        "accel": (2 * n, accel),
        "force": (2 * n, accel + ground),
        "height": (n, p2),
        "footvel": (2 * n, [foot_vy]),
        "links": (n, pts),
        "impact": (n, flat(Du) + flat(E2u)),
        "energy": (n, flat(D) + flat(V)),
        "push": (n, flat(D) + flat(exprs["link_points_J"])),
    }
    return Derivation(q=q, dq=dq, dxy=dxy, F=F, exprs=exprs, T=sp.Matrix(Ti.tolist()),
                      mg=mtot * g, numbers=num, defs=st.defs, programs=programs, hoist=hoist)
