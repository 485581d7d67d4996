"""Physical identities of the compiled model (SPEC 1, 5 and 10) and its disk cache.

Every identity is checked on the two bundled robots (``three_link``, ``rabbit``) at seeded
random states, mostly against ``tests/independent.py``: a plain-NumPy computation from the
robot description that shares no code with the SymPy derivation or the generated modules.
Tolerances are relative to the size of the compared quantity unless stated otherwise.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import independent as ind
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from thrustwalk_cli.files.robot_file import load_robot
from thrustwalk_cli.model import cache
from thrustwalk_cli.model import compiler as model_mod
from thrustwalk_cli.model.compiled import FUNCTIONS as _FUNCTIONS
from thrustwalk_cli.model.compiler import load_model

ROBOTS = ["three_link", "rabbit"]
over_robots = pytest.mark.parametrize("name", ROBOTS)


def _states(n: int, count: int, seed: int, spread: float = 1.0):
    """Seeded configurations ``q`` (uniform in +-spread rad) and rates ``q'`` (normal)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-spread, spread, size=(count, n)), rng.normal(0.0, 1.0, size=(count, n))


def _worst(err: np.ndarray) -> int:
    """Index of the state with the largest error (first axis)."""
    return int(np.argmax(err.reshape(err.shape[0], -1).max(axis=1)))


def _assert_close(name: str, what: str, got, want, rel: float, scale: float | None = None):
    """``|got - want| <= rel * scale`` entrywise; the message names robot, quantity, state."""
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert got.shape == want.shape, f"{name}: {what}: shape {got.shape} != {want.shape}"
    scale = max(1.0, float(np.abs(want).max())) if scale is None else scale
    err = np.abs(got - want)
    if err.max() > rel * scale:
        i = _worst(err) if err.ndim > 1 else int(np.argmax(err))
        raise AssertionError(
            f"{name}: {what}: error {err.max():.3e} > {rel:.1e} * {scale:.3g} "
            f"(worst at state/entry {i})"
        )


# -- SPEC 10: D symmetric positive definite, independent of q_N, D' - 2C skew ----------------
@over_robots
def test_mass_matrix_symmetric_positive_definite(name, request):
    """SPEC 10: D(q) is symmetric positive definite (50 seeded states)."""
    model = request.getfixturevalue(name)
    q, _ = _states(model.n, 50, seed=0, spread=np.pi)
    D = model.D(q)
    scale = np.abs(D).max()
    for i in range(len(q)):
        asym = np.abs(D[i] - D[i].T).max()
        assert asym <= 1e-13 * scale, f"{name}: D not symmetric at state {i}: {asym:.3e}"
        lam = np.linalg.eigvalsh(D[i]).min()
        assert lam > 0, f"{name}: D not positive definite at state {i}: min eig {lam:.3e}"


@over_robots
def test_mass_matrix_does_not_depend_on_q_N(name, request):
    """SPEC 1/10: dD/dq_N = 0 (central differences, h = 1e-5) and D(q + c e_N) = D(q)."""
    model = request.getfixturevalue(name)
    q, _ = _states(model.n, 20, seed=1)
    e = np.zeros(model.n)
    e[-1] = 1.0
    D = model.D(q)
    scale = np.abs(D).max()
    h = 1e-5
    dD = (model.D(q + h * e) - model.D(q - h * e)) / (2 * h)
    _assert_close(name, "dD/dq_N", dD, np.zeros_like(dD), rel=1e-9, scale=scale)
    for c in (-2 * np.pi, -1.0, 0.3, 5.0, 100.0):
        _assert_close(name, f"D(q + {c} e_N) - D(q)", model.D(q + c * e), D, rel=1e-14,
                      scale=scale)


@over_robots
def test_D_dot_minus_2C_is_skew_symmetric(name, request):
    """SPEC 10: D' - 2C is skew-symmetric, D' = sum_i dD/dq_i q'_i by central differences
    (h = 1e-5, truncation ~1e-10); tolerance 1e-7 relative to max(|D'|, |C|)."""
    model = request.getfixturevalue(name)
    q, dq = _states(model.n, 20, seed=2)
    h = 1e-5
    Ddot = sum(
        (model.D(q + h * np.eye(model.n)[i]) - model.D(q - h * np.eye(model.n)[i]))
        / (2 * h) * dq[:, i, None, None]
        for i in range(model.n)
    )
    N = Ddot - 2 * model.C(q, dq)
    scale = max(np.abs(Ddot).max(), np.abs(model.C(q, dq)).max())
    _assert_close(name, "(D' - 2C) + (D' - 2C)^T", N + np.swapaxes(N, -1, -2),
                  np.zeros_like(N), rel=1e-7, scale=scale)


# -- two independent computations of the same quantities -------------------------------------
@over_robots
def test_mass_matrices_match_independent_computation(name, request):
    """SPEC 1: D and D_u equal sum_j m_j Jc_j^T Jc_j + I_j w_j^T w_j + rotor terms computed
    by tests/independent.py (to 1e-10 relative); the top-left N x N block of D_u is D."""
    model = request.getfixturevalue(name)
    robot = model.robot
    q, _ = _states(model.n, 20, seed=3, spread=np.pi)
    D_ref = np.array([ind.mass_matrix(robot, qi) for qi in q])
    Du_ref = np.array([ind.unpinned_mass_matrix(robot, qi) for qi in q])
    _assert_close(name, "D vs independent", model.D(q), D_ref, rel=1e-10)
    _assert_close(name, "D_u vs independent", model.D_u(q), Du_ref, rel=1e-10)
    n = model.n
    _assert_close(name, "D_u[:N, :N] vs D", model.D_u(q)[:, :n, :n], model.D(q), rel=1e-14)


@over_robots
def test_coriolis_matches_independent_christoffel_symbols(name, request):
    """SPEC 1: C and C_u equal the Christoffel matrices of the independent D and D_u (their
    derivatives by complex step); h = C q' + G and h_u = C_u q_u' + G_u with
    G_u = [G; 0; m_tot g]."""
    model = request.getfixturevalue(name)
    robot = model.robot
    n = model.n
    q, dq = _states(n, 10, seed=4)
    dq_u = np.random.default_rng(5).normal(size=(len(q), n + 2))
    C_ref = np.array([ind.christoffel_C(robot, qi, vi) for qi, vi in zip(q, dq)])
    Cu_ref = np.array([ind.christoffel_C(robot, qi, vi, unpinned=True)
                       for qi, vi in zip(q, dq_u)])
    _assert_close(name, "C vs independent Christoffel", model.C(q, dq), C_ref, rel=1e-10)
    _assert_close(name, "C_u vs independent Christoffel", model.C_u(q, dq_u), Cu_ref,
                  rel=1e-10)
    h_ref = np.einsum("kij,kj->ki", model.C(q, dq), dq) + model.G(q)
    _assert_close(name, "h vs C q' + G", model.h(q, dq), h_ref, rel=1e-12)
    G_u = np.concatenate(
        [model.G(q), np.zeros((len(q), 1)),
         np.full((len(q), 1), robot.total_mass * robot.gravity)], axis=1)
    hu_ref = np.einsum("kij,kj->ki", model.C_u(q, dq_u), dq_u) + G_u
    _assert_close(name, "h_u vs C_u q_u' + G_u", model.h_u(q, dq_u), hu_ref, rel=1e-12)


@over_robots
def test_potential_and_gravity_match_independent_computation(name, request):
    """SPEC 1: V = g sum_j m_j y_cj (independent COM heights) and G = dV/dq, the gradient of
    the independent V by complex step (to 1e-10 relative)."""
    model = request.getfixturevalue(name)
    robot = model.robot
    q, _ = _states(model.n, 20, seed=6, spread=np.pi)
    V_ref = np.array([[ind.potential(robot, qi)] for qi in q])
    G_ref = np.array([ind.complex_step(lambda x: ind.potential(robot, x), qi) for qi in q])
    _assert_close(name, "V vs independent", model.V(q), V_ref, rel=1e-10)
    _assert_close(name, "G vs dV/dq (independent, complex step)", model.G(q), G_ref,
                  rel=1e-10)


@over_robots
def test_kinematics_match_independent_computation(name, request):
    """SPEC 1: swing foot p_2 and its Jacobians E_2 = [dp_2/dq, I_2], centre of mass and its
    Jacobian, thruster points and world directions, and link drawing points all equal the
    independent forward kinematics (to 1e-12 relative)."""
    model = request.getfixturevalue(name)
    robot = model.robot
    n = model.n
    q, _ = _states(n, 20, seed=7, spread=np.pi)
    checks = {
        "p_swing": (model.p_swing, lambda x: ind.swing_foot(robot, x)),
        "E_swing": (model.E_swing, lambda x: ind.swing_jacobian(robot, x)),
        "E_swing_u": (model.E_swing_u,
                      lambda x: np.hstack([ind.swing_jacobian(robot, x), np.eye(2)])),
        "p_com": (model.p_com, lambda x: ind.com(robot, x)),
        "J_com": (model.J_com, lambda x: ind.com_jacobian(robot, x)),
        "thruster_points": (model.thruster_points, lambda x: np.stack(
            [ind.thruster_point(robot, x, k) for k in range(model.n_thrusters)], axis=1)),
        "thruster_dirs": (model.thruster_dirs, lambda x: np.stack(
            [ind.thruster_direction(robot, x, k) for k in range(model.n_thrusters)], axis=1)),
    }

    def link_points(x):
        org = ind.origins(robot, x)
        th = ind.angles(robot, x)
        out = []
        for j, lk in enumerate(robot.links):
            o = ind.point(robot, x, robot.root.name, (0.0, 0.0)) if lk.parent is None \
                else org[lk.name]
            out += [*o, *(org[lk.name] + ind.rot(th[j], lk.end))]
        return np.array(out)

    checks["link_points"] = (model.link_points, link_points)
    for what, (f, ref) in checks.items():
        _assert_close(name, f"{what} vs independent", f(q), np.array([ref(x) for x in q]),
                      rel=1e-12)


@over_robots
def test_independent_jacobians_agree_with_complex_step(name, request):
    """Self-check of the reference: the analytic Jacobians of tests/independent.py equal
    complex-step derivatives of its own positions (to 1e-13)."""
    robot = request.getfixturevalue(name).robot
    q, _ = _states(robot.n, 5, seed=8, spread=np.pi)
    for i, qi in enumerate(q):
        for lk in robot.links:
            J = ind.point_jacobian(robot, qi, lk.name, lk.com)
            J_cs = ind.complex_step(lambda x, lk=lk: ind.point(robot, x, lk.name, lk.com), qi)
            _assert_close(name, f"state {i}: COM Jacobian of {lk.name}", J, J_cs, rel=1e-13)


def test_three_link_matches_published_point_masses(three_link):
    """SPEC 9: the 3-link walker's D and V equal those of its four point masses (Grizzle,
    Abba, Plestan, IEEE TAC 2001: m = 5 kg at r/2 on each leg, M_H = 15 kg at the hip,
    M_T = 10 kg at L = 0.5 m on the torso, r = 1 m, g = 9.8), independent of how the loader
    lumps them into link inertias."""
    robot = three_link.robot
    assert robot.gravity == 9.8
    q, _ = _states(3, 20, seed=9, spread=np.pi)
    ref = [ind.three_link_point_mass_D(robot, qi) for qi in q]
    _assert_close("three_link", "D vs point masses", three_link.D(q),
                  np.array([r[0] for r in ref]), rel=1e-12)
    _assert_close("three_link", "V vs point masses", three_link.V(q)[:, 0],
                  np.array([r[1] for r in ref]), rel=1e-12)


# -- SPEC 10: energy, thruster power -----------------------------------------------------------
@over_robots
def test_energy_conserved_without_inputs(name, request):
    """SPEC 10: the unactuated, thrust-free pinned model D q'' + h = 0 conserves
    K + V = 1/2 q'^T D q' + V: relative drift < 1e-8 over 1 s (DOP853, rtol = atol = 1e-12,
    seed 10), relative to max K + max |V| along the trajectory."""
    model = request.getfixturevalue(name)
    n = model.n
    rng = np.random.default_rng(10)
    x0 = np.concatenate([rng.uniform(-0.5, 0.5, n), rng.normal(0.0, 1.0, n)])

    def rhs(_t, x):
        q, dq = x[:n].tolist(), x[n:].tolist()
        D = np.array(model.D_s(q)).reshape(n, n)
        return np.concatenate([x[n:], np.linalg.solve(D, -np.array(model.h_s(q, dq)))])

    sol = solve_ivp(rhs, (0.0, 1.0), x0, method="DOP853", rtol=1e-12, atol=1e-12)
    assert sol.success, f"{name}: integration failed: {sol.message}"
    q, dq = sol.y[:n].T, sol.y[n:].T
    E = model.energy(q, dq)
    K = E - model.V(q)[:, 0]
    scale = K.max() + np.abs(model.V(q)).max()
    drift = np.abs(E - E[0]).max() / scale
    assert drift < 1e-8, f"{name}: energy drift {drift:.3e} (E0 = {E[0]:.6g} J)"


@over_robots
def test_thruster_power_identity(name, request):
    """SPEC 10: q'^T B_F(q) F = sum_k F_k d_k . p_k', with p_k' and d_k from the independent
    kinematics; likewise q_u'^T B_Fu(q) F with the stance foot moving (to 1e-11 relative)."""
    model = request.getfixturevalue(name)
    robot = model.robot
    n, m = model.n, model.n_thrusters
    q, dq = _states(n, 20, seed=11, spread=np.pi)
    rng = np.random.default_rng(12)
    F = rng.uniform(-100.0, 100.0, size=(len(q), m))
    dq_u = np.concatenate([dq, rng.normal(size=(len(q), 2))], axis=1)
    got = np.einsum("ki,kij,kj->k", dq, model.B_F(q), F)
    want = np.array([ind.thruster_power(robot, *a) for a in zip(q, dq, F)])
    _assert_close(name, "q'^T B_F F vs thruster power", got, want, rel=1e-11,
                  scale=max(1.0, np.abs(F).max() * np.abs(dq).max()))
    got_u = np.einsum("ki,kij,kj->k", dq_u, model.B_Fu(q), F)
    want_u = np.array([ind.thruster_power(robot, *a) for a in zip(q, dq_u, F)])
    _assert_close(name, "q_u'^T B_Fu F vs thruster power", got_u, want_u, rel=1e-11,
                  scale=max(1.0, np.abs(F).max() * np.abs(dq_u).max()))


# -- SPEC 5/10: impact and relabelling ---------------------------------------------------------
@over_robots
def test_impact_identities(name, request):
    """SPEC 5/10 at 20 seeded pre-impact states (swing foot anywhere):

    * angular momentum about the impact point (the swing foot) is conserved, computed by the
      independent kinematics on q_u'^- = [q'; 0; 0] and q_u'^+ (rotor terms excluded, see
      ``independent.angular_momentum``);
    * the new stance foot does not move after impact: E_2 q_u'^+ = 0;
    * the impulse is the only external impulse: m_tot (v_com^+ - v_com^-) = F_2 (N s);
    * q^+ = R q^- + b and q'^+ = R q_u'^+[:N]; a batch call equals single calls.
    """
    model = request.getfixturevalue(name)
    robot = model.robot
    n = model.n
    q, dq = _states(n, 20, seed=13, spread=0.8)
    batch = model.impact(q, dq)
    for i in range(len(q)):
        imp = model.impact(q[i], dq[i])
        for field in ("q_plus", "dq_plus", "dq_u_plus", "impulse"):
            _assert_close(name, f"state {i}: batch vs single impact {field}",
                          getattr(batch, field)[i], getattr(imp, field), rel=1e-12)
        before = np.concatenate([dq[i], [0.0, 0.0]])
        after = imp.dq_u_plus
        p = ind.swing_foot(robot, q[i])
        H0 = ind.angular_momentum(robot, q[i], before, about=p)
        H1 = ind.angular_momentum(robot, q[i], after, about=p)
        scale = max(1.0, abs(H0), robot.total_mass * np.abs(p).max() * np.abs(before).max())
        _assert_close(name, f"state {i}: angular momentum about the impact point", H1, H0,
                      rel=1e-11, scale=scale)
        v_foot = model.E_swing_u(q[i]) @ after
        _assert_close(name, f"state {i}: new stance-foot velocity", v_foot, np.zeros(2),
                      rel=1e-12, scale=max(1.0, np.abs(after).max()))
        dP = ind.linear_momentum(robot, q[i], after) - ind.linear_momentum(robot, q[i], before)
        _assert_close(name, f"state {i}: momentum change vs impulse F_2", dP, imp.impulse,
                      rel=1e-11)
        Jc_u = np.hstack([model.J_com(q[i]), np.eye(2)])
        dP_model = robot.total_mass * Jc_u @ (after - before)
        _assert_close(name, f"state {i}: m_tot dv_com vs impulse F_2", dP_model, imp.impulse,
                      rel=1e-11)
        _assert_close(name, f"state {i}: q_plus", imp.q_plus, robot.R @ q[i] + robot.b,
                      rel=1e-14)
        _assert_close(name, f"state {i}: dq_plus", imp.dq_plus, robot.R @ after[:n],
                      rel=1e-14)


@over_robots
def test_relabel_swaps_the_feet(name, request):
    """SPEC 1: after q^+ = R q^- + b the old swing foot is the stance foot, so
    p_swing(R q + b) = -p_swing(q) (model and independent kinematics, 50 seeded states)."""
    model = request.getfixturevalue(name)
    robot = model.robot
    q, _ = _states(model.n, 50, seed=14, spread=np.pi)
    qp = model.relabel(q)
    _assert_close(name, "relabel", qp, q @ robot.R.T + robot.b, rel=1e-14)
    _assert_close(name, "p_swing(R q + b) + p_swing(q)", model.p_swing(qp) + model.p_swing(q),
                  np.zeros((len(q), 2)), rel=1e-12)
    ref = np.array([ind.swing_foot(robot, a) + ind.swing_foot(robot, b) for a, b in zip(qp, q)])
    _assert_close(name, "independent p_swing(R q + b) + p_swing(q)", ref, np.zeros_like(ref),
                  rel=1e-12)


# -- batch semantics (STYLE 7) -----------------------------------------------------------------
def _arguments(model, names, count: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    size = {"q": model.n, "dq": model.n, "dq_u": model.n + 2}
    return [rng.uniform(-2.0, 2.0, size=(count, size[a])) for a in names]


@over_robots
@pytest.mark.parametrize("count", [1, 7])
def test_batch_equals_single_and_scalar_calls(name, count, request):
    """Every generated function on a batch (count, N) has shape (count, rows[, cols]) and
    equals the stack of single-state calls and of the scalar ``_s`` versions (flat, row-major),
    constant entries included; a (2, 3, N) grid keeps its shape."""
    model = request.getfixturevalue(name)
    for seed, (fname, (args, _doc)) in enumerate(_FUNCTIONS.items()):
        f, f_s = getattr(model, fname), getattr(model, fname + "_s")
        xs = _arguments(model, args, count, seed=100 + seed)
        out = f(*xs)
        single = np.array([f(*[x[i] for x in xs]) for i in range(count)])
        scalar = np.array([f_s(*[x[i].tolist() for x in xs]) for i in range(count)])
        assert out.shape == single.shape, f"{name}: {fname}: batch shape {out.shape}"
        assert out.shape[0] == count, f"{name}: {fname}: batch shape {out.shape}"
        _assert_close(name, f"{fname}: batch vs single calls", out, single, rel=1e-14)
        _assert_close(name, f"{fname}: batch vs scalar _s", out.reshape(count, -1), scalar,
                      rel=1e-13)
        grid = [np.broadcast_to(x[:1], (2, 3, x.shape[1])) for x in xs]
        out_grid = f(*grid)
        assert out_grid.shape == (2, 3) + single.shape[1:], f"{name}: {fname}: grid shape"
        _assert_close(name, f"{fname}: (2, 3) grid", out_grid,
                      np.broadcast_to(single[0], out_grid.shape), rel=1e-14)


@over_robots
def test_constant_entries_broadcast(name, request):
    """STYLE 7: constant entries fill the whole batch: D_u's mass block m_tot I_2,
    E_swing_u's identity block, world-fixed thruster directions; q of shape (7, N) broadcasts
    against rates of shape (N,)."""
    model = request.getfixturevalue(name)
    robot = model.robot
    n = model.n
    q, dq = _states(n, 7, seed=15)
    Du = model.D_u(q)
    np.testing.assert_array_equal(
        Du[:, n:, n:], np.broadcast_to(robot.total_mass * np.eye(2), (7, 2, 2)),
        err_msg=f"{name}: D_u mass block")
    np.testing.assert_array_equal(model.E_swing_u(q)[:, :, n:],
                                  np.broadcast_to(np.eye(2), (7, 2, 2)),
                                  err_msg=f"{name}: E_swing_u identity block")
    dirs = model.thruster_dirs(q)
    for k, t in enumerate(robot.thrusters):
        if t.frame == "world":
            np.testing.assert_array_equal(dirs[:, :, k], np.broadcast_to(t.direction, (7, 2)),
                                          err_msg=f"{name}: direction of thruster {t.name}")
            np.testing.assert_array_equal(model.B_Fu(q)[:, n:, k],
                                          np.broadcast_to(t.direction, (7, 2)),
                                          err_msg=f"{name}: B_Fu foot rows, {t.name}")
    for fname in ("C", "h"):
        f = getattr(model, fname)
        _assert_close(name, f"{fname}(q (7, N), dq (N,))", f(q, dq[0]),
                      f(q, np.broadcast_to(dq[0], q.shape)), rel=1e-14)


# -- cache behaviour ---------------------------------------------------------------------------
@pytest.fixture
def fresh_cache(tmp_path, monkeypatch) -> Path:
    """An empty model cache for one test."""
    path = tmp_path / "cache"
    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(path))
    return path


def _probe(model, seed: int = 16) -> dict[str, np.ndarray]:
    """Values of every generated function at a few seeded states (for bitwise comparison)."""
    return {fname: getattr(model, fname)(*_arguments(model, args, 3, seed))
            for fname, (args, _doc) in _FUNCTIONS.items()}


def _assert_identical(a: dict, b: dict, what: str) -> None:
    for fname in a:
        np.testing.assert_array_equal(a[fname], b[fname], err_msg=f"{what}: {fname}")


def _seed_entry(source_model) -> Path:
    """Copy a valid entry (compiled by the session fixture) into the current cache dir."""
    path = cache.entry_path(source_model.robot.name, source_model.key)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(source_model.cache_path.read_bytes())
    return path


def test_cache_second_load_is_a_hit_with_identical_numbers(fresh_cache):
    """A compiled model is cached: the second load is a hit and gives bit-identical values."""
    robot = load_robot("three_link")
    first = load_model(robot)
    assert not first.cache_hit, "first load into an empty cache must compile"
    assert first.cache_path.parent == fresh_cache
    model_mod._LOADED.clear()  # force the round trip through the file on disk
    second = load_model(robot)
    assert second.cache_hit, "second load must come from the cache"
    assert second.cache_path == first.cache_path
    _assert_identical(_probe(first), _probe(second), "second load")
    assert cache.verify_entry(second.cache_path, second.key) is None


def test_in_process_reuse_is_a_hit_and_sees_rewritten_entries(fresh_cache):
    """A model already imported in this process is reused (no re-import) and reported as a
    cache hit; rewriting the entry on disk sends the next load through verification again."""
    robot = load_robot("three_link")
    first = load_model(robot)
    again = load_model(robot)
    assert again.cache_hit and again._m is first._m
    _assert_identical(_probe(first), _probe(again), "in-process reuse")
    path = first.cache_path
    path.write_bytes(path.read_bytes()[:100])  # truncated: the signature changes
    rebuilt = load_model(robot)
    assert not rebuilt.cache_hit and rebuilt._m is not first._m
    _assert_identical(_probe(first), _probe(rebuilt), "rebuilt after truncation")


def _flip_body_byte(b: bytes) -> bytes:
    i = b.index(b"\n") + len(b) // 2
    i += next(k for k, ch in enumerate(b[i:]) if chr(ch).isdigit())
    return b[:i] + bytes([b[i] ^ 0x01]) + b[i + 1:]


CORRUPTIONS = {
    "flip_body_byte": (_flip_body_byte, {"checksum mismatch"}),
    "truncate_half": (lambda b: b[: len(b) // 2], {"checksum mismatch"}),
    "truncate_in_header": (lambda b: b[:30], {"no header"}),
    "empty": (lambda b: b"", {"no header"}),
    "garbage_text": (lambda b: b"print('not a model')\n" * 20, {"no header"}),
    # not UTF-8: unreadable in a UTF-8 locale, headerless in a single-byte one
    "binary_garbage": (lambda b: bytes(range(128, 256)) * 8,
                       {"unreadable (UnicodeDecodeError)", "no header"}),
    "wrong_key_header": (lambda b: b.replace(b" key=", b" key=0", 1), {"stale key"}),
}


@pytest.mark.parametrize("kind", list(CORRUPTIONS))
def test_cache_corrupted_entry_is_detected_and_rebuilt(kind, fresh_cache, three_link):
    """A corrupted entry (flipped byte, truncation, garbage, wrong key header) is reported by
    ``cache.verify_entry`` and ``load_model`` rebuilds it with correct numbers."""
    path = _seed_entry(three_link)
    key = three_link.key
    assert cache.verify_entry(path, key) is None
    corrupt, reasons = CORRUPTIONS[kind]
    path.write_bytes(corrupt(path.read_bytes()))
    reason = cache.verify_entry(path, key)
    assert reason in reasons, f"{kind}: verify_entry gave {reason!r}, expected one of {reasons}"
    model = load_model(three_link.robot)
    assert not model.cache_hit, f"{kind}: corrupted entry was used"
    assert cache.verify_entry(path, key) is None, f"{kind}: entry not rebuilt"
    _assert_identical(_probe(model), _probe(three_link), f"{kind}: rebuilt model")


def test_cache_stale_key_and_rebuild_flag(fresh_cache, three_link):
    """New numbers (gravity) reuse the entry, bound to the new value (G scales with g); a
    changed structure (the torso's centre of mass off its axis: a zero becomes a number)
    has a new key, is compiled afresh and does not reuse the old entry; ``rebuild=True``
    recompiles a valid entry."""
    old_path = _seed_entry(three_link)
    assert load_model(three_link.robot).cache_hit
    heavier = dataclasses.replace(three_link.robot, gravity=9.81)
    model = load_model(heavier)
    assert model.cache_hit, "new numbers must reuse the compiled structure"
    assert model.key == three_link.key and model.cache_path == old_path
    q, _ = _states(3, 5, seed=17)
    _assert_close("three_link", "G after gravity change", model.G(q),
                  three_link.G(q) * (9.81 / 9.8), rel=1e-13)
    links = list(three_link.robot.links)
    links[1] = dataclasses.replace(links[1], com=(0.01, links[1].com[1]))  # the torso
    skewed = dataclasses.replace(three_link.robot, links=tuple(links))
    model = load_model(skewed)
    assert not model.cache_hit, "a robot with a new structure must not hit the old entry"
    assert model.key != three_link.key and model.cache_path != old_path
    assert cache.verify_entry(old_path, model.key) == "stale key"
    forced = load_model(three_link.robot, rebuild=True)
    assert not forced.cache_hit
    _assert_identical(_probe(forced), _probe(three_link), "rebuild=True")


def _subprocess_env(cache_dir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["THRUSTWALK_CACHE_DIR"] = str(cache_dir)
    return env


@pytest.mark.slow
def test_cache_concurrent_compiles_leave_one_valid_entry(fresh_cache, three_link):
    """Two processes compiling the same robot into one empty cache both succeed, agree, and
    leave exactly one valid entry (atomic rename; no temporary files left)."""
    go = fresh_cache.parent / "go"
    script = textwrap.dedent(f"""
        import json, os, time
        from thrustwalk_cli.model.compiler import load_model
        from thrustwalk_cli.files.robot_file import load_robot
        robot = load_robot("three_link")
        while not os.path.exists({str(go)!r}):
            time.sleep(0.005)
        m = load_model(robot)
        print(json.dumps({{"hit": m.cache_hit, "D": m.D([0.1, -0.2, 0.3]).tolist()}}))
    """)
    procs = [subprocess.Popen([sys.executable, "-c", script], env=_subprocess_env(fresh_cache),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    time.sleep(0.2)
    go.touch()
    outs = [p.communicate(timeout=120) for p in procs]
    for i, (p, (out, err)) in enumerate(zip(procs, outs)):
        assert p.returncode == 0, f"process {i} failed:\n{err}"
        D = np.array(json.loads(out)["D"])
        np.testing.assert_array_equal(D, three_link.D([0.1, -0.2, 0.3]),
                                      err_msg=f"process {i}: D")
    # one entry, beside the lock file its build held (thrustwalk_cli/model/cache.py) and
    # Python's own bytecode folder wherever bytecode is written
    files = sorted(x.name for x in fresh_cache.iterdir()
                   if x.suffix != ".lock" and x.name != "__pycache__")
    assert len(files) == 1 and files[0].endswith(".py"), f"cache dir holds {files}"
    assert cache.verify_entry(fresh_cache / files[0], three_link.key) is None


def test_cached_load_does_not_import_sympy(fresh_cache, three_link):
    """model.py contract (shared/PERF_NOTES.md): loading a cached model in a fresh process
    never imports SymPy (about 0.6 s)."""
    _seed_entry(three_link)
    script = textwrap.dedent("""
        import json, sys
        from thrustwalk_cli.model.compiler import load_model
        from thrustwalk_cli.files.robot_file import load_robot
        m = load_model(load_robot("three_link"))
        m.D([0.1, 0.2, 0.3]); m.impact([0.1, 0.2, 0.3], [1.0, 0.0, -1.0])
        print(json.dumps({"hit": m.cache_hit, "sympy": sorted(
            k for k in sys.modules if k == "sympy" or k.startswith("sympy."))[:5]}))
    """)
    res = subprocess.run([sys.executable, "-c", script], env=_subprocess_env(fresh_cache),
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["hit"], "the seeded entry was not used"
    assert out["sympy"] == [], f"sympy imported on a cached load: {out['sympy']}"


def test_names_from_the_robot_file_never_run_as_code(fresh_cache, tmp_path):
    """The generated model module quotes the robot's names as a string literal: a name that
    holds triple quotes and a call (which used to end the module's docstring and run when the
    cached module was imported) compiles to the same model and runs nothing."""
    import re

    from thrustwalk_cli.files.robot_file import load_robot_text

    marker = tmp_path / "ran"
    name = f'x"""+__import__("pathlib").Path({str(marker)!r}).touch()+"""'
    text = (Path(__file__).parents[1] / "robots" / "three_link.yaml").read_text()
    text = re.sub(r"^name: .*$", "name: " + json.dumps(name), text, count=1, flags=re.M)
    robot = load_robot_text(text, str(tmp_path / "evil.yaml"))
    assert robot.name == name
    model = load_model(robot)
    model_mod._LOADED.clear()  # and once more through the file on disk
    again = load_model(robot)
    assert again.cache_hit and not marker.exists()
    q = [0.1, -0.2, 0.3]
    np.testing.assert_array_equal(again.D(q), load_model(load_robot("three_link")).D(q))
    import ast

    assert repr(name) in ast.get_docstring(ast.parse(model.cache_path.read_text()))
