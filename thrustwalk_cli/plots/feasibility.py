"""Figures of ``thrustwalk feasibility`` (SPEC 5): ground forces along the step and the
feasible region. Plain data in."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

from .style import corner_note, style

MAX_LINES = 12


def _pick(n: int, limit: int = MAX_LINES) -> list[int]:
    """At most ``limit`` evenly spread indices (first and last included)."""
    if n <= limit:
        return list(range(n))
    return sorted(set(np.linspace(0, n - 1, limit).round().astype(int).tolist()))


def grf_figure(profiles: Sequence[dict | None], values: Sequence[float] | None, *,
               value_label: str, mu: float, eps: float, swing: dict, joint_names: list[str],
               title: str = ""):
    """Ground reaction force, friction ratio, joint torques and swing-foot height along the step.

    ``profiles[i]``: dict with ``alpha`` [rad], ``F1`` (g, 2) [N], ``ratio`` (g,), ``torque``
    (g, N-1) [N m] or None (no orbit). ``values``: the swept thrust [N] (colour bar) or None for
    a single schedule.
    """
    with style():
        fig, axs = plt.subplots(2, 2, figsize=(7.0, 4.6), sharex=True)
        (a_f, a_r), (a_u, a_h) = axs
        idx = [i for i in _pick(len(profiles)) if profiles[i] is not None]
        sweep = values is not None and len(values) > 1
        if sweep:
            vals = np.asarray(values, float)
            norm = matplotlib.colors.Normalize(vmin=vals.min(), vmax=vals.max())
            cmap = matplotlib.colormaps["viridis"]
            colour = [cmap(norm(v)) for v in vals]
        else:
            colour = ["C0"] * len(profiles)
        dashes = ["-", "--", ":", "-."]
        for i in idx:
            p = profiles[i]
            a = p["alpha"]
            a_f.plot(a, p["F1"][:, 1], color=colour[i], lw=0.8)
            a_f.plot(a, p["F1"][:, 0], color=colour[i], lw=0.8, ls="--")
            r = np.where(np.isfinite(p["ratio"]), p["ratio"], np.nan)
            a_r.plot(a, r, color=colour[i], lw=0.8)
            for j in range(p["torque"].shape[1]):
                a_u.plot(a, p["torque"][:, j], color=colour[i], lw=0.8,
                         ls=dashes[j % len(dashes)])
        a_f.axhline(eps, color="firebrick", lw=0.6, ls=":")
        a_f.set_ylabel(r"ground force $F_1$ [N]")
        a_f.legend([Line2D([], [], color="k", lw=0.8), Line2D([], [], color="k", ls="--", lw=0.8),
                    Line2D([], [], color="firebrick", ls=":", lw=0.6)],
                   [r"vertical $F_1^v$", r"horizontal $F_1^h$", rf"$\varepsilon$ = {eps:g} N"],
                   loc="best")
        a_r.axhline(mu, color="firebrick", lw=0.8)
        a_r.axhline(mu / np.sqrt(2), color="firebrick", lw=0.6, ls=":")
        a_r.set_ylabel(r"friction ratio $|F_1^h|/F_1^v$ [-]")
        a_r.legend([Line2D([], [], color="k", lw=0.8), Line2D([], [], color="firebrick", lw=0.8),
                    Line2D([], [], color="firebrick", ls=":", lw=0.6)],
                   ["along the step", rf"cone $\mu$ = {mu:g}",
                    r"inscribed pyramid $\mu/\sqrt{2}$ (not used)"], loc="best")
        a_u.set_ylabel(r"joint torque $u$ [N m]")
        a_u.legend([Line2D([], [], color="k", ls=dashes[j % len(dashes)], lw=0.8)
                    for j in range(len(joint_names))], joint_names, loc="best")
        a_h.plot(swing["alpha"], 1e3 * swing["height"], color="k", lw=0.8, label="swing foot")
        a_h.axhline(0.0, color="firebrick", lw=0.6, ls=":", label="ground")
        a_h.set_ylabel("swing-foot height [mm]")
        a_h.legend(loc="best")
        for ax in (a_u, a_h):
            ax.set_xlabel(r"$\alpha$ [rad]")
        if sweep:
            sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
            cb = fig.colorbar(sm, ax=axs, pad=0.02, fraction=0.04)
            cb.set_label(value_label)
        if title:
            fig.suptitle(title)
        missing = [i for i in range(len(profiles)) if profiles[i] is None]
        if missing and values is not None:
            corner_note(a_f, "no orbit for " + ", ".join(f"{values[i]:g}" for i in missing))
    return fig


def region_figure(region, *, scale_label: str, mu: float, eps: float,
                  cases: Sequence[tuple[float, float | None]] = (), title: str = ""):
    """Feasible region over (scale, zeta^-): colour = worst friction ratio where the step
    completes with ``F^v > 0``; black contour = boundary of the feasible set; the limit-cycle
    fixed-point curve (solid where feasible) and the nominal point (scale 0); ``cases``:
    (scale, zeta*) of the evaluated cases."""
    with style():
        fig, ax = plt.subplots(figsize=(4.6, 3.2))
        S, Z = np.meshgrid(region.scale, region.zeta, indexing="ij")
        ratio = np.where(region.completes & np.isfinite(region.max_ratio), region.max_ratio,
                         np.nan)
        vmax = max(1.5 * mu, 1e-3)
        mesh = ax.pcolormesh(S, Z, np.ma.masked_invalid(ratio), cmap="magma_r", vmin=0,
                             vmax=vmax, shading="auto", rasterized=True)
        cb = fig.colorbar(mesh, ax=ax, pad=0.02)
        cb.set_label(r"worst friction ratio $|F_1^h|/F_1^v$ [-]")
        cb.ax.axhline(mu, color="c", lw=1.0)
        stop = np.where(region.completes, np.nan, 1.0)
        ax.pcolormesh(S, Z, np.ma.masked_invalid(stop), cmap="Greys", vmin=0, vmax=2,
                      shading="auto", rasterized=True)
        handles = [matplotlib.patches.Patch(color=matplotlib.colormaps["Greys"](0.5),
                                            label="walker stops"),
                   matplotlib.patches.Patch(facecolor="white", edgecolor="k",
                                            label="unilateral contact lost")]
        if region.feasible.any() and not region.feasible.all():
            ax.contour(S, Z, region.feasible.astype(float), levels=[0.5], colors="c",
                       linewidths=1.2)
        handles.append(Line2D([], [], color="c", lw=1.2, label=rf"feasible boundary ($\mu$ = "
                              rf"{mu:g}, $\varepsilon$ = {eps:g} N)"))
        v = region.fixed_point_valid
        if v.any():
            zs = np.where(v, region.fixed_point, np.nan)
            ax.plot(region.scale, zs, color="w", lw=2.2)
            ax.plot(region.scale, np.where(region.fixed_point_feasible, zs, np.nan), color="k",
                    lw=1.2)
            ax.plot(region.scale, np.where(~region.fixed_point_feasible, zs, np.nan),
                    color="k", lw=1.0, ls=":")
            handles.append(Line2D([], [], color="k", lw=1.2, label=r"fixed points $\zeta^*$"))
        zero = np.argmin(np.abs(region.scale))
        if v[zero] and abs(region.scale[zero]) < 1e-12:
            ax.plot([0.0], [region.fixed_point[zero]], marker="*", color="gold", ms=10,
                    mec="k", ls="none")
            handles.append(Line2D([], [], marker="*", color="gold", mec="k", ms=8, ls="none",
                                  label="nominal (no thrust)"))
        pts = [(s, z) for s, z in cases if z is not None]
        if pts:
            ax.plot(*zip(*pts), marker="o", ms=3.5, color="c", mec="k", ls="none")
            handles.append(Line2D([], [], marker="o", color="c", mec="k", ms=4, ls="none",
                                  label="evaluated cases"))
        ax.set_xlabel(scale_label)
        ax.set_ylabel(r"pre-impact $\zeta^-$ [kg$^2$ m$^4$/s$^2$]")
        ax.set_xlim(region.scale.min(), region.scale.max())
        ax.set_ylim(region.zeta.min(), region.zeta.max())
        ax.grid(False)
        ax.legend(handles=handles, loc="upper left", fontsize=6, frameon=True,
                  framealpha=0.85)
        if not region.impact_ok:
            ax.text(0.5, 0.02, "impact inadmissible everywhere", transform=ax.transAxes,
                    ha="center", color="firebrick", fontsize=7)
        if title:
            ax.set_title(title)
        fig.tight_layout()
    return fig
