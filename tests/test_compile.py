"""``thrustwalk compile``: the summary of a compiled robot (the model itself: test_model.py)
and the one-time numba compile of its simulation kernel."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


def test_compile_summary(cli):
    res = cli("compile", "three_link")
    assert res.exit_code == 0, res.output
    assert "total mass" in res.output and "35 kg" in res.output
    words = set(res.output.replace("(", " ").replace(")", " ").replace(",", " ").split())
    assert "numba kernel" in res.output and {"every", "robot"} <= words  # rows may wrap
    assert {"instructions", "right-hand", "registers"} <= words


def test_warm_compile_reports_the_cached_kernel_without_importing_numba(cli, _cache_dir):
    assert cli("compile", "three_link", "-q").exit_code == 0  # kernel compiled and cached
    code = ("import sys\n"
            "from thrustwalk_cli.commands.compile import run_compile\n"
            "s = run_compile('three_link')\n"
            "print(s['kernel']['cache_hit'], s['kernel']['seconds'] > 0, "
            "'numba' in sys.modules, 'matplotlib' in sys.modules)\n")
    env = dict(os.environ, THRUSTWALK_CACHE_DIR=str(_cache_dir))
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.split() == ["True", "True", "False", "False"], res.stdout


@pytest.mark.slow
def test_commands_that_draw_nothing_import_neither_matplotlib_nor_numba(_cache_dir, tmp_path):
    """``--formats none`` writes the JSON only and never imports matplotlib; a warm
    ``inspect`` imports neither matplotlib, numba nor SymPy (issue 13: warm commands)."""
    out = tmp_path / "lc"
    code = ("import sys\n"
            "from thrustwalk_cli.cli import main\n"
            "args = sys.argv[1:]\n"
            "try:\n"
            "    sys.argv = ['thrustwalk', *args]\n"
            "    main()\n"
            "except SystemExit as e:\n"
            "    assert not e.code, e.code\n"
            "print(sorted(m for m in ('matplotlib', 'numba', 'sympy') if m in sys.modules))\n")
    env = dict(os.environ, THRUSTWALK_CACHE_DIR=str(_cache_dir))
    runs = {
        "limit-cycle": ["limit-cycle", "three_link", "three_link_walk", "--thrust", "0:-10:-5",
                        "--formats", "none", "--out", str(out), "-q"],
        "inspect": ["inspect", "three_link", "--q", "0.1,0.2,0.3", "--json", "-"],
    }
    for name, args in runs.items():
        for _ in range(2):  # the second run is warm (the first may compile the robot)
            res = subprocess.run([sys.executable, "-c", code, *args], env=env,
                                 capture_output=True, text=True, timeout=300)
            assert res.returncode == 0, (name, res.stderr[-2000:])
        assert res.stdout.strip().splitlines()[-1] == "[]", (name, res.stdout[-500:])
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "limit_cycles.json"]


def _chains():
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "chains", Path(__file__).resolve().parents[1] / "bench" / "chains.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_compile_tells_its_progress(tmp_path, monkeypatch):
    """``load_model(robot, progress=...)`` hears about every step of a compile, in order
    (derivation, code generation, tape, checks), each once, ending at the total; loading
    the cached model tells nothing."""
    from thrustwalk_cli.files.robot_file import load_robot_text
    from thrustwalk_cli.model.compiler import load_model

    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(tmp_path / "cache"))
    robot = load_robot_text(_chains().chain_yaml(5), str(tmp_path / "chain5.yaml"))
    seen: list[tuple[int, int, str]] = []
    model = load_model(robot, progress=lambda *a: seen.append(a))
    assert not model.cache_hit
    total = seen[0][1]
    assert [d for d, _, _ in seen] == list(range(1, total + 1))
    assert {t for _, t, _ in seen} == {total}
    phases = [p.split(":")[0] for _, _, p in seen]
    assert phases[0] == "derivation" and phases[-1] == "checks"
    assert sorted(set(phases), key=phases.index) == ["derivation", "code generation", "tape",
                                                     "checks"]
    assert sum(p == "code generation: D" for _, _, p in seen) == 1
    seen.clear()
    assert load_model(robot, progress=lambda *a: seen.append(a)).cache_hit and seen == []


def test_a_long_compile_shows_its_progress_on_the_console(cli, tmp_path, monkeypatch):
    """A compile that takes longer than ``COMPILE_QUIET_SECONDS`` (here 0) shows its phases
    on standard error and says when it is done, in ``compile`` and in a command that loads
    a walker; ``--quiet`` shows nothing, nor does a model from the cache."""
    from pathlib import Path

    from thrustwalk_cli.commands import common

    monkeypatch.setattr(common, "COMPILE_QUIET_SECONDS", 0.0)
    monkeypatch.setenv("THRUSTWALK_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    robot = tmp_path / "robots" / "chain4.yaml"
    robot.parent.mkdir()
    robot.write_text(_chains().chain_yaml(4))
    res = cli("compile", "robots/chain4.yaml", "--no-kernel")
    assert res.exit_code == 0, res.output
    assert "compiling the robot model (once per robot structure): " in res.stderr
    for phase in ("derivation", "code generation", "tape", "checks"):
        assert phase in res.stderr, (phase, res.stderr)
    assert "compiled the robot model in" in res.stderr
    res = cli("compile", "robots/chain4.yaml", "--no-kernel")  # cached
    assert res.exit_code == 0 and "compiling" not in res.stderr, res.stderr
    res = cli("compile", "robots/chain4.yaml", "--no-kernel", "--rebuild", "-q")
    assert res.exit_code == 0 and res.stderr == "", res.stderr
    data = Path(__file__).parent / "data"
    res = cli("limit-cycle", str(data / "walker5.yaml"), str(data / "walker5_walk.yaml"),
              "--formats", "none", "--out", str(tmp_path / "lc"))
    assert res.exit_code == 0, res.output
    assert "tape" in res.stderr and "compiled the robot model in" in res.stderr, res.stderr
