"""Where the points of a sweep run: in this process, in local worker processes, or on an
existing Dask distributed cluster.

Every executor has the same three calls: ``submit(fn, task)`` returns a handle, ``wait(handles)``
blocks until at least one has finished and returns ``(handle, result, error)`` for each
finished one (``error`` an exception that lost the task: a worker process that died, a worker
lost by the cluster; or the exception the task raised), and ``close()``. Results travel back
to the calling process, which alone writes files, so workers never need the result folder.

* :class:`InProcess` (one worker): the tasks run here, one after the other.
* :class:`LocalProcesses` (``workers`` > 1): a pool of worker processes on this machine; they
  talk to this process through pipes (nothing listens on the network) and exit when this
  process dies (even by ``kill -9``). A pool broken by a dying worker is restarted.
* :class:`DaskCluster`: a Dask distributed client connected to a running scheduler
  (``tcp://HOST:PORT`` or ``tls://HOST:PORT``); Dask is imported only here (the optional extra
  ``thrustwalk[cluster]``).
"""

from __future__ import annotations

import os
import queue
import sys
import threading
import time
from collections.abc import Callable, Iterable
from concurrent import futures
from typing import Any

from .._version import __version__
from ..errors import ComputationError, InputError

Outcome = tuple[Any, Any, BaseException | None]


class InProcess:
    """Run each task in this process when it is waited for."""

    kind = "in-process"

    def __init__(self) -> None:
        self.workers = 1
        self._queue: list[tuple[int, Callable, Any]] = []
        self._next = 0

    def describe(self) -> dict:
        return {"kind": self.kind, "workers": 1}

    def submit(self, fn: Callable, task: Any) -> int:
        self._next += 1
        self._queue.append((self._next, fn, task))
        return self._next

    def wait(self, handles: Iterable) -> list[Outcome]:
        """Run the first task submitted of ``handles``: its result, or the exception it
        raised (as a worker process would hand it back)."""
        wanted = set(handles)
        for i, (h, fn, task) in enumerate(self._queue):
            if h in wanted:
                del self._queue[i]
                try:
                    return [(h, fn(task), None)]
                except Exception as exc:  # noqa: BLE001 - the task's error is its outcome
                    return [(h, None, exc)]
        raise RuntimeError("nothing to wait for")

    def close(self) -> None:
        self._queue.clear()


def _watch_parent(parent: int) -> None:
    """In a worker process: exit as soon as the process that started the pool is gone (a
    ``kill -9`` of the sweep leaves no orphan computing for nobody)."""
    def watch() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="thrustwalk-parent-watch").start()


class LocalProcesses:
    """A pool of ``workers`` local processes (forked on Linux, spawned elsewhere)."""

    kind = "local"

    def __init__(self, workers: int):
        self.workers = workers
        self.restarts = 0
        # finished futures, put by their done-callbacks: waiting costs O(1) per task (waiting
        # on every future in flight each time costs O(tasks) per wait, O(tasks^2) a sweep)
        self._done: queue.SimpleQueue = queue.SimpleQueue()
        self._pools: dict[int, futures.ProcessPoolExecutor] = {}  # id(future) -> its pool
        self._pool = self._start()

    def _start(self) -> futures.ProcessPoolExecutor:
        import multiprocessing

        method = "fork" if sys.platform.startswith("linux") else "spawn"
        pool = futures.ProcessPoolExecutor(
            max_workers=self.workers, mp_context=multiprocessing.get_context(method),
            initializer=_watch_parent, initargs=(os.getpid(),))
        pool.submit(int).result()  # start the processes now, before a progress bar's thread
        return pool

    def describe(self) -> dict:
        return {"kind": self.kind, "workers": self.workers, "restarts": self.restarts}

    def submit(self, fn: Callable, task: Any) -> futures.Future:
        f = self._pool.submit(fn, task)
        self._pools[id(f)] = self._pool
        f.add_done_callback(self._done.put)
        return f

    def wait(self, handles: Iterable) -> list[Outcome]:
        """Every task submitted and not yet returned that has finished (at least one; the
        ``handles`` are all of those, as the runner keeps them)."""
        done = [self._done.get()]
        while True:
            try:
                done.append(self._done.get_nowait())
            except queue.Empty:
                break
        out: list[Outcome] = []
        broken = False
        for f in done:
            pool = self._pools.pop(id(f), None)
            err = futures.CancelledError() if f.cancelled() else f.exception()
            if err is None:
                out.append((f, f.result(), None))
            else:
                # only a future of the current pool restarts it (the old pool's other futures
                # may arrive in a later wait)
                broken = broken or (isinstance(err, futures.process.BrokenProcessPool)
                                    and pool is self._pool)
                out.append((f, None, err))
        if broken:  # a worker died: every task in flight is lost with the pool
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = self._start()
            self.restarts += 1
        return out

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


def worker_version() -> str:
    """The thrustwalk version of a worker (checked against this process's)."""
    return __version__


class DaskCluster:
    """A client of a running Dask distributed scheduler at ``address``."""

    kind = "dask"

    def __init__(self, address: str, timeout: float = 30.0):
        if not address.startswith(("tcp://", "tls://")) or ":" not in address[6:]:
            raise InputError.param("scheduler", f"expected tcp://HOST:PORT or tls://HOST:PORT, "
                                                f"got {address!r}")
        try:
            from distributed import Client
        except ImportError:
            raise InputError.param("scheduler", "needs Dask distributed: pip install "
                                                "'thrustwalk[cluster]'") from None
        self.address = address
        try:
            self.client = Client(address, timeout=f"{timeout:g}s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise ComputationError(f"cannot reach the Dask scheduler at {address}: "
                                   f"{str(exc).splitlines()[0]}") from None
        try:
            self.client.wait_for_workers(1, timeout=timeout)
            versions = self.client.run(worker_version)
        except (OSError, TimeoutError) as exc:
            self.client.close()
            raise ComputationError(f"no usable worker at the Dask scheduler {address} within "
                                   f"{timeout:g} s ({str(exc).splitlines()[0]})") from None
        except Exception as exc:  # noqa: BLE001 - a worker that cannot import thrustwalk
            self.client.close()
            raise ComputationError(f"the Dask workers at {address} cannot run thrustwalk "
                                   f"({type(exc).__name__}: {exc}); install thrustwalk "
                                   f"{__version__} on every worker") from None
        other = sorted({v for v in versions.values() if v != __version__})
        if other:
            self.client.close()
            raise ComputationError(f"the Dask workers at {address} run thrustwalk "
                                   f"{', '.join(other)}, not {__version__}: install the same "
                                   "version everywhere")
        self.workers = len(versions)
        from distributed import as_completed

        self._done = as_completed(loop=self.client.loop)

    def describe(self) -> dict:
        return {"kind": self.kind, "scheduler": self.address, "workers": self.workers}

    def submit(self, fn: Callable, task: Any) -> Any:
        f = self.client.submit(fn, task, pure=False)
        self._done.add(f)
        return f

    def wait(self, handles: Iterable) -> list[Outcome]:
        done = [next(self._done)] + self._done.next_batch(block=False)
        out: list[Outcome] = []
        for f in done:
            if f.status == "finished":
                out.append((f, f.result(), None))
            else:  # a lost worker (KilledWorker) or a cancelled task
                try:
                    err = f.exception()
                except BaseException as exc:  # noqa: BLE001 - cancelled futures raise here
                    err = exc
                out.append((f, None, err if err is not None else RuntimeError(f.status)))
            f.release()
        return out

    def close(self) -> None:
        self.client.close()
