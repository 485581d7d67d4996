"""The resumable runner: submit every point not yet finished, hand each result to the caller
as it arrives (who writes it at once), start a point that continues another once that one is
finished.

A point is finished when its record exists (``ok`` or ``failed``, with the reason): a failed
computation is a result, recorded and never retried. A task lost with its worker (a worker
process that died, a worker the cluster lost) is not a result: it is submitted again, up to
``attempts`` times in all, then recorded as failed. Stopping the caller at any moment loses at
most the points in flight; running again computes exactly the points without a record.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from ..errors import ComputationError
from .tasks import PointTask

ATTEMPTS = 3  # submissions of a task whose worker is lost before it is recorded as failed


@dataclass
class RunCounts:
    """What one run did: points computed ``ok`` or ``failed``, points ``skipped`` (a record
    existed), workers lost (``resubmitted`` tasks), and the wall time [s]."""

    ok: int = 0
    failed: int = 0
    skipped: int = 0
    resubmitted: int = 0
    seconds: float = 0.0


def lost_record(task: PointTask, reason: str) -> dict:
    """The record of a point whose task could not be run (see the module docstring)."""
    return {"key": task.key, "index": task.index, "study": task.study,
            "values": dict(task.values), "status": "failed", "reason": reason,
            "fields": {}, "document": None, "next_start": task.start, "seconds": 0.0}


def _is_loss(err: BaseException) -> bool:
    """Whether ``err`` lost the task with its worker (rather than failing the computation)."""
    name = type(err).__name__
    return name in ("BrokenProcessPool", "KilledWorker", "CancelledError", "CommClosedError")


def run_tasks(tasks: Sequence[PointTask], fn: Callable[[PointTask], dict], executor,
              finished: dict[str, dict], on_record: Callable[[dict], None],
              attempts: int = ATTEMPTS) -> RunCounts:
    """Run the ``tasks`` without a record in ``finished`` (key -> record) on ``executor``;
    ``on_record(record)`` for each new record as soon as it arrives (``finished`` is updated).
    A task with ``after`` waits for that point's record and gets its ``next_start``."""
    t0 = time.perf_counter()
    counts = RunCounts(skipped=sum(t.key in finished for t in tasks))
    todo = [t for t in tasks if t.key not in finished]
    waiting: dict[str, list[PointTask]] = {}
    inflight: dict = {}
    tries: dict[str, int] = {}

    def submit(t: PointTask) -> None:
        if t.after is not None:
            t = replace(t, start=finished[t.after].get("next_start"))
        tries[t.key] = tries.get(t.key, 0) + 1
        inflight[executor.submit(fn, t)] = t

    def record(rec: dict) -> None:
        finished[rec["key"]] = rec
        counts.ok += rec["status"] == "ok"
        counts.failed += rec["status"] != "ok"
        on_record(rec)
        for t in waiting.pop(rec["key"], []):
            submit(t)

    for t in todo:
        if t.after is not None and t.after not in finished:
            waiting.setdefault(t.after, []).append(t)
        else:
            submit(t)
    while inflight:
        try:
            outcomes = executor.wait(list(inflight))
        except (OSError, TimeoutError) as exc:
            raise ComputationError(f"lost the workers ({type(exc).__name__}: {exc}); the "
                                   "finished points are kept: run the sweep again to "
                                   "resume") from None
        for handle, result, err in outcomes:
            t = inflight.pop(handle)
            if err is None:
                record(result)
            elif _is_loss(err) and tries[t.key] < attempts:
                counts.resubmitted += 1
                submit(t)
            elif _is_loss(err):
                record(lost_record(t, f"its worker was lost {tries[t.key]} times "
                                      f"({type(err).__name__}): a crash in the computation?"))
            else:
                record(lost_record(t, f"the task could not run ({type(err).__name__}: {err})"))
    counts.seconds = time.perf_counter() - t0
    return counts
