"""`thrustwalk report` at the end of the figure pipeline (`make figures`), run on a reduced
setting into a temporary folder: every figure, and every key number traced to its JSON."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
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


# what the pipeline's commands import, imported once per pipeline run (tests/preforked.py)
MODULES = ["thrustwalk_cli.cli", "thrustwalk_cli.commands.limit_cycle",
           "thrustwalk_cli.commands.shape", "thrustwalk_cli.commands.feasibility",
           "thrustwalk_cli.commands.simulate", "thrustwalk_cli.commands.report",
           "thrustwalk_cli.studies.limit_cycle", "thrustwalk_cli.studies.shape",
           "thrustwalk_cli.studies.feasibility", "thrustwalk_cli.studies.simulate",
           "matplotlib.backends.backend_agg", "matplotlib.backends.backend_pdf",
           "scipy.integrate", "scipy.optimize", "numba"]


def _make(fig: Path, *extra: str) -> None:
    """`make figures` on the reduced settings. Its commands (TW) are processes forked from a
    process that imported the package and its dependencies once for this run (2 s of
    imports saved per command); each run of the pipeline has its own, so that what differs
    between two fresh interpreters (hash seed, address layout) differs between two runs."""
    from preforked import command_server

    with command_server(MODULES) as tw:
        cmd = ["make", "-j2", "figures", f"FIG={fig}", f"TW={tw}",
               "TW_DEP=", "LC_THRUST=0:-50:-25", "SHAPE_K=0:50:25", "FIELD_K=60",
               "FEAS_THRUST=0:-50:-25", "SIM_STEPS=3", "SIM_THRUST=0:-50:-25", *extra]
        res = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory) -> Path:
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    fig = tmp_path_factory.mktemp("figures")
    _make(fig)
    return fig


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_rerunning_the_pipeline_rewrites_every_file_byte_for_byte(pipeline):
    """`make figures` leaves `git status` clean: result files record the source date
    (SOURCE_DATE_EPOCH), not the clock, and nothing else varies between runs."""
    first = _files(pipeline)
    _make(pipeline, "-B")
    second = _files(pipeline)
    assert sorted(first) == sorted(second)
    changed = [name for name in first if first[name] != second[name]]
    assert not changed, changed


def test_pdfs_are_ieee_ready(pipeline):
    """Every PDF embeds TrueType (Type 42, as Type0/CIDFontType2) fonts, never Type 3, and is
    one (3.5 in = 252 pt) or two (7.16 in = 515.52 pt) IEEE columns wide."""
    pdfs = sorted(pipeline.rglob("*.pdf"))
    assert len(pdfs) >= len(EXPECTED)
    for pdf in pdfs:
        data = pdf.read_bytes()
        assert b"/Type3" not in data, f"{pdf.name}: Type 3 font"
        assert re.search(rb"/Subtype\s*/(Type0|TrueType)", data), pdf.name
        box = re.search(rb"/MediaBox\s*\[\s*0\s+0\s+([\d.]+)\s+([\d.]+)\s*\]", data)
        width = float(box.group(1))
        assert min(abs(width - 252.0), abs(width - 515.52)) < 0.5, (pdf.name, width)


def test_every_figure_exists_and_is_valid(pipeline):
    for stem in EXPECTED:
        png = (pipeline / f"{stem}.png").read_bytes()
        pdf = (pipeline / f"{stem}.pdf").read_bytes()
        assert png[:8] == PNG and len(png) > 10_000, stem
        assert pdf[:5] == b"%PDF-" and b"%%EOF" in pdf[-1024:], stem


def test_index_numbers_equal_json(pipeline):
    index = (pipeline / "index.md").read_text()
    # | quantity | value | `file#path` | verdict | `file#path` | (verdict cells may be empty)
    rows = re.findall(r"^\| (.+?) \| (.+?) \| `([^`#]+)#([^`]+)` \| "
                      r"(?:(.+?) \| `([^`#]+)#([^`]+)`|\s*\|\s*) \|$", index, flags=re.M)
    assert len(rows) >= 10
    for label, value, rel, path, verdict, vrel, vpath in rows:
        doc = json.loads((pipeline / rel).read_text())
        assert json.loads(value.replace("\\|", "|")) == lookup(doc, path), (label, rel, path)
        if vpath:  # the verdict of a number comes from the same document
            assert vrel == rel, (label, vrel)
            assert json.loads(verdict.replace("\\|", "|")) == lookup(doc, vpath), (label, vpath)
    # every figure is listed with the command that made it
    for stem in EXPECTED:
        assert f"]({stem}.png)" in index, stem
    assert index.count("Command: `thrustwalk ") >= 2
    # the key-number table covers every result kind the pipeline writes
    for name in KEY_NUMBERS:
        if list(pipeline.rglob(name)):
            assert f"{name}#" in index, name
