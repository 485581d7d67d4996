"""export-mjcf (SPEC 16): the MJCF is accepted by MuJoCo's own compiler and is the same
mechanical model as thrustwalk's: MuJoCo's joint-space inertia (mj_fullM), gravity and
Coriolis forces, mapped to the pinned coordinates, equal thrustwalk's D, G and h to 1e-10 at
random states; the thruster actuators push as B_F says; re-rooting at the other foot keeps the
physical state. Without MuJoCo the export still works (unchecked)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
WALKER5 = str(DATA / "walker5.yaml")
WALKER5_WALK = str(DATA / "walker5_walk.yaml")
CASES = [("three_link", "three_link_walk"), ("rabbit", "rabbit_walk"),
         (WALKER5, WALKER5_WALK)]


@pytest.fixture(scope="module")
def walkers(_cache_dir):
    from thrustwalk_cli.walker import load_walker

    return {r: load_walker(r, g) for r, g in CASES}


def _loaded(walker):
    pytest.importorskip("mujoco")
    from thrustwalk_cli.interchange.mjcf import CONTACT_PRESETS
    from thrustwalk_cli.interchange.mujoco_run import MujocoModel

    return MujocoModel(walker.robot, CONTACT_PRESETS["default"], 0.7)


@pytest.mark.parametrize("robot", [c[0] for c in CASES], ids=["three_link", "rabbit",
                                                              "walker5"])
def test_mujoco_inertia_gravity_and_coriolis_equal_thrustwalks(walkers, robot):
    """M (mj_fullM), qfrc_bias at rest (gravity) and in motion (Coriolis + gravity) of the
    MJCF, mapped by q_u' -> qvel (J), equal D_u, G_u and h_u of thrustwalk's own derivation
    (the top-left block of J^T M J is the pinned D) to 1e-10, with the foot anywhere."""
    import mujoco

    from thrustwalk_cli.interchange.mujoco_run import full_inertia

    w = walkers[robot]
    sim = _loaded(w)
    m, d, n = sim.m, sim.d, w.robot.n
    J = sim.layout.unpinned_map()
    rng = np.random.default_rng(7)
    for _ in range(10):
        q, dq = rng.uniform(-np.pi, np.pi, n), rng.normal(size=n)
        foot, foot_rate = rng.normal(size=2), rng.normal(size=2)
        sim.set_state(q, dq, foot, foot_rate)
        mujoco.mj_forward(m, d)
        Du = J.T @ full_inertia(mujoco, m, d) @ J
        assert np.abs(Du[:n, :n] - w.model.D(q)).max() < 1e-10
        assert np.abs(Du - w.model.D_u(q)).max() < 1e-10
        h = J.T @ d.qfrc_bias
        assert np.abs(h - w.model.h_u(q, np.concatenate([dq, foot_rate]))).max() < 1e-10
        sim.set_state(q, np.zeros(n), foot)
        mujoco.mj_forward(m, d)
        assert np.abs((J.T @ d.qfrc_bias)[:n] - w.model.G(q)).max() < 1e-10


def test_thruster_actuators_push_as_B_F(walkers):
    """Each thruster's actuator with ctrl = 1 N gives MuJoCo generalised forces that map to
    thrustwalk's unpinned thruster column B_Fu[:, k] (world-fixed: refsite world; link-fixed:
    the site's frame), for both of three_link's thrusters (one of each kind)."""
    import mujoco

    w = walkers["three_link"]
    assert {t.frame for t in w.robot.thrusters} == {"world", "link"}
    sim = _loaded(w)
    m, d, n = sim.m, sim.d, w.robot.n
    J = sim.layout.unpinned_map()
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, n)
        sim.set_state(q, np.zeros(n), rng.normal(size=2))
        for k, t in enumerate(w.robot.thrusters):
            d.ctrl[:] = 0.0
            d.ctrl[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, t.name)] = 1.0
            mujoco.mj_forward(m, d)
            assert np.abs(J.T @ d.qfrc_actuator - w.model.B_Fu(q)[:, k]).max() < 1e-10


def test_relabel_keeps_the_physical_state(walkers):
    """Re-rooting MuJoCo's model at the swing foot (the relabelling at touchdown) keeps every
    body where it was and the kinetic energy; the feet exchange places; thrustwalk's mirror
    check is at round-off for the three robots."""
    import mujoco

    from thrustwalk_cli.interchange.mujoco_run import full_inertia, mirror_error

    for w in walkers.values():
        sim = _loaded(w)
        m, d, n = sim.m, sim.d, w.robot.n
        rng = np.random.default_rng(11)
        q, dq = w.zd.maps.q_minus + 0.1 * rng.normal(size=n), rng.normal(size=n)
        assert mirror_error(w.model, q) < 1e-12
        sim.set_state(q, dq, (0.2, 0.0), (0.1, -0.3))
        mujoco.mj_forward(m, d)
        ke = 0.5 * d.qvel @ full_inertia(mujoco, m, d) @ d.qvel
        feet = [d.site_xpos[s].copy() for s in sim.foot_site]
        com = d.subtree_com[1].copy()
        sim.relabel()
        mujoco.mj_forward(m, d)
        assert abs(0.5 * d.qvel @ full_inertia(mujoco, m, d) @ d.qvel - ke) < 1e-9 * max(1, ke)
        assert np.abs(d.site_xpos[sim.foot_site[0]] - feet[1]).max() < 1e-12
        assert np.abs(d.site_xpos[sim.foot_site[1]] - feet[0]).max() < 1e-12
        assert np.abs(d.subtree_com[1] - com).max() < 1e-12


def test_export_cli_from_another_folder(cli, tmp_path, monkeypatch, _cache_dir):
    """export-mjcf ROBOT GAIT writes an MJCF that MuJoCo compiles, with the gait's mu and the
    key 'start' just after an impact on the orbit (thrustwalk's q^+ mapped to qpos)."""
    mujoco = pytest.importorskip("mujoco")
    from thrustwalk_cli.walker import load_walker

    monkeypatch.chdir(tmp_path)
    res = cli("export-mjcf", WALKER5, WALKER5_WALK, "--out", "w5.xml")
    assert res.exit_code == 0, res.stderr
    assert "checked by MuJoCo" in res.stdout
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "w5.xml"))
    w = load_walker(WALKER5, WALKER5_WALK)
    assert m.nq == w.robot.n + 2 and m.nkey == 1
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    assert m.geom_friction[floor][0] == pytest.approx(w.gait.mu)
    from thrustwalk_cli.interchange.mjcf import layout

    q = layout(w.robot).q_of(m.key_qpos[0][2:])
    assert np.abs(q - w.zd.maps.q_plus).max() < 1e-12
    # the robot alone: default friction, no key
    res = cli("export-mjcf", WALKER5, "--out", "alone.xml", "--mu", "0.4", "-q")
    assert res.exit_code == 0, res.stderr
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "alone.xml"))
    assert m.nkey == 0 and m.geom_friction[floor][0] == pytest.approx(0.4)


@pytest.mark.parametrize("args, message", [
    (["--contact", "hard"], "option --contact: unknown preset 'hard'"),
    (["--solref", "0.0001,1"], "at least 2 timesteps"),
    (["--solref", "0.01"], "option --solref: expected 2"),
    (["--foot-radius", "-1"], "option --foot-radius: must lie in"),
    (["--mu", "0"], "option --mu: must be > 0"),
    (["--mu", "11"], "option --mu: must be <= 10"),
])
def test_export_bad_input_one_line(cli, tmp_path, args, message):
    res = cli("export-mjcf", "three_link", "--out", str(tmp_path / "x.xml"), *args)
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], res.stderr
    assert not (tmp_path / "x.xml").exists()


def test_export_without_mujoco(cli, tmp_path, monkeypatch):
    """Without MuJoCo export-mjcf still writes the file, and says it is unchecked and how to
    install MuJoCo; the mujoco command says how to install it, one line, exit 2."""
    monkeypatch.setitem(sys.modules, "mujoco", None)  # `import mujoco` raises ImportError
    res = cli("export-mjcf", "three_link", "--out", str(tmp_path / "x.xml"), "-q")
    assert res.exit_code == 0, res.stderr
    assert "pip install 'thrustwalk[mujoco]'" in res.stderr
    assert "<mujoco model=\"three_link\">" in (tmp_path / "x.xml").read_text()
    res = cli("mujoco", "three_link", "--steps", "1", "--out", str(tmp_path / "run"))
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'thrustwalk[mujoco]'" in lines[0], res.stderr
