"""Figures of center-manifold shaping (SPEC 4, 8: the paper's figures 4 and 5).

Rendered from :class:`thrustwalk_cli.studies.shape_result.ShapeResult` results; shared style from
:mod:`thrustwalk_cli.plots` (labels with units, colour bar for a swept value, black every 10).
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from .limit_cycle import phase_portrait
from .style import PAGE, black_step, corner_note, layout, missing_note, place_legends, style

YLABEL = {"alpha_dot": r"$\dot\alpha$ [rad/s]", "sigma": r"$\sigma_N$ [kg m$^2$/s]"}


def _knot_lines(ax, knots: Sequence[float]) -> None:
    """Interior knots alpha_2 .. alpha_{n-1} as dotted vertical lines."""
    for a in knots[1:-1]:
        ax.axvline(a, color="0.45", ls=":", lw=0.6, zorder=0)
    if len(knots) > 2:
        ax.plot([], [], color="0.45", ls=":", lw=0.6, label="knots")


def _cycle(ax, orbit: dict | None, jump, y: str, color, lw: float, label: str | None,
           zorder: int = 3) -> None:
    if orbit is None:
        return
    ax.plot(orbit["alpha"], orbit[y], color=color, lw=lw, label=label, zorder=zorder)
    if jump is not None:
        ax.plot([jump[0], jump[2]], [jump[1], jump[3]], color=color, ls="--", lw=0.5,
                zorder=zorder - 1)


def shape_portrait(values: Sequence[float] | None, labels: Sequence[str],
                   orbits: Sequence[dict | None], jumps: Sequence[tuple | None],
                   nominal: tuple[dict | None, tuple | None], knots: Sequence[float], *,
                   value_label: str, y: str = "alpha_dot", title: str = "", note: str = ""):
    """Shaped limit cycles in the (alpha, alpha') plane with the knots marked.

    With ``values`` (a pattern sweep, e.g. k = 0..50 for T_j = k(j - 2)): one orbit per value,
    coloured by it with a colour bar, black every 10 (the paper's figure 4). Without: the
    nominal orbit in black and each shaped orbit in colour, with a legend.
    ``orbits[i]`` holds arrays ``alpha``, ``alpha_dot``, ``sigma``; ``jumps[i]`` is
    (alpha_f, y^-, alpha_i, y^+) and is drawn dashed (the impact).
    """
    if values is not None:
        fig = phase_portrait(values, orbits, jumps, value_label=value_label, y=y,
                             black_every=black_step(values), title=title, note=note)
        ax = fig.axes[0]
        with style():
            _knot_lines(ax, knots)
            handles, lbls = ax.get_legend_handles_labels()
            leg = ax.get_legend()
            old = ([] if leg is None else list(leg.legend_handles),
                   [] if leg is None else [t.get_text() for t in leg.get_texts()])
            ax.legend(old[0] + handles, old[1] + lbls, loc="best")
            place_legends(fig)
        return fig
    with style():
        fig = Figure(figsize=(3.5, 2.7))
        ax = fig.subplots()
        _cycle(ax, nominal[0], nominal[1], y, "k", 1.0, "nominal")
        colors = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
        missing = []
        for i, (lab, orb, jump) in enumerate(zip(labels, orbits, jumps)):
            if orb is None:
                missing.append(lab)
            _cycle(ax, orb, jump, y, colors[i % len(colors)], 1.0, f"shaped ({lab})")
        _knot_lines(ax, knots)
        ax.set_xlabel(r"$\alpha$ [rad]")
        ax.set_ylabel(YLABEL[y])
        ax.legend(loc="best")
        if title:
            ax.set_title(title)
        text = note + ("\n" if note and missing else "")
        if missing:
            text += missing_note(missing)
        corner_note(ax, text)
        layout(fig)
    return fig


DELTA_LABEL = {"alpha_dot": r"change of $\ddot\alpha$ [rad/s$^2$]",
               "sigma": r"change of $\dot\sigma_N$ [N m]"}


def vector_field_figure(fields: dict, nominal: dict, shaped: dict, knots: Sequence[float], *,
                        shaped_label: str, title: str = "", note: str = ""):
    """Zero-dynamics vector field under shaping (the paper's figure 5, k = 60), two columns
    wide. Left: the shaped field (grey streamlines) with the nominal (black) and shaped (red)
    limit cycles. Right: what the thrust changes, the shaped minus the nominal field's
    acceleration component (a diverging colour map with its colour bar; the velocity component
    alpha' is the same in both), with both cycles and the knots. Rows: (alpha, alpha') and
    (alpha, sigma_N).

    ``fields[plane] = (nominal VectorField, shaped VectorField)`` for plane "alpha_dot" and
    "sigma"; ``nominal[plane]`` / ``shaped[plane]``: (orbit dict or None, impact jump or None).
    """
    planes = [p for p in ("alpha_dot", "sigma") if p in fields]
    with style():
        fig = Figure(figsize=(PAGE, 2.5 * len(planes) + 0.4))
        axes = fig.subplots(len(planes), 2, squeeze=False, sharex=True)
        for r, plane in enumerate(planes):
            vn, vs = fields[plane]
            ax, ad = axes[r, 0], axes[r, 1]
            sa = np.ptp(vs.alpha) or 1.0
            sy = np.ptp(vs.y) or 1.0
            ax.streamplot(vs.alpha, vs.y, vs.d_alpha / sa, vs.d_y / sy, color="0.65",
                          density=1.0, linewidth=0.5, arrowsize=0.6)
            delta = vs.d_y - vn.d_y
            lim = float(np.abs(delta).max()) or 1.0
            mesh = ad.pcolormesh(vs.alpha, vs.y, delta, cmap="RdBu_r", vmin=-lim, vmax=lim,
                                 shading="nearest", rasterized=True)
            cb = fig.colorbar(mesh, ax=ad, pad=0.02)
            cb.set_label(DELTA_LABEL[plane])
            for a in (ax, ad):
                _cycle(a, *nominal[plane], plane, "k", 1.0, "nominal cycle")
                _cycle(a, *shaped[plane], plane, "tab:red", 1.1,
                       f"shaped cycle ({shaped_label})", zorder=4)
                _knot_lines(a, knots)
                a.set_xlim(vs.alpha.min(), vs.alpha.max())
                a.set_ylim(vs.y.min(), vs.y.max())
                a.grid(False)
                if r == len(planes) - 1:
                    a.set_xlabel(r"$\alpha$ [rad]")
            ax.set_ylabel(YLABEL[plane])
            if r == 0:
                ax.set_title(f"shaped field ({shaped_label})")
                ad.set_title("change made by the thrust (shaped minus nominal)")
        handles, labels = axes[0, 0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncol=len(labels),
                   bbox_to_anchor=(0.5, 0.0))
        if title:
            fig.suptitle(title)
        if note:
            fig.text(0.01, 0.005, note, fontsize=6, color="firebrick", va="bottom")
        layout(fig, rect=(0, 0.06, 1, 1))
    return fig
