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
    assert "numba kernel" in res.output


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
