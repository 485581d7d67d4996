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

    STARTS = 3  # attempts to start a pool whose processes die at once (killed from outside)

    def _start(self) -> futures.ProcessPoolExecutor:
        """A new pool, its processes started now (before a progress bar's thread); a pool
        whose processes die while starting is started again, up to ``STARTS`` times, then
        :class:`ComputationError` (the finished points are kept)."""
        import multiprocessing

        method = "fork" if sys.platform.startswith("linux") else "spawn"
        for _ in range(self.STARTS):
            pool = futures.ProcessPoolExecutor(
                max_workers=self.workers, mp_context=multiprocessing.get_context(method),
                initializer=_watch_parent, initargs=(os.getpid(),))
            try:
                pool.submit(int).result()
                return pool
            except futures.process.BrokenProcessPool:
                pool.shutdown(wait=False, cancel_futures=True)
        raise ComputationError(f"the {self.workers} local worker processes died as they "
                               f"started, {self.STARTS} times (killed, or out of memory?); the "
                               "finished points are kept: run the sweep again to resume")

    def describe(self) -> dict:
        return {"kind": self.kind, "workers": self.workers, "restarts": self.restarts}

    def submit(self, fn: Callable, task: Any) -> futures.Future:
        """A future of ``fn(task)``; a pool broken since the last wait (a worker process
        died) gives a future already failed with ``BrokenProcessPool``: the task is lost, as
        those in flight, and the next wait restarts the pool."""
        try:
            f = self._pool.submit(fn, task)
        except futures.process.BrokenProcessPool as exc:
            f = futures.Future()
            f.set_exception(exc)
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


def quiet_dask_logs() -> None:
    """Keep Dask's own log lines and tracebacks (a lost scheduler, a reconnect that failed)
    off standard error: a command says what happened in one line. Dask sets its loggers'
    levels when it is imported, so it is imported here first (if installed)."""
    import logging

    try:
        import distributed  # noqa: F401 - configures its loggers on import
    except ImportError:
        return
    for name in ["distributed", "tornado", "asyncio",
                 *[n for n in logging.Logger.manager.loggerDict
                   if n.startswith(("distributed.", "tornado."))]]:
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)


HANDSHAKE_SECONDS = 10.0  # [s] connect to a scheduler and read its Dask handshake, at most
HANDSHAKE_BYTES = 65536  # a scheduler's handshake is ~60 bytes; more is not Dask


def scheduler_address(address: str) -> tuple[str, str, int]:
    """``(protocol, host, port)`` of ``tcp://HOST:PORT`` or ``tls://HOST:PORT`` (an IPv6 host
    in brackets); :class:`InputError` on ``scheduler`` otherwise (a port outside 1-65535)."""
    proto, sep, rest = address.partition("://")
    host, colon, port = rest.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not sep or proto not in ("tcp", "tls") or not colon or not host or \
            not port.isdigit() or not 1 <= int(port) <= 65535 or "/" in rest:
        raise InputError.param("scheduler", f"expected tcp://HOST:PORT or tls://HOST:PORT "
                                            f"(port 1 to 65535), got {address!r}")
    return proto, host, int(port)


def probe_scheduler(address: str, timeout: float = HANDSHAKE_SECONDS,
                    ssl_context: Any = None) -> None:
    """Check that ``address`` is a Dask scheduler before a Dask client connects to it: open a
    TCP connection (TLS with ``ssl_context`` for ``tls://``) and read the handshake a Dask
    server sends first (a length-prefixed msgpack mapping with ``python`` and
    ``pickle-protocol``), within ``timeout`` seconds in all, at most ``HANDSHAKE_BYTES``;
    then answer with this side's handshake and close. A Dask client connecting to a server
    that is not Dask waits for a handshake that never comes, or reads a length from junk
    and allocates it (exabytes). :class:`InputError` on ``scheduler``: unreachable, no
    answer within the time, or an answer that is not a Dask handshake."""
    import pickle
    import socket
    import struct

    proto, host, port = scheduler_address(address)
    deadline = time.monotonic() + timeout

    def left() -> float:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutError
        return remaining

    def read(sock, n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            sock.settimeout(left())
            chunk = sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("closed the connection")
            buf += chunk
        return buf

    def bad(why: str) -> InputError:
        return InputError.param("scheduler", f"{address} {why}: is it a Dask scheduler's "
                                             "address (dask scheduler prints it)?")

    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except (OSError, TimeoutError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else \
            (str(exc) or type(exc).__name__)
        raise InputError.param("scheduler", f"cannot reach {address} ({why})") from None
    try:
        if proto == "tls":
            sock.settimeout(left())
            sock = ssl_context.wrap_socket(sock, server_hostname=host)
        (size,) = struct.unpack("Q", read(sock, 8))
        if not 8 <= size <= HANDSHAKE_BYTES:
            raise bad("answered with something that is not a Dask handshake")
        body = read(sock, size)
        try:
            from distributed.protocol import dumps, loads
            from distributed.protocol.utils import pack_frames, unpack_frames

            info = loads(unpack_frames(body), deserialize=False)
        except Exception:  # noqa: BLE001 - whatever the junk made the decoder raise
            info = None
        if not isinstance(info, dict) or not {"python", "pickle-protocol"} <= set(info):
            raise bad("answered with something that is not a Dask handshake")
        mine = {"compression": None, "python": tuple(sys.version_info)[:3],
                "pickle-protocol": pickle.HIGHEST_PROTOCOL}
        frames = pack_frames(dumps(mine))
        sock.settimeout(left())
        sock.sendall(struct.pack("Q", len(frames)) + frames)
    except TimeoutError:
        raise bad(f"did not send a Dask handshake within {timeout:g} s") from None
    except InputError:
        raise
    except OSError as exc:  # reset, closed, a TLS failure
        raise bad(f"broke off the Dask handshake ({exc.strerror or exc})") from None
    finally:
        sock.close()


class DaskCluster:
    """A client of a running Dask distributed scheduler at ``address``.

    Before the Dask client connects, :func:`probe_scheduler` checks within
    ``HANDSHAKE_SECONDS`` that the address answers as a Dask scheduler (an unreachable or
    non-Dask address is an :class:`InputError` on ``scheduler``). For ``tls://`` the TLS
    settings (CA, client certificate and key) come from Dask's configuration
    (``distributed.comm.tls.*``: its YAML files or ``DASK_DISTRIBUTED__COMM__TLS__...``
    environment variables), or from ``security`` (a ``distributed.Security``). A scheduler
    lost while the sweep runs stops it (:class:`ComputationError` from :meth:`wait`); a
    task the cluster cancels otherwise is a lost task (resubmitted by the runner)."""

    kind = "dask"

    def __init__(self, address: str, timeout: float = 30.0, security: Any = None):
        scheduler_address(address)
        try:
            from distributed import Client, Security
        except ImportError:
            raise InputError.param("scheduler", "needs Dask distributed: pip install "
                                                "'thrustwalk[cluster]'") from None
        self.address = address
        if security is None:
            security = Security()
        ctx = None
        if address.startswith("tls://"):
            ctx = security.get_connection_args("client").get("ssl_context")
            if ctx is None:
                raise InputError.param("scheduler", (
                    f"{address} is a TLS address, but Dask's configuration gives no TLS "
                    "certificates: set distributed.comm.tls.ca-file, .client.cert and "
                    ".client.key (e.g. DASK_DISTRIBUTED__COMM__TLS__CA_FILE=ca.pem)"))
        probe_scheduler(address, min(timeout, HANDSHAKE_SECONDS), ctx)
        try:
            self.client = Client(address, timeout=f"{timeout:g}s", set_as_default=False,
                                 security=security)
        except (OSError, TimeoutError) as exc:
            raise ComputationError(f"cannot connect to the Dask scheduler at {address}: "
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
        self._lost_check()
        f = self.client.submit(fn, task, pure=False)
        self._done.add(f)
        return f

    def _lost_check(self) -> None:
        """:class:`ComputationError` when the client has lost its scheduler (it cancels
        every task then, and reconnects or closes)."""
        if self.client.status != "running":
            raise ComputationError(
                f"lost the connection to the Dask scheduler at {self.address} (the "
                "scheduler stopped or the network failed); the finished points are kept: "
                "run the sweep again to resume")

    def wait(self, handles: Iterable) -> list[Outcome]:
        """Every finished task (at least one). A task the cluster cancelled is lost
        (``CancelledError``, resubmitted by the runner) while the client is connected; with
        the scheduler gone, :class:`ComputationError`."""
        done = [next(self._done)] + self._done.next_batch(block=False)
        out: list[Outcome] = []
        for f in done:
            if f.status == "finished":
                out.append((f, f.result(), None))
            elif f.status in ("cancelled", "lost"):
                self._lost_check()
                out.append((f, None, futures.CancelledError(f"the cluster cancelled the "
                                                            f"task ({f.status})")))
            else:  # a lost worker (KilledWorker) or the task's own error
                try:
                    err = f.exception()
                except BaseException as exc:  # noqa: BLE001 - cancelled meanwhile
                    err = exc
                out.append((f, None, err if err is not None else
                            futures.CancelledError(str(f.status))))
            f.release()
        return out

    def close(self) -> None:
        try:
            self.client.close(timeout=5)
        except Exception:  # noqa: BLE001 - a client whose scheduler is gone: nothing to close
            pass
