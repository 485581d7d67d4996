"""Figures of ``thrustwalk limit-cycle``: zero-dynamics limit cycles over a swept value and
the fixed-point shift versus thrust (SPEC 3, 4; the paper's figure 3). Plain data in."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from .style import COLUMN, corner_note, curve_family, is_multiple, layout, missing_note, style

ORBIT_LW = 0.6  # [pt] coloured orbits
BLACK_LW = 0.9  # [pt] black orbits (round values of the sweep)
# the impact jumps: thinner and lighter than any orbit, behind them (and in the legend alike)
JUMP = {"color": "0.7", "ls": (0, (3.0, 2.0)), "lw": 0.4, "zorder": 1}


def phase_portrait(
    values: Sequence[float],
    orbits: Sequence[dict | None],
    jumps: Sequence[tuple[float, float, float, float] | None],
    *,
    value_label: str,
    y: str = "alpha_dot",
    black_every: float | None = 10.0,
    title: str = "",
    note: str = "",
):
    """Orbits in the (alpha, alpha') or (alpha, sigma_N) plane, coloured by a swept value.

    ``orbits[i]``: dict with arrays ``alpha`` [rad] and ``y`` (None when no orbit exists).
    ``jumps[i]``: (alpha_f, y^-, alpha_i, y^+), the impact (SPEC 3: ``sigma_N^+ =
    delta_zero sigma_N^-``), drawn as one thin light-grey dashed segment per orbit behind the
    orbits (``JUMP``), so a fine sweep's jumps never outweigh its orbits; the legend entry is
    drawn with the same style. Values that are multiples of ``black_every`` are drawn in black
    (the paper's style), the others in the colour bar's colour.
    """
    ylabel = {"alpha_dot": r"$\dot\alpha$ [rad/s]",
              "sigma": r"$\sigma_N$ [kg m$^2$/s]"}[y]
    with style():
        fig = Figure(figsize=(COLUMN, 2.7))
        ax = fig.subplots()
        vals = np.asarray(values, float)
        lo, hi = (vals.min(), vals.max()) if vals.size else (0.0, 1.0)
        norm = matplotlib.colors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1)
        cmap = matplotlib.colormaps["viridis"]
        missing = []
        black_curves, colour_curves, colours, jump_curves = [], [], [], []
        for v, orb, jump in zip(vals, orbits, jumps):
            if orb is None:
                missing.append(v)
                continue
            if black_every is not None and is_multiple(v, black_every):
                black_curves.append((orb["alpha"], orb[y]))
            else:
                colour_curves.append((orb["alpha"], orb[y]))
                colours.append(cmap(norm(v)))
            if jump is not None:
                jump_curves.append(([jump[0], jump[2]], [jump[1], jump[3]]))
        # each family one artist: coloured orbits, black orbits above them, jumps behind
        curve_family(ax, colour_curves, colours, lw=ORBIT_LW, zorder=2)
        curve_family(ax, black_curves, ["k"] * len(black_curves), lw=BLACK_LW, zorder=3)
        curve_family(ax, jump_curves, [JUMP["color"]] * len(jump_curves), lw=JUMP["lw"],
                     ls=JUMP["ls"], zorder=JUMP["zorder"])
        any_black, any_jump = bool(black_curves), bool(jump_curves)
        sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
        cb = fig.colorbar(sm, ax=ax, pad=0.02)
        cb.set_label(value_label)
        ax.set_xlabel(r"$\alpha$ [rad]")
        ax.set_ylabel(ylabel)
        unit = (value_label.rsplit("[", 1)[1][:-1] if value_label.endswith("]") else "")
        # legend entries only for what is drawn, each in the style it is drawn with
        if any_black:
            handles = [matplotlib.lines.Line2D([], [], color="k", lw=BLACK_LW)]
            labels = [f"every {black_every:g} {unit}".rstrip()]
        else:
            handles = [matplotlib.lines.Line2D([], [], color=cmap(0.5), lw=ORBIT_LW)]
            labels = ["orbit"]
        if any_jump:
            handles.append(matplotlib.lines.Line2D([], [], **JUMP))
            labels.append("impact jump")
        if len(vals) > len(missing):
            ax.legend(handles, labels, loc="best")
        if title:
            ax.set_title(title)
        text = note
        if missing:
            text += ("\n" if text else "") + missing_note(missing, unit)
        corner_note(ax, text)
        layout(fig)
    return fig


def fixed_point_shift(values: Sequence[float], zeta_star: Sequence[float | None],
                      speed: Sequence[float | None], slope: float, zeta0: float | None,
                      *, thruster: str, title: str = ""):
    """Fixed point zeta* [kg^2 m^4/s^2] and speed [m/s] versus constant thrust [N] (SPEC 4).

    The line is the exact affine law ``zeta*(F) = zeta*(0) + Gamma(alpha_f) F / (1 - delta^2)``;
    markers are the computed fixed points (missing where no orbit exists).
    """
    vals = np.asarray(values, float)
    ok = np.array([z is not None for z in zeta_star])
    with style():
        fig = Figure(figsize=(COLUMN, 2.6))
        ax = fig.subplots()
        if zeta0 is not None:
            grid = np.linspace(vals.min(), vals.max(), 200)
            ax.plot(grid, zeta0 + slope * grid, color="0.6", lw=0.8,
                    label=r"affine law $\zeta^*_0 + \Gamma F/(1-\delta^2)$")
        ax.plot(vals[ok], [z for z in zeta_star if z is not None], "o", ms=2.5, color="k",
                label=r"computed $\zeta^*$")
        if (~ok).any():
            ax.plot(vals[~ok], np.zeros((~ok).sum()), "x", ms=3, color="firebrick",
                    label="no periodic orbit")
        ax.set_xlabel(f"thrust {thruster} [N]")
        ax.set_ylabel(r"$\zeta^*$ [kg$^2$ m$^4$/s$^2$]")
        ax2 = ax.twinx()
        ax2.grid(False)
        ax2.plot(vals[ok], [v for v in speed if v is not None], "--", color="tab:blue", lw=0.8,
                 label="average speed (right axis)")
        ax2.set_ylabel("average speed [m/s]", color="tab:blue")
        ax2.tick_params(axis="y", colors="tab:blue")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, loc="best")
        if title:
            ax.set_title(title)
        layout(fig)
    return fig
