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
     lambda w: tw.shape(w, tw.ShapeRequest(ks=(0.0, 20.0))), "shape.json"),
])
@pytest.mark.slow
def test_python_result_is_the_document_the_command_writes(walker3, tmp_path, cli, command,
                                                          study, json_name):
    res = cli(*command, "--out", tmp_path, "-q")
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
    assert 25 <= len(tw.__all__) <= 45
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
