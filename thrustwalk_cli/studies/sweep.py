"""The ``sweep`` study: one study at many points, from a sweep file, on local worker processes
or a Dask cluster; resumable point by point.

:func:`load_sweep` reads and checks everything before any work (the file's keys, the axes, the
robot and gait, every robot and gait parameter named, the study's parameters, the fields to
collect) and keys every point by a content hash (:mod:`thrustwalk_cli.sweep.tasks`).
:func:`sweep_executor` starts where the points run; :func:`run_sweep` runs every point not
yet finished and hands each record over as it arrives (``on_point``: the command writes it at
once) and returns a :class:`SweepResult` over all the points, which renders ``sweep.json``,
``results.csv`` (one row per point: the axes and the collected fields), heat maps, and for a
gait library ``library.csv``, the gait files and the atlas figure.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..description.sweep import Axis, SweepSpec
from ..errors import (
    InputError,
    Problem,
    check_callable,
    check_count,
    check_instance,
    check_path,
    check_text,
)
from ..files.bundled import EXPLICITLY, resolve, resolve_inside
from ..files.gait_file import load_gait_text
from ..files.robot_file import load_robot_text
from ..files.schema import suggest
from ..files.sweep_file import SweepSource, load_sweep_file, read_source, value_problem
from ..sweep.executors import DaskCluster, InProcess, LocalProcesses
from ..sweep.points import expand, grid_coordinates, neighbours
from ..sweep.runner import RunCounts, run_tasks
from ..sweep.tasks import PointTask, canonical, identity, task_key
from ..walker import assemble_walker, default_gait, gait_robot_mismatch
from .documents import SCHEMA_VERSION, Table, col, result_repr
from .sweep_points import SweepStudy, point_model, point_walker
from .sweep_studies import STUDIES, run_point
from .trial_studies import trial_chunk


@dataclass(frozen=True)
class Sweep:
    """A checked sweep, ready to run: its description, study, one task per point (in point
    order) and its identity (the hash of the points' keys)."""

    spec: SweepSpec
    study: SweepStudy = field(repr=False)
    tasks: tuple[PointTask, ...] = field(repr=False)
    identity: str
    gait_name: str | None = None

    @property
    def name(self) -> str:
        """The sweep's name (its file's ``name:``)."""
        return self.spec.name

    @property
    def points(self) -> list[dict[str, float]]:
        """The axis values of every point, in order."""
        return [dict(t.values) for t in self.tasks]

    def __repr__(self) -> str:
        """One line: name, study, files, points and axes (the dataclass's own repr printed
        the robot and gait files' whole text)."""
        s = self.spec
        return (f"Sweep(name={s.name!r}, study={s.study!r}, robot={s.robot!r}, "
                f"gait={s.gait!r}, points={len(self.tasks)}, "
                f"axes={[a.name for a in s.axes]!r}, collect={list(s.collect)!r})")

    def units(self) -> dict[str, str]:
        """Unit of every axis and collectable field."""
        return {**{a.name: a.unit for a in self.spec.axes},
                **{k: u for k, (u, _) in self.study.fields.items()}}


def load_sweep(path: str | Path, *, robot: str | None = None,
               gait: str | None = None) -> Sweep:
    """Read and check a sweep file (see the module docstring); raises :class:`InputError`
    with every problem (``file:line: key.path: message``) before any point runs. Loads (and
    compiles if needed) the base robot's model to check the gait against it.

    The files a sweep file names (``robot:``, ``gait:``, and the ``robot:`` of a gait it
    names) are read only inside the sweep file's folder, or bundled
    (:func:`~thrustwalk_cli.files.sweep_file.load_sweep_file`); ``robot`` / ``gait``: a file
    (relative to the working folder) or bundled name given explicitly instead, read
    wherever it is, its gait's ``robot:`` as for every command."""
    robot = None if robot is None else check_path("robot", robot)
    gait = None if gait is None else check_path("gait", gait)
    spec, source = load_sweep_file(check_path("path", path), robot=robot, gait=gait)
    study = STUDIES[spec.study]
    problems: list[Problem] = []
    for i, name in enumerate(spec.collect):
        if name not in study.fields:
            problems.append(source.where(("collect", i), f"unknown field '{name}' of the "
                                                         f"{spec.study} study (one of: "
                                                         f"{', '.join(study.fields)})"
                                                         f"{suggest(name, study.fields)}"))
    robot = load_robot_text(spec.robot_text, spec.robot)
    gait_name = None
    if study.uses_gait and spec.gait is None:
        try:
            gait_name = default_gait(robot)
        except InputError as exc:
            raise InputError(source.where(("gait",), exc.problems[0].message)) from None
        gpath = str(resolve(gait_name, "gaits").resolve())
        spec = replace(spec, gait=gpath, gait_text=read_source(gpath, "gait"))
    gait_params: dict[str, float] = {}
    if study.uses_gait:
        gait, gsource = load_gait_text(spec.gait_text, spec.gait)
        gait_params = gsource.res.params
        if source.gait_inside:  # named by the sweep file: its robot is confined as well
            try:
                resolve_inside(gsource.res.data["robot"], "robots", source.root,
                               base=Path(spec.gait).parent,
                               how=f"{EXPLICITLY} `gait` (the gait, read wherever it is)")
            except InputError as exc:
                raise InputError(gsource.where(("robot",), exc.problems[0].message)) from None
        wrong = gait_robot_mismatch(robot, gait, lambda ref: load_robot_text(
            read_source(str(resolve(ref, "robots")), "robot"), ref))
        if wrong:
            problems.append(source.where(("gait",), wrong))
    robot_params = dict(robot.parameters)
    for a in spec.axes:
        known = robot_params if a.target == "robot" else gait_params
        if a.target != "study" and a.parameter not in known:
            what = f"{a.target} {robot.name if a.target == 'robot' else spec.gait}"
            problems.append(source.where(source.axis_key(a), (
                f"no parameter '{a.parameter}' in the {what} (its parameters: "
                f"{', '.join(sorted(known)) or 'none'}){suggest(a.parameter, known)}")))
    if problems:
        raise InputError(sorted(problems, key=lambda p: p.line or 0))
    if study.uses_gait:
        base = assemble_walker(robot, gait, gsource)
    else:
        from ..model.compiler import load_model

        base = load_model(robot)
    sweep = _plan(spec, study, gait_name)
    _check_parameters(sweep, source, base)
    return sweep


MAX_CHECKED = 20_000  # distinct parameter sets checked one by one (more: each value once)


def _check_parameters(sweep: Sweep, source: SweepSource, base) -> None:
    """Every point's study parameters before any point runs: each axis value against the
    parameter table's bounds (the draws of random axes included), then the study's own check
    of every distinct set of study parameters the points take (beyond :data:`MAX_CHECKED`
    sets: the settings with the first value of every axis, then each value of each axis).
    Each problem is reported once, at the axis that sets the parameter, else at its key under
    ``settings`` (``schedule.knots``: ``settings.schedule.knots``)."""
    spec, study = sweep.spec, sweep.study
    settings = dict(spec.settings)
    axes = {a.name: a for a in spec.axes if a.target == "study"}
    problems: dict[tuple, Problem] = {}

    def key_of(name: str) -> tuple:
        if name in axes:
            return source.axis_key(axes[name])
        parts = tuple(name.split("."))
        if parts[0] == "schedule" and len(parts) > 1 and parts[1] == "values":
            swept = [a for a in axes if a.startswith("schedule.")]
            if swept:  # a value of the schedule: the first axis that sets one
                return source.axis_key(axes[swept[0]])
        return ("settings", *parts) if parts[0] in settings else ("settings",)

    points = [t.parameters for t in sweep.tasks]
    for name in axes:  # the values of every axis, drawn ones included
        for v in sorted({p[name] for p in points}):
            bad = value_problem(spec.study, name, v)
            if bad:
                problems.setdefault(key_of(name), source.where(key_of(name),
                                                               f"value {v:g}: {bad}"))
                break
    if problems:
        raise InputError(sorted(problems.values(), key=lambda p: p.line or 0))
    if study.check is None:
        return
    distinct = {canonical(p): p for p in points}
    if len(distinct) > MAX_CHECKED:
        first = points[0]
        sets = [first] + [{**first, n: v} for n in axes for v in {p[n] for p in points}]
        distinct = {canonical(p): p for p in sets}
    for i, p in enumerate(distinct.values()):  # the first point first
        for name, message in study.check(base, p):
            key = key_of(name)
            if key not in problems:  # a problem of some points only says which
                shown = ", ".join(f"{n} = {p[n]:g}" for n in axes
                                  if source.axis_key(axes[n]) != key)
                where = f" (at {shown})" if shown and i else ""
                problems[key] = source.where(key, message + where)
    if problems:
        raise InputError(sorted(problems.values(), key=lambda p: p.line or 0))


def _plan(spec: SweepSpec, study: SweepStudy, gait_name: str | None) -> Sweep:
    """One task per point, keyed (continuation: each key includes its neighbour's)."""
    points = expand(spec)
    settings = dict(spec.settings)
    follow = neighbours(spec) if study.continuation and settings.get("continuation") else \
        [None] * len(points)
    tasks: list[PointTask] = []
    for i, (values, after) in enumerate(zip(points, follow)):
        prev = tasks[after].key if after is not None else None
        key = task_key(spec.study, spec.robot_text, spec.gait_text, settings, values, prev)
        tasks.append(PointTask(i, key, spec.study, tuple(values.items()),
                               tuple(settings.items()), spec.robot, spec.robot_text,
                               spec.gait, spec.gait_text, after=prev,
                               name=f"{spec.name}_{i:04d}",
                               label=f"sweep {spec.name}, point {i}"))
    return Sweep(spec, study, tuple(tasks), identity([t.key for t in tasks]), gait_name)


# ------------------------------------------------------------------------------ running
def default_workers() -> int:
    """Local worker processes by default: one per core."""
    return max(1, os.cpu_count() or 1)


def sweep_executor(sweep: Sweep, workers: int | None = None, scheduler: str | None = None,
                   todo: int | None = None):
    """Where the points run: ``scheduler`` (``tcp://HOST:PORT``), else ``workers`` local
    processes (default: one per core; 1 runs in this process). Before local processes start,
    the first point's model (and the study's one-time preparation, e.g. the simulation
    kernel) is made here, so that workers inherit or load it instead of each making it."""
    return task_executor(sweep.tasks, sweep.study, dict(sweep.spec.settings), workers,
                         scheduler, todo)


MAX_WORKERS = 1024  # local worker processes


def check_executor(workers: object = None, scheduler: object = None) -> None:
    """Where the points are to run, checked before anything is created: ``workers`` a whole
    number 1 ... :data:`MAX_WORKERS` (or None), ``scheduler`` a Dask scheduler address
    ``tcp://HOST:PORT`` or ``tls://HOST:PORT`` with a port 1 ... 65535 (or None; Dask
    distributed must be installed), not both. :class:`InputError` naming the parameter."""
    if workers is not None and scheduler is not None:
        raise InputError.param(("workers", "scheduler"), "give one of them, not both")
    check_count("workers", workers, ge=1, le=MAX_WORKERS, optional=True)
    if scheduler is None:
        return
    from importlib.util import find_spec
    from urllib.parse import urlsplit

    address = check_text("scheduler", scheduler)
    expected = f"expected tcp://HOST:PORT or tls://HOST:PORT, got {address!r}"
    try:
        parts = urlsplit(address.strip())
        host = parts.hostname
    except ValueError:  # e.g. an unclosed [
        raise InputError.param("scheduler", expected) from None
    if parts.scheme not in ("tcp", "tls") or not host or parts.path not in ("", "/") or \
            parts.query or parts.fragment or "@" in parts.netloc:
        raise InputError.param("scheduler", expected)
    try:
        port = parts.port
    except ValueError:  # not a number, or beyond 65535
        port = -1
    if port is None or not 1 <= port <= 65535:
        raise InputError.param("scheduler", f"the port must be a number 1 ... 65535 (got "
                                            f"{address!r})")
    if find_spec("distributed") is None:
        raise InputError.param("scheduler", "needs Dask distributed: pip install "
                                            "'thrustwalk[cluster]'")


def task_executor(tasks, study: SweepStudy, settings: dict, workers: int | None = None,
                  scheduler: str | None = None, todo: int | None = None):
    """:func:`sweep_executor` for any tasks of ``study`` (``settings``: what its one-time
    preparation needs)."""
    check_executor(workers, scheduler)
    if scheduler is not None:
        return DaskCluster(scheduler)
    n = default_workers() if workers is None else workers
    n = max(1, min(n, len(tasks) if todo is None else todo))
    first = next(iter(tasks))
    try:
        base = point_walker(first) if study.uses_gait else point_model(first)
        if study.prepare is not None:
            study.prepare(base, settings)
    except InputError:
        pass  # the first point's own problem: it is recorded when it runs
    return InProcess() if n == 1 else LocalProcesses(n)


@dataclass(frozen=True)
class SweepResult:
    """Every point of a sweep with its record (``None`` for a point without one: the run was
    stopped), what this run did (``counts``), and where it ran (``executor``)."""

    __repr__ = result_repr

    sweep: Sweep
    records: tuple[dict | None, ...] = field(repr=False)
    counts: RunCounts
    executor: dict

    name = "sweep"

    @property
    def done(self) -> int:
        """The number of points computed whose study succeeded (status ``ok``)."""
        return sum(r is not None and r["status"] == "ok" for r in self.records)

    @property
    def failed(self) -> int:
        """The number of points computed whose study failed."""
        return sum(r is not None and r["status"] != "ok" for r in self.records)

    @property
    def answered_no(self) -> int:
        """Points computed whose study's answer is no (not walkable, fell...): ``ok``, a reason."""
        return sum(r is not None and r["status"] == "ok" and bool(r["reason"])
                   for r in self.records)

    @property
    def missing(self) -> int:
        """The number of points not run yet."""
        return sum(r is None for r in self.records)

    @property
    def success(self) -> bool:
        """Every point was computed (a point whose study failed counts as computed)."""
        return self.missing == 0

    @property
    def reason(self) -> str:
        """Points ok, failed and not run (and why points were lost)."""
        n = len(self.records)
        no = self.answered_no
        text = f"{self.done} of {n} points ok" + (
            f" ({no} answered no: see `reason` in results.csv)" if no else "") + \
            f", {self.failed} failed"
        if self.missing:
            lost = len(self.counts.lost)
            text += f", {self.missing} not run" + (
                f" ({lost} lost: {self.counts.lost_reason})" if lost else "") + \
                " (run the sweep again to resume)"
        return text

    def _axis_columns(self) -> list[tuple[str, str]]:
        return [(a.name, col(a.name.replace(".", "_"), a.unit)) for a in self.sweep.spec.axes]

    def document(self) -> dict:
        """The JSON body of ``sweep.json`` (provenance is added by the command)."""
        s, spec = self.sweep, self.sweep.spec
        axes = []
        for a in spec.axes:
            entry = {"name": a.name, "unit": a.unit, "group": a.group,
                     "column": col(a.name.replace(".", "_"), a.unit)}
            if a.group == "random":
                entry.update(distribution=a.distribution, parameters=list(a.parameters))
            else:
                entry["values"] = list(a.values)
            axes.append(entry)
        failures = [{"point": r["index"], "key": r["key"], "reason": r["reason"]}
                    for r in self.records if r is not None and r["status"] != "ok"]
        return {
            "schema_version": SCHEMA_VERSION,
            "units": {k: u for k, u in s.units().items()},
            "sweep": {"name": spec.name, "description": spec.description, "study": spec.study,
                      "file": spec.source_file, "sha256": spec.source_sha256,
                      "identity": s.identity, "robot": spec.robot, "gait": spec.gait},
            "settings": dict(spec.settings),
            "axes": axes,
            "random": ({"samples": spec.samples, "seed": spec.seed}
                       if spec.group("random") else None),
            "collect": list(spec.collect),
            "success": self.success, "reason": self.reason,
            "counts": {"points": len(self.records), "done": self.done, "failed": self.failed,
                       "answered_no": self.answered_no,
                       "skipped": self.counts.skipped, "computed": self.counts.ok +
                       self.counts.failed, "not_run": self.missing,
                       "resubmitted": self.counts.resubmitted},
            "wall_time": self.counts.seconds,
            "executor": self.executor,
            "points_folder": "points",
            "failures": failures,
            "library": sorted(self.library_files()),
        }

    def attachments(self, doc: dict) -> dict[str, str]:
        """The gait library's files (:meth:`library_files`)."""
        return self.library_files()

    def tables(self) -> dict[str, Table]:
        """``results``: one row per point (point, key, status, the axes, the collected fields,
        reason); ``library`` for a design-gait sweep (the gait files and their numbers)."""
        spec = self.sweep.spec
        units = self.sweep.units()
        axes = self._axis_columns()
        fixed = {"point", "key", "status", "reason"} | {c for _, c in axes}
        study = spec.study.replace("-", "_")
        # a collected field named like a column of the point (the study's own `status` beside
        # the point's) is prefixed with the study's name: one column per name
        header = ["point", "key", "status"] + [c for _, c in axes] + \
            [col(f"{study}_{f}" if f in fixed else f, units[f]) for f in spec.collect] + \
            ["reason"]
        rows = []
        for t, r in zip(self.sweep.tasks, self.records):
            if r is None:
                continue
            vals = dict(t.values)
            rows.append([t.index, t.key[:20], r["status"]] + [vals[n] for n, _ in axes]
                        + [r["fields"].get(f) for f in spec.collect] + [r["reason"]])
        out = {"results": Table(header, rows, [
            "one row per point: the axis values and the collected fields (SI units in the "
            "column names); the point's full JSON is points/KEY.json"])}
        if spec.study == "design-gait":
            out["library"] = self._library_table()
        return out

    # -- gait library ------------------------------------------------------------------
    def gait_name(self, index: int) -> str:
        """The name (and file stem) of point ``index``'s designed gait."""
        return self.sweep.tasks[index].name

    def library_files(self) -> dict[str, str]:
        """``gaits/NAME.yaml`` of every feasible design point (the gait library)."""
        return {f"gaits/{self.gait_name(r['index'])}.yaml": r["extra"]["gait_yaml"]
                for r in self.records if r is not None and (r.get("extra") or {}).get(
                    "gait_yaml")}

    def _library_table(self) -> Table:
        fields = [f for f in self.sweep.study.fields if f != "iterations"]
        units = self.sweep.units()
        axes = self._axis_columns()
        header = ["gait", "file"] + [c for _, c in axes] + [col(f, units[f]) for f in fields]
        rows = []
        for t, r in zip(self.sweep.tasks, self.records):
            if r is None:
                continue
            ok = bool((r.get("extra") or {}).get("gait_yaml"))
            name = self.gait_name(t.index)
            vals = dict(t.values)
            rows.append([name if ok else None, f"gaits/{name}.yaml" if ok else None]
                        + [vals[n] for n, _ in axes] + [r["fields"].get(f) for f in fields])
        return Table(header, rows, ["one row per design point; file empty: no feasible gait"])

    # -- figures -----------------------------------------------------------------------
    def heat_map_data(self) -> list[dict]:
        """Per pair of numeric axes that vary: the points with every other axis at its first
        value (grid), first zip entry and first sample, unless the pair includes those
        groups; x, y and the first collected field (booleans as 0/1; None when missing)."""
        spec = self.sweep.spec
        if not spec.collect:
            return []
        first = spec.collect[0]
        unit = self.sweep.units()[first]
        coords = grid_coordinates(spec)
        grid = [a.name for a in spec.group("grid")]
        axes = [a for a in spec.axes if len(set(a.values)) > 1 or a.group == "random"]
        out = []
        for i, a in enumerate(axes):
            for b in axes[i + 1:]:
                if a.group == b.group == "zip":
                    continue  # they vary together: a line, not a map
                pair = {a.name, b.name}
                groups = {a.group, b.group}
                xs, ys, cs = [], [], []
                for (g, rest), t, r in zip(coords, self.sweep.tasks, self.records):
                    if any(g[k] != 0 for k, n in enumerate(grid) if n not in pair):
                        continue
                    if not groups & {"zip", "random"} and rest != 0:
                        continue
                    v = dict(t.values)
                    value = None if r is None else r["fields"].get(first)
                    if isinstance(value, bool):
                        value = float(value)
                    if value is not None and not isinstance(value, (int, float)):
                        return []  # the first field is not a number: no heat map
                    xs.append(v[a.name])
                    ys.append(v[b.name])
                    cs.append(value)
                out.append({"x": a, "y": b, "xs": xs, "ys": ys, "values": cs, "field": first,
                            "unit": unit, "gridded": a.group == b.group == "grid"})
        return out

    def figures(self, titles: bool = False) -> dict:
        """``heatmap_X_Y`` for every pair of numeric axes (:meth:`heat_map_data`) and, for a
        gait library, ``atlas``."""
        from ..plots.sweep import atlas, heat_map

        def label(a: Axis) -> str:
            return f"{a.name} [{a.unit}]" if a.unit else a.name

        out = {}
        for d in self.heat_map_data():
            name = "heatmap_" + "_".join(n.name.replace(".", "-") for n in (d["x"], d["y"]))
            out[name] = heat_map(
                d["xs"], d["ys"], d["values"], xlabel=label(d["x"]), ylabel=label(d["y"]),
                clabel=f"{d['field']} [{d['unit']}]" if d["unit"] else d["field"],
                gridded=d["gridded"],
                title=f"{self.sweep.name}: {d['field']}" if titles else "")
        data = self.atlas_data()
        if data is not None:
            out["atlas"] = atlas(data, title=f"{self.sweep.name}: gait library" if titles
                                 else "")
        return out

    def atlas_data(self) -> dict | None:
        """For a design-gait sweep: effort, delta_zero^2 and the contact margins against the
        first axis, one line per value of the second (None otherwise)."""
        spec = self.sweep.spec
        if spec.study != "design-gait" or not spec.axes:
            return None
        x = next((a for a in spec.axes if a.name == "target_speed"), spec.axes[0])
        other = next((a for a in spec.axes if a is not x), None)
        series: dict = {}
        for t, r in zip(self.sweep.tasks, self.records):
            v = dict(t.values)
            key = None if other is None else v[other.name]
            s = series.setdefault(key, {"x": [], **{f: [] for f in ATLAS_FIELDS}})
            s["x"].append(v[x.name])
            for f in ATLAS_FIELDS:
                ok = r is not None and r["fields"].get("feasible")
                s[f].append(r["fields"].get(f) if ok else None)
        units = self.sweep.units()
        return {"x_label": f"{x.name} [{x.unit}]" if x.unit else x.name,
                "line_label": None if other is None else other.name,
                "line_unit": "" if other is None else other.unit,
                "series": series,
                "panels": [(f, f"{ATLAS_LABELS[f]} [{units[f]}]") for f in ATLAS_FIELDS]}


ATLAS_FIELDS = ("effort", "delta_zero_sq", "vertical_force_margin", "friction_margin")
ATLAS_LABELS = {"effort": "effort", "delta_zero_sq": "delta_zero^2",
                "vertical_force_margin": "F_1^v margin", "friction_margin": "friction margin"}


def run_sweep(sweep: Sweep, *, workers: int | None = None, scheduler: str | None = None,
              executor=None, finished: Mapping[str, dict] | None = None,
              on_point: Callable[[dict], None] | None = None,
              library: Path | None = None, chunk: int | None = None) -> SweepResult:
    """Run every point of ``sweep`` without a record in ``finished`` (key -> record, e.g. the
    points a stopped run already wrote) on ``executor`` (default: :func:`sweep_executor` of
    ``workers`` / ``scheduler``); ``on_point(record)`` as each point finishes. ``library``:
    the folder a design-gait sweep's gait files will be written to (their ``robot:``
    reference is relative to it). ``chunk``: push trials per engine task (default
    :func:`~.trial_studies.trial_chunk` of the trials to run, the workers and the most steps of
    a trial; 1: one per task); other studies run one point per task (their points cost tens
    of milliseconds or more). The records do not depend on it. Returns the result over all
    points."""
    from ..files.gait_file import robot_reference

    check_instance("sweep", sweep, Sweep, "a Sweep (tw.load_sweep)")
    if executor is None:
        check_executor(workers, scheduler)
    check_instance("finished", finished, Mapping, "a mapping of point keys to records",
                   optional=True)
    check_callable("on_point", on_point)
    library = check_path("library", library, optional=True)
    chunk = check_count("chunk", chunk, optional=True)
    done = {k: v for k, v in (finished or {}).items()
            if k in {t.key for t in sweep.tasks}}
    tasks = list(sweep.tasks)
    if library is not None:
        robot = load_robot_text(sweep.spec.robot_text, sweep.spec.robot)
        ref = robot_reference(robot, _given_robot(sweep), Path(library) / "x.yaml")
        tasks = [replace(t, robot_ref=ref) for t in tasks]
    todo = sum(t.key not in done for t in tasks)
    own = executor is None and todo > 0
    if own:
        executor = sweep_executor(sweep, workers, scheduler, todo)
    if chunk is None:
        trials = [t for t in tasks if t.study == "push-trial" and t.key not in done]
        steps = max((int(t.parameters.get("steps", 1)) for t in trials), default=1)
        chunk = trial_chunk(len(trials), getattr(executor, "workers", 1), steps)
    try:
        counts = run_tasks(tasks, run_point, executor, done, on_point or (lambda r: None),
                           chunk={"push-trial": int(chunk)}) \
            if todo else RunCounts(skipped=len(tasks))
    finally:
        if own:
            executor.close()
    desc = executor.describe() if executor is not None else {"kind": "none", "workers": 0}
    return SweepResult(sweep, tuple(done.get(t.key) for t in tasks), counts, desc)


def _given_robot(sweep: Sweep) -> str:
    """The robot as the sweep file names it when that is a bundled name (gait files then
    name it the same way), else its path."""
    spec = sweep.spec
    name = Path(spec.robot).stem
    try:
        if resolve(name, "robots").resolve() == Path(spec.robot).resolve():
            return name
    except InputError:
        pass
    return spec.robot

