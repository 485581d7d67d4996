"""The ``report`` study: ``index.md`` for a results folder: every figure, the command that made
it, key numbers.

Each key number is printed with the JSON path it comes from (``file#path``), so the index can
be checked against the JSON outputs mechanically. A number that belongs to a case, a run, a
strategy or a design that has a verdict (walkable, feasible, completed, stable, ...) is printed
with that verdict beside it, itself with its path: never a speed of an orbit that lifts its
foot without the word that says so. The folder is read by
:func:`thrustwalk_cli.files.results.read_results`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, NamedTuple

from ..files.results import ResultFile, read_results


class Key(NamedTuple):
    """One key number of a result document.

    ``path`` is a dotted list of keys and list indices (negative ones count from the end) with
    two selectors over a list: ``*`` (a row for every item) and ``?KEY`` (only the items whose
    ``KEY`` is true, the next segment indexing them: ``cycles.?walkable.-1`` is the last
    walkable cycle). ``{PATH}`` in a path is replaced by the value at the absolute ``PATH``
    (``cot.{energy.basis}``). ``verdict``: the path (or paths: the first that is present and
    not empty) of the verdict printed beside the number; its selectors pick the same item as
    the number's. ``{PATH}`` in ``label`` is the value at ``PATH`` for the same item (e.g. the
    thrust of the case). A row whose number or verdict is absent is left out."""

    label: str
    path: str
    verdict: str | tuple[str, ...] | None = None


# per case of a thrust sweep: the case's verdict beside each of its numbers
def _cases(lst: str, pick: str, what: str, fields: list[tuple[str, str]], verdict: str,
           thrust: str = "thrust") -> list[Key]:
    return [Key(f"{what} ({{{lst}.{pick}.{thrust}}} N): {label}", f"{lst}.{pick}.{field}",
                f"{lst}.{pick}.{verdict}") for label, field in fields]


_LC = [("thrust [N]", "thrust"), ("zeta* [kg^2 m^4/s^2]", "zeta_star"), ("speed [m/s]", "speed")]
_FEAS = [("thrust [N]", "thrust"), ("speed [m/s]", "speed"),
         ("min vertical force [N]", "min_vertical_force"),
         ("max friction ratio", "max_friction_ratio")]
_ENERGY = [("thrust [N]", "thrust"), ("speed [m/s]", "speed"),
           ("CoT ({energy.basis}) [1]", "energy.cot.{energy.basis}")]
_RUN = [("F_ss [N]", "f_ss"), ("steps completed", "steps_completed")]

# result file name -> its key numbers (:class:`Key`)
KEY_NUMBERS: dict[str, list[Key]] = {
    "limit_cycles.json": [
        Key("delta_zero^2", "zero_dynamics.delta_zero_sq"),
        Key("d zeta*/d F [kg^2 m^4/s^2 per N]", "zero_dynamics.zeta_star_per_newton"),
        Key("every case walkable", "success", "reason"),
        *_cases("cycles", "0", "first cycle", _LC, "verdict"),
        *_cases("cycles", "-1", "last cycle", _LC, "verdict"),
        *_cases("cycles", "?walkable.-1", "last walkable cycle", _LC, "verdict"),
    ],
    "shape.json": [
        Key("delta_zero^2", "zero_dynamics.delta_zero_sq"),
        Key("knot fractions", "knots.fraction"),
        Key("nominal zeta* [kg^2 m^4/s^2]", "nominal.zeta_star", "nominal.reason"),
        Key("nominal speed [m/s]", "nominal.speed", "nominal.reason"),
        Key("last k", "schedules.-1.k", "schedules.-1.reason"),
        Key("speed at the last k [m/s] (orbit only: contact is `feasibility`'s check)",
            "schedules.-1.speed", "schedules.-1.reason"),
        Key("true fixed-point shift at the last k [kg^2 m^4/s^2]",
            "schedules.-1.shift.true_fixed_point_shift", "schedules.-1.reason"),
        Key("vector-field speed [m/s] (orbit only)", "vector_field.speed",
            "vector_field.reason"),
    ],
    "feasibility.json": [
        Key("verdict", "verdict", "reason"),
        Key("friction coefficient mu", "mu"),
        *_cases("cases", "0", "first case", _FEAS, "reason"),
        Key("first case ({cases.0.thrust} N): impact friction ratio",
            "cases.0.impact_friction_ratio", "cases.0.reason"),
        Key("first case ({cases.0.thrust} N): lift-off velocity [m/s]",
            "cases.0.liftoff_velocity", "cases.0.reason"),
        *_cases("cases", "-1", "last case", _FEAS, "reason"),
        *_cases("cases", "?feasible.-1", "last feasible case", _FEAS, "reason"),
    ],
    "simulation.json": [
        Key("all runs completed", "success", "reason"),
        *[Key(f"{label}, first run", f"runs.0.{f}", "runs.0.reason") for label, f in _RUN],
        Key("final zeta^- relative error vs zero dynamics, first run",
            "runs.0.final_relative_error", "runs.0.reason"),
        *[Key(f"{label}, last run", f"runs.-1.{f}", "runs.-1.reason") for label, f in _RUN],
        Key("final zeta^- [kg^2 m^4/s^2], last run", "runs.-1.final_zeta_minus",
            "runs.-1.reason"),
        Key("predicted zeta* [kg^2 m^4/s^2], last run (zero-dynamics orbit, contact not "
            "checked)", "runs.-1.predicted.zeta_star", "runs.-1.predicted.reason"),
    ],
    "mujoco.json": [
        Key("status", "status", "reason"),
        *[Key(f"{label}, run {{runs.*.run}}", f"runs.*.{f}", "runs.*.reason")
          for label, f in _RUN],
        Key("zeta^- gap to the rigid model at the last step, run {runs.*.run} [1]",
            "runs.*.final.relative_gap", "runs.*.reason"),
    ],
    "optimal_schedule.json": [
        Key("feasible", "feasible", "reason"),
        Key("thrust values", "values", "status"),
        Key("objective", "objective", "status"),
        Key("zeta* [kg^2 m^4/s^2]", "zeta_star", "status"),
        Key("speed [m/s]", "speed", "status"),
    ],
    "energy.json": [
        Key("CoT compared", "energy.basis", "energy.basis_reason"),
        *_cases("cases", "0", "first case", _ENERGY, "reason"),
        *_cases("cases", "-1", "last case", _ENERGY, "reason"),
        *_cases("cases", "?walkable.0", "first walkable case", _ENERGY, "reason"),
        *_cases("cases", "?walkable.-1", "last walkable case", _ENERGY, "reason"),
        Key("gait library vs thrust (the cheapest way to each speed, walkable orbits only)",
            "library.headline", "library.comparison"),
    ],
    "slope.json": [
        Key("walkable (slope, thrust) pairs", "walkable_pairs", "reason"),
        Key("pairs", "pairs"),
        Key("steepest walkable uphill slope [rad]", "steepest.uphill", "headline"),
        Key("its thrust [N]", "steepest.uphill_thrust", "headline"),
        Key("steepest walkable downhill slope [rad]", "steepest.downhill", "headline"),
        Key("its thrust [N]", "steepest.downhill_thrust", "headline"),
    ],
    "stability.json": [
        Key("verdict", "verdict", "reason"),
        Key("delta_zero^2 (zero dynamics)", "zero_dynamics.delta_zero_sq"),
        Key("spectral radius (largest |multiplier|), case {cases.*.case}",
            "cases.*.spectral_radius", "cases.*.verdict"),
    ],
    "control.json": [
        Key("status", "status", "reason"),
        Key("steps completed", "summary.steps_completed", "reason"),
        Key("final tracking error ({summary.tracked})", "summary.final_tracking_error",
            "reason"),
        Key("max tracking error over the last 5 steps", "summary.max_tracking_error_last_5",
            "reason"),
        Key("mean mechanical CoT [1]", "summary.energy.mean_cot.mechanical", "reason"),
    ],
    "robustness.json": [
        Key("all trials computed", "success", "reason"),
        Key("survivable push of {strategies.*.label} (mean over phases) [N s]",
            "strategies.*.push.summary", "strategies.*.orbit.reason"),
        Key("recovered push trials of {strategies.*.label} [1]",
            "strategies.*.push.recovered_fraction", "strategies.*.orbit.reason"),
        Key("basin slice of {strategies.*.label}: converging fraction [1]",
            "strategies.*.basin_slice.converging_fraction", "strategies.*.orbit.reason"),
        Key("speed of the orbit of {strategies.*.label} [m/s]", "strategies.*.orbit.speed",
            "strategies.*.orbit.reason"),
    ],
    "rough_ground.json": [
        Key("all trials run", "success", "reason"),
        Key("target MFPT [steps]", "headline.target_mfpt"),
        Key("sigma at the target MFPT, {headline.strategies.*.label} [m]",
            "headline.strategies.*.sigma", ("headline.strategies.*.reason", "reason")),
    ],
    "sweep.json": [
        Key("points", "counts.points", "reason"),
        Key("points computed (`ok`: the study ran; its answer may still be no: "
            "results.csv `reason`)", "counts.done", "reason"),
        Key("points failed", "counts.failed", "reason"),
        Key("first failure (point {failures.0.point})", "failures.0.reason"),
    ],
}

# design-gait writes NAME.report.json (NAME the gait's name)
DESIGN_REPORT: list[Key] = [
    Key("feasible", "feasible", "reason"),
    Key("speed [m/s]", "fixed_point.speed", "reason"),
    Key("step length [m]", "fixed_point.step_length", "reason"),
    Key("zeta* [kg^2 m^4/s^2]", "fixed_point.zeta_star", "reason"),
    Key("delta_zero^2", "fixed_point.delta_zero_sq", "reason"),
    Key("objective ({objective.name}) [{objective.unit}]", "objective.value",
        ("optimality.note", "optimality.certified")),
]


def keys_for(name: str) -> list[Key]:
    """The key numbers of a result file named ``name``."""
    if name.endswith(".report.json"):
        return DESIGN_REPORT
    return KEY_NUMBERS.get(name, [])


def lookup(doc: Any, path: str) -> Any:
    """Value at a dotted path (no selectors); raises KeyError/IndexError when absent."""
    cur = doc
    for part in path.split("."):
        if isinstance(cur, list):
            cur = cur[int(part)]
        else:
            cur = cur[part]
    return cur


_ABSENT = (KeyError, IndexError, TypeError, ValueError)
_BRACES = re.compile(r"\{([^{}]+)\}")


def expand(doc: Any, path: str) -> list[tuple[str, dict[str, str]]]:
    """The concrete paths a :class:`Key` path stands for (no selectors, list indices
    non-negative), each with the map from the pattern's prefixes up to each list index to the
    concrete prefixes (to place a verdict or label path on the same item). Absent: []."""
    try:
        path = _BRACES.sub(lambda m: str(lookup(doc, m.group(1))), path)
    except _ABSENT:
        return []
    out: list[tuple[str, dict[str, str]]] = []

    def walk(cur: Any, parts: list[str], pat: list[str], conc: list[str],
             bind: dict[str, str]) -> None:
        if not parts:
            out.append((".".join(conc), bind))
            return
        head, rest = parts[0], parts[1:]
        if isinstance(cur, list):
            idx = list(range(len(cur)))
            if head.startswith("?"):
                if not rest:
                    return
                idx = [i for i in idx if isinstance(cur[i], dict) and cur[i].get(head[1:])]
                head, rest, pat = rest[0], rest[1:], [*pat, parts[0]]
            if head == "*":
                picks = idx
            else:
                try:
                    picks = [idx[int(head)]]
                except (IndexError, ValueError):
                    return
            for i in picks:
                p2, c2 = [*pat, head], [*conc, str(i)]
                walk(cur[i], rest, p2, c2, {**bind, ".".join(p2): ".".join(c2)})
        elif isinstance(cur, dict) and head in cur:
            walk(cur[head], rest, [*pat, head], [*conc, head], bind)

    walk(doc, path.split("."), [], [], {})
    return out


def place(path: str, bind: dict[str, str]) -> str:
    """``path`` with its longest prefix in ``bind`` replaced (see :func:`expand`)."""
    for pat in sorted(bind, key=len, reverse=True):
        if path == pat or path.startswith(pat + "."):
            return bind[pat] + path[len(pat):]
    return path


def _label(doc: Any, label: str, bind: dict[str, str]) -> str | None:
    def value(m: re.Match) -> str:
        v = lookup(doc, place(m.group(1), bind))
        return f"{v:g}" if isinstance(v, float) else str(v)

    try:
        return _BRACES.sub(value, label)
    except _ABSENT:
        return None


def _verdict(doc: Any, verdict: str | tuple[str, ...], bind: dict[str, str]
             ) -> tuple[str, Any] | None:
    for path in (verdict,) if isinstance(verdict, str) else verdict:
        concrete = place(path, bind)
        try:
            value = lookup(doc, concrete)
        except _ABSENT:
            continue
        if value not in ("", None):
            return concrete, value
    return None


def key_rows(doc: Any, keys: list[Key]) -> list[tuple[str, Any, str, tuple[str, Any] | None]]:
    """``(label, value, path, (verdict path, verdict) or None)`` of every key number present
    in ``doc``, each path once (the last walkable case is not repeated when it is the last
    case); a key with a verdict whose verdict is absent is left out (never a number without
    its verdict)."""
    rows, seen = [], set()
    for key in keys:
        for concrete, bind in expand(doc, key.path):
            label = _label(doc, key.label, bind)
            verdict = None if key.verdict is None else _verdict(doc, key.verdict, bind)
            if label is None or (key.verdict is not None and verdict is None) \
                    or concrete in seen:
                continue
            seen.add(concrete)
            rows.append((label, lookup(doc, concrete), concrete, verdict))
    return rows


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        text = repr(v)
    elif isinstance(v, list):
        text = "[" + ", ".join(_fmt(x) for x in v) + "]"
    else:
        text = json.dumps(v)
    return text.replace("|", "\\|")


def render_index(results: list[ResultFile], title: str = "thrustwalk figures") -> str:
    """Markdown index of result documents (see :func:`read_results`)."""
    out = [f"# {title}", "",
           "Generated by `thrustwalk report`; every number is followed by the JSON path it "
           "comes from, and a number of a case or run that has a verdict (walkable, "
           "feasible, completed, stable, ...) by that verdict and its path.", ""]
    for res in results:
        doc = res.document
        rel = Path(res.relative)
        out += [f"## {(rel.parent / rel.stem).as_posix()}", "",
                f"Command: `{doc['provenance'].get('command', '?')}`", ""]
        for png, pdf in res.figures:
            extra = f" ([PDF]({pdf}))" if pdf else ""
            out += [f"![{Path(png).stem}]({png}){extra}", ""]
        rows = []
        for label, value, path, verdict in key_rows(doc, keys_for(rel.name)):
            vcells = (f"{_fmt(verdict[1])} | `{res.relative}#{verdict[0]}`" if verdict
                      else " | ")
            label = label.replace("|", "\\|")
            rows.append(f"| {label} | {_fmt(value)} | `{res.relative}#{path}` | {vcells} |")
        if rows:
            out += ["| quantity | value | source | verdict | verdict source |",
                    "|---|---|---|---|---|", *rows, ""]
    return "\n".join(out) + "\n"


def build_index(folder: Path, title: str = "thrustwalk figures",
                problems: list[str] | None = None) -> str:
    """Markdown index of every result JSON (with provenance) below ``folder``; files that
    cannot be read are skipped with a line in ``problems``."""
    return render_index(read_results(folder, problems), title)
