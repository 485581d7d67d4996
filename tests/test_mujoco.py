"""The MuJoCo second opinion (SPEC 16), on real MuJoCo: the gait's controller on MuJoCo's soft
contact against the rigid-impact model (the zero dynamics, computed independently of
MuJoCo). Each run is a few steps: a few seconds per test."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
WALKER5 = str(DATA / "walker5.yaml")
WALKER5_WALK = str(DATA / "walker5_walk.yaml")
WALKER5_THRUST = str(DATA / "walker5_thrust.yaml")


@pytest.fixture(scope="module")
def mj():
    return pytest.importorskip("mujoco")


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    from thrustwalk_cli.walker import load_walker

    return load_walker(WALKER5, WALKER5_WALK)


@pytest.fixture(scope="module")
def walker5_thrust(_cache_dir):
    from thrustwalk_cli.walker import load_walker

    return load_walker(WALKER5, WALKER5_THRUST)


def _gaps(result) -> list[float]:
    return [e["zeta_minus"]["relative"] for e in result.step_entries()]


@pytest.mark.slow
def test_stiff_contact_approaches_the_rigid_prediction(mj, walker3):
    """With stiff contact (solref 1 ms, timestep 0.1 ms) the 3-link gait's zeta^- stays within
    2 % of the rigid prediction, at the last step and at the steady value the Poincare map
    extrapolates (the gap contracts by delta_zero^2 per step); the default contact (5 ms) is
    farther off: the gap shrinks as the contact stiffens (docs/commands.md has the trend)."""
    from thrustwalk_cli.studies.mujoco import mujoco_run

    stiff = mujoco_run(walker3, steps=4, contact="stiff")
    soft = mujoco_run(walker3, steps=3, contact="default")
    assert stiff.success and soft.success
    g, d2 = _gaps(stiff), walker3.zd.delta_zero_sq
    steady = g[-1] + (g[-1] - g[-2]) * d2 / (1 - d2)
    assert abs(g[-1]) < 0.02 and abs(steady) < 0.02, (g, steady)
    assert abs(_gaps(soft)[-1]) > abs(g[-1])
    # the rigid prediction is the zero-dynamics fixed point (the run starts on it)
    zs = stiff.runs[0].cycle.zeta_star
    assert all(e["zeta_minus"]["rigid"] == pytest.approx(zs, rel=1e-6)
               for e in stiff.step_entries())


@pytest.mark.slow
def test_walker5_first_step_follows_the_zero_dynamics(mj, walker5):
    """The knee walker (not bundled; point feet as 0.1 mm spheres): started on the predicted
    orbit, MuJoCo's first step (a stance phase, no MuJoCo impact yet) ends within 0.5 % of
    the zero-dynamics zeta*, with the step time and length of the orbit; then the soft
    impacts lose energy the rigid model does not (reported, not hidden)."""
    from thrustwalk_cli.studies.mujoco import mujoco_run

    res = mujoco_run(walker5, steps=3, contact="stiff")
    assert res.success, res.reason
    first = res.step_entries()[0]
    assert abs(first["zeta_minus"]["relative"]) < 0.005
    assert first["step_time"]["mujoco"] == pytest.approx(first["step_time"]["rigid"], rel=0.005)
    assert first["step_length"]["mujoco"] == pytest.approx(first["step_length"]["rigid"],
                                                           rel=0.005)
    assert first["double_support"]["mujoco"] is None  # it starts after an impact
    later = res.step_entries()[1:]
    assert all(e["zeta_minus"]["difference"] < 0 for e in later)  # soft impacts dissipate
    assert all(e["penetration"]["mujoco"] > 0 and e["double_support"]["mujoco"] is not None
               for e in later)


def test_infeasible_friction_slips_in_mujoco(mj, walker3):
    """At mu = 0.25 thrustwalk's feasibility calls the 3-link orbit infeasible (stance
    |F^h|/F^v reaches 0.31); in MuJoCo at that mu the stance contact saturates the friction
    cone and the foot slides, during the first step already (a stance phase started on the
    orbit); at the gait's mu = 0.7 the friction use stays inside the cone, as the rigid model
    computes it, and the foot does not slide."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.studies.mujoco import mujoco_run

    case = tw.feasibility(walker3, thrust=[0.0], mu=0.25).cases[0]
    assert not case.feasible and "friction ratio" in case.reason
    slip = mujoco_run(walker3, steps=1, mu=0.25)
    grip = mujoco_run(walker3, steps=1, mu=0.7)
    s, g = slip.step_entries()[0], grip.step_entries()[0]
    rigid_ratio = g["max_friction_ratio"]["rigid"]
    assert rigid_ratio > 0.25
    assert s["max_friction_ratio"]["mujoco"] == pytest.approx(0.25, rel=1e-6)  # on the cone
    assert g["max_friction_ratio"]["mujoco"] == pytest.approx(rigid_ratio, rel=0.02)
    assert s["slip_path"]["mujoco"] > 10 * g["slip_path"]["mujoco"]
    assert s["slip_path"]["mujoco"] > 3e-4
    assert slip.rigid_contact[0]["feasible"] is False
    assert grip.rigid_contact[0]["feasible"] is True


def test_an_orbit_the_rigid_model_calls_contact_infeasible_is_no_ok(mj, walker5):
    """walker5's gait needs |F^h|/F^v = 0.46 in stance (SPEC 5, computed by feasibility, not
    by the MuJoCo code). At mu = 0.4 MuJoCo's stance contact sits on the cone; zeta^- agrees
    to a fraction of a percent in one step, yet the rigid prediction it is compared with
    does not hold: the run is a warning that says why, never ok. At the gait's mu it is ok."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.studies.mujoco import mujoco_run

    need = tw.feasibility(walker5, thrust=[0.0], mu=0.7).cases[0].max_friction_ratio
    assert 0.4 < need < 0.7
    low, grip = mujoco_run(walker5, steps=1, mu=0.4), mujoco_run(walker5, steps=1, mu=0.7)
    assert abs(low.step_entries()[0]["zeta_minus"]["relative"]) < low.zeta_tol
    assert low.success and low.status == "warning", low.reason
    run = low.run_entries()[0]
    assert run["status"] == "warning" and run["rigid_contact"]["feasible"] is False
    assert "not contact-feasible at mu = 0.4 (infeasible: friction ratio" in run["reason"]
    assert grip.status == "ok" and grip.rigid_contact[0]["feasible"], grip.reason


@pytest.mark.slow
def test_thrust_speeds_the_walker_up_as_predicted(mj, walker5_thrust):
    """walker5 on its thrust gait, stiff contact: a constant -20 N on the torso thruster makes
    MuJoCo's walker faster by the factor the zero dynamics predict (speed and zeta^- ratios
    within 2 %), and each run stays within 2 % of its own prediction."""
    from thrustwalk_cli.studies.mujoco import mujoco_run

    res = mujoco_run(walker5_thrust, steps=2, thrust=[0.0, -20.0], contact="stiff")
    assert res.success, res.reason
    last = {e["run"]: e for e in res.step_entries()}
    for e in last.values():
        assert abs(e["zeta_minus"]["relative"]) < 0.02
    a, b = last[0], last[1]
    mj_ratio = b["speed"]["mujoco"] / a["speed"]["mujoco"]
    rigid_ratio = b["speed"]["rigid"] / a["speed"]["rigid"]
    assert rigid_ratio > 2  # thrust makes a real difference here
    assert mj_ratio == pytest.approx(rigid_ratio, rel=0.02)
    assert (b["zeta_minus"]["mujoco"] / a["zeta_minus"]["mujoco"]) == pytest.approx(
        b["zeta_minus"]["rigid"] / a["zeta_minus"]["rigid"], rel=0.02)


def test_push_and_thruster_dynamics(mj, walker3):
    """A forward push at the hip mid-step makes that step faster than the unpushed rigid
    prediction; a second-order thruster runs with its states (the prediction is the reduced
    cascade with the same thruster); the piecewise schedule is refused without one."""
    from thrustwalk_cli.errors import InputError
    from thrustwalk_cli.studies.mujoco import mujoco_run

    res = mujoco_run(walker3, steps=1, push=[(1, 0.5, 10.0, 0.0)])
    e = res.step_entries()[0]
    assert e["pushed"] and e["step_time"]["difference"] < -0.01
    dyn = mujoco_run(walker3, steps=2, thrust_model="second-order", thrust=[-20.0], wn=4.0)
    assert dyn.success
    steps = dyn.step_entries()
    assert steps[1]["thrust_at_touchdown"]["hip_x"] < steps[0]["thrust_at_touchdown"]["hip_x"]
    assert all(abs(x["zeta_minus"]["relative"]) < 0.05 for x in steps)
    with pytest.raises(InputError, match="thrust schedule"):
        mujoco_run(walker3, steps=1, thrust_model="piecewise")


@pytest.mark.slow
def test_cli_writes_everything_from_another_folder(mj, cli, tmp_path, monkeypatch):
    """thrustwalk mujoco on the user robot: JSON (each step's quantity beside the rigid
    prediction and the difference), CSV, the model that ran, the phase portraits; the video is
    written or its absence explained in one warning."""
    monkeypatch.chdir(tmp_path)
    res = cli("mujoco", WALKER5, WALKER5_WALK, "--steps", "2", "--out", "run", "-q",
              "--formats", "csv,png")
    assert res.exit_code == 0, res.stderr
    out = tmp_path / "run"
    doc = json.loads((out / "mujoco.json").read_text())
    assert {"mujoco.json", "steps.csv", "trajectory.csv", "robot.xml",
            "phase_portraits.png"} <= {p.name for p in out.iterdir()}
    assert (out / "walker.gif").exists() or "no video" in res.stderr
    if (out / "walker.gif").exists():
        assert (out / "walker.gif").read_bytes()[:4] == b"GIF8"
    assert doc["status"] in ("ok", "warning") and doc["success"]
    e = doc["steps"][1]
    for key in ("zeta_minus", "step_time", "speed", "slip", "bounce", "double_support",
                "penetration"):
        assert set(e[key]) >= {"mujoco", "rigid", "difference"}
    assert e["slip"]["rigid"] == 0.0 and e["penetration"]["rigid"] == 0.0
    assert doc["mujoco"]["contact"]["preset"] == "default"
    mj.MjModel.from_xml_path(str(out / "robot.xml"))
    header, *rows = (out / "steps.csv").read_text().splitlines()
    assert "zeta_minus_rigid" in header
    for row in rows:  # every cell a plain number, a boolean or empty (never 'np.float64(..)')
        for cell in row.split(","):
            assert cell in ("", "true", "false") or np.isfinite(float(cell)), row


@pytest.mark.parametrize("args, message", [
    (["--push", "1:x:3"], "option --push: '1:x:3' is not STEP:PHASE:PX[:PY]"),
    (["--push", "5:0.5:3"], "option --push: a push needs a step in 1..2"),
    (["--steps", "0"], "option --steps: must be 1..2000"),
    (["--contact", "rubber"], "option --contact: unknown preset"),
    (["--thrust", "-500"], "outside the limits"),
    (["--timestep", "1"], "option --timestep: must lie in"),
])
def test_bad_input_one_line(cli, tmp_path, args, message):
    res = cli("mujoco", "three_link", "--steps", "2", "--out", str(tmp_path / "o"), *args)
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], res.stderr


def test_api_without_mujoco(monkeypatch, walker3):
    """tw.mujoco_run says how to install MuJoCo when it is missing."""
    import thrustwalk_cli as tw

    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(tw.InputError, match=r"pip install 'thrustwalk\[mujoco\]'"):
        tw.mujoco_run(walker3, steps=1)


def test_video_frames_render_or_explain(mj, walker3):
    """Frames kept at the video rate render to a GIF offscreen (EGL or OSMesa), or the result
    says which renderers were tried and why none works."""
    from thrustwalk_cli.studies.mujoco import mujoco_run

    res = mujoco_run(walker3, steps=1, fps=4.0)
    assert len(res.runs[0].frames) == pytest.approx(4.0 * 0.66, abs=2)
    gif, note = res.video(fps=4.0, size=(160, 120))
    if gif is None:
        assert "tried" in note
    else:
        assert gif[:4] == b"GIF8" and "rendered offscreen" in note
    assert np.isfinite(res.runs[0].wall_time)
