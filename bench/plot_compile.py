"""Log-log plot of the cold compile time of chain bipeds against their number of links
(issue 26): ``python bench/plot_compile.py docs/compile_scaling.json docs/compile_scaling.png``.

The JSON holds ``{"series": {label: {N: CPU seconds}}, "targets": {N: seconds}, "note": str}``
(the CPU times printed by ``python bench/bench_compile.py --chains --json FILE``, one file
per code version, collected by hand).
"""

from __future__ import annotations

import json
import sys
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot(data: dict, out: str) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for (label, series), marker in zip(data["series"].items(), "os^"):
        n = np.array(sorted(int(k) for k in series))
        t = np.array([series[str(k)] for k in n])
        slope = np.polyfit(np.log(n[n >= 8]), np.log(t[n >= 8]), 1)[0] if (n >= 8).sum() > 1 \
            else float("nan")
        ax.loglog(n, t, marker=marker, label=f"{label} (N >= 8: ~N^{slope:.1f})")
    targets = data.get("targets", {})
    if targets:
        tn = sorted(int(k) for k in targets)
        ax.loglog(tn, [targets[str(k)] for k in tn], "rv", linestyle="none",
                  label="targets (issue 26)")
    ax.set_xlabel("links N")
    ax.set_ylabel("cold compile, CPU of the whole process [s]")
    ticks = [3, 4, 5, 6, 8, 10, 12, 16, 20]
    ax.set_xticks(ticks)
    ax.set_xticklabels([str(t) for t in ticks])
    ax.minorticks_off()
    ax.grid(True, which="major", alpha=0.3)
    ax.set_title("thrustwalk compile of a planar N-link chain biped")
    if data.get("note"):
        fig.text(0.01, 0.01, textwrap.fill(data["note"], 115), fontsize=6.5, alpha=0.7)
    ax.legend(fontsize=8)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    with open(sys.argv[1]) as fh:
        plot(json.load(fh), sys.argv[2])
