"""Energy along a compiled run through the compiled kernel (SPEC 15, 7; issue 28's speed
target): the closed loop at the quadrature nodes of a compiled run is evaluated by the kernel
(``step_stats.energy_nodes``), never by NumPy's ``ClosedLoop.law``, and every energy equals the
one of the NumPy path on the same dense output (``ClosedLoop.law``, an independent
implementation of the equations of SPEC 7) to 1e-10 relative: thrust ideal, first-order and
second-order, torques saturated, the thrust given per step as data (``seg_force``) with a
lagging thruster, a robot with motors and a robot without."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from thrustwalk_cli.energetics.run import run_energy, simulation_energy
from thrustwalk_cli.simulation.closed_loop import ClosedLoop, SimConfig, ThrustModel
from thrustwalk_cli.simulation.full_order import simulate
from thrustwalk_cli.walker import load_walker

DATA = Path(__file__).resolve().parent / "data"
FIELDS = ("joint_work", "joint_positive_work", "joint_absolute_work", "joint_electrical",
          "thrust_work", "thrust_positive_work", "generalized_work", "thruster_input",
          "fuel_mass", "kinetic_start", "kinetic_end", "potential_start", "potential_end",
          "step_time", "distance", "kinetic_after", "push_energy")


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))


def _steps(res, numpy_path: bool = False) -> list[tuple]:
    """``run_energy``'s steps of a run; ``numpy_path``: each dense solution wrapped so that
    only its rows show (not the kernel's type): the NumPy path on the same interpolants."""
    by_step: dict[int, list] = {}
    for s in res.segments:
        sol = (SimpleNamespace(rows=s.sol.rows, t_old=s.sol.t_old, t_new=s.sol.t_new)
               if numpy_path else s.sol)
        by_step.setdefault(s.step, []).append((s.t0, s.t1, s.interval, sol))
    return [(r.step, by_step[r.step], r.q_minus, r.dq_minus) for r in res.steps]


def _same(a, b) -> None:
    """Every field of two lists of step energies equal to 1e-10 relative (of the step's
    scale for a value near 0: the absolute work and energies it is made of)."""
    assert len(a) == len(b) > 0
    for ea, eb in zip(a, b):
        scale = (sum(eb.joint_absolute_work) + sum(map(abs, eb.thrust_work))
                 + eb.kinetic_start + abs(eb.potential_start))
        for f in FIELDS:
            va, vb = getattr(ea, f), getattr(eb, f)
            va, vb = (va, vb) if isinstance(va, tuple) else ((va,), (vb,))
            assert len(va) == len(vb), f
            for x, y in zip(va, vb):
                assert (x is None) == (y is None), f
                if x is not None:
                    assert abs(x - y) <= 1e-10 * max(abs(y), 1e-3 * scale), (f, x, y)


def _no_numpy_law(monkeypatch) -> None:
    def refuse(*args, **kwargs):
        raise AssertionError("ClosedLoop.law called for a compiled run's energies")
    monkeypatch.setattr(ClosedLoop, "law", refuse)


@pytest.mark.parametrize("model", ["ideal", "first-order", "second-order"])
def test_a_compiled_runs_energies_come_from_the_kernel_and_equal_the_numpy_path(
        walker5, model, monkeypatch):
    """walker5, thrust -20 N on its torso thruster through each thrust model (a lagging
    thruster: the thrust a state of the run): the step energies of a compiled run never call
    ``ClosedLoop.law`` and equal the NumPy path's on the same dense output."""
    th = ThrustModel(model, np.array([-20.0]), tau=0.3, wn=4.0, xi=0.8,
                     initial=np.array([-5.0]))
    res = simulate(walker5.zd, th, SimConfig(steps=2))
    assert res.success, res.reason
    want = run_energy(res.sim, _steps(res, numpy_path=True))
    with monkeypatch.context() as mp:
        _no_numpy_law(mp)
        got = simulation_energy(res)
    _same(got, want)


def test_saturated_torques_and_motors(walker3, monkeypatch):
    """The bundled 3-link walker (motors: the electrical energy, clipped and regenerated)
    with a torque limit below its largest torque, so that the kernel's saturated branch
    (``D q'' = -h + B_tau u + B_F F`` solved again) is taken at some nodes."""
    free = simulate(walker3.zd, ThrustModel("ideal", np.array([-10.0, 0.0])), SimConfig(steps=1))
    limit = 0.97 * free.steps[0].max_abs_torque
    res = simulate(walker3.zd, ThrustModel("ideal", np.array([-10.0, 0.0])),
                   SimConfig(steps=1, torque_limit=limit))
    assert res.steps and res.steps[0].torque_saturated
    for regenerate in (False, True):
        want = run_energy(res.sim, _steps(res, numpy_path=True), regenerate=regenerate)
        with monkeypatch.context() as mp:
            _no_numpy_law(mp)
            got = run_energy(res.sim, _steps(res), regenerate=regenerate)
        assert any(v is not None for v in got[0].joint_electrical)
        _same(got, want)


def test_thrust_given_per_step_with_a_lagging_thruster(walker5, monkeypatch):
    """``seg_force`` (a controller's thrust set step by step, T = 0) on a closed loop whose
    thruster has states (first-order): the kernel takes the given thrust, not its thruster
    states, as ``ClosedLoop.law`` does; two steps with different thrust in one call."""
    res = simulate(walker5.zd, ThrustModel("first-order", np.array([-20.0]), tau=0.3),
                   SimConfig(steps=2))
    assert res.success, res.reason
    nseg = len(res.sim.breaks) + 1
    forces = [np.linspace(-30.0, -10.0, nseg).reshape(nseg, 1), np.full((nseg, 1), -5.0)]
    want = run_energy(res.sim, _steps(res, numpy_path=True), seg_force=forces)
    with monkeypatch.context() as mp:
        _no_numpy_law(mp)
        got = run_energy(res.sim, _steps(res), seg_force=forces)
    _same(got, want)
    # the thrust work is that of the given thrust: -5 N in the second step, not the run's
    other = run_energy(res.sim, _steps(res))
    assert abs(got[1].thrust_work[0] - other[1].thrust_work[0]) > 1e-3


def test_piecewise_thrust_with_a_generalised_force_and_a_slope(walker5, monkeypatch):
    """A piecewise schedule in force and generalised mode (``T`` on ``q_N`` per segment: the
    generalised work) on level ground, and constant thrust on a 0.03 rad downhill slope (the
    kernel's turned posture): the kernel's energies equal the NumPy path's."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.thrust.schedule import Schedule

    zd = walker5.zd
    knots = np.linspace(zd.alpha_i, zd.alpha_f, 4)
    sched = Schedule(knots, np.array([[[-10.0], [-20.0], [-5.0]]]),
                     np.array([[1.0, -2.0, 0.5]]))
    runs = [simulate(zd, ThrustModel("piecewise", np.zeros(1), schedule=sched),
                     SimConfig(steps=2)),
            tw.simulate(walker5, steps=2, thrust_model="ideal", thrust=[-20.0],
                        slope=-0.03).outcomes[0].full]
    for res in runs:
        assert res.success, res.reason
        want = run_energy(res.sim, _steps(res, numpy_path=True))
        with monkeypatch.context() as mp:
            _no_numpy_law(mp)
            got = run_energy(res.sim, _steps(res))
        _same(got, want)
    assert all(abs(e.generalized_work) > 1e-3 for e in run_energy(runs[0].sim, _steps(runs[0])))
