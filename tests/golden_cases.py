"""Golden documents: the JSON every command writes on the bundled robots and gaits, kept in
tests/golden/ so that a change meant to move no number (a change of layout, a speed-up) is
shown to move none (tests/test_golden.py compares every number).

Regenerate after a change that is meant to change results (and say why in the commit):

    make golden          # = .venv/bin/python tests/golden_cases.py --update

Each case is a command line; the document is the command's main JSON with the parts that
are not results taken out: provenance, wall-clock times, absolute paths (replaced by
``<repo>`` and ``<out>``).
"""

from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GOLDEN = REPO / "tests" / "golden"

# (name, command line without --out, the JSON file the command writes). `--formats` asks for
# the files a document names (its CSV tables; robustness and sweep also list their figures, so
# they draw PNGs) and no other figure: a document is the same with or without the figures
# (the golden documents were made with every format), and drawing them cost half the time
CASES: list[tuple[str, list[str], str]] = []
# cases compared loosely unless bit for bit is asked for: name -> (rtol, keys left out)
LOOSE: dict[str, tuple[float, frozenset[str]]] = {}


def _add(name: str, args: list[str], doc: str) -> None:
    CASES.append((name, args, doc))


for _robot, _gait, _thr in (("three_link", "three_link_walk", "hip_x"),
                            ("rabbit", "rabbit_walk", "torso_x")):
    _r = _robot.split("_")[0]
    _add(f"limit_cycle_{_r}", ["limit-cycle", _robot, _gait, "--thrust", "0:-50:-10",
                               "--formats", "csv"],
         "limit_cycles.json")
    _add(f"shape_{_r}", ["shape", _robot, _gait, "--pattern", "k*(j-2)", "--k", "0:50:25",
                         "--field-k", "30", "--formats", "csv"], "shape.json")
    _add(f"feasibility_{_r}", ["feasibility", _robot, _gait, "--thrust", "0:-40:-20",
                               "--mu", "0.7", "--formats", "none"], "feasibility.json")
    _add(f"optimize_{_r}", ["optimize", _robot, _gait, "--knots", "0:1:0.25",
                            "--target-speed", "0.9" if _r == "three" else "0.6",
                            "--max-thrust", "40"], "optimal_schedule.json")
    _add(f"simulate_{_r}", ["simulate", _robot, _gait, "--steps", "4", "--thrust-model",
                            "second-order", "--thrust", "0,-20", "--wn", "2", "--xi", "1",
                            "--samples", "20", "--formats", "csv"], "simulation.json")
    _add(f"control_{_r}", ["control", _robot, _gait, "--reference", "speed", "--profile",
                           "0:0.8,4:1.0" if _r == "three" else "0:0.53,4:0.6",
                           "--knots", "0,0.5,1", "--steps", "8", "--push", "6:0.5:-10",
                           "--formats", "csv"],
         "control.json")
    _add(f"stability_{_r}", ["stability", _robot, _gait, "--thrust-model", "second-order",
                             "--wn", "2", "--xi", "0.7", "--thrust", "-10", "--formats", "csv"],
         "stability.json")
    _add(f"robustness_{_r}", ["robustness", _robot, _gait, "--push-impulse", "-20:20:20",
                              "--push-phase", "0.2:0.8:0.3", "--strategy",
                              "none,constant:-10,control", "--steps", "4",
                              "--basin-sigma", "-0.5:0.5", "--workers", "1",
                              "--formats", "csv,png"],
         "robustness.json")
# an optimiser's end point: reproducible bit for bit on one machine, to about 1e-5 where the
# BLAS (thread count, CPU kernels) sums in another order (SLSQP follows its rounding); the
# runs converge, so their verdicts do not depend on it
_add("design_gait_three", ["design-gait", "three_link", "--target-speed", "0.8", "--clearance",
                           "0", "--starts", "1", "--name", "g", "--formats", "none"],
     "g.report.json")
_add("design_gait_rabbit", ["design-gait", "rabbit", "--target-speed", "0.53", "--starts", "1",
                            "--name", "g", "--formats", "none"], "g.report.json")
# measured between 1 and 2 BLAS threads: coefficients and margins within 2e-4 relative; the
# iteration counts and whether SLSQP's last line search certified the optimum differ
for _name in ("design_gait_three", "design_gait_rabbit"):
    LOOSE[_name] = (1e-3, frozenset({"evaluations", "iterations", "optimality", "starts",
                                     "warnings", "status", "solver_value", "reason"}))
_add("sweep_thrust_torso_mass", ["sweep", "sweeps/thrust_torso_mass.yaml", "--workers", "1",
                                 "--formats", "csv,png"],
     "sweep.json")

# keys whose values are not results: wall-clock times and where things ran
VOLATILE = {"provenance", "seconds", "wall_time", "qp_time", "qp_time_median", "qp_time_max",
            "load_seconds", "compile_seconds", "created_utc", "executor", "elapsed",
            "polish_time", "polish_time_median", "polish_time_max"}


VOLATILE_IN = {("qp", "time")}  # (parent key, key): the QP's wall-clock solve time


def normalise(doc, out: str, parent: str = ""):
    """The document without volatile parts; paths made machine-independent."""
    if isinstance(doc, dict):
        return {k: normalise(v, out, k) for k, v in doc.items()
                if k not in VOLATILE and (parent, k) not in VOLATILE_IN}
    if isinstance(doc, list):
        return [normalise(v, out, parent) for v in doc]
    if isinstance(doc, str):
        return doc.replace(out, "<out>").replace(str(REPO), "<repo>")
    return doc


def run_case(args: list[str], doc: str, out: Path, invoke) -> dict:
    """Run one case with ``invoke(argv) -> exit code`` into ``out``; its normalised document."""
    code = invoke([*args, "--out", str(out), "-q"])
    path = out / doc
    if not path.is_file():
        raise AssertionError(f"{' '.join(args)}: exit {code}, no {doc}")
    return normalise(json.loads(path.read_text()), str(out))


def differences(got, want, path: str = "", rtol: float = 0.0, atol: float = 0.0,
                skip: frozenset[str] = frozenset()) -> list[str]:
    """Every place where ``got`` differs from ``want``: structure, strings, booleans and
    numbers (``|g - w| <= atol + rtol |w|``; 0 and 0: exactly equal); keys in ``skip`` are
    not compared."""
    out: list[str] = []
    if isinstance(want, dict) and isinstance(got, dict):
        for k in sorted((set(want) | set(got)) - skip):
            if k not in got or k not in want:
                out.append(f"{path}.{k}: {'missing' if k not in got else 'new'}")
            else:
                out += differences(got[k], want[k], f"{path}.{k}", rtol, atol, skip)
        return out
    if isinstance(want, list) and isinstance(got, list):
        if len(want) != len(got):
            return [f"{path}: {len(got)} items, want {len(want)}"]
        for i, (g, w) in enumerate(zip(got, want)):
            out += differences(g, w, f"{path}[{i}]", rtol, atol, skip)
        return out
    num = (int, float)
    if isinstance(want, num) and isinstance(got, num) and not isinstance(want, bool) \
            and not isinstance(got, bool):
        if got == want or (math.isfinite(want) and abs(got - want) <= atol + rtol * abs(want)):
            return []
        return [f"{path}: {got!r} != {want!r}"]
    if isinstance(want, str) and isinstance(got, str) and got != want and (rtol or atol):
        if _same_text(got, want, rtol, max(atol, TEXT_NOISE)):
            return []
    return [] if got == want else [f"{path}: {got!r} != {want!r}"]


# numbers printed in a sentence (a verdict's statement) that are rounding noise, such as two
# methods' difference of 8.9e-09 against a tolerance of 1e-06: compared to this, absolutely
# (a number is a word of its own: the digits of a name or a hash are text)
TEXT_NOISE = 1e-7
_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")


def _same_text(got: str, want: str, rtol: float, atol: float) -> bool:
    """The same sentence with the same numbers in it, each to ``atol + rtol |want|``: the
    text between the numbers equal, and as many numbers."""
    if _NUMBER.split(got) != _NUMBER.split(want):
        return False
    g, w = _NUMBER.findall(got), _NUMBER.findall(want)
    return len(g) == len(w) and all(abs(float(a) - float(b)) <= atol + rtol * abs(float(b))
                                    for a, b in zip(g, w))


def _update(names: list[str]) -> None:
    import tempfile

    from typer.testing import CliRunner

    from thrustwalk_cli.cli import app

    runner = CliRunner()

    def invoke(argv):
        return runner.invoke(app, argv, catch_exceptions=False).exit_code

    GOLDEN.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name, args, doc in CASES:
            if names and name not in names:
                continue
            got = run_case(args, doc, Path(tmp) / name, invoke)
            (GOLDEN / f"{name}.json").write_text(json.dumps(got, indent=1, sort_keys=True)
                                                 + "\n")
            print(f"wrote tests/golden/{name}.json")


if __name__ == "__main__":
    if sys.argv[1:2] != ["--update"]:
        sys.exit("usage: python tests/golden_cases.py --update [CASE ...]")
    import os

    for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # as the CLI and the tests run
        os.environ.setdefault(var, "1")
    os.chdir(REPO)
    _update(sys.argv[2:])
