"""Figures of ``thrustwalk slope``: the walkability map over slope x constant thrust with speed
contours, and the steepest walkable uphill and downhill slope against thrust (SPEC 14).
Plain data in."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from .style import COLUMN, corner_note, layout, style

# one colour per first failing condition ('' = walkable), light enough for contours on top
FAILURE_COLOURS = {"": "#a6dba0", "invalid gait": "#636363", "no orbit": "#d9d9d9",
                   "unstable": "#bdbdbd", "stops": "#fdd0a2", "lifts": "#9ecae1",
                   "slips": "#c6dbef", "impact": "#dadaeb", "scuffs": "#fcbba1"}


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around the centres ``v`` (for pcolormesh)."""
    v = np.asarray(v, float)
    if v.size == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


def walkability_figure(slopes: np.ndarray, thrust: np.ndarray, first: np.ndarray,
                       speed: np.ndarray, failures: Sequence[str], *, thrust_label: str,
                       title: str = ""):
    """The map: each (thrust, slope) cell coloured by the first failing condition (green:
    walkable), with contours of the speed along the ground [m/s] in the walkable region.
    ``first``: (slopes, thrust) indices into ``failures``; ``speed`` NaN where none."""
    with style():
        fig = Figure(figsize=(COLUMN, 2.8))
        ax = fig.subplots()
        present = sorted(set(np.asarray(first).ravel().tolist()))
        colours = [FAILURE_COLOURS.get(failures[i], "#ffffff") for i in range(len(failures))]
        cmap = matplotlib.colors.ListedColormap(colours)
        norm = matplotlib.colors.BoundaryNorm(np.arange(len(failures) + 1) - 0.5, len(failures))
        ax.pcolormesh(_edges(thrust), _edges(slopes), first, cmap=cmap, norm=norm,
                      shading="flat", rasterized=True)
        walk = np.where(np.asarray(first) == 0, speed, np.nan)
        if np.isfinite(walk).sum() >= 4 and len(thrust) > 1 and len(slopes) > 1:
            cs = ax.contour(thrust, slopes, walk, colors="k", linewidths=0.5)
            ax.clabel(cs, fontsize=5, fmt="%.2g")
        ax.axhline(0.0, color="0.4", lw=0.4, ls=":")
        handles = [matplotlib.patches.Patch(color=colours[i], label=failures[i] or "walkable")
                   for i in present]
        ax.legend(handles=handles, fontsize=5, loc="upper left", bbox_to_anchor=(1.0, 1.0),
                  frameon=False)
        ax.set_xlabel(thrust_label)
        ax.set_ylabel("slope [rad] (uphill > 0)")
        corner_note(ax, "contours: speed along the ground [m/s]")
        if title:
            ax.set_title(title)
        layout(fig)
    return fig


def steepest_figure(thrust: np.ndarray, uphill: Sequence[float | None],
                    downhill: Sequence[float | None], *, thrust_label: str, title: str = ""):
    """Highest and lowest walkable slope [rad] against thrust (``uphill``, ``downhill``: the
    steepest uphill and downhill slope where they lie on their side of level ground; both
    may be uphill, or both downhill, so the lines are labelled highest and lowest); a gap
    where no slope of the map is walkable at that thrust."""
    up = np.array([np.nan if v is None else v for v in uphill], float)
    down = np.array([np.nan if v is None else v for v in downhill], float)
    with style():
        fig = Figure(figsize=(COLUMN, 2.4))
        ax = fig.subplots()
        ms = 2 if len(thrust) <= 40 else 0  # markers only where they can be told apart
        ax.plot(thrust, up, "-o", ms=ms, lw=0.9, color="C3", label="highest walkable slope")
        ax.plot(thrust, down, "-s", ms=ms, lw=0.9, color="C0", label="lowest walkable slope")
        ax.fill_between(thrust, down, up, color="0.85", lw=0, label="walkable slopes")
        ax.axhline(0.0, color="0.4", lw=0.4, ls=":")
        ax.set_xlabel(thrust_label)
        ax.set_ylabel("slope [rad]")
        ax.legend(fontsize=6, frameon=False)
        if not np.isfinite(up).any():
            corner_note(ax, "no walkable slope in the map")
        if title:
            ax.set_title(title)
        layout(fig)
    return fig
