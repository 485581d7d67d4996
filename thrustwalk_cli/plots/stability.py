"""Figures of ``thrustwalk stability``: Floquet multipliers in the complex plane with the unit
circle, and the modulus of each multiplier against a swept parameter with ``delta_zero^2`` as
reference (SPEC 13). Plain data in (see ``StabilityResult.figure_data``)."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from .style import COLUMN, corner_note, layout, style

MARKERS = {"zero dynamics": ("o", "k"), "outputs": ("s", "tab:blue"),
           "thruster": ("^", "tab:orange")}


def _note(cases: list[dict]) -> str:
    bad = [c for c in cases if c["verdict"] in ("undetermined", "no orbit")]
    if not bad:
        return ""
    vals = ", ".join("" if c["value"] is None else f"{c['value']:g}" for c in bad[:6])
    return (f"{len(bad)} case{'s' if len(bad) > 1 else ''} undetermined or without an orbit"
            + (f" ({vals}{', ...' if len(bad) > 6 else ''})" if vals.strip(", ") else ""))


def _log_spaced(values: np.ndarray) -> bool:
    v = values[np.isfinite(values)]
    return v.size > 2 and bool(np.all(v > 0)) and v.max() / v.min() >= 20


def multiplier_plane(data: dict, *, title: str = ""):
    """Multipliers [1] of every case in the complex plane, the unit circle (stability
    boundary) and ``delta_zero^2`` on the real axis; marker by kind, colour by the swept
    value (black without a sweep)."""
    cases = data["cases"]
    d2 = data["delta_zero_sq"]
    with style():
        fig = Figure(figsize=(COLUMN, 3.0))
        ax = fig.subplots()
        th = np.linspace(0, 2 * np.pi, 361)
        ax.plot(np.cos(th), np.sin(th), color="0.5", lw=0.7, label="unit circle")
        ax.plot([d2], [0.0], marker="x", ms=6, color="firebrick", ls="none",
                label=r"$\delta_0^2$ (zero dynamics)")
        vals = np.array([np.nan if c["value"] is None else c["value"] for c in cases], float)
        sweep = data.get("label") is not None and np.isfinite(vals).any()
        cmap = matplotlib.colormaps["viridis"]
        if sweep:
            lo, hi = np.nanmin(vals), np.nanmax(vals)
            norm = (matplotlib.colors.LogNorm(lo, hi) if _log_spaced(vals) else
                    matplotlib.colors.Normalize(lo, hi if hi > lo else lo + 1))
        # the multipliers of one kind, every case, as one artist (markers coloured by the
        # swept value: one scatter; without a sweep: one marker line in the kind's colour)
        points: dict[str, list] = {}
        for c, v in zip(cases, vals):
            for re, im, kind in zip(c["re"], c["im"], c["kind"]):
                points.setdefault(kind, []).append((re, im, v))
        handles, labels = ax.get_legend_handles_labels()
        for kind, pts in points.items():
            mk, col = MARKERS[kind]
            re, im, v = (np.array(x, float) for x in zip(*pts))
            if sweep:
                ax.scatter(re, im, s=3.2 ** 2, marker=mk, facecolors="none",
                           edgecolors=cmap(norm(v)), linewidths=0.7, zorder=2)
            else:
                ax.plot(re, im, marker=mk, ms=3.2, ls="none", mfc=col, mec=col, mew=0.7)
            handles.append(matplotlib.lines.Line2D(
                [], [], marker=mk, ms=3.2, ls="none", mfc="none" if sweep else col,
                mec="0.3" if sweep else col, mew=0.7))
            labels.append(kind)
        if sweep:
            sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
            fig.colorbar(sm, ax=ax, pad=0.02).set_label(data["label"])
        ax.set_aspect("equal", adjustable="datalim")
        ax.axhline(0, color="0.8", lw=0.4, zorder=0)
        ax.axvline(0, color="0.8", lw=0.4, zorder=0)
        ax.set_xlabel(r"Re $\lambda$ [1]")
        ax.set_ylabel(r"Im $\lambda$ [1]")
        ax.legend(handles, labels, loc="upper left", fontsize=6)
        if title:
            ax.set_title(title)
        corner_note(ax, _note(cases))
        layout(fig)
    return fig


def spectral_radius(data: dict, *, title: str = ""):
    """Modulus [1] of each multiplier against the swept parameter (log axes where the sweep
    spans a decade or more), the spectral radius as a line, ``delta_zero^2`` and 1 as
    references."""
    cases = data["cases"]
    d2 = data["delta_zero_sq"]
    with style():
        fig = Figure(figsize=(COLUMN, 3.1))
        ax = fig.subplots()
        vals = np.array([c["value"] for c in cases], float)
        points: dict[str, list] = {}  # the moduli of one kind, every case: one marker line
        for c, v in zip(cases, vals):
            mod = np.hypot(c["re"], c["im"])
            for r, kind in zip(mod, c["kind"]):
                points.setdefault(kind, []).append((v, max(r, 1e-16)))
        for kind, pts in points.items():
            mk, col = MARKERS[kind]
            ax.plot(*zip(*pts), marker=mk, ms=2.8, ls="none", mfc="none", mec=col, mew=0.7,
                    label=kind)
        ok = np.array([c["spectral_radius"] is not None for c in cases])
        if ok.any():
            ax.plot(vals[ok], [c["spectral_radius"] for c in cases if c["spectral_radius"]
                               is not None], color="k", lw=0.8, label="spectral radius")
        ax.axhline(d2, color="firebrick", ls="--", lw=0.8, label=r"$\delta_0^2$")
        ax.axhline(1.0, color="0.4", ls=":", lw=0.8, label="1 (stability limit)")
        if _log_spaced(vals):
            ax.set_xscale("log")
        mods = [m for c in cases for m in np.hypot(c["re"], c["im"]) if m > 0]
        if mods and max(mods) / max(min(mods), 1e-16) > 100:
            ax.set_yscale("log")
        ax.set_xlabel(data["label"] or "value")
        ax.set_ylabel(r"$|\lambda|$ [1]")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, fontsize=6)
        if title:
            ax.set_title(title)
        corner_note(ax, _note(cases))
        layout(fig)
    return fig
