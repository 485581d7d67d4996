"""Independent plain-NumPy kinematics and dynamics of a ``Robot`` description (tests only).

Written from the conventions of ``thrustwalk_cli/description/robot.py`` alone (SPEC 1),
without the SymPy derivation, the code generator or the compiled model, so that tests can
compare two computations of the same quantity (SPEC 10):

* absolute link angles ``theta = T q`` (counter-clockwise from the world frame);
* the root link is pinned at the stance foot, placed at ``foot`` (default the origin); every
  other link's frame origin is its joint, a point of the parent's frame;
* a point ``p`` of link ``j`` sits at ``origin_j + Rot(theta_j) p``.

Positions are computed by walking the tree from the root. Jacobians are analytic: changing
the absolute angle of a link on the path from the stance foot to a point, with every other
absolute angle fixed, rotates that link's segment (from where the path enters the link to
where it leaves it) about the entry point, so ``dp/dtheta_j = S (exit_j - entry_j)`` with
``S`` the 90-degree rotation; then ``dp/dq = (dp/dtheta) T``. Every function accepts complex
``q`` (analytic continuation), so derivatives of these quantities can be taken by the
complex-step method to machine precision (:func:`complex_step`).

Units: SI (m, kg, kg m^2, s, rad).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from thrustwalk_cli.description.robot import Robot

S = np.array([[0.0, -1.0], [1.0, 0.0]])  # d/dtheta Rot(theta) = S Rot(theta)


def rot(theta, v) -> np.ndarray:
    """``Rot(theta) v`` for a planar vector ``v`` (theta may be complex)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def _q(q) -> np.ndarray:
    q = np.asarray(q)
    return q if np.iscomplexobj(q) else q.astype(float)


def angles(robot: Robot, q) -> np.ndarray:
    """Absolute link angles ``theta = T q`` [rad], in the order of ``robot.links``."""
    return robot.T @ _q(q)


def origins(robot: Robot, q, foot=(0.0, 0.0)) -> dict[str, np.ndarray]:
    """World position of every link frame's origin [m], the stance foot at ``foot``."""
    th = angles(robot, q)
    idx = {lk.name: i for i, lk in enumerate(robot.links)}
    by_name = {lk.name: lk for lk in robot.links}
    root = robot.root
    out = {root.name: np.asarray(foot) - rot(th[idx[root.name]], robot.stance_foot.point)}
    pending = [lk for lk in robot.links if lk.parent is not None]
    while pending:  # parents before children, whatever the order of the file
        rest = []
        for lk in pending:
            if lk.parent in out:
                parent = by_name[lk.parent]
                out[lk.name] = out[parent.name] + rot(th[idx[parent.name]], lk.joint)
            else:
                rest.append(lk)
        if len(rest) == len(pending):
            raise ValueError("link tree is not connected to the root")
        pending = rest
    return out


def point(robot: Robot, q, link: str, local, foot=(0.0, 0.0)) -> np.ndarray:
    """World position of ``local`` (in the frame of ``link``) [m]."""
    th = angles(robot, q)
    return origins(robot, q, foot)[link] + rot(th[robot.link_index(link)], local)


def point_jacobian(robot: Robot, q, link: str, local) -> np.ndarray:
    """Analytic ``dp/dq`` (2 x N) of a point fixed on ``link``, stance foot pinned [m]."""
    q = _q(q)
    org = origins(robot, q)
    path = robot.path_from_root(link)
    target = point(robot, q, link, local)
    J_theta = np.zeros((2, robot.n), dtype=q.dtype)
    for k, name in enumerate(path):
        entry = np.zeros(2) if k == 0 else org[name]
        exit_ = target if k == len(path) - 1 else org[path[k + 1]]
        J_theta[:, robot.link_index(name)] = S @ (exit_ - entry)
    return J_theta @ robot.T


def complex_step(f: Callable[[np.ndarray], np.ndarray], q, h: float = 1e-30) -> np.ndarray:
    """``df/dq`` by the complex-step method: last axis of the result indexes ``q``."""
    q = np.asarray(q, dtype=float)
    cols = []
    for i in range(q.size):
        qc = q.astype(complex)
        qc[i] += 1j * h
        cols.append(np.imag(np.asarray(f(qc))) / h)
    return np.stack(cols, axis=-1)


# -- mass properties --------------------------------------------------------------------------
def link_coms(robot: Robot, q, foot=(0.0, 0.0)) -> list[np.ndarray]:
    """World centre of mass of every link [m]."""
    return [point(robot, q, lk.name, lk.com, foot) for lk in robot.links]


def com(robot: Robot, q) -> np.ndarray:
    """Whole-robot centre of mass relative to the stance foot [m]."""
    cs = link_coms(robot, q)
    return sum(lk.mass * c for lk, c in zip(robot.links, cs)) / robot.total_mass


def com_jacobian(robot: Robot, q) -> np.ndarray:
    """Whole-robot COM Jacobian (2 x N) [m]."""
    Js = [point_jacobian(robot, q, lk.name, lk.com) for lk in robot.links]
    return sum(lk.mass * J for lk, J in zip(robot.links, Js)) / robot.total_mass


def angular_rate_rows(robot: Robot) -> np.ndarray:
    """Row ``j`` maps ``q'`` to the absolute angular velocity of link ``j``: ``T[j, :]``."""
    return robot.T


def mass_matrix(robot: Robot, q) -> np.ndarray:
    """Pinned inertia matrix (SPEC 1) [kg m^2]:

    ``D = sum_j m_j Jc_j^T Jc_j + I_j w_j^T w_j + J_rot,j (w_j - w_parent)^T (w_j - w_parent)``

    with ``Jc_j`` the COM Jacobian of link ``j``, ``w_j = T[j, :]`` and ``J_rot,j`` the
    reflected rotor inertia on the joint of link ``j`` to its parent.
    """
    q = _q(q)
    T = angular_rate_rows(robot)
    D = np.zeros((robot.n, robot.n), dtype=q.dtype)
    for j, lk in enumerate(robot.links):
        Jc = point_jacobian(robot, q, lk.name, lk.com)
        w = T[j]
        D = D + lk.mass * Jc.T @ Jc + lk.inertia * np.outer(w, w)
        if lk.parent is not None and lk.rotor_inertia:
            rel = w - T[robot.link_index(lk.parent)]
            D = D + lk.rotor_inertia * np.outer(rel, rel)
    return D


def unpinned_mass_matrix(robot: Robot, q) -> np.ndarray:
    """Inertia matrix in ``q_u = [q; x_1; y_1]`` (SPEC 1): a foot translation moves every
    point by the same amount, so ``Jc_u = [Jc, I_2]``; the rotor and link-inertia terms do
    not involve the translation [kg m^2, kg m, kg]."""
    q = _q(q)
    n = robot.n
    T = angular_rate_rows(robot)
    Du = np.zeros((n + 2, n + 2), dtype=q.dtype)
    for j, lk in enumerate(robot.links):
        Jc = np.hstack([point_jacobian(robot, q, lk.name, lk.com), np.eye(2)])
        w = np.concatenate([T[j], [0.0, 0.0]])
        Du = Du + lk.mass * Jc.T @ Jc + lk.inertia * np.outer(w, w)
        if lk.parent is not None and lk.rotor_inertia:
            rel = w - np.concatenate([T[robot.link_index(lk.parent)], [0.0, 0.0]])
            Du = Du + lk.rotor_inertia * np.outer(rel, rel)
    return Du


def potential(robot: Robot, q):
    """Potential energy ``V = g sum_j m_j y_cj`` with the stance foot at height 0 [J]."""
    return robot.gravity * sum(lk.mass * c[1] for lk, c in zip(robot.links, link_coms(robot, q)))


def christoffel_C(robot: Robot, q, dq, unpinned: bool = False) -> np.ndarray:
    """Coriolis matrix from Christoffel symbols of the independent inertia matrix:

    ``C_kj = sum_i 1/2 (dD_kj/dq_i + dD_ki/dq_j - dD_ij/dq_k) q'_i``,

    derivatives of ``D`` by complex step. ``unpinned``: use ``D_u`` and ``q_u' = dq`` (N+2;
    ``D_u`` does not depend on the foot position).
    """
    q = np.asarray(q, dtype=float)
    dq = np.asarray(dq, dtype=float)
    if unpinned:
        dD = complex_step(lambda x: unpinned_mass_matrix(robot, x), q)  # (N+2, N+2, N)
        dD = np.concatenate([dD, np.zeros(dD.shape[:2] + (2,))], axis=-1)
    else:
        dD = complex_step(lambda x: mass_matrix(robot, x), q)  # (N, N, N): [k, j, i]
    gam = 0.5 * (dD + np.transpose(dD, (0, 2, 1)) - np.transpose(dD, (2, 1, 0)))
    # gam[k, j, i] = 1/2 (dD_kj/dq_i + dD_ki/dq_j - dD_ji/dq_k); D symmetric.
    return gam @ dq


# -- feet and thrusters ------------------------------------------------------------------------
def swing_foot(robot: Robot, q) -> np.ndarray:
    """Swing-foot position relative to the stance foot [m]."""
    sf = robot.swing_foot
    return point(robot, q, sf.link, sf.point)


def swing_jacobian(robot: Robot, q) -> np.ndarray:
    """Swing-foot Jacobian ``dp_2/dq`` (2 x N) [m]."""
    sf = robot.swing_foot
    return point_jacobian(robot, q, sf.link, sf.point)


def thruster_point(robot: Robot, q, k: int) -> np.ndarray:
    """World application point of thruster ``k`` relative to the stance foot [m]."""
    t = robot.thrusters[k]
    return point(robot, q, t.link, t.point)


def thruster_direction(robot: Robot, q, k: int) -> np.ndarray:
    """World unit direction of thruster ``k``: fixed, or rotated with its link."""
    t = robot.thrusters[k]
    if t.frame == "link":
        return rot(angles(robot, q)[robot.link_index(t.link)], t.direction)
    return np.asarray(t.direction, dtype=float)


def thruster_power(robot: Robot, q, dq_u, F) -> float:
    """Power of the thrusters ``sum_k F_k d_k . p_k'`` [W]; ``dq_u`` is ``q'`` (N) or
    ``[q'; x_1'; y_1']`` (N+2, the foot moving)."""
    dq_u = np.asarray(dq_u, dtype=float)
    n = robot.n
    foot_v = dq_u[n:] if dq_u.size == n + 2 else np.zeros(2)
    total = 0.0
    for k, t in enumerate(robot.thrusters):
        v = point_jacobian(robot, q, t.link, t.point) @ dq_u[:n] + foot_v
        total += F[k] * thruster_direction(robot, q, k) @ v
    return float(total)


# -- momenta (unpinned velocities q_u' = [q'; x_1'; y_1']) ---------------------------------
def link_velocities(robot: Robot, q, dq_u) -> tuple[list[np.ndarray], list[np.ndarray], list]:
    """World COM positions, COM velocities and angular velocities of every link."""
    dq_u = np.asarray(dq_u, dtype=float)
    n = robot.n
    cs, vs, ws = [], [], []
    for j, lk in enumerate(robot.links):
        cs.append(point(robot, q, lk.name, lk.com))
        vs.append(point_jacobian(robot, q, lk.name, lk.com) @ dq_u[:n] + dq_u[n:])
        ws.append(float(robot.T[j] @ dq_u[:n]))
    return cs, vs, ws


def angular_momentum(robot: Robot, q, dq_u, about) -> float:
    """``H = sum_j m_j (c_j - p) x c_j' + I_j w_j`` about the world point ``p`` [kg m^2/s].

    Rotor terms are left out on purpose: the reflected rotor energy
    ``1/2 J (w_j - w_parent)^2`` does not change under a rigid rotation of the whole robot,
    so it does not contribute to the momentum conjugate to that rotation, which is the
    quantity an impulse at ``p`` leaves unchanged.
    """
    about = np.asarray(about, dtype=float)
    cs, vs, ws = link_velocities(robot, q, dq_u)
    H = 0.0
    for lk, c, v, w in zip(robot.links, cs, vs, ws):
        r = c - about
        H += lk.mass * (r[0] * v[1] - r[1] * v[0]) + lk.inertia * w
    return float(H)


def linear_momentum(robot: Robot, q, dq_u) -> np.ndarray:
    """``sum_j m_j c_j'`` [kg m/s]."""
    _, vs, _ = link_velocities(robot, q, dq_u)
    return sum(lk.mass * v for lk, v in zip(robot.links, vs))


# -- the 3-link walker from its published point masses (SPEC 9) -------------------------------
def three_link_point_mass_D(robot: Robot, q, r=1.0, m=5.0, MH=15.0, MT=10.0, L=0.5):
    """Inertia matrix of the 3-link walker of Grizzle, Abba, Plestan (IEEE TAC 2001) built
    from its four point masses (leg masses ``m`` at ``r/2``, hip ``MH``, torso ``MT`` at
    ``L`` above the hip), not from the combined link inertias of the loaded description.

    Links of ``three_link.yaml`` in order: stance leg, torso, swing leg; ``theta = T q``.
    Returns ``(D, V)`` with ``V`` the potential energy (stance foot at height 0) [J].
    """
    th = angles(robot, q)
    e = [rot(a, (0.0, 1.0)) for a in th]  # unit "up" of each link frame

    def jac(*terms):  # d/dq of sum_l c_l Rot(theta_l)(0, 1); terms [(link index, c_l)]
        J = np.zeros((2, robot.n))
        for row, c in terms:
            J += c * np.outer(S @ e[row], robot.T[row])
        return J

    stance, torso, swing = 0, 1, 2
    hip = r * e[stance]
    masses = [
        (m, 0.5 * r * e[stance], jac((stance, 0.5 * r))),
        (MH, hip, jac((stance, r))),
        (MT, hip + L * e[torso], jac((stance, r), (torso, L))),
        (m, hip - 0.5 * r * e[swing], jac((stance, r), (swing, -0.5 * r))),
    ]
    D = sum(mm * J.T @ J for mm, _, J in masses)
    V = robot.gravity * sum(mm * p[1] for mm, p, _ in masses)
    return D, V
