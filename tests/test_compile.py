"""``thrustwalk compile``: the summary of a compiled robot (the model itself: test_model.py)
and the one-time numba compile of its simulation kernel."""

from __future__ import annotations

import os
import subprocess
import sys


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
