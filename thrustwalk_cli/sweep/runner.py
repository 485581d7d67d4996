"""The resumable runner: submit every point not yet finished, hand each result to the caller
as it arrives (who writes it at once), start a point that continues another once that one is
finished.

A point is finished when its record exists (``ok`` or ``failed``, with the reason): a failed
computation is a result, recorded and never retried. A task lost with its worker (a worker
process that died, a worker the cluster lost) or cancelled by the cluster is not a result: it
is submitted again, up to ``attempts`` times in all, then left without a record (``lost`` in
:class:`RunCounts`: the run is incomplete, and running again tries the point again). Stopping
the caller at any moment loses at most the points in flight; running again computes exactly
the points without a record.

Points that are cheap beside the engine's own cost per task (pickling, submitting, waiting)
run in **chunks**: up to ``chunk`` consecutive points of one study in one task
(:func:`run_chunk`), whose records come back together and are handed over one by one, exactly
as if each point had been a task of its own (a point that raises gets the record it would have
had alone; the others keep theirs). A chunk lost with its worker is submitted again point by
point (each of its points counts the lost submission), so that a point that kills its worker
is found and left without a record alone. Points that continue another (``after``) run one per
task. :func:`chunk_size` is a rule for ``chunk``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

from ..errors import ComputationError
from .tasks import PointTask

ATTEMPTS = 3  # submissions of a task whose worker is lost before the run gives it up
CHUNKS_PER_WORKER = 8  # chunk_size: at least this many chunks per worker (balance, progress)
MOST_PER_CHUNK = 32  # chunk_size: at most this many points per chunk by default


@dataclass
class RunCounts:
    """What one run did: points computed ``ok`` or ``failed``, points ``skipped`` (a record
    existed), points submitted again because their worker was lost (``resubmitted``), the
    indices of the points left without a record because their task was lost ``attempts``
    times (``lost``, with the last ``lost_reason``), and the wall time [s]."""

    ok: int = 0
    failed: int = 0
    skipped: int = 0
    resubmitted: int = 0
    seconds: float = 0.0
    lost: list[int] = field(default_factory=list)
    lost_reason: str = ""


def failed_record(task: PointTask, reason: str) -> dict:
    """The record of a point whose task raised instead of returning its record (the same
    keys as the record of :func:`~thrustwalk_cli.studies.sweep_studies.run_point`)."""
    return {"key": task.key, "index": task.index, "study": task.study,
            "values": dict(task.values), "status": "failed", "reason": reason,
            "fields": {}, "document": None, "extra": {}, "next_start": task.start,
            "seconds": 0.0}


LOSSES = ("BrokenProcessPool", "KilledWorker", "CancelledError", "FutureCancelledError",
          "CommClosedError")


def _is_loss(err: BaseException) -> bool:
    """Whether ``err`` lost the task with its worker, or the cluster cancelled it (rather
    than the computation failing)."""
    return type(err).__name__ in LOSSES


def _error_record(task: PointTask, err: BaseException) -> dict:
    """The record of a point whose task raised (not a lost worker)."""
    return failed_record(task, f"the task could not run ({type(err).__name__}: {err})")


def _waiting_on(key: str, waiting: dict[str, list[PointTask]]) -> list[PointTask]:
    """The tasks that continue from ``key``, directly or not (removed from ``waiting``): they
    cannot start once that point is lost."""
    out = []
    stack = [key]
    while stack:
        for t in waiting.pop(stack.pop(), []):
            out.append(t)
            stack.append(t.key)
    return out


def chunk_size(todo: int, workers: int, most: int = MOST_PER_CHUNK,
               per_worker: int = CHUNKS_PER_WORKER) -> int:
    """Points per task for ``todo`` points on ``workers`` workers:
    ``ceil(todo / (per_worker * workers))`` clipped to ``[1, most]``.

    Up to ``most`` points share a task, so the engine's cost per task is spread over them,
    while every worker still gets at least ``per_worker`` tasks when there are enough points
    (load balance at the end of a run, and progress that advances often). ``most`` is the
    caller's bound from the cost of one point (about a few tens of milliseconds of work per
    task is enough)."""
    if todo <= 0:
        return 1
    return max(1, min(int(most), math.ceil(todo / (per_worker * max(1, int(workers))))))


def run_chunk(fn: Callable[[PointTask], dict], tasks: Sequence[PointTask]) -> list[dict]:
    """``fn`` on each of ``tasks`` in turn, in a worker: their records in order. A point whose
    ``fn`` raises gets the record its own task would have had (:func:`_error_record`); the
    others are unaffected."""
    out = []
    for t in tasks:
        try:
            out.append(fn(t))
        except Exception as exc:  # noqa: BLE001 - one point's failure is its record
            out.append(_error_record(t, exc))
    return out


def run_tasks(tasks: Sequence[PointTask], fn: Callable[[PointTask], dict], executor,
              finished: dict[str, dict], on_record: Callable[[dict], None],
              attempts: int = ATTEMPTS, chunk: int | Mapping[str, int] = 1,
              many: Callable[[Sequence[PointTask]], list[dict]] | None = None) -> RunCounts:
    """Run the ``tasks`` without a record in ``finished`` (key -> record) on ``executor``;
    ``on_record(record)`` for each new record as soon as it arrives (``finished`` is updated).
    A task with ``after`` waits for that point's record and gets its ``next_start``. ``chunk``:
    points per task, for every study or by study name (a study not named: 1); up to that many
    consecutive points to run (in ``tasks`` order, of one study, without ``after``) share a
    task (module docstring). The records are the same as with ``chunk`` 1. ``many``: the task
    of a chunk, its points' records in order, the same as ``fn``'s one by one (default
    :func:`run_chunk` of ``fn``; e.g. one that batches part of the points' work)."""
    t0 = time.perf_counter()
    counts = RunCounts(skipped=sum(t.key in finished for t in tasks))
    todo = [t for t in tasks if t.key not in finished]
    waiting: dict[str, list[PointTask]] = {}
    inflight: dict = {}
    tries: dict[str, int] = {}
    many = many or partial(run_chunk, fn)

    def submit(group: tuple[PointTask, ...]) -> None:
        if len(group) == 1:
            t = group[0]
            if t.after is not None:
                t = replace(t, start=finished[t.after].get("next_start"))
            group = (t,)
            handle = executor.submit(fn, t)
        else:
            handle = executor.submit(many, group)
        for t in group:
            tries[t.key] = tries.get(t.key, 0) + 1
        inflight[handle] = group

    def record(rec: dict) -> None:
        finished[rec["key"]] = rec
        counts.ok += rec["status"] == "ok"
        counts.failed += rec["status"] != "ok"
        on_record(rec)
        for t in waiting.pop(rec["key"], []):
            submit((t,))

    def size(study: str) -> int:
        n = chunk.get(study, 1) if isinstance(chunk, Mapping) else chunk
        return max(1, int(n))

    group: list[PointTask] = []
    for t in todo:
        if group and (t.study != group[0].study or t.after is not None):
            submit(tuple(group))
            group = []
        if t.after is not None and t.after not in finished:
            waiting.setdefault(t.after, []).append(t)
        elif t.after is not None:
            submit((t,))
        else:
            group.append(t)
            if len(group) >= size(t.study):
                submit(tuple(group))
                group = []
    if group:
        submit(tuple(group))
    while inflight:
        try:
            outcomes = executor.wait(list(inflight))
        except (OSError, TimeoutError) as exc:
            raise ComputationError(f"lost the workers ({type(exc).__name__}: {exc}); the "
                                   "finished points are kept: run the sweep again to "
                                   "resume") from None
        for handle, result, err in outcomes:
            sent = inflight.pop(handle)
            if err is None:
                for rec in (result if len(sent) > 1 else [result]):
                    record(rec)
                continue
            for t in sent:  # a lost chunk runs again point by point
                if _is_loss(err) and tries[t.key] < attempts:
                    counts.resubmitted += 1
                    submit((t,))
                elif _is_loss(err):  # no record: a later run tries it again
                    counts.lost.append(t.index)
                    counts.lost_reason = (f"its task was lost {tries[t.key]} times "
                                          f"({type(err).__name__}: a worker that died, or a "
                                          "cluster that cancelled it)")
                    for w in _waiting_on(t.key, waiting):
                        counts.lost.append(w.index)
                else:
                    record(_error_record(t, err))
    counts.seconds = time.perf_counter() - t0
    return counts
