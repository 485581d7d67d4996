"""The robot's numbers as inputs of the compiled model (issue 14) and the derivation in
absolute link angles (issue 26): one compiled model per structure, bound to each robot's
numbers, equal to a model compiled by the reference derivation with the numbers folded into
its code (``compiler.folded_model``: ``derive_reference.derive_reference``, the Lagrange derivation
with Christoffel sums in ``q`` that the model used before issue 26, and SymPy's
common-subexpression elimination) to 1e-12 relative: every generated function (D, C, G,
h = C q' + G, B_F, the unpinned model, the kinematics), the impact map, every tape program,
the compiled batch D and C q' + G, the limit cycle (zeta*, speed, delta_zero^2) and a short
compiled simulation (zeta^- per step), on the bundled robots and on chain bipeds of 4 to 9
links (``bench/chains.py``), which are also checked against ``tests/independent.py``. Also:
the cache key is the structure, new numbers are checked (a negative mass is reported with
the robot file and key), and a sweep over a robot parameter compiles once.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import textwrap
from pathlib import Path

import independent as ind
import numpy as np
import pytest

from thrustwalk_cli.errors import InputError
from thrustwalk_cli.files.robot_file import load_robot, load_robot_text
from thrustwalk_cli.model import compiler, jit
from thrustwalk_cli.model.compiled import FUNCTIONS
from thrustwalk_cli.model.compiler import folded_model, load_model

GAITS = {"three_link": "three_link_walk", "rabbit": "rabbit_walk"}
SEEDS = (1, 2, 3)
REL = 1e-12


def _parameters(name: str, seed: int, keep: tuple[str, ...] = ()) -> dict[str, float]:
    """The robot file's named parameters (but ``keep``), each scaled by a seeded factor in
    [0.85, 1.15]."""
    rng = np.random.default_rng(seed)
    return {k: v * float(rng.uniform(0.85, 1.15)) for k, v in load_robot(name).parameters
            if k not in keep}


# a gait's impact posture puts the swing foot on the ground for its robot's leg lengths:
# RABBIT's femur and tibia lengths stay (the 3-link's legs scale together with r)
LENGTHS = {"three_link": (), "rabbit": ("lf", "lt")}


_FOLDED: dict[tuple[str, int], tuple] = {}


def _chain_module():
    spec = importlib.util.spec_from_file_location(
        "chains", Path(__file__).resolve().parents[1] / "bench" / "chains.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


chains = _chain_module()
# the folded reference models (_pair) are computed once per process and used by two tests
# each: pytest-xdist keeps this module in one worker (tests/conftest.py)
ONE_WORKER = True


def _robot(name: str, seed: int):
    """A bundled robot or ``chain<N>`` (bench/chains.py) with its named parameters scaled
    by seeded factors."""
    if not name.startswith("chain"):
        return load_robot(name, _parameters(name, seed))
    text = chains.chain_yaml(int(name[5:]))
    rng = np.random.default_rng(seed)
    base = load_robot_text(text, f"{name}.yaml")
    params = {k: v * float(rng.uniform(0.85, 1.15)) for k, v in base.parameters}
    return load_robot_text(text, f"{name}.yaml", params)


def _pair(name: str, seed: int):
    """(robot, model with the numbers as inputs, model with the numbers folded in by the
    reference derivation)."""
    if (name, seed) not in _FOLDED:
        robot = _robot(name, seed)
        _FOLDED[name, seed] = (robot, load_model(robot), folded_model(robot))
    return _FOLDED[name, seed]


def _close(what: str, got, want, rel: float = REL) -> None:
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert got.shape == want.shape, (what, got.shape, want.shape)
    scale = max(float(np.abs(want).max()) if want.size else 0.0, 1e-300)
    err = float(np.abs(got - want).max()) if want.size else 0.0
    assert err <= rel * scale, f"{what}: error {err:.3e} > {rel:.0e} * {scale:.3g}"


def _states(n: int, k: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(100 + seed)
    return rng.uniform(-np.pi, np.pi, (k, n)), rng.normal(0.0, 2.0, (k, n))


# chains: even (no torso, the anchor is the top stance link) and odd (a torso anchor)
CHAINS = [("chain4", 1), ("chain7", 2),
          pytest.param("chain9", 3, marks=pytest.mark.slow)]  # the reference: 5 s
over = pytest.mark.parametrize("name, seed", [(n, s) for n in GAITS for s in SEEDS] + CHAINS)


@pytest.mark.slow
@over
def test_every_generated_function_equals_the_folded_model(name, seed, _cache_dir):
    robot, model, ref = _pair(name, seed)
    assert model.numbers.tolist() == [v for _, v in robot.numbers()]
    n = model.n
    q, dq = _states(n, 25, seed)
    dqu = np.concatenate([dq, np.random.default_rng(seed).normal(size=(25, 2))], axis=1)
    args = {"q": q, "dq": dq, "dq_u": dqu}
    for fname, (names, _doc) in FUNCTIONS.items():
        a = [args[x] for x in names]
        _close(f"{name}/{seed}: {fname}", getattr(model, fname)(*a), getattr(ref, fname)(*a))
        for i in range(3):  # the scalar functions (lists in, flat list out)
            s = [args[x][i].tolist() for x in names]
            _close(f"{name}/{seed}: {fname}_s", getattr(model, fname + "_s")(*s),
                   getattr(ref, fname + "_s")(*s))
    for part in ("q_plus", "dq_plus", "dq_u_plus", "impulse"):
        _close(f"{name}/{seed}: impact {part}", getattr(model.impact(q, dq), part),
               getattr(ref.impact(q, dq), part))
    for got, want in zip(model.impact_maps(q), ref.impact_maps(q)):
        _close(f"{name}/{seed}: impact maps", got, want)
    _close(f"{name}/{seed}: energy", model.energy(q, dq), ref.energy(q, dq))


@pytest.mark.slow
@over
def test_every_tape_program_equals_the_folded_model(name, seed, _cache_dir):
    _, model, ref = _pair(name, seed)
    assert model.tape.consts.size > ref.tape.consts.size  # the numbers' coefficients
    q, dq = _states(model.n, 40, seed)
    x = np.concatenate([q, dq], axis=1)
    for program, p in model.tape.programs.items():
        n_in = int(model.tape.code[p])
        _close(f"{name}/{seed}: tape {program}", jit.run_batch(model, program, x[:, :n_in]),
               jit.run_batch(ref, program, x[:, :n_in]))
    for got, want in zip(jit.D_h_batch(model, q, dq), jit.D_h_batch(ref, q, dq)):
        _close(f"{name}/{seed}: D_h_batch", got, want)
    # the parametric tape against the folded model's generated NumPy functions
    D, h = jit.D_h_batch(model, q, dq)
    _close(f"{name}/{seed}: D_h_batch D vs NumPy", D, ref.D(q))
    _close(f"{name}/{seed}: D_h_batch h vs NumPy", h, ref.h(q, dq), rel=1e-11)


@pytest.mark.parametrize("name, seed", [("chain4", 1), ("chain7", 2)])
def test_chains_match_the_independent_computation(name, seed, _cache_dir):
    """SPEC 1 on chain bipeds: D and D_u (sum of m J^T J + I w^T w), C and C_u (the
    Christoffel symbols of those, by complex step), G = dV/dq, h = C q' + G, h_u = C_u q_u'
    + G_u, the swing foot and its Jacobian, the thruster's power identity, all from
    tests/independent.py (1e-10 relative; 1e-12 for positions)."""
    robot = _robot(name, seed)
    model = load_model(robot)
    n = model.n
    q, dq = _states(n, 4, seed)
    q = q / 3  # [-pi/3, pi/3]
    dqu = np.concatenate([dq, np.random.default_rng(seed).normal(size=(4, 2))], axis=1)
    D_ref = np.array([ind.mass_matrix(robot, x) for x in q])
    Du_ref = np.array([ind.unpinned_mass_matrix(robot, x) for x in q])
    C_ref = np.array([ind.christoffel_C(robot, x, v) for x, v in zip(q, dq)])
    Cu_ref = np.array([ind.christoffel_C(robot, x, v, unpinned=True) for x, v in zip(q, dqu)])
    G_ref = np.array([ind.complex_step(lambda y: ind.potential(robot, y), x) for x in q])
    G_u = np.concatenate([G_ref, np.zeros((4, 1)),
                          np.full((4, 1), robot.total_mass * robot.gravity)], axis=1)
    _close(f"{name}: D", model.D(q), D_ref, 1e-10)
    _close(f"{name}: D_u", model.D_u(q), Du_ref, 1e-10)
    _close(f"{name}: C", model.C(q, dq), C_ref, 1e-10)
    _close(f"{name}: C_u", model.C_u(q, dqu), Cu_ref, 1e-10)
    _close(f"{name}: G", model.G(q), G_ref, 1e-10)
    _close(f"{name}: h", model.h(q, dq), np.einsum("kij,kj->ki", C_ref, dq) + G_ref, 1e-10)
    _close(f"{name}: h_u", model.h_u(q, dqu), np.einsum("kij,kj->ki", Cu_ref, dqu) + G_u,
           1e-10)
    _close(f"{name}: p_swing", model.p_swing(q), [ind.swing_foot(robot, x) for x in q])
    _close(f"{name}: E_swing", model.E_swing(q), [ind.swing_jacobian(robot, x) for x in q])
    F = np.array([7.0])
    for x, v in zip(q, dqu):
        power = ind.thruster_power(robot, x, np.concatenate([v[:n], [0.0, 0.0]]), F)
        _close(f"{name}: thruster power", v[:n] @ model.B_F(x) @ F, power, 1e-10)


@pytest.mark.parametrize("name", list(GAITS))
def test_one_compiled_model_serves_every_set_of_numbers(name, _cache_dir):
    """Robots differing only in their numbers share the key, the cache entry, the generated
    module and the tape's instructions (one array); each binds its own numbers."""
    base = load_model(load_robot(name))
    before = compiler.COMPILES
    models = [load_model(load_robot(name, _parameters(name, s))) for s in (11, 12, 13)]
    assert compiler.COMPILES == before, "new numbers must not compile"
    for m in models:
        assert m.cache_hit and m.key == base.key and m.cache_path == base.cache_path
        assert m._m is base._m and m.tape.code is base.tape.code
        assert not np.array_equal(m.numbers, base.numbers)
        assert not np.array_equal(m.tape.consts, base.tape.consts)
        assert not np.array_equal(m.D([0.1] * m.n), base.D([0.1] * m.n))


def test_the_cache_key_is_the_structure(_cache_dir):
    """Numbers do not change the key; a zero that becomes a number, a thruster's frame or a
    renamed link do (they change the generated code)."""
    robot = load_robot("rabbit")
    key = compiler.model_key(robot)
    assert compiler.model_key(load_robot("rabbit", {"mT": 20.0, "lf": 0.45,
                                                    "Jr": 1e-4})) == key
    assert compiler.model_key(dataclasses.replace(robot, gravity=1.62)) == key
    assert compiler.model_key(load_robot("rabbit", {"Jr": 0.0})) != key  # rotors dropped
    thr = dataclasses.replace(robot.thrusters[0], frame="link")
    assert compiler.model_key(dataclasses.replace(robot, thrusters=(thr,))) != key
    links = list(robot.links)
    links[2] = dataclasses.replace(links[2], name="body")
    assert compiler.model_key(dataclasses.replace(robot, links=tuple(links))) != key
    assert compiler.model_key(robot, folded=True) != compiler.model_key(
        dataclasses.replace(robot, gravity=1.62), folded=True)


def test_bad_numbers_are_reported_with_the_file_and_key(_cache_dir):
    """Negative leg masses (D indefinite) bound to an already compiled structure are still
    reported as ``file:line: links: ...``; the shared cache entry stays valid."""
    good = load_model(load_robot("three_link"))
    robot = good.robot
    links = list(robot.links)
    for i in (0, 2):  # both legs (the relabelling still swaps the feet)
        links[i] = dataclasses.replace(links[i], mass=-40.0)
    bad = dataclasses.replace(robot, links=tuple(links))
    assert compiler.model_key(bad) == good.key
    with pytest.raises(InputError) as exc:
        load_model(bad)
    msg = str(exc.value)
    assert msg.startswith(f"{robot.source_file}:{robot.line_of('links')}: links: ")
    assert "not positive definite" in msg
    with pytest.raises(InputError):  # checked again, not remembered as good
        load_model(bad)
    from thrustwalk_cli.model import cache

    assert cache.verify_entry(good.cache_path, good.key) is None
    assert load_model(robot).cache_hit


@pytest.mark.slow
@pytest.mark.parametrize("name", list(GAITS))
def test_limit_cycle_equals_the_folded_model(name, _cache_dir, monkeypatch):
    """zeta*, speed and delta_zero^2 of the gait on a robot with new numbers."""
    import thrustwalk_cli.walker as walker_mod
    from thrustwalk_cli.studies.limit_cycle import limit_cycle

    params = _parameters(name, 4, LENGTHS[name])
    w = walker_mod.load_walker(name, GAITS[name], robot_parameters=params)
    monkeypatch.setattr(walker_mod, "load_model", folded_model)
    w_ref = walker_mod.load_walker(name, GAITS[name], robot_parameters=params)
    assert w.model.key != w_ref.model.key
    thrust = [0.0, -10.0, -20.0]
    got, want = limit_cycle(w, thrust), limit_cycle(w_ref, thrust)
    _close(f"{name}: delta_zero^2", w.zd.delta_zero_sq, w_ref.zd.delta_zero_sq)
    assert any(c.exists for c in want.cycles)
    for a, b in zip(got.cycles, want.cycles):
        assert a.exists == b.exists
        if b.exists:
            _close(f"{name}: zeta*", a.zeta_star, b.zeta_star)
            _close(f"{name}: speed", a.speed, b.speed)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(GAITS))
def test_compiled_simulation_equals_the_folded_model(name, _cache_dir, monkeypatch):
    """zeta^- of every step of a compiled run (the numba kernel reads the bound numbers
    from its input arrays) equals the run of the model with the numbers folded in."""
    import thrustwalk_cli.walker as walker_mod
    from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
    from thrustwalk_cli.simulation.full_order import Start, simulate

    params = _parameters(name, 5, LENGTHS[name])
    w = walker_mod.load_walker(name, GAITS[name], robot_parameters=params)
    monkeypatch.setattr(walker_mod, "load_model", folded_model)
    w_ref = walker_mod.load_walker(name, GAITS[name], robot_parameters=params)
    th = ThrustModel("constant", np.zeros(w.model.n_thrusters))
    cfg = SimConfig(steps=4, method="compiled")
    got = simulate(w.zd, th, cfg, Start(perturb=0.05))
    want = simulate(w_ref.zd, th, cfg, Start(perturb=0.05))
    assert want.success and got.success, (got.reason, want.reason)
    assert len(got.steps) == len(want.steps) == 4
    for a, b in zip(got.steps, want.steps):
        _close(f"{name}: zeta^- of step {b.step}", a.zeta_minus, b.zeta_minus)


SWEEP = """\
name: once
study: limit-cycle
robot: three_link
gait: three_link_walk
grid:
  robot.MT: {values: [8.5, 9.5, 10.5, 11.5], unit: kg}
  thrust: {values: [0, -10]}
collect: [speed, zeta_star]
"""


def test_a_sweep_over_a_robot_parameter_compiles_once(tmp_path, monkeypatch):
    """Every point of a torso-mass sweep binds its numbers to one compiled model: one
    derivation in the process, one model entry in an empty cache."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.studies import sweep_points

    cache_dir = tmp_path / "cache"
    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(cache_dir))
    monkeypatch.setattr(compiler, "_LOADED", {})
    monkeypatch.setattr(sweep_points, "CACHE", type(sweep_points.CACHE)())
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(SWEEP))
    before = compiler.COMPILES
    sweep = tw.load_sweep(path)
    res = tw.run_sweep(sweep, workers=1)
    assert res.success and res.done == len(sweep.tasks) == 8
    assert compiler.COMPILES - before == 1
    entries = [p.name for p in cache_dir.iterdir() if p.name.startswith("three_link-")
               and not p.name.endswith(".lock")]  # (the entry's build lock beside it)
    assert len(entries) == 1, entries
    speeds = {rec["values"]["robot.MT"]: rec["fields"]["speed"] for rec in res.records
              if rec["values"]["thrust"] == 0}
    assert len(set(speeds.values())) == 4  # the numbers did reach the points
