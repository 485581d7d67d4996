"""Where the points of a sweep run: in this process, in local worker processes, or on an
existing Dask distributed cluster.

Every executor has the same three calls: ``submit(fn, task)`` returns a handle, ``wait(handles)``
blocks until at least one has finished and returns ``(handle, result, error)`` for each
finished one (``error`` an exception that lost the task: a worker process that died, a worker
lost by the cluster; or the exception the task raised), and ``close()``. Results travel back
to the calling process, which alone writes files, so workers never need the result folder.

* :class:`InProcess` (one worker): the tasks run here, one after the other.
* :class:`LocalProcesses` (``workers`` > 1): worker processes on this machine, each talking
  to this process through a pipe of its own (nothing listens on the network, nothing is
  shared between workers); they exit when this process dies (even by ``kill -9``). A worker
  that dies loses only its task and is replaced.
* :class:`DaskCluster`: a Dask distributed client connected to a running scheduler
  (``tcp://HOST:PORT`` or ``tls://HOST:PORT``); Dask is imported only here (the optional extra
  ``thrustwalk[cluster]``).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from concurrent import futures
from concurrent.futures.process import BrokenProcessPool
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


def _serve(conn: Any, parent: int) -> None:
    """A local worker process: say ``ready``, then run each ``(handle, fn, task)`` received
    on ``conn`` and send back ``(handle, result, error)``, until ``None`` or the end of the
    pipe. Ctrl-C is the calling process's to handle (it stops the workers)."""
    import pickle
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _watch_parent(parent)
    conn.send(("ready", os.getpid(), None))
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        handle, fn, task = msg
        try:
            out = (handle, fn(task), None)
        except BaseException as exc:  # noqa: BLE001 - the task's error is its outcome
            out = (handle, None, exc)
        try:
            conn.send(out)
        except (pickle.PicklingError, TypeError, AttributeError) as exc:
            conn.send((handle, None, RuntimeError(
                f"the task's outcome cannot be sent back ({type(exc).__name__}: {exc})")))


class _Worker:
    """One worker process of :class:`LocalProcesses` and its end of their pipe;
    ``sent``: the ``(handle, fn, task)`` sent to it, in order, whose outcome has not come
    back (the first one runs); ``ready`` once it has answered."""

    def __init__(self, ctx: Any, parent: int):
        here, there = ctx.Pipe(duplex=True)
        self.proc = ctx.Process(target=_serve, args=(there, parent), daemon=True,
                                name="thrustwalk-worker")
        self.proc.start()
        there.close()
        self.conn = here
        self.sent: deque[tuple[int, Callable, Any]] = deque()
        self.ready = False

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the process: an idle one is asked to exit (and killed if it has not within
        ``timeout`` [s]), a busy one (the run was stopped) is killed at once."""
        if not self.sent:
            try:
                self.conn.send(None)
            except (OSError, ValueError):
                pass
            self.proc.join(timeout)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()


class LocalProcesses:
    """``workers`` local worker processes (forked on Linux, spawned elsewhere), each with a
    pipe of its own to this process; each has up to ``QUEUED`` tasks sent (the next one
    waits in its pipe while it computes).

    Nothing is shared between workers (no common queue, no lock a killed process could
    hold), and no thread runs here: a worker that dies (killed, out of memory, a task that
    exits) loses only the task it runs (``BrokenProcessPool``, resubmitted by the runner; the
    task waiting in its pipe, never started, goes to the next worker as it is) and is
    replaced at once (``restarts``). Workers that die before they answer, ``STARTS`` per
    worker in a row (killed from outside as they start), stop the run with
    :class:`ComputationError` (the finished points are kept)."""

    kind = "local"
    STARTS = 3  # workers in a row that die before answering, per worker slot, then give up
    QUEUED = 2  # tasks sent to a worker at a time (one runs, one waits in its pipe)

    def __init__(self, workers: int):
        import multiprocessing

        self.workers = workers
        self.restarts = 0
        method = "fork" if sys.platform.startswith("linux") else "spawn"
        self._ctx = multiprocessing.get_context(method)
        self._parent = os.getpid()
        self._todo: deque[tuple[int, Callable, Any]] = deque()  # not yet sent
        self._done: list[Outcome] = []
        self._next = 0
        self._dead_starts = 0  # workers in a row that died before answering
        self._slots: list[_Worker] = []
        try:
            self._slots = [_Worker(self._ctx, self._parent) for _ in range(workers)]
            # the processes answer now (before a progress bar's thread starts)
            while not all(w.ready for w in self._slots):
                self._poll()
        except BaseException:
            self.close()
            raise

    def describe(self) -> dict:
        return {"kind": self.kind, "workers": self.workers, "restarts": self.restarts}

    def submit(self, fn: Callable, task: Any) -> int:
        """A handle of ``fn(task)``, sent to the first worker with room for it."""
        self._next += 1
        self._todo.append((self._next, fn, task))
        self._dispatch()
        return self._next

    def _dispatch(self) -> None:
        """Send waiting tasks to the ready workers, one each in turn, up to ``QUEUED``."""
        for level in range(self.QUEUED):
            for w in self._slots:
                if not self._todo:
                    return
                if not w.ready or len(w.sent) > level:
                    continue
                item = self._todo.popleft()
                w.sent.append(item)
                try:
                    w.conn.send(item)
                except (OSError, ValueError):
                    pass  # the worker died: its sentinel says so, and the task is lost
                except Exception as exc:  # noqa: BLE001 - a task that cannot be pickled
                    w.sent.pop()
                    self._done.append((item[0], None, exc))

    def _poll(self, timeout: float | None = None) -> None:
        """Read every answer that has arrived and replace every worker that has died,
        waiting up to ``timeout`` [s] (``None``: until something happens)."""
        from multiprocessing.connection import wait

        conns = {w.conn: w for w in self._slots}
        sentinels = {w.proc.sentinel: w for w in self._slots}
        for r in wait([*conns, *sentinels], timeout):
            w = conns.get(r) or sentinels[r]
            if w not in self._slots:  # its pipe and its sentinel were both ready: replaced
                continue
            while w.conn.poll():  # a result sent just before dying still counts
                try:
                    kind, value, err = w.conn.recv()
                except (EOFError, OSError):
                    break
                if kind == "ready":
                    w.ready, self._dead_starts = True, 0
                else:
                    self._done.append((kind, value, err))
                    w.sent.popleft()
            if r in sentinels or not w.proc.is_alive():
                self._replace(w)
        self._dispatch()

    def _replace(self, w: _Worker) -> None:
        """A new worker in the slot of ``w``, which has died; the task it ran is lost."""
        if w not in self._slots:
            return
        w.proc.join()
        code = w.proc.exitcode
        how = f"killed by signal {-code}" if code is not None and code < 0 else \
            f"exit code {code}"
        if w.sent:  # the first task ran and is lost; the others never started
            self._done.append((w.sent[0][0], None, BrokenProcessPool(
                f"worker process {w.proc.pid} died ({how}) while running the task")))
            self._todo.extendleft(reversed(list(w.sent)[1:]))
        w.conn.close()
        if not w.ready:
            self._dead_starts += 1
        if self._dead_starts >= self.STARTS * self.workers:
            self._slots.remove(w)
            raise ComputationError(
                f"the local worker processes died as they started, {self._dead_starts} "
                "times in a row (killed, or out of memory?); the finished points are kept: "
                "run the sweep again to resume")
        self._slots[self._slots.index(w)] = _Worker(self._ctx, self._parent)
        self.restarts += 1

    def wait(self, handles: Iterable) -> list[Outcome]:
        """Every task submitted and not yet returned that has finished (at least one; the
        ``handles`` are all of those, as the runner keeps them)."""
        if not self._done and not self._todo and not any(w.sent for w in self._slots):
            raise RuntimeError("nothing to wait for")
        while not self._done:
            self._poll()
        self._poll(0)
        out, self._done = self._done, []
        return out

    def close(self) -> None:
        """Stop every worker process (:meth:`_Worker.stop`)."""
        for w in self._slots:
            w.stop()
        self._slots = []
        self._todo.clear()


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
