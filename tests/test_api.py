"""The public Python API (``import thrustwalk_cli as tw``): the README example runs and prints
what the README shows, a notebook gets the numbers the command writes, every public name loads
from its home and is documented, and importing the package (or the CLI) loads no heavy
library."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import thrustwalk_cli as tw

REPO = Path(__file__).resolve().parents[1]


def _readme_example() -> tuple[str, str]:
    """The code block of the README's "Use from Python" section and the output shown."""
    text = (REPO / "README.md").read_text()
    sec = text.split("## Use from Python", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```(\w*)\n(.*?)```", sec, re.S)
    code = next(b for lang, b in blocks if lang == "python")
    shown = next(b for lang, b in blocks if lang == "")
    return code, shown


def _run(code: str, cwd: Path, cache: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND="Agg", THRUSTWALK_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


@pytest.mark.slow
def test_readme_example_runs_and_prints_what_the_readme_shows(tmp_path, _cache_dir):
    code, shown = _readme_example()
    res = _run(code, tmp_path, _cache_dir)
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout == shown, "README output block is stale:\n" + res.stdout
    assert (tmp_path / "limit_cycles.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _without_provenance(doc: dict) -> dict:
    return {k: v for k, v in doc.items() if k not in ("provenance", "tables")}


@pytest.mark.parametrize("command, study, json_name", [
    (["limit-cycle", "--thrust", "0,-15,-40"],
     lambda w: tw.limit_cycle(w, thrust=[0.0, -15.0, -40.0]), "limit_cycles.json"),
    (["feasibility", "--thrust", "0,-25"],
     lambda w: tw.feasibility(w, thrust=[0.0, -25.0]), "feasibility.json"),
    (["shape", "--k", "0,20"],
     lambda w: tw.shape(w, k=[0.0, 20.0]), "shape.json"),
])
@pytest.mark.slow
def test_python_result_is_the_document_the_command_writes(walker3, tmp_path, cli, command,
                                                          study, json_name):
    res = cli(*command, "--out", tmp_path, "--formats", "none", "-q")  # the JSON alone
    assert res.exit_code == 0, res.output
    written = json.loads((tmp_path / json_name).read_text())
    from thrustwalk_cli.files.output import jsonable

    mine = json.loads(json.dumps(jsonable(study(walker3).document())))
    assert _without_provenance(written) == mine


def test_every_public_name_loads_from_its_home_and_is_documented():
    doc = tw.__doc__
    for name in tw.__all__:
        if name == "__version__":
            continue
        obj = getattr(tw, name)
        assert obj.__module__.startswith("thrustwalk_cli."), name
        assert re.search(rf"^\s+{name}\s+\S", doc, re.M), f"{name} missing from the docstring"
    # the cap counts public names only (deprecated aliases are not in __all__); it rose from 45
    # to 50 with the config objects made public (SimConfig, Start, ThrusterDynamics and its
    # constructor) and InspectResult, to 52 with the energy study (energy, EnergyResult) and
    # to 54 with the rough-ground study (rough_ground, RoughGroundResult), to 58 with the
    # slope map (slope_map, SlopeMapResult) and the results of import_urdf and mujoco_run
    # (ImportResult, MujocoResult); ThrustSchedule -> WrittenSchedule left the count alone
    assert 25 <= len(tw.__all__) <= 58
    assert not set(tw._DEPRECATED) & set(tw.__all__) and not set(tw._DEPRECATED) & set(dir(tw))
    with pytest.raises(AttributeError):
        tw.no_such_name  # noqa: B018


def test_importing_the_package_and_the_cli_loads_no_heavy_library():
    code = ("import sys, thrustwalk_cli, thrustwalk_cli.cli;"
            "heavy = [m for m in ('numpy', 'scipy', 'sympy', 'matplotlib', 'rich') "
            "if m in sys.modules]; print(','.join(heavy))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert res.stdout.strip() == "", res.stdout


def test_walker_parses_each_file_once(monkeypatch, _cache_dir):
    """load_walker reads the gait and its robot once each (the gait names the same robot)."""
    from thrustwalk_cli.files import yamlio

    seen: list[str] = []
    real = yamlio.load_yaml

    def counting(path, **kw):
        seen.append(Path(path).name)
        return real(path, **kw)

    import thrustwalk_cli.files.gait_file as gf
    import thrustwalk_cli.files.robot_file as rf

    monkeypatch.setattr(gf, "load_yaml", counting)
    monkeypatch.setattr(rf, "load_yaml", counting)
    from thrustwalk_cli.walker import load_walker

    load_walker("three_link", "three_link_walk")
    assert sorted(seen) == ["three_link.yaml", "three_link_walk.yaml"]
    seen.clear()
    load_walker(None, "rabbit_walk")
    assert sorted(seen) == ["rabbit.yaml", "rabbit_walk.yaml"]


def test_parameter_errors_name_the_parameter_in_python_and_the_flag_on_the_command_line(
        walker3, cli, tmp_path):
    with pytest.raises(tw.InputError) as exc:
        tw.feasibility(walker3, thrust=[0.0], mu=-1.0)
    assert str(exc.value) == "mu: the friction coefficient must be > 0 (got -1)"
    res = cli("feasibility", "--mu", "-1", "--out", tmp_path / "x", "-q")
    assert res.exit_code == 2
    assert res.output.strip() == "error: option --mu: the friction coefficient must be > 0 (got -1)"
    with pytest.raises(tw.InputError, match=r"^q0/dq0: give both or neither$"):
        tw.simulate(walker3, steps=1, q0=[0.0, 0.0, 0.0])
    res = cli("simulate", "--steps", "1", "--q0", "0,0,0", "--out", tmp_path / "y", "-q")
    assert res.exit_code == 2
    assert res.output.strip() == "error: options --q0/--dq0: give both or neither"


# -- one consistent API (issue 25): renames with deprecated aliases, keywords, result objects --
DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    return tw.load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))


@pytest.mark.parametrize("old, new", [("ShapeStudy", "ShapeResult"),
                                      ("limit_cycles", "zd_limit_cycles"),
                                      ("ThrustSchedule", "WrittenSchedule")])
def test_a_renamed_name_still_loads_with_a_deprecation_warning_naming_the_new_one(old, new):
    with pytest.warns(DeprecationWarning, match=rf"{old} is deprecated .*tw\.{new}"):
        value = getattr(tw, old)
    assert value is getattr(tw, new)
    assert old not in tw.__all__ and old not in dir(tw)


def test_the_old_thrust_schedule_name_imports_from_its_old_home_with_a_warning():
    """CHANGELOG (issue 25): ``description.gait.ThrustSchedule`` stays a deprecated alias of
    the written form of a schedule, the type a gait's ``thrust:`` section reads into."""
    import importlib

    from thrustwalk_cli.thrust.schedule import WrittenSchedule

    module = "thrustwalk_cli.description.gait"
    namespace: dict = {}
    with pytest.warns(DeprecationWarning, match=r"ThrustSchedule is deprecated .*WrittenSchedule"):
        exec(f"from {module} import ThrustSchedule as old", namespace)
    assert namespace["old"] is WrittenSchedule
    with pytest.raises(AttributeError):
        importlib.import_module(module).NoSuchName  # noqa: B018
    from thrustwalk_cli.files.gait_file import load_gait_text

    text = (DATA / "walker5_thrust.yaml").read_text() + (
        "thrust:\n  knots: [0, 1]\n  values:\n    back: [-10]\n")
    gait, _ = load_gait_text(text, str(DATA / "walker5_thrust.yaml"))
    assert isinstance(gait.thrust, tw.WrittenSchedule)  # what a gait's thrust: reads into


def test_every_study_result_is_named_result():
    studies = [n for n in tw.__all__ if n[0].isupper() and hasattr(getattr(tw, n), "document")
               and hasattr(getattr(tw, n), "figures")]
    assert studies and all(n.endswith("Result") for n in studies), studies


def test_shape_takes_keywords_and_a_request_object_still_works_with_a_warning(walker5):
    new = tw.shape(walker5, pattern="k*(j-2)", k=[0.0, 10.0])
    assert isinstance(new, tw.ShapeResult) and new.values == (0.0, 10.0)
    with pytest.warns(DeprecationWarning, match="ShapeRequest"):
        request = tw.ShapeRequest(pattern="k*(j-2)", ks=(0.0, 10.0))
    for call in (lambda: tw.shape(walker5, request), lambda: tw.shape(walker5, req=request)):
        with pytest.warns(DeprecationWarning, match="pass its fields as keywords"):
            old = call()
        assert old.document() == new.document()
    with pytest.raises(tw.InputError, match="^req: give either"), \
            pytest.warns(DeprecationWarning):
        tw.shape(walker5, req=request, pattern="k")


def test_inspect_state_is_a_result_with_attributes_items_and_a_document(walker5):
    q = [0.1, 0.2, 0.3, -0.2, 0.1]
    res = tw.inspect_state(walker5.model, q, dq=[0.5, -0.2, 0.1, 0.3, -0.4])
    assert isinstance(res, tw.InspectResult) and res.success
    assert res.D is res["D"] and res.impact is res["impact"] and "G" in res
    assert res.document() == dict(res) and {**res}["q"] == q
    assert res.tables() == {} and res.figures() == {}
    import numpy as np

    D = np.array(res.D)  # a mass matrix: symmetric, positive definite
    assert np.allclose(D, D.T, rtol=0, atol=1e-12) and np.linalg.eigvalsh(D).min() > 0
    # kinetic energy is 1/2 dq' D dq
    dq = np.array([0.5, -0.2, 0.1, 0.3, -0.4])
    assert res.kinetic_energy == pytest.approx(0.5 * dq @ D @ dq, rel=1e-12)
    for given in (walker5, walker5.robot):  # a walker or a robot: the same model
        assert dict(tw.inspect_state(given, q)) == dict(tw.inspect_state(walker5.model, q))
    with pytest.raises(AttributeError):
        res.no_such_key  # noqa: B018


@pytest.mark.parametrize("which", ["robot", "model", "walker"])
def test_design_gait_takes_a_robot_a_model_or_a_walker(walker5, which):
    given = {"robot": walker5.robot, "model": walker5.model, "walker": walker5}[which]
    with pytest.raises(tw.InputError) as exc:  # the robot accepted: the spec is refused
        tw.design_gait(given, "x")
    assert [p for pr in exc.value.problems for p in pr.params] == ["spec"]


def _params(exc) -> list[str]:
    return [p for pr in exc.value.problems for p in pr.params]


def test_design_gait_and_inspect_state_name_their_first_parameter_robot_or_walker(walker5):
    """The first parameter takes a Robot, a model or a Walker: ``robot_or_walker``; the old
    keywords (``robot=`` of design_gait, ``model=`` of inspect_state) work with a warning."""
    with pytest.raises(tw.InputError) as exc:  # the keyword accepted: the spec is refused
        tw.design_gait(robot_or_walker=walker5, spec="x")
    assert _params(exc) == ["spec"]
    with pytest.warns(DeprecationWarning, match=r"design_gait\(robot=.*robot_or_walker"), \
            pytest.raises(tw.InputError) as exc:
        tw.design_gait(robot=walker5.robot, spec="x")
    assert _params(exc) == ["spec"]
    with pytest.raises(tw.InputError) as exc:
        tw.design_gait(walker5, "x", robot=walker5.robot)
    assert _params(exc) == ["robot_or_walker", "robot"]
    with pytest.raises(tw.InputError) as exc:
        tw.design_gait(spec="x")
    assert _params(exc) == ["robot_or_walker"]

    q = [0.1, 0.2, 0.3, -0.2, 0.1]
    new = tw.inspect_state(robot_or_walker=walker5.robot, q=q)
    with pytest.warns(DeprecationWarning, match=r"inspect_state\(model=.*robot_or_walker"):
        old = tw.inspect_state(model=walker5.model, q=q)
    assert dict(old) == dict(new)  # the robot's model either way (its dynamics: tests above)
    with pytest.raises(tw.InputError) as exc:
        tw.inspect_state(walker5, q, model=walker5.model)
    assert _params(exc) == ["robot_or_walker", "model"]


def test_thruster_dynamics_builds_the_models_of_the_simulation():
    import numpy as np
    from scipy.linalg import expm

    dyn = tw.thruster_dynamics("second-order", 2, wn=3.0, xi=0.5)
    assert isinstance(dyn, tw.ThrusterDynamics) and dyn.m == 2
    A = dyn.matrices()[0]
    # each thruster F'' + 2 xi wn F' + wn^2 F = wn^2 u: eigenvalues -xi wn +- i wn sqrt(1-xi^2)
    lam = np.sort_complex(np.linalg.eigvals(A))
    wd = 3.0 * np.sqrt(1 - 0.25)
    assert np.allclose(lam, np.sort_complex([-1.5 - 1j * wd] * 2 + [-1.5 + 1j * wd] * 2))
    lag = tw.thruster_dynamics("first-order", 1, tau=0.25)
    assert np.allclose(expm(lag.matrices()[0] * 0.5), np.exp(-0.5 / 0.25))
    assert tw.thruster_dynamics("ideal", 1).matrices()[0].shape == (0, 0)


def test_simulate_reuses_a_sim_config_and_a_start(walker5):
    config, start = tw.SimConfig(steps=2), tw.Start(perturb=0.01)
    reused = tw.simulate(walker5, thrust=[-10.0], reduced=True, config=config, start=start)
    plain = tw.simulate(walker5, thrust=[-10.0], reduced=True, steps=2, perturb=0.01)
    strip = lambda d: {k: v for k, v in d.items() if k != "wall_time"}  # noqa: E731
    assert strip(reused.document()) == strip(plain.document())
    with pytest.raises(tw.InputError, match="^config: .*`steps`"):
        tw.simulate(walker5, steps=3, config=config, check_only=True)
    with pytest.raises(tw.InputError, match="^start: "):
        tw.simulate(walker5, zeta0=1.0, start=start, check_only=True)


def test_robustness_and_rough_ground_show_every_option_in_their_signature():
    """`help(tw.robustness)` shows the options it passes on to `plan_robustness` (and so for
    rough-ground): the signature is the plan's keyword options with their defaults."""
    import inspect

    from thrustwalk_cli.studies.robustness import plan_robustness
    from thrustwalk_cli.studies.rough_ground import plan_rough_ground

    for run, plan in ((tw.robustness, plan_robustness), (tw.rough_ground, plan_rough_ground)):
        shown = inspect.signature(run).parameters
        assert not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in shown.values())
        for name, p in inspect.signature(plan).parameters.items():
            if p.kind is inspect.Parameter.KEYWORD_ONLY:
                assert shown[name].default == p.default, (run.__name__, name)
        for name in ("workers", "scheduler", "progress"):
            assert name in shown


def test_design_gait_takes_its_settings_as_keywords(walker3):
    """`tw.design_gait(robot, speed=..., ...)` is `tw.design_gait(robot, DesignSpec(...))`:
    the same designed gait, bit for bit; both at once, or an unknown setting, is bad input
    naming the keyword; the signature shows every setting."""
    import inspect

    kw = dict(speed=0.8, clearance=0.0, starts=1, max_iter=3)
    a = tw.design_gait(walker3, tw.DesignSpec(**kw))
    b = tw.design_gait(walker3, **kw)
    da, db = a.document(), b.document()
    for d in (da, db):  # wall times
        d.pop("seconds")
        for start in d["starts"]:
            start.pop("seconds")
    assert da == db and da["coefficients"]
    with pytest.raises(tw.InputError, match="speed"):
        tw.design_gait(walker3, tw.DesignSpec(**kw), speed=0.7)
    with pytest.raises(tw.InputError, match="sped"):
        tw.design_gait(walker3, sped=0.8)
    shown = inspect.signature(tw.design_gait).parameters
    assert shown["objective"].default == "effort" and shown["starts"].default == 8
