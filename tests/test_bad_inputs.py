"""A corpus of bad inputs (issue 18), table-driven: malformed robot and gait files, non-finite
and huge numbers in options, thrust outside a thruster's limits, unusable output targets,
malformed option values and requests beyond the sanity limits.

Every case must end as promised: exit code 2 (bad input), one line on standard error that
starts ``error: <file>:<line>: <key.path>:`` or ``error: option --name:`` (the expected start
is written here by hand, from the promise, not copied from the tool's output), no traceback,
and the output target untouched: a folder that did not exist is not created, a file or a
previous run's folder keeps its exact contents.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from thrustwalk_cli.errors import InputError

REPO = Path(__file__).parents[1]
ROBOT = (REPO / "robots" / "three_link.yaml").read_text()
GAIT = (REPO / "gaits" / "three_link_walk.yaml").read_text()


@dataclass(frozen=True)
class Case:
    """``argv`` may use ``{out}`` (the output folder), ``{file}`` (the input file written from
    ``text``), ``{tmp}``; ``first``: a regular expression the first stderr line must match
    (``{file}`` and ``{out}`` are replaced by their escaped paths); ``target``: the state of
    the output target before the run (``none``: absent, ``run``: a previous run's folder,
    ``file``: an existing file, ``foreign``: a folder with someone else's file)."""

    argv: tuple[str, ...]
    first: str
    text: str | bytes | None = None
    target: str = "none"
    exit: int = 2
    tags: tuple[str, ...] = field(default=())


CASES: dict[str, Case] = {}


def add(name: str, argv, first: str, **kw) -> None:
    assert name not in CASES, name
    CASES[name] = Case(tuple(argv), first, **kw)


def _file_error(keypath: str, message: str) -> str:
    """``error: FILE:LINE: KEY.PATH: ...MESSAGE...`` (a whole-file problem has no key path and
    may have no line: ``error: FILE: file is empty``). ``keypath`` and ``message`` are regular
    expressions; the message may come after a few words of context."""
    if keypath:
        head = r"error: \{file\}:\d+: " + keypath + ": "
    else:
        head = r"error: \{file\}(:\d+)?: "
    return head + (".*" + message if message else "")


def robot_case(name: str, text: str | bytes, keypath: str, message: str = "") -> None:
    """A malformed robot file, compiled: the error names the file, a line and the key."""
    add(f"robot-{name}", ["compile", "{file}"], _file_error(keypath, message), text=text)


def gait_case(name: str, text: str | bytes, keypath: str, message: str = "") -> None:
    """A malformed gait file for the bundled 3-link robot, analysed by limit-cycle."""
    add(f"gait-{name}", ["limit-cycle", "three_link", "{file}", "--out", "{out}", "-q"],
        _file_error(keypath, message), text=text)


def sub(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


# -- malformed robot files --------------------------------------------------------------------
robot_case("yaml-syntax", ROBOT + "links: [\n", "", r".*")
robot_case("unknown-key", ROBOT + "colour: red\n", "colour", "unknown key")
robot_case("negative-mass", sub(ROBOT, "m: 5.0 ", "m: -5.0 "),
           r"links\[0\]\.point_masses\[0\]\.mass", "must be > 0")
robot_case("huge-mass", sub(ROBOT, "m: 5.0 ", "m: 1e308 "), r"parameters\.m",
           "beyond any physical value")
robot_case("nan-mass", sub(ROBOT, "m: 5.0 ", "m: .nan "), r"parameters\.m")
robot_case("inf-mass", sub(ROBOT, "m: 5.0 ", "m: .inf "), r"parameters\.m")
robot_case("zero-gravity", sub(ROBOT, "gravity: 9.8 ", "gravity: 0 "), "gravity")
robot_case("text-gravity", sub(ROBOT, "gravity: 9.8 ", "gravity: strong "), "gravity")
robot_case("unknown-name", sub(ROBOT, "at: [0, r/2]", "at: [0, rr/2]"),
           r"links\[0\]\.point_masses\[0\]\.at\[1\]", "unknown name 'rr'")
robot_case("code-in-expression", sub(ROBOT, "m: 5.0 ", "m: \"__import__('os').getcwd()\" "),
           r"parameters\.m")
robot_case("long-expression", sub(ROBOT, "m: 5.0 ", "m: " + "+".join(["1"] * 600) + " "),
           r"parameters\.m", "expression too long")
robot_case("deep-expression", sub(ROBOT, "m: 5.0 ", "m: " + "(" * 150 + "5" + ")" * 150 + " "),
           r"parameters\.m", "expression nested deeper")
robot_case("division-by-zero", sub(ROBOT, "m: 5.0 ", "m: 5/0 "), r"parameters\.m")
robot_case("parameter-cycle", sub(sub(ROBOT, "m: 5.0 ", "m: MH "), "MH: 15.0", "MH: m"),
           r"parameters\.(m|MH)")
robot_case("duplicate-thruster", sub(ROBOT, "name: torso_back", "name: hip_x"),
           r"thrusters\[1\]\.name", "duplicate thruster name")
robot_case("thruster-unknown-link", sub(ROBOT, "link: torso\n    point: [0, 0]",
                                        "link: tail\n    point: [0, 0]"), r"thrusters\[0\]\.link")
robot_case("thruster-zero-direction", sub(ROBOT, "direction: [-1, 0]\n    frame: world",
                                          "direction: [0, 0]\n    frame: world"),
           r"thrusters\[0\]\.direction", "direction is zero")
robot_case("thruster-limits-reversed", sub(ROBOT, "limits: [-100, 100]", "limits: [100, -100]"),
           r"thrusters\[0\]\.limits")
robot_case("thruster-frame", sub(ROBOT, "frame: world", "frame: body"), r"thrusters\[0\]\.frame")
robot_case("duplicate-link", sub(ROBOT, "name: swing_leg", "name: torso"), r"links\[2\]\.name")
robot_case("two-roots", sub(ROBOT, "parent: stance_leg", "parent: null"), "links")
robot_case("unknown-parent", sub(ROBOT, "parent: torso ", "parent: pelvis "), r"links\[2\]\.parent")
robot_case("unknown-joint", sub(ROBOT, "joint: swing_leg,", "joint: tail,"),
           r"coordinates\.actuated\[1\]\.joint")
robot_case("unknown-foot-link", sub(ROBOT, "swing: {link: swing_leg", "swing: {link: tail"),
           r"feet\.swing\.link")
robot_case("unknown-swap-link", sub(ROBOT, "swap: [[stance_leg, swing_leg]]",
                                    "swap: [[stance_leg, tail]]"), r"relabel\.swap\[0\]",
           "unknown link 'tail'")
robot_case("string-for-list", sub(ROBOT, "point_masses:\n      - {mass: m, at: [0, r/2]}",
                                  "point_masses: heavy"), r"links\[0\]\.point_masses")
robot_case("point-short", sub(ROBOT, "at: [0, r/2]", "at: [0]"),
           r"links\[0\]\.point_masses\[0\]\.at", "expected 2 values")
robot_case("python-tag", sub(ROBOT, "gravity: 9.8 ", "gravity: !!python/object:os.system x "),
           "")
robot_case("duplicate-key", sub(ROBOT, "gravity: 9.8 ", "gravity: 9.8\ngravity: 9.7 "),
           "gravity")
robot_case("tab-indent", sub(ROBOT, "  r: 1.0", "\tr: 1.0"), "", r".*")
robot_case("not-utf8", ROBOT.encode().replace(b"3-link planar", b"3-link \xff\xfe planar"), "",
           r".*UTF-8")
robot_case("empty", "", "", r".*")
robot_case("top-level-list", "- a\n- b\n", "", r".*mapping")
robot_case("top-level-scalar", "just a robot\n", "", r".*mapping")
robot_case("deep-block-nesting",
           ROBOT + "extra:\n" + "".join("  " * (i + 1) + f"k{i}:\n" for i in range(80))
           + "  " * 81 + "v: 1\n", "", "nesting deeper than 64")
robot_case("deep-flow-nesting", ROBOT + "extra: " + "[" * 600 + "]" * 600 + "\n", "",
           "nesting deeper than 64")
robot_case("alias-bomb",
           "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
           + "".join(f"{chr(98 + i)}: &{chr(98 + i)} [" + ", ".join([f"*{chr(97 + i)}"] * 10)
                     + "]\n" for i in range(8)), "", "document too large")
robot_case("too-many-links",
           sub(ROBOT, "links:\n", "links:\n" + "".join(
               f"  - {{name: extra{i}, parent: stance_leg, joint: [0, 0], mass: 1, "
               f"com: [0, 0], inertia: 0.1}}\n" for i in range(20))), "links",
           "23 items: the limit is 20")
robot_case("too-many-thrusters",
           ROBOT + "".join(f"  - {{name: t{i}, link: torso, point: [0, 0], direction: [1, 0]}}\n"
                           for i in range(16)), "thrusters", "18 items: the limit is 16")
robot_case("massless-link", sub(ROBOT, "point_masses:\n      - {mass: m, at: [0, -r/2]}",
                                "mass: 0"), r"links\[2\]")

# -- malformed gait files ---------------------------------------------------------------------
add("gait-unknown-robot", ["design-gait", "three_link", "--target-speed", "0.8", "--compare",
                          "{file}", "--out", "{out}"],
    r"error: \{file\}:\d+: robot: four_link: no such file",
    text=sub(GAIT, "robot: three_link", "robot: four_link"))
gait_case("other-robot", sub(GAIT, "robot: three_link", "robot: rabbit"), "robot",
          "gait 'three_link_walk' is for robot 'rabbit'")
gait_case("alpha-unknown-coordinate", sub(GAIT, "c: {q3: -1}", "c: {q9: -1}"), r"alpha\.c\.q9")
gait_case("alpha-actuated-only", sub(GAIT, "c: {q3: -1}", "c: {q1: 1}"), r"alpha\.c",
          "alpha must depend on the unactuated")
gait_case("alpha-tiny", sub(GAIT, "c: {q3: -1}", "c: {q3: -1e-15}"), r"alpha\.c")
gait_case("alpha-span-zero", sub(GAIT, "af: 0.2669080288119819", "af: 0.0"), r"alpha\.final",
          "swing foot is .* above the ground at impact")
gait_case("final-in-degrees", sub(GAIT, "af: 0.2669080288119819", "af: 15.29"), r"alpha\.final")
gait_case("final-wrong-sign", sub(GAIT, "af: 0.2669080288119819", "af: -0.2669080288119819"),
          r"alpha\.final")
gait_case("row-missing", sub(GAIT, "    q2: [", "    q9: ["), r"bezier\.coefficients\.q9",
          "unknown actuated coordinate 'q9'")
gait_case("rows-unequal", sub(GAIT, "0.039547914228207505]", "0.039547914228207505, 0.1]"),
          r"bezier\.coefficients")
gait_case("order-too-high", sub(sub(GAIT, "0.039547914228207505]",
                                    "0.039547914228207505" + ", 0.0" * 20 + "]"),
                                "0.49426814341686387]", "0.49426814341686387" + ", 0.0" * 20 + "]"),
          r"bezier\.coefficients\.q[12]", "27 items: the limit is 21")
gait_case("row-too-short", sub(sub(GAIT, "q1: [~, ~, -0.4284376715853535, -0.21916883372523013, "
                                   "-0.169656538864774, -0.06556582558161443, "
                                   "0.039547914228207505]", "q1: [~, ~, 0.1]"),
                               "q2: [~, ~, 0.11874783356434716, 0.2445021030062819, "
                               "0.4729868829529832, 0.47685680863412244, 0.49426814341686387]",
                               "q2: [~, ~, 0.1]"), r"bezier\.coefficients\.q[12]")
gait_case("auto-with-numbers", sub(GAIT, "q1: [~, ~,", "q1: [0.1, ~,"),
          r"bezier\.coefficients\.q1\[0\]", "with invariance: auto")
gait_case("given-with-tilde", sub(GAIT, "  invariance: auto", "  invariance: given"),
          r"bezier\.coefficients\.q1\[0\]", "missing value")
gait_case("negative-kp", sub(GAIT, "kp: 400", "kp: -400"), r"controller\.kp")
gait_case("zero-mu", sub(GAIT, "mu: 0.7", "mu: 0"), "mu")
gait_case("nan-coefficient", sub(GAIT, "-0.4284376715853535", ".nan"),
          r"bezier\.coefficients\.q1\[2\]")
gait_case("unknown-key", GAIT + "speed: fast\n", "speed", "unknown key")
gait_case("broken-parameter", sub(sub(GAIT, "af: 0.2669080288119819", "af: 0.26 + zz"),
                                  "kp: 400", "kp: af * 1000"), r"parameters\.af",
          "unknown name 'zz'")
_THRUST = ("thrust:\n  mode: force\n  knots: [0, 0.5, 1]\n  values:\n"
           "    hip_x: [-10, -20]\n")
gait_case("thrust-values-count", GAIT + _THRUST.replace("[-10, -20]", "[-10, -20, -30]"),
          r"thrust\.values\.hip_x")
gait_case("thrust-unknown-thruster", GAIT + _THRUST.replace("hip_x", "jet"),
          r"thrust\.values\.jet")
gait_case("thrust-knots-decreasing", GAIT + _THRUST.replace("[0, 0.5, 1]", "[0, 0.7, 0.5]"),
          r"thrust\.knots")
gait_case("thrust-outside-limits", GAIT + _THRUST.replace("[-10, -20]", "[-10, -1000000]"),
          r"thrust\.values\.hip_x")
gait_case("thrust-too-many-knots",
          GAIT + _THRUST.replace("[0, 0.5, 1]", "[" + ", ".join(
              f"{i / 300:.6f}" for i in range(301)) + "]"),
          r"thrust\.knots", "301 items: the limit is 257")
gait_case("thrust-mode", GAIT + _THRUST.replace("mode: force", "mode: push"), r"thrust\.mode")

# -- non-finite and huge numbers in options ---------------------------------------------------
NUMBER_OPTIONS = [
    ("limit-cycle", "--thrust"), ("feasibility", "--thrust"), ("feasibility", "--mu"),
    ("feasibility", "--min-vertical-force"), ("feasibility", "--fit-tol"),
    ("simulate", "--thrust"), ("simulate", "--wn"), ("simulate", "--xi"), ("simulate", "--tau"),
    ("simulate", "--f0"), ("simulate", "--perturb"), ("simulate", "--zeta0"),
    ("simulate", "--scuff-tol"), ("simulate", "--rtol"), ("simulate", "--torque-limit"),
    ("simulate", "--mu"), ("shape", "--k"), ("optimize", "--target-speed"),
    ("optimize", "--max-thrust"), ("design-gait", "--target-speed"),
    ("design-gait", "--thrust-weight"), ("design-gait", "--clearance"),
]
for _cmd, _opt in NUMBER_OPTIONS:
    for _value in ("nan", "inf", "-inf", "1e308"):
        _robot = ["three_link"] if _cmd == "design-gait" else []
        _pre = ["--target-speed", "0.8"] if _cmd == "design-gait" and _opt != "--target-speed" \
            else []
        add(f"number-{_cmd}{_opt}={_value}", [_cmd, *_robot, *_pre, _opt, _value, "--out",
                                              "{out}", "-q"],
            "error: option " + re.escape(_opt) + ": ")
for _value in ("nan", "inf", "-1e308"):
    add(f"number-inspect--q={_value}", ["inspect", "three_link", "--q", f"0.1,{_value},0.2"],
        "error: option --q: ")
for _spec in ("inf:0:-1", "0:-inf:-1", "0:-10:nan", "1e308:0:-1e307", "0:1e300:1"):
    add(f"range-limit-cycle--thrust={_spec}", ["limit-cycle", "--thrust", _spec, "--out",
                                               "{out}", "-q"], "error: option --thrust: ")

# -- slopes and terrain files (issue 27, SPEC 14) --------------------------------------------
for _cmd, _extra in (("shape", ["--k", "0,10"]), ("optimize", ["--target-speed", "0.9"]),
                     ("robustness", ["--push-impulse", "1"]),
                     ("rough-ground", ["--sigma", "0.004"])):
    for _value in ("1.6", "nan", "-1.5708"):
        add(f"slope-{_cmd}={_value}", [_cmd, *_extra, "--slope", _value, "--out", "{out}",
                                       "-q"], "error: option --slope: ")
for _cmd, _extra in (("control", ["--reference", "nominal"]),
                     ("robustness", ["--push-impulse", "1"])):
    add(f"terrain-{_cmd}-nan-height", [_cmd, *_extra, "--terrain", "{file}", "--out", "{out}",
                                       "-q"], _file_error(r"steps\[1\]", "finite"),
        text="steps: [0.01, .nan]\n")
    add(f"terrain-{_cmd}-unknown-distribution",
        [_cmd, *_extra, "--terrain", "{file}", "--out", "{out}", "-q"],
        _file_error(r"rough\.distribution", "cauchy"),
        text="rough: {distribution: cauchy, sigma: 0.01}\n")

# -- thrust outside the thruster's limits (100 N) ---------------------------------------------
for _cmd in ("limit-cycle", "feasibility", "simulate"):
    for _value in ("-1e6", "150", "0,-20,-101"):
        add(f"limits-{_cmd}={_value}", [_cmd, "--thrust", _value, "--out", "{out}", "-q"],
            r"error: options? --thrust(/--f0)?: .*outside the limits \[-100, 100\] N")
add("limits-shape-k", ["shape", "--mode", "force", "--thruster", "hip_x", "--k", "0,-500",
                       "--out", "{out}", "-q"],
    r"error: options --pattern/--k: .*outside the limits")
add("limits-inspect", ["inspect", "three_link", "--q", "0.1,0.2,0.3", "--thrust", "1e6,0"],
    r"error: option --thrust: ")

# -- output targets ---------------------------------------------------------------------------
for _cmd, _extra in (("limit-cycle", ["--thrust", "0"]), ("feasibility", ["--thrust", "0"]),
                     ("simulate", ["--steps", "1", "--thrust", "0"]),
                     ("shape", ["--k", "0,10"]), ("optimize", ["--target-speed", "0.9"])):
    add(f"out-file-{_cmd}", [_cmd, *_extra, "--out", "{out}", "-q"],
        r"error: option --out: \{out\} is a file, not a folder", target="file")
    add(f"out-under-file-{_cmd}", [_cmd, *_extra, "--out", "{out}/sub", "-q"],
        r"error: option --out: cannot create \{out\}/sub: \{out\} is a file", target="file")
    add(f"out-foreign-{_cmd}", [_cmd, *_extra, "--out", "{out}", "-q"],
        r"error: option --out: \{out\} is a folder with files that thrustwalk did not write",
        target="foreign")
    add(f"out-bad-input-keeps-run-{_cmd}", [_cmd, *_extra, "--thruster", "nozzle", "--out",
                                            "{out}", "-q"],
        r"error: option --thruster: ", target="run")
add("json-is-folder", ["inspect", "three_link", "--q", "0.1,0.2,0.3", "--json", "{out}"],
    r"error: option --json: \{out\} is a folder", target="foreign")
add("json-under-file", ["limit-cycle", "--thrust", "0", "--out", "{tmp}/lc", "--json",
                        "{out}/x.json", "-q"], r"error: option --json: ", target="file")
add("design-out-under-file", ["design-gait", "three_link", "--target-speed", "0.8", "--out",
                              "{out}/gaits"], r"error: option --out: cannot create", target="file")

# -- malformed option values ------------------------------------------------------------------
for _spec, _why in (("abc", "not a number"), ("1:2:0", "step must be non-zero"),
                    ("0:10:-1", "step must be non-zero"), ("1:2:3:4", "start:stop:step"),
                    ("", "no values"), (",", "no values"), ("0:-1:-1e-5", "the limit is 10000")):
    add(f"values-thrust={_spec or 'empty'}", ["limit-cycle", "--thrust", _spec, "--out",
                                              "{out}", "-q"],
        "error: option --thrust: .*" + re.escape(_why))
add("values-list-too-long", ["feasibility", "--thrust", ",".join(["0"] * 10001), "--out",
                             "{out}", "-q"], "error: option --thrust: 10001 values")
add("formats-unknown", ["limit-cycle", "--formats", "jpg", "--out", "{out}", "-q"],
    "error: option --formats: unknown jpg")
# a kind other commands write: the refusal says this command writes none and what it does
add("formats-feasibility-csv", ["feasibility", "--formats", "csv,png", "--out", "{out}", "-q"],
    r"error: option --formats: feasibility writes no csv file \(.*choose from png, pdf, md, "
    r"or none")
add("formats-optimize-md", ["optimize", "--target-speed", "1", "--formats", "md", "--out",
                            "{out}", "-q"],
    r"error: option --formats: optimize writes no md file \(.*choose from png, pdf, or none")
add("shape-empty-pattern", ["shape", "--pattern", "", "--k", "0,1", "--out", "{out}", "-q"],
    "error: option --pattern: ")
add("shape-pattern-code", ["shape", "--pattern", "__import__('os')", "--k", "0,1", "--out",
                           "{out}", "-q"], "error: option --pattern: ")
add("knots-unordered", ["optimize", "--knots", "0,0.7,0.5,1", "--target-speed", "0.9",
                        "--out", "{out}", "-q"], "error: option --knots: ")
add("knots-text", ["optimize", "--knots", "0,x,1", "--target-speed", "0.9", "--out", "{out}",
                   "-q"], "error: option --knots: ")
add("unknown-thruster", ["limit-cycle", "--thruster", "nozzle", "--out", "{out}", "-q"],
    "error: option --thruster: ")
add("unknown-thrust-model", ["simulate", "--thrust-model", "jet", "--out", "{out}", "-q"],
    "error: option --thrust-model: ")
add("unknown-method", ["simulate", "--method", "euler", "--out", "{out}", "-q"],
    "error: option --method: ")
add("compiled-with-lsoda", ["simulate", "--method", "compiled", "--integrator", "LSODA",
                            "--out", "{out}", "-q"], "error: option --integrator: ")
add("q0-without-dq0", ["simulate", "--q0", "0.1,0.2,0.3", "--out", "{out}", "-q"],
    "error: options --q0/--dq0: give both or neither")
add("q0-wrong-length", ["simulate", "--q0", "0.1,0.2", "--dq0", "0,0", "--out", "{out}", "-q"],
    "error: option")
add("int-option-text", ["simulate", "--steps", "many", "--out", "{out}", "-q"],
    "error: option --steps: ")
add("int-option-nan", ["simulate", "--steps", "nan", "--out", "{out}", "-q"],
    "error: option --steps: ")
add("unknown-option", ["limit-cycle", "--speed", "3", "--out", "{out}", "-q"],
    "error: no such option --speed")
add("option-without-value", ["simulate", "--q0"], "error: option --q0: requires an argument")
add("unknown-command", ["walk"], "error: no such command 'walk'")
add("missing-robot-argument", ["design-gait"], "error: argument ROBOT: required")
add("unknown-robot", ["limit-cycle", "five_link", "--out", "{out}", "-q"],
    "error: five_link: no such file and no bundled robot")
add("unknown-gait", ["limit-cycle", "three_link", "walk9", "--out", "{out}", "-q"],
    "error: walk9: no such file")
add("gait-for-other-robot", ["limit-cycle", "rabbit", "three_link_walk", "--out", "{out}",
                             "-q"], r"error: .*three_link_walk\.yaml:\d+: robot: gait "
                                    "'three_link_walk' is for robot 'three_link'")
add("design-order", ["design-gait", "three_link", "--target-speed", "0.8", "--order", "40",
                     "--out", "{out}"], "error: option --order: Bezier order must be 3..12")
add("design-starts", ["design-gait", "three_link", "--target-speed", "0.8", "--starts",
                      "100000000", "--out", "{out}"], "error: option --starts: must be 1..1000")
add("design-name", ["design-gait", "three_link", "--target-speed", "0.8", "--name", "../evil",
                    "--out", "{out}"], "error: option --name: ")
add("design-no-target", ["design-gait", "three_link", "--out", "{out}"],
    "error: options --target-speed/--step-length: ")

# -- beyond the sanity limits -----------------------------------------------------------------
add("limit-simulate-total", ["simulate", "--thrust", "0:-100:-0.1", "--out", "{out}", "-q"],
    "error: options --thrust/--steps: 1001 runs x 30 steps = 30030 steps, above the limit of "
    "20000")
add("limit-simulate-steps", ["simulate", "--steps", "100000", "--thrust", "0", "--out", "{out}",
                             "-q"], "error: option")
add("limit-simulate-samples", ["simulate", "--samples", "1", "--out", "{out}", "-q"],
    "error: option --samples: must be 2..10000")
add("limit-simulate-samples-high", ["simulate", "--samples", "100001", "--out", "{out}", "-q"],
    "error: option --samples: must be 2..10000")
add("limit-sweep-values", ["limit-cycle", "--thrust", "0:-100:-0.001", "--out", "{out}", "-q"],
    "error: option --thrust: 100001 values: the limit is 10000")
add("limit-max-output", ["limit-cycle", "--thrust", "0:-9.999:-0.001", "--max-output", "1",
                         "--out", "{out}", "-q"], "error: option --max-output: 10000 thrust "
                                                  "values make a CSV")


# -- the runner -------------------------------------------------------------------------------
def _snapshot(path: Path) -> dict[str, str] | str | None:
    """Exact contents of the target: None if absent, a file's hash, or every file's hash."""
    if not path.exists():
        return None
    if path.is_file():
        return hashlib.sha256(path.read_bytes()).hexdigest()
    return {p.relative_to(path).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(path.rglob("*")) if p.is_file()}


def _prepare(case: Case, tmp: Path) -> Path:
    out = tmp / "out"
    if case.target == "file":
        out.write_text("my notes\n")
    elif case.target == "foreign":
        out.mkdir()
        (out / "thesis.tex").write_text("\\documentclass{article}\n")
    elif case.target == "run":  # a previous run's folder (manifest written by thrustwalk)
        out.mkdir()
        (out / "limit_cycles.json").write_text('{"provenance": {"tool": "thrustwalk"}}\n')
        (out / ".thrustwalk-run.json").write_text('{"tool": "thrustwalk", "files": {}}\n')
    return out


def test_the_corpus_is_large_enough():
    assert len(CASES) >= 150, len(CASES)


SLOW_CASES = {"robot-alias-bomb"}  # seconds each (the others: milliseconds)


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_CASES
                                  else n for n in sorted(CASES)])
def test_bad_input(name, tmp_path, cli):
    check_case(name, CASES[name], tmp_path, cli)


def check_case(name: str, case: Case, tmp_path: Path, cli) -> None:
    """Run one case and check the promise (module docstring); shared with the corpora of
    later issues (tests/test_validation.py)."""
    out = _prepare(case, tmp_path)
    file = tmp_path / "input.yaml"
    if case.text is not None:
        file.write_bytes(case.text if isinstance(case.text, bytes) else case.text.encode())
    subst = {"{out}": str(out), "{file}": str(file), "{tmp}": str(tmp_path)}

    def fill(arg: str) -> str:
        for key, value in subst.items():
            arg = arg.replace(key, value)
        return arg

    before = _snapshot(out)
    listing = sorted(p.name for p in tmp_path.iterdir())
    res = cli(*[fill(a) for a in case.argv])
    err = res.stderr
    assert res.exit_code == case.exit, f"{name}: exit {res.exit_code}\n{err}{res.stdout}"
    assert "Traceback" not in err + res.stdout, f"{name}: traceback\n{err}"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines, f"{name}: nothing on standard error"
    pattern = case.first
    for key, value in subst.items():
        pattern = pattern.replace(key.replace("{", r"\{").replace("}", r"\}"), re.escape(value))
    assert re.match(pattern, lines[0]), f"{name}: first line\n  {lines[0]}\nexpected\n  {pattern}"
    assert all(ln.startswith(("error: ", "warning: ")) for ln in lines), \
        f"{name}: every stderr line is an error or warning line\n{err}"
    assert _snapshot(out) == before, f"{name}: the output target changed"
    assert sorted(p.name for p in tmp_path.iterdir()) == listing, \
        f"{name}: something was written beside the target"


# -- files a sweep file names, and files that are not of the expected kind (issue 30) ------------
SECRET = "root:$6$SECRETHASH0123:19000:0:99999:7:::\ndaemon:*:19000:0:99999:7:::\n"
SWEEP = """\
name: s
study: limit-cycle
robot: three_link
gait: GAIT
grid:
  thrust: {values: [0, -10]}
collect: [speed]
"""


def _one_error(res, start: str) -> str:
    """Exit 2, exactly one line on standard error, starting with ``start``, no traceback."""
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith(start), lines[0]
    assert "Traceback" not in res.stderr + res.stdout
    return lines[0]


@pytest.mark.parametrize("how", ["dotdot-to-root", "dotdot", "absolute"])
def test_a_sweep_file_cannot_name_a_file_outside_its_folder(how, cli, tmp_path, monkeypatch):
    """``gait: ../../../../etc/passwd``-style paths, a ``..`` to a file beside the folder and
    an absolute path are refused at the key's line, unread: nothing of the file is shown (on
    main the secret's lines came back as "unknown key" errors), no folder is created."""
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "project" / "sweeps"
    folder.mkdir(parents=True)
    secret = tmp_path / "project" / "shadow.yaml"
    secret.write_text(SECRET)
    ref = {"dotdot-to-root": "../" * len(folder.parts) + str(secret).lstrip("/"),
           "dotdot": "../shadow.yaml", "absolute": str(secret)}[how]
    assert (folder / ref).resolve() == secret.resolve()
    sweep = folder / "s.yaml"
    sweep.write_text(SWEEP.replace("GAIT", ref))
    line = _one_error(cli("sweep", sweep, "--out", tmp_path / "o", "-q"),
                      f"error: {sweep}:4: gait: {ref}: ")
    assert "outside the folder" in line and "--gait PATH" in line
    assert "SECRET" not in line and "root:" not in line and "daemon" not in line
    assert not (tmp_path / "o").exists()


def test_an_explicit_gait_may_be_anywhere_and_keeps_its_own_robot_rule(tmp_path, _cache_dir):
    """The ``robot:`` of a gait that the sweep file names is confined to the sweep file's
    folder (``robot: ../walker5.yaml`` from a subfolder is refused at the gait's line); the
    same gait given explicitly (``gait=``, the command's ``--gait``) keeps the rule of every
    gait file: its ``robot:`` relative to its own folder, ``..`` allowed (as design-gait
    writes it for ``--out gaits``)."""
    from thrustwalk_cli.studies.sweep import load_sweep

    data = Path(__file__).parent / "data"
    (tmp_path / "walker5.yaml").write_text((data / "walker5.yaml").read_text())
    sub_ = tmp_path / "sweeps"
    sub_.mkdir()
    text = (data / "walker5_walk.yaml").read_text()
    gait = sub_ / "walk.yaml"
    gait.write_text(sub(text, "robot: walker5.yaml", "robot: ../walker5.yaml"))
    sweep = sub_ / "s.yaml"
    sweep.write_text(SWEEP.replace("robot: three_link", "robot: walk.yaml")
                     .replace("GAIT", "walk.yaml"))
    with pytest.raises(InputError) as err:  # the sweep's own robot: is a gait file
        load_sweep(sweep)
    assert str(err.value) == f"{gait.resolve()}: this is a gait file, not a robot file (a " \
                             "gait file belongs in the GAIT argument or a gait: key)"
    with pytest.raises(InputError) as err:
        load_sweep(sweep, robot=str(tmp_path / "walker5.yaml"))
    (p,) = err.value.problems
    assert (p.file, p.path) == (str(gait.resolve()), "robot")
    assert p.line == text.splitlines().index("robot: walker5.yaml") + 1
    assert p.message.startswith("../walker5.yaml: outside the folder")
    s = load_sweep(sweep, robot=str(tmp_path / "walker5.yaml"), gait=str(gait))
    assert s.spec.gait == str(gait.resolve()) and len(s.tasks) == 2


@pytest.mark.parametrize("content, kind", [
    (SECRET, "a mapping without any key of a gait file"),
    ("root:x:0:0:root:/root:/bin/bash\nbin:x:1:1::/bin:/sbin/nologin\n",
     "not a mapping of keys"),
    ("id,name\n1,\t'secret'\n", "not a mapping of keys"),
    ("password: [SECRET\n  other: x\n", "a mapping without any key of a gait file"),
], ids=["shadow", "passwd", "csv", "broken-yaml"])
def test_a_file_of_another_kind_is_named_never_quoted(content, kind, cli, tmp_path,
                                                      monkeypatch):
    """A file inside the sweep's folder that is not a gait file, named as ``gait:``: one line
    naming the file and the kind, none of its content (its keys would have been "unknown
    keys", its syntax errors would have quoted it); the same as the ROBOT argument."""
    monkeypatch.chdir(tmp_path)
    notes = tmp_path / "notes.yaml"
    notes.write_text(content)
    sweep = tmp_path / "s.yaml"
    sweep.write_text(SWEEP.replace("GAIT", "notes.yaml"))
    line = _one_error(cli("sweep", sweep, "--out", tmp_path / "o", "-q"),
                      f"error: {notes}: not a gait file: its top level is {kind}")
    res = cli("compile", notes)
    line2 = _one_error(res, f"error: {notes}: not a robot file: its top level is "
                            f"{kind.replace('gait', 'robot')}")
    for text in (line, line2):
        shown = text.split(str(notes), 1)[1]
        assert "SECRET" not in shown and "root" not in shown and "secret" not in shown


def _run_limited(args, tmp_path, timeout: float = 60):
    """The CLI in a subprocess, bounded in time and in memory (a file read until memory runs
    out must not take the machine with it)."""
    import os
    import resource
    import subprocess
    import sys

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    return subprocess.run([sys.executable, "-m", "thrustwalk_cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=tmp_path,
                          preexec_fn=limit, env=dict(os.environ, MPLBACKEND="Agg"))


@pytest.mark.parametrize("what", ["sweep-dev-zero", "sweep-fifo",
                                  pytest.param("uncertainty-dev-zero", marks=pytest.mark.slow),
                                  pytest.param("uncertainty-fifo", marks=pytest.mark.slow),
                                  "gait-fifo-in-sweep"])
def test_special_files_are_refused_unread(what, tmp_path):
    """Issue 30 item 9: ``/dev/zero`` (read until memory ran out) and a FIFO (an open that
    blocked for ever) as the sweep file, the uncertainty file, or a gait a sweep file names:
    one line, exit 2, at once; nothing is created."""
    import os

    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    special = "/dev/zero" if what.endswith("dev-zero") else str(fifo)
    if what.startswith("sweep"):
        args = ["sweep", special, "--out", tmp_path / "o", "-q"]
    elif what.startswith("uncertainty"):
        args = ["robustness", "--uncertainty", special, "--out", tmp_path / "o", "-q"]
    else:
        (tmp_path / "s.yaml").write_text(SWEEP.replace("GAIT", "pipe.yaml"))
        args = ["sweep", tmp_path / "s.yaml", "--out", tmp_path / "o", "-q"]
    res = _run_limited(args, tmp_path)
    lines = res.stderr.splitlines()
    assert res.returncode == 2 and len(lines) == 1, res.stderr[-2000:]
    kind = "a character device" if special == "/dev/zero" else "a FIFO (named pipe)"
    assert lines[0] == f"error: {special if what != 'gait-fifo-in-sweep' else fifo}: is " \
                       f"{kind}, not a regular file: thrustwalk reads only regular files"
    assert not (tmp_path / "o").exists()


def test_a_file_above_the_size_limit_is_refused_unread(cli, tmp_path):
    from thrustwalk_cli.files.yamlio import MAX_FILE_MB

    big = tmp_path / "big.yaml"
    with open(big, "wb") as fh:
        fh.truncate(int(MAX_FILE_MB * 1e6) + 1)  # sparse: no disk used
    _one_error(cli("sweep", big, "--out", tmp_path / "o", "-q"),
               f"error: {big}: larger than {MAX_FILE_MB} MB")


def test_a_count_of_one_is_singular(tmp_path, _cache_dir):
    """"expected 1 value", not "expected 1 values": the thrust of a robot with one thruster
    (inspect), and a thrust schedule of one interval (a gait's thrust: section, a strategy's
    schedule, a sweep's settings.schedule)."""
    import thrustwalk_cli as tw
    from thrustwalk_cli.resilience.strategy import Strategy, realize

    data = Path(__file__).parent / "data"
    w5 = tw.load_walker(str(data / "walker5.yaml"), str(data / "walker5_thrust.yaml"))
    assert w5.robot.thruster_names == ["back"]
    q = [0.1, 0.2, 0.3, -0.2, 0.1]
    with pytest.raises(InputError, match=r"^thrust: expected 1 value \(back\), got 2$"):
        tw.inspect_state(w5, q, thrust=[1.0, 2.0])
    with pytest.raises(InputError, match=r"^thrust: expected 1 comma-separated number \(back\)"):
        tw.inspect_state(w5, q, thrust="1,x")
    one = r"expected 1 value \(one per interval between 2 knots\), got 2$"
    with pytest.raises(InputError, match=one):
        tw.WrittenSchedule((0.0, 1.0), (("back", (1.0, 2.0)),)).resolve(
            w5.zd, w5.robot, "schedule", pad=True)
    with pytest.raises(InputError, match=r"^schedule: expected 1 value \(one per interval\)"):
        realize(w5.zd, Strategy("schedule", "back", schedule=((0.0, 1.0), (-5.0, -10.0),
                                                                "force")), mu=1.0)
    for name in ("walker5.yaml", "walker5_thrust.yaml"):
        (tmp_path / name).write_bytes((data / name).read_bytes())
    (tmp_path / "s.yaml").write_text(
        "name: s\nstudy: limit-cycle\nrobot: walker5.yaml\ngait: walker5_thrust.yaml\n"
        "settings:\n  schedule: {knots: [0, 1], values: [0, -10]}\n"
        "grid:\n  schedule.1: {values: [0, -5]}\ncollect: [speed]\n")
    with pytest.raises(InputError, match=r"settings\.schedule\.values: " + one):
        tw.load_sweep(tmp_path / "s.yaml")
