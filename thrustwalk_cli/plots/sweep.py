"""Figures of ``thrustwalk sweep``: a heat map of one result field over a pair of axes, and
the atlas of a gait library. Plain data in."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from .style import COLUMN, PAGE, corner_note, layout, style


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres ``v`` (midpoints; half a spacing beyond the ends)."""
    if v.size == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def heat_map(xs: Sequence[float], ys: Sequence[float], values: Sequence[float | None], *,
             xlabel: str, ylabel: str, clabel: str, gridded: bool = True, title: str = ""):
    """``values`` at the points (xs, ys): cells of a grid (``gridded``; one cell per point,
    edges half-way between values), else coloured markers (random axes). Missing values
    (failed points) are grey crosses, counted in a corner note."""
    x, y = np.asarray(xs, float), np.asarray(ys, float)
    c = np.array([np.nan if v is None else float(v) for v in values], float)
    ok = np.isfinite(c)
    with style():
        fig = Figure(figsize=(COLUMN, 2.7))
        ax = fig.subplots()
        cmap = matplotlib.colormaps["viridis"]
        lo, hi = (np.nanmin(c), np.nanmax(c)) if ok.any() else (0.0, 1.0)
        norm = matplotlib.colors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
        ux, uy = np.unique(x), np.unique(y)
        if gridded and ux.size * uy.size == x.size:
            grid = np.full((uy.size, ux.size), np.nan)
            grid[np.searchsorted(uy, y), np.searchsorted(ux, x)] = c
            ax.pcolormesh(_edges(ux), _edges(uy), np.ma.masked_invalid(grid), cmap=cmap,
                          norm=norm, shading="flat")
        else:
            ax.scatter(x[ok], y[ok], c=c[ok], cmap=cmap, norm=norm, s=12, edgecolors="none")
        if (~ok).any():
            ax.plot(x[~ok], y[~ok], "x", color="0.5", ms=4, label="failed")
            corner_note(ax, f"{int((~ok).sum())} failed point(s) (x)")
        cb = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, pad=0.02)
        cb.set_label(clabel)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(False)
        if title:
            ax.set_title(title)
        layout(fig)
    return fig


def atlas(data: dict, title: str = ""):
    """A gait library's atlas: one panel per field of ``data["panels"]`` ((key, label)),
    against ``data["x_label"]``, one line per series (``data["series"]``: line value ->
    ``{"x": [...], key: [...]}``, None for an infeasible design), labelled by
    ``data["line_label"]`` and ``data["line_unit"]``."""
    panels = data["panels"]
    series = data["series"]
    keys = sorted(series, key=lambda k: (k is None, k))
    with style():
        fig = Figure(figsize=(PAGE, 4.0))
        axs = fig.subplots(2, (len(panels) + 1) // 2, sharex=True)
        axs = np.atleast_1d(axs).ravel()
        cmap = matplotlib.colormaps["viridis"]
        for ax, (key, label) in zip(axs, panels):
            for i, k in enumerate(keys):
                s = series[k]
                xv = np.asarray(s["x"], float)
                yv = np.array([np.nan if v is None else float(v) for v in s[key]], float)
                order = np.argsort(xv)
                color = cmap(i / max(len(keys) - 1, 1)) if len(keys) > 1 else "k"
                name = (f"{data['line_label']} = {k:g} {data.get('line_unit', '')}".rstrip()
                        if k is not None and data["line_label"] else "designs")
                ax.plot(xv[order], yv[order], "o-", ms=3, lw=0.8, color=color, label=name)
            if key.endswith("margin"):
                ax.axhline(0.0, color="firebrick", lw=0.6, ls="--")
            ax.set_ylabel(label)
        for ax in axs[len(panels):]:
            ax.set_visible(False)
        for ax in axs[-2:]:
            ax.set_xlabel(data["x_label"])
        axs[0].legend(loc="best")
        if title:
            fig.suptitle(title)
        layout(fig)
    return fig
