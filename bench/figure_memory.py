"""Figures in a loop do not grow memory (issue 25): ``figures()`` of one limit-cycle result
(the 3-link walker, 26 thrust values; two figures a call) called 1,000 times in one process,
the resident set size [MB] after every 100 calls (after a garbage collection). The figures
are :class:`matplotlib.figure.Figure` objects that pyplot never holds, freed with their last
reference (tests/test_plots.py checks that with weakrefs on 25 calls; this runs the issue's
1,000). The baseline is the size after the first 100 calls (matplotlib's font and text
caches are filled by then); the ratio is the size after 1,000.

    python bench/figure_memory.py [--calls 1000]    (about 5-8 min; not part of `make bench`)
"""

from __future__ import annotations

import gc
import sys
import time


def _rss_mb() -> float:
    with open("/proc/self/status") as fh:  # Linux; elsewhere the bench says so
        for line in fh:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1024
    raise OSError("no VmRSS")


def main(calls: int = 1000) -> None:
    import numpy as np

    import thrustwalk_cli as tw

    try:
        _rss_mb()
    except OSError:
        print("figure memory: skipped (no /proc/self/status on this system)")
        return
    walker = tw.load_walker("three_link", None)
    result = tw.limit_cycle(walker, thrust=np.linspace(0.0, -50.0, 26))
    t0 = time.perf_counter()
    sizes = {}
    for i in range(1, calls + 1):
        figs = result.figures()
        del figs
        if i % 100 == 0 or i == calls:
            gc.collect()
            sizes[i] = _rss_mb()
    seconds = time.perf_counter() - t0
    base = sizes[min(sizes)]
    print("figures() calls -> resident set size [MB]: "
          + ", ".join(f"{k}: {v:.1f}" for k, v in sizes.items()))
    print(f"figure memory: {calls} figures() calls in {seconds:.0f} s; "
          f"{sizes[calls]:.1f} MB after {calls} vs {base:.1f} MB after {min(sizes)} "
          f"(ratio {sizes[calls] / base:.3f}; growth {sizes[calls] - base:+.1f} MB)")


if __name__ == "__main__":
    n = int(sys.argv[sys.argv.index("--calls") + 1]) if "--calls" in sys.argv else 1000
    main(n)
