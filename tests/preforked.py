"""Runs of ``python -m thrustwalk_cli ARGS...`` as processes of their own, forked from one
process that imported the package and its heavy dependencies once (matplotlib, scipy, numba:
about 2 s of CPU a fresh interpreter pays before its first line of work).

For tests that start many short runs in processes of their own to kill them (SIGKILL: no
clean-up at all) or to run them to the end: each run is a real process, with its own standard
output and error, working directory and environment, killed for real; what it skips is the
imports. Not for what depends on a fresh interpreter: its hash seed (a forked run shares its
parent's, so it cannot show output that varies with it), import-time errors, start-up time,
timing of a kill after a delay.

``python tests/preforked.py MODULE...`` is the forking process (the zygote): it imports the
modules, then reads one JSON request a line on standard input and answers one JSON line on
standard output: ``{"run": {...}}`` forks a run and answers its ``pid``; ``{"wait": PID}``
waits for it and answers its ``status`` (the exit code, or minus the signal that ended it, as
:class:`subprocess.Popen` says it). Its runs are its children, reaped by it, and it is the
test's child, so their CPU time is counted as the test's.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path


class Zygote:
    """The forking process, started with ``modules`` imported; :meth:`run` forks a run."""

    def __init__(self, modules: list[str], env: dict[str, str] | None = None):
        self._proc = subprocess.Popen(
            [sys.executable, __file__, *modules], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, text=True, env=dict(os.environ if env is None else env))
        assert self._ask({"ping": 1}) == {"ok": 1}, "the forking process did not start"
        self.cpu_seconds = 0.0  # of the runs, reaped

    def _ask(self, request: dict) -> dict:
        self._proc.stdin.write(json.dumps(request) + "\n")
        self._proc.stdin.flush()
        line = self._proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the forking process ended (exit {self._proc.wait()})")
        return json.loads(line)

    def run(self, args, *, folder: Path, env: dict[str, str] | None = None,
            cwd: Path | None = None, prelude: str = "",
            timeout: float = 300) -> subprocess.CompletedProcess:
        """``thrustwalk ARGS...`` in a forked process (environment ``env``, default this
        process's; working directory ``cwd``), after running the Python source ``prelude`` in
        it (e.g. a hook that kills the run at some call); waits for it. Its standard output
        and error go to files in ``folder`` and come back as text."""
        folder.mkdir(parents=True, exist_ok=True)
        out, err = folder / "preforked.stdout", folder / "preforked.stderr"
        argv = [str(a) for a in args]
        pid = self._ask({"run": {"argv": argv, "env": dict(os.environ if env is None else env),
                                 "cwd": str(cwd or Path.cwd()), "stdout": str(out),
                                 "stderr": str(err), "prelude": prelude}})["pid"]
        done = self._ask({"wait": pid})
        status = done["status"]
        self.cpu_seconds += done["cpu"]
        return subprocess.CompletedProcess(["thrustwalk", *argv], status, out.read_text(),
                                           err.read_text())

    def close(self) -> None:
        self._proc.stdin.close()
        self._proc.stdout.close()
        try:
            self._proc.wait(timeout=30)
        except subprocess.TimeoutExpired:  # pragma: no cover
            self._proc.kill()
            self._proc.wait()


def _command(argv: list[str], env: dict[str, str], cwd: str, prelude: str = "") -> int:
    """In the forked process (standard streams in place): the run's directory, environment
    and command line; then the command as ``python -m thrustwalk_cli`` runs it. Its exit
    code."""
    code = 1
    try:
        os.chdir(cwd)
        os.environ.clear()
        os.environ.update(env)
        sys.argv = ["thrustwalk", *argv]
        if prelude:
            exec(compile(prelude, "<prelude>", "exec"), {"__name__": "__prelude__"})
        import runpy

        try:
            runpy.run_module("thrustwalk_cli", run_name="__main__", alter_sys=True)
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            if not isinstance(exc.code, (int, type(None))):
                sys.stderr.write(f"{exc.code}\n")
    except BaseException:
        import traceback

        traceback.print_exc()
        code = 1
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except BaseException:  # pragma: no cover
        pass
    return code


def _child(req: dict) -> None:
    """In the forked process: standard output and error to the run's files, then the
    command. Never returns."""
    code = 1
    try:
        for fd, path in ((1, req["stdout"]), (2, req["stderr"])):
            f = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            os.dup2(f, fd)
            os.close(f)
        os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
        code = _command(req["argv"], req["env"], req["cwd"], req["prelude"])
    finally:
        os._exit(code)


def _serve(modules: list[str]) -> None:
    import importlib

    for name in modules:
        importlib.import_module(name)
    for line in sys.stdin:
        req = json.loads(line)
        if "ping" in req:
            answer = {"ok": 1}
        elif "run" in req:
            sys.stdout.flush()
            pid = os.fork()
            if pid == 0:
                _child(req["run"])
            answer = {"pid": pid}
        else:
            _, status, usage = os.wait4(req["wait"], 0)
            answer = {"status": os.waitstatus_to_exitcode(status),
                      "cpu": usage.ru_utime + usage.ru_stime}
        sys.stdout.write(json.dumps(answer) + "\n")
        sys.stdout.flush()


# ---------------------------------------------------------- for programs that run commands
@contextlib.contextmanager
def command_server(modules: list[str]) -> Iterator[str]:
    """A forking process serving a command line: yields ``TW``, a command that runs as
    ``python -m thrustwalk_cli`` would (``TW ARGS...``: the same arguments, standard streams,
    working directory, environment and exit code) in a process forked from it, for a program
    that starts commands itself (``make``; several at once). Each server is a process of its
    own, with its own hash seed and address layout: two servers differ as two fresh
    interpreters do."""
    import shlex
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="tw-fork-"))  # short: a socket's path is <= 107
    sock = folder / "s"
    proc = subprocess.Popen([sys.executable, __file__, "--serve", str(sock), *modules],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        if proc.stdout.readline().strip() != "ready":
            raise RuntimeError(f"the command server did not start (exit {proc.wait()})")
        yield shlex.join([sys.executable, __file__, "--client", str(sock)])
    finally:
        proc.stdin.close()  # the server waits for its runs, then ends
        try:
            proc.wait(timeout=120)
        except subprocess.TimeoutExpired:  # pragma: no cover
            proc.kill()
            proc.wait()
        proc.stdout.close()
        sock.unlink(missing_ok=True)
        folder.rmdir()


def _serve_socket(path: str, modules: list[str]) -> None:
    """The command server: forks a run for each client (its standard streams passed over
    the socket), which sends its exit code back; reaps its runs; ends when its standard input
    closes, once its runs have ended."""
    import importlib
    import select
    import socket

    for name in modules:
        importlib.import_module(name)
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    srv.bind(path)
    srv.listen(16)
    sys.stdout.write("ready\n")
    sys.stdout.flush()
    runs: set[int] = set()
    while True:
        ready, _, _ = select.select([srv, sys.stdin], [], [], 0.2)
        while runs:
            pid, _ = os.waitpid(-1, os.WNOHANG)
            if not pid:
                break
            runs.discard(pid)
        if sys.stdin in ready and not sys.stdin.readline():
            break
        if srv not in ready:
            continue
        conn, _ = srv.accept()
        msg, fds, _, _ = socket.recv_fds(conn, 1 << 20, 3)
        req = json.loads(msg)
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                srv.close()
                for fd, target in zip(fds, (0, 1, 2)):
                    os.dup2(fd, target)
                code = _command(req["argv"], req["env"], req["cwd"])
                conn.send(str(code).encode())
            finally:
                os._exit(code)
        runs.add(pid)
        conn.close()
        for fd in fds:
            os.close(fd)
    srv.close()
    for pid in runs:
        os.waitpid(pid, 0)


def _client(path: str, argv: list[str]) -> int:
    """``TW ARGS...``: the run's arguments, directory, environment and standard streams to
    the server; its exit code (1 if the run ended without one)."""
    import socket

    with socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET) as sock:
        sock.connect(path)
        req = {"argv": argv, "env": dict(os.environ), "cwd": os.getcwd()}
        socket.send_fds(sock, [json.dumps(req).encode()], [0, 1, 2])
        answer = sock.recv(64)
    return int(answer) if answer else 1


if __name__ == "__main__":
    if sys.argv[1:2] == ["--serve"]:
        _serve_socket(sys.argv[2], sys.argv[3:])
    elif sys.argv[1:2] == ["--client"]:
        sys.exit(_client(sys.argv[2], sys.argv[3:]))
    else:
        _serve(sys.argv[1:])
