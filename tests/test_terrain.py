"""Steps and rough ground in the full-order simulation (SPEC 14): terrain files, the guard at
the step's height, step-downs past s = 1, the missed footing, ``simulate --terrain``.

Each check against an independent computation or an identity: the level-ground run (a
terrain of zero heights is that run bit for bit), the zero-dynamics fixed point (a single
step-up followed by level ground converges back to it), the swing foot's position at the
impact from the kinematics (it lands at the step's height), the SciPy path against the
compiled kernel, numpy's seeded draws for rough ground.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.description.terrain import Terrain
from thrustwalk_cli.errors import InputError
from thrustwalk_cli.files.terrain_file import load_terrain
from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel, zeta_star_at
from thrustwalk_cli.simulation.full_order import simulate
from thrustwalk_cli.studies.simulate import simulate as simulate_study
from thrustwalk_cli.walker import load_walker

DATA = Path(__file__).resolve().parent / "data"
ROBOT5, GAIT5 = DATA / "walker5.yaml", DATA / "walker5_thrust.yaml"
F5 = np.array([-20.0])  # walker5's gait is designed over -40..0 N of its torso thruster


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return load_walker(str(ROBOT5), str(GAIT5))


def _ideal(walker, F=None):
    return ThrustModel("constant", np.zeros(walker.model.n_thrusters) if F is None else F)


@pytest.mark.parametrize("method", ["compiled", "scipy"])
def test_zero_heights_are_level_ground_bit_for_bit(method, walker5):
    """A terrain of zero heights reproduces the level-ground run exactly (every record field,
    to the bit)."""
    th, cfg = _ideal(walker5, F5), SimConfig(steps=3, method=method)
    a = simulate(walker5.zd, th, cfg)
    b = simulate(walker5.zd, th, cfg, heights=[0.0, 0.0, 0.0])
    assert a.success and a.steps == b.steps


def test_zero_height_terrain_file_is_level_ground(walker5, tmp_path):
    """Through the study: a terrain file ``steps: [0.0]`` gives the steps of the run without
    a terrain, each with ``terrain_height`` 0, and records the terrain."""
    f = tmp_path / "flat.yaml"
    f.write_text("steps: [0.0]\n")
    kw = dict(steps=2, thrust=[-20.0], thrust_model="ideal")
    base = simulate_study(walker5, **kw).document()
    doc = simulate_study(walker5, terrain=str(f), **kw).document()
    assert [e.pop("terrain_height") for e in doc["steps"]] == [0.0, 0.0]
    assert doc["steps"] == base["steps"]
    assert doc["settings"]["terrain"]["steps"] == [0.0]
    assert doc["status"] == base["status"] == "ok"


def test_step_up_then_level_ground_converges_to_the_fixed_point(walker5):
    """One 1 cm step up, then level ground: the swing foot lands at the step's height (its
    position from the kinematics), early (s < 1), the run is off the fixed point and then
    converges back to the zero dynamics' zeta* (within 1e-6, relative)."""
    n = 45
    res = simulate(walker5.zd, _ideal(walker5, F5), SimConfig(steps=n),
                   heights=[0.01] + [0.0] * (n - 1))
    assert res.success, res.reason
    first = res.steps[0]
    assert first.terrain_height == 0.01 and all(st.terrain_height == 0.0
                                                for st in res.steps[1:])
    assert float(walker5.model.p_swing(np.array(first.q_minus))[1]) == pytest.approx(
        0.01, abs=1e-9)
    assert first.s_minus < 0.95
    zs = zeta_star_at(walker5.zd, F5)
    assert abs(res.steps[1].zeta_minus - zs) > 1e-3 * zs  # knocked off the orbit
    assert res.steps[-1].zeta_minus == pytest.approx(zs, rel=1e-6)


def test_step_down_lands_after_s_1_and_methods_agree(walker_rabbit):
    """A 5 mm step down: the foot lands past s = 1 on the continued Bezier polynomials, at
    the step's height; compiled and SciPy agree per step as on level ground."""
    th = _ideal(walker_rabbit)
    heights = [-0.005, 0.0, 0.0]
    a = simulate(walker_rabbit.zd, th, SimConfig(steps=3, method="scipy"), heights=heights)
    b = simulate(walker_rabbit.zd, th, SimConfig(steps=3), heights=heights)
    assert a.success and b.success, (a.reason, b.reason)
    assert b.steps[0].s_minus > 1.01
    for st in b.steps:
        p = walker_rabbit.model.p_swing(np.array(st.q_minus))
        assert float(p[1]) == pytest.approx(st.terrain_height, abs=1e-9)
    for x, y in zip(a.steps, b.steps):
        assert y.zeta_minus == pytest.approx(x.zeta_minus, rel=1e-9)
        assert y.s_minus == pytest.approx(x.s_minus, rel=1e-9)
        assert y.impulse == pytest.approx(x.impulse, rel=1e-8)
        assert y.terrain_height == x.terrain_height


@pytest.mark.parametrize("method", ["compiled", "scipy"])
def test_missed_footing(method, walker3):
    """A 20 cm drop with s_max 1.02: no touchdown by s_max is ``missed_footing``."""
    res = simulate(walker3.zd, _ideal(walker3), SimConfig(steps=2, max_s=1.02, method=method),
                   heights=[-0.2, 0.0])
    assert not res.success and res.failure == "missed_footing", res.reason
    assert "s = 1.02 (s_max)" in res.reason and not res.steps


def test_rough_ground_is_seeded_and_methods_agree(walker_rabbit, tmp_path):
    """Rough ground (uniform, seeded): the heights are numpy's default_rng(seed) draws, each
    step lands on its own, compiled and SciPy agree per step."""
    f = tmp_path / "rough.yaml"
    f.write_text("rough: {distribution: uniform, half_width: 0.004, seed: 11}\n")
    terrain = load_terrain(f)
    want = np.random.default_rng(11).uniform(-0.004, 0.004, 3)
    assert terrain.heights(3).tolist() == want.tolist()
    th = _ideal(walker_rabbit)
    a = simulate(walker_rabbit.zd, th, SimConfig(steps=3, method="scipy"), heights=want)
    b = simulate(walker_rabbit.zd, th, SimConfig(steps=3), heights=want)
    assert a.success and b.success, (a.reason, b.reason)
    assert [st.terrain_height for st in b.steps] == want.tolist()
    for x, y in zip(a.steps, b.steps):
        assert y.zeta_minus == pytest.approx(x.zeta_minus, rel=1e-9)
    normal = Terrain(distribution="normal", spread=0.01, seed=3).heights(5)
    assert normal.tolist() == np.random.default_rng(3).normal(0.0, 0.01, 5).tolist()
    assert Terrain(steps=(0.01, -0.02)).heights(4).tolist() == [0.01, -0.02, 0.0, 0.0]


def test_cli_simulate_terrain(cli, tmp_path, monkeypatch):
    """``simulate --terrain`` from another folder: the terrain is recorded, every step carries
    its height (JSON and CSV), a run off the level-ground prediction is a warning, not ok."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    (tmp_path / "up.yaml").write_text("description: a step up\nsteps: [0.01]\n")
    r = cli("simulate", str(ROBOT5), str(GAIT5), "--terrain", "../up.yaml", "--steps", "4",
            "--thrust-model", "ideal", "--thrust", "-20", "--formats", "csv", "--out", "o",
            "--quiet")
    assert r.exit_code == 0, r.output
    doc = json.loads((work / "o" / "simulation.json").read_text())
    t = doc["settings"]["terrain"]
    assert t["steps"] == [0.01] and t["s_max"] == 1.3 and t["description"] == "a step up"
    assert [e["terrain_height"] for e in doc["steps"]] == [0.01, 0.0, 0.0, 0.0]
    assert doc["runs"][0]["status"] == "warning"
    assert "terrain" in doc["runs"][0]["reason"]
    header = (work / "o" / "steps.csv").read_text().splitlines()[0].split(",")
    assert "terrain_height_m" in header


@pytest.mark.parametrize("text,line,key", [
    ("steps: [0.01, .nan]\n", 1, "steps[1]"),
    ("description: x\nrough: {distribution: gauss, sigma: 0.01}\n", 2, "rough.distribution"),
    ("rough:\n  distribution: normal\n  sigma: -0.01\n", 3, "rough.sigma"),
    ("rough:\n  distribution: uniform\n  sigma: 0.01\n", 3, "rough.sigma"),
    ("steps: [0.01]\nrough: {distribution: normal, sigma: 0.01}\n", 2, "rough"),
])
def test_cli_simulate_bad_terrain(text, line, key, cli, tmp_path, monkeypatch):
    """A NaN height, an unknown distribution, a sigma below 0, a parameter of the other
    distribution, both steps and rough: one line naming file, line and key, exit 2, nothing
    written."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.yaml").write_text(text)
    r = cli("simulate", str(ROBOT5), str(GAIT5), "--terrain", "bad.yaml", "--steps", "2",
            "--out", "o")
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: bad.yaml:{line}: {key}: "), lines
    assert not (tmp_path / "o").exists()
    with pytest.raises(InputError):
        load_terrain(tmp_path / "bad.yaml")


def test_terrain_slope_and_slope_option_conflict(walker5, tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("slope: 0.02\nsteps: [0.0]\n")
    with pytest.raises(InputError, match="slope"):
        simulate_study(walker5, terrain=str(f), slope=0.03, steps=2, check_only=True)
    with pytest.raises(InputError, match="reduced"):
        simulate_study(walker5, terrain=str(f), reduced=True, steps=2, check_only=True)
