"""Figures of ``thrustwalk energy`` (SPEC 15): cost of transport against speed over a thrust
sweep (mechanical and total, legs / thrust split), the power along the step (joints and
thrusters stacked) and the Pareto comparison with a gait library. Plain data in."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from .style import COLUMN, corner_note, layout, style

LEGS = "#9ecae1"  # legs' share
THRUST = "#fdae6b"  # thrust's share


def cot_speed_figure(curves: dict, *, thruster: str, note_total: str = "", title: str = ""):
    """CoT [1] against speed [m/s] over the thrust values: one panel per basis
    (``mechanical``, ``total``), the legs' share filled below the curve and the thrust's
    share between it and the curve. ``curves[basis]``: ``(speed, cot, cot_legs, thrust,
    walkable)`` per thrust value with that CoT; a thrust value whose orbit is not walkable is
    drawn as an open marker. ``note_total``: why a total panel is empty."""
    with style():
        fig = Figure(figsize=(COLUMN, 4.2))
        axes = fig.subplots(2, 1, sharex=True)
        for ax, basis in zip(axes, ("mechanical", "total")):
            pts = sorted(curves.get(basis) or [], key=lambda p: p[0])
            ax.set_ylabel(f"{basis} CoT [1]")
            if not pts:
                corner_note(ax, note_total or f"no {basis} CoT")
                continue
            v = np.array([p[0] for p in pts])
            c = np.array([p[1] for p in pts])
            legs = np.array([p[2] for p in pts])
            ax.fill_between(v, 0.0, legs, color=LEGS, lw=0, label="legs")
            ax.fill_between(v, legs, c, color=THRUST, lw=0, label="thrust")
            ax.plot(v, c, "-", color="k", lw=0.8)
            ok = np.array([p[4] for p in pts], bool)
            ms = 2.5 if len(pts) <= 40 else 0
            if ms:
                ax.plot(v[ok], c[ok], "o", color="k", ms=ms, label="walkable")
                if (~ok).any():
                    ax.plot(v[~ok], c[~ok], "o", mfc="white", mec="k", ms=ms,
                            label="not walkable")
            for i, side in ((int(np.argmin(v)), "left"), (int(np.argmax(v)), "right")):
                ax.annotate(f"{pts[i][3]:g} N", (v[i], c[i]), fontsize=5, ha=side,
                            xytext=(3 if side == "left" else -3, 3),
                            textcoords="offset points")
            ax.set_ylim(bottom=0.0)
            ax.legend(fontsize=5, frameon=False, loc="upper left")
        axes[-1].set_xlabel(f"speed [m/s] (constant thrust on {thruster})")
        if title:
            axes[0].set_title(title)
        layout(fig)
    return fig


def power_step_figure(panels: Sequence[tuple[str, dict]], *, basis: str, title: str = ""):
    """Power [W] along one step against time [s], one panel per case (``(label, stack)``,
    ``stack`` with ``time`` and ``layers`` ``[(name, values)]``, each >= 0): the layers
    stacked, joints and thrusters, so that the area is the step's energy of the CoT
    ``basis`` (total: electrical and thruster input; mechanical: positive work)."""
    n = max(len(panels), 1)
    with style():
        fig = Figure(figsize=(COLUMN, 1.2 + 1.5 * n))
        axes = np.atleast_1d(fig.subplots(n, 1))
        what = ("electrical / input power" if basis == "total"
                else "positive mechanical power")
        if not panels:
            corner_note(axes[0], "no stable orbit: no power")
        for ax, (label, stack) in zip(axes, panels):
            t = stack["time"]
            layers = stack["layers"]
            if layers:
                ax.stackplot(t, *[v for _, v in layers], labels=[n_ for n_, _ in layers],
                             colors=[f"C{i}" for i in range(len(layers))], lw=0)
                ax.legend(fontsize=5, frameon=False, loc="upper right", ncol=2)
            ax.set_ylabel(f"{what} [W]", fontsize=6)
            ax.set_xlim(t[0], t[-1])
            ax.set_ylim(bottom=0.0)
            ax.text(0.01, 0.97, f"thrust {label}", transform=ax.transAxes, fontsize=6,
                    va="top")
        axes[-1].set_xlabel("time in the step [s]")
        if title:
            axes[0].set_title(title)
        layout(fig)
    return fig


def pareto_figure(designed: tuple, pushed: tuple, envelope: Sequence[tuple[float, float]], *,
                  basis: str, gait: str, thruster: str, title: str = ""):
    """Speed [m/s] against CoT [1], one curve per strategy: ``designed`` = (speeds, CoTs,
    gait names) of the library's gaits without thrust, ``pushed`` = (speeds, CoTs, thrust
    values) of the command's gait under constant thrust; ``envelope``: (speed, cheapest CoT)
    on a fine grid of speeds (NaN where neither strategy reaches), a thick grey line behind
    the curves."""
    with style():
        fig = Figure(figsize=(COLUMN, 2.6))
        ax = fig.subplots()
        if envelope:
            e = np.array(envelope, float)
            ax.plot(e[:, 0], e[:, 1], "-", color="0.8", lw=3.0, zorder=1, label="cheapest")
        xa, ya, names = designed
        xb, yb, thrust = pushed
        if len(xa):
            ax.plot(xa, ya, "-s", color="C0", ms=3, lw=0.9, zorder=3,
                    label="designed gaits, no thrust")
        if len(xb):
            ax.plot(xb, yb, "-o", color="C3", ms=2 if len(xb) <= 40 else 0, lw=0.9, zorder=3,
                    label=f"{gait} + thrust on {thruster}")
            for i, side in ((0, "left"), (len(xb) - 1, "right")):
                ax.annotate(f"{thrust[i]:g} N", (xb[i], yb[i]), fontsize=5, ha=side,
                            xytext=(3 if side == "left" else -3, 3),
                            textcoords="offset points")
        ax.set_xlabel("speed [m/s]")
        ax.set_ylabel(f"{basis} CoT [1]" + (" (total: models missing)" if basis == "mechanical"
                                           else ""))
        ax.set_ylim(bottom=0.0)
        ax.legend(fontsize=5, frameon=False)
        if not len(xa) or not len(xb):
            corner_note(ax, "one strategy has no walkable orbit")
        if title:
            ax.set_title(title)
        layout(fig)
    return fig
