"""`thrustwalk report` at the end of the figure pipeline (`make figures`), run on a reduced
setting into a temporary folder: every figure, and every key number traced to its JSON."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from thrustwalk_cli.studies.report import KEY_NUMBERS, lookup

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
PNG = b"\x89PNG\r\n\x1a\n"

# every figure the pipeline must produce (relative to FIG), as PNG and PDF
EXPECTED = [
    "limit_cycle/limit_cycles", "limit_cycle/fixed_point_shift",
    "shape/shape", "shape/vector_field",
    "feasibility/grf", "feasibility/feasible_region",
    "simulate/thrust_time", "simulate/phase_portrait",
]


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory) -> Path:
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    fig = tmp_path_factory.mktemp("figures")
    cmd = ["make", "-j2", "figures", f"FIG={fig}", f"TW={sys.executable} -m thrustwalk_cli",
           "TW_DEP=", "LC_THRUST=0:-50:-25", "SHAPE_K=0:50:25", "FIELD_K=60",
           "FEAS_THRUST=0:-50:-25", "SIM_STEPS=3", "SIM_THRUST=0:-50:-25",
           *PIPELINE_OVERRIDES]
    res = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return fig


PIPELINE_OVERRIDES: list[str] = []


def test_every_figure_exists_and_is_valid(pipeline):
    for stem in EXPECTED:
        png = (pipeline / f"{stem}.png").read_bytes()
        pdf = (pipeline / f"{stem}.pdf").read_bytes()
        assert png[:8] == PNG and len(png) > 10_000, stem
        assert pdf[:5] == b"%PDF-" and b"%%EOF" in pdf[-1024:], stem


def test_index_numbers_equal_json(pipeline):
    index = (pipeline / "index.md").read_text()
    rows = re.findall(r"^\| (.+?) \| (.+?) \| `(.+?)#(.+?)` \|$", index, flags=re.M)
    assert len(rows) >= 10
    for label, value, rel, path in rows:
        doc = json.loads((pipeline / rel).read_text())
        assert json.loads(value) == lookup(doc, path), (label, rel, path)
    # every figure is listed with the command that made it
    for stem in EXPECTED:
        assert f"]({stem}.png)" in index, stem
    assert index.count("Command: `thrustwalk ") >= 2
    # the key-number table covers every result kind the pipeline writes
    for name in KEY_NUMBERS:
        if list(pipeline.rglob(name)):
            assert f"{name}#" in index, name
