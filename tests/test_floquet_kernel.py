"""The variational equations' right-hand side through the compiled kernel (SPEC 7, 13), and
the modes of a repeated multiplier (two identical thrusters) described independently of the
eigenvector basis a solver happens to return."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.floquet.multipliers import _dominant
from thrustwalk_cli.floquet.poincare import Setting
from thrustwalk_cli.floquet.variational import closed_loop, rhs, rhs_numpy
from thrustwalk_cli.simulation.closed_loop import ThrustModel

DATA = Path(__file__).resolve().parent / "data"


def _states(walker, cl, thrust_states: int, k: int = 12, seed: int = 0) -> np.ndarray:
    """States on and off the gait: postures along the step with rates and thruster states
    drawn around it."""
    rng = np.random.default_rng(seed)
    zd = walker.zd
    s = np.linspace(0.05, 0.95, k)
    q = zd.maps.q_Z(zd.alpha_i + s * (zd.alpha_f - zd.alpha_i))
    dq = rng.normal(0.0, 1.0, q.shape)
    z = rng.normal(-10.0, 5.0, (k, thrust_states))
    return np.concatenate([q, dq, z], axis=1)


@pytest.mark.parametrize("which, model, slope", [
    ("rabbit", "second-order", 0.0), ("walker5", "first-order", 0.0), ("three", "ideal", 0.0),
    ("three", "second-order", -0.05), ("walker5", "ideal", 0.03)])
def test_kernel_right_hand_side_equals_the_numpy_closed_loop(which, model, slope, walker3,
                                                             walker_rabbit):
    """The kernel's ``x'`` (on a slope: the level-ground tape at the turned posture) against
    the NumPy closed loop's (on a slope: the slope model's own equations), every segment."""
    from thrustwalk_cli.walker import load_walker

    walker = {"rabbit": walker_rabbit, "three": walker3}.get(which) or load_walker(
        str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))
    if slope:
        walker = walker.on_slope(slope)
    m = walker.model.n_thrusters
    th = ThrustModel(model, np.full(m, -12.0), wn=3.0, xi=0.8, tau=0.05)
    cl = closed_loop(walker.zd, Setting(th, walker.gait.kp, walker.gait.kd))
    X = _states(walker, cl, th.n_states)
    for seg in range(len(cl.breaks) + 1):
        got, want = rhs(cl, X, seg), rhs_numpy(cl, X, seg)
        scale = np.maximum(np.abs(want).max(axis=0), 1.0)
        assert np.all(np.abs(got - want) <= 1e-10 * scale), (which, seg)


def test_a_repeated_multipliers_modes_do_not_depend_on_the_eigenvector_basis():
    """A 2-fold multiplier's eigenspace spanned by e0 + e2 and e1 - e3: any two independent
    combinations are an eigenvector basis; the weights reported are the eigenspace's (the
    row norms of an orthonormal basis: 1/sqrt(2) on each of the four components), the same
    for both multipliers of the group and for every basis; a simple multiplier keeps its
    own eigenvector's."""
    lam = np.array([0.5, 0.5 + 1e-12, 0.2])
    a = np.array([1.0, 0.0, 1.0, 0.0]) / np.sqrt(2)
    b = np.array([0.0, 1.0, 0.0, -1.0]) / np.sqrt(2)
    c = np.array([0.0, 0.6, 0.0, 0.8])
    got = []
    for t in (0.0, 0.3, 1.1):
        u = np.cos(t) * a + np.sin(t) * b
        v = -np.sin(t) * a + 2.0 * np.cos(t) * b
        full = np.stack([u / np.linalg.norm(u), v / np.linalg.norm(v), c], axis=1)
        for j in (0, 1):
            comp, idx, basis = _dominant(lam, full, j, 3)
            assert np.allclose(comp, np.full(4, 1 / np.sqrt(2)), atol=1e-12)
            assert basis is not None and basis.shape == (4, 2)
            got.append(tuple(idx))
        comp, idx, basis = _dominant(lam, full, 2, 2)
        assert basis is None and np.array_equal(comp, np.abs(c)) and tuple(idx) == (3, 1)
    assert set(got) == {(0, 1, 2)}  # ties: in the order of the state's components
