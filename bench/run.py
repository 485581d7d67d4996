"""Run every ``bench/bench_*.py`` (each defines ``main()``) and print its ratio lines.

Timings are medians of repeated runs measured in this process; each benchmark prints ratios
against a baseline measured in the same run, since the machine is noisy.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> None:
    os.environ.setdefault("THRUSTWALK_CACHE_DIR", tempfile.mkdtemp(prefix="tw-bench-cache-"))
    only = sys.argv[1:]
    for path in sorted(HERE.glob("bench_*.py")):
        if only and path.stem.removeprefix("bench_") not in only:
            continue
        spec = importlib.util.spec_from_file_location(path.stem, path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = mod  # a process pool pickles its functions by module name
        spec.loader.exec_module(mod)
        print(f"== {path.stem} ==", flush=True)
        mod.main()


if __name__ == "__main__":
    main()
