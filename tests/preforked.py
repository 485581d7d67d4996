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

import json
import os
import subprocess
import sys
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


def _child(req: dict) -> None:
    """In the forked process: the run's files, directory, environment and command line; then
    the command as ``python -m thrustwalk_cli`` runs it. Never returns."""
    code = 1
    try:
        for fd, path in ((1, req["stdout"]), (2, req["stderr"])):
            f = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            os.dup2(f, fd)
            os.close(f)
        os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
        os.chdir(req["cwd"])
        os.environ.clear()
        os.environ.update(req["env"])
        sys.argv = ["thrustwalk", *req["argv"]]
        if req["prelude"]:
            exec(compile(req["prelude"], "<prelude>", "exec"), {"__name__": "__prelude__"})
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
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
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


if __name__ == "__main__":
    _serve(sys.argv[1:])
