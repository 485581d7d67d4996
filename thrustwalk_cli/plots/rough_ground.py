"""The figure of ``thrustwalk rough-ground`` (SPEC 14), from the figure data of
:meth:`thrustwalk_cli.studies.rough_ground_result.RoughGroundResult.figure_data`: the mean first
passage time against the roughness sigma, one colour per strategy, the Monte-Carlo estimate as
points with their 95 % interval, the mesh chain as lines."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from .style import COLUMN, corner_note, layout, style

STRATEGY_COLOURS = ("k", "tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange",
                    "tab:brown", "tab:pink")
STRATEGY_LINES = ("-", "--", "-.", ":")  # curves that coincide stay visible


def mfpt(d: dict, title: str = ""):
    """MFPT [steps] (log axis) against sigma [mm]: per strategy (colour) the mesh chain's
    ``1/(1 - lambda_2)`` (solid line; an infinite value is left out) and the Monte-Carlo
    estimate (circles with their 95 % interval; a run without a failure: an open triangle at
    the interval's lower end, the MFPT above it), the strategies' points side by side around
    their sigma and their lines in their own dash pattern (coinciding curves stay visible).
    Dotted grey: the headline's target MFPT."""
    sig = sorted({sg for s in d["strategies"] for sg, _ in s["mesh"]})
    step = 1e3 * (min(np.diff(sig)) if len(sig) > 1 else max(sig[0], 1e-3) if sig else 1e-3)
    n = len(d["strategies"])
    with style():
        fig = Figure(figsize=(COLUMN, 2.8))
        ax = fig.subplots()
        handles = []
        infinite = []
        for k, s in enumerate(d["strategies"]):
            c = STRATEGY_COLOURS[k % len(STRATEGY_COLOURS)]
            ls = STRATEGY_LINES[k % len(STRATEGY_LINES)]
            dodge = (k - 0.5 * (n - 1)) * 0.12 * step / max(n, 1)
            mesh = [(1e3 * sg, v) for sg, v in s["mesh"] if v is not None]
            if len(mesh) < len(s["mesh"]):
                infinite.append(s["label"])
            if mesh:
                x, y = np.array(mesh).T
                ax.plot(x, y, ls, color=c, lw=1.0)
            for sg, v, lo, hi in s["mc"]:
                x = 1e3 * sg + dodge
                if v is None:
                    if lo is not None:
                        ax.plot([x], [lo], "^", mfc="none", color=c, ms=4)
                    continue
                top = hi if hi is not None else v
                ax.errorbar([x], [v], yerr=[[v - lo], [top - v]], fmt="o", color=c, ms=3,
                            mfc="white", capsize=2, lw=0.7)
            handles.append(Line2D([], [], color=c, ls=ls, lw=1.0, label=s["label"]))
        handles += [Line2D([], [], color="0.3", lw=1.0, label="mesh chain (lines)"),
                    Line2D([], [], color="0.3", marker="o", mfc="white", ms=3, lw=0.7,
                           label="Monte-Carlo, 95 % CI"),
                    Line2D([], [], color="0.3", marker="^", mfc="none", ms=4, lw=0,
                           label="no failure: above")]
        ax.axhline(d["target"], color="0.5", lw=0.6, ls=":")
        ax.set_yscale("log")
        ax.set_xlabel(r"roughness $\sigma$ [mm]")
        ax.set_ylabel("MFPT [steps]")
        ax.legend(handles=handles, fontsize=6, frameon=False, loc="upper right")
        if infinite:
            corner_note(ax, "mesh: no failure (infinite) for part of " + ", ".join(infinite))
        if title:
            ax.set_title(title)
        layout(fig)
    return fig
