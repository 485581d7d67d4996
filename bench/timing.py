"""Tiny timing helpers shared by the benchmarks."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def median_time(fn: Callable[[], object], repeat: int = 7, number: int = 1) -> float:
    """Median wall time of ``number`` calls, in seconds per call."""
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        runs.append((time.perf_counter() - t0) / number)
    return statistics.median(runs)


def median_cpu(fn: Callable[[], object], repeat: int = 7) -> float:
    """Median CPU time of this process [s] (``time.process_time``) over ``repeat`` calls."""
    out = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        out.append(time.process_time() - t0)
    return statistics.median(out)


def report(label: str, seconds: float, baseline: float | None = None, unit: str = "s") -> None:
    scale = {"s": 1.0, "ms": 1e3, "us": 1e6}[unit]
    ratio = f"  ratio {seconds / baseline:8.3f}" if baseline else ""
    print(f"{label:<58s} {seconds * scale:12.4g} {unit}{ratio}", flush=True)


def run_cli_here(args: list[str]) -> float:
    """Run ``thrustwalk ARGS`` in this process as its console script does (``cli.main``: its
    environment settings, its exit) and return this process's user + system CPU [s] so far,
    start-up included; a non-zero exit is raised."""
    import resource
    import sys

    from thrustwalk_cli.cli import main

    sys.argv = ["thrustwalk", *args]
    try:
        main()
    except SystemExit as exc:
        if exc.code:
            raise
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime
