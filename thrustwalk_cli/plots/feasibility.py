"""Figures of ``thrustwalk feasibility`` (SPEC 5): ground forces along the step and the
feasible region. Plain data in."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

from .style import COLUMN, PAGE, corner_note, missing_note, style

MAX_LINES = 12


def _pick(n: int, limit: int = MAX_LINES) -> list[int]:
    """At most ``limit`` evenly spread indices (first and last included)."""
    if n <= limit:
        return list(range(n))
    return sorted(set(np.linspace(0, n - 1, limit).round().astype(int).tolist()))


def grf_figure(profiles: Sequence[dict | None], values: Sequence[float] | None, *,
               value_label: str, mu: float, eps: float, swing: dict, joint_names: list[str],
               impacts: Sequence[dict] | None = None, title: str = ""):
    """Stance phase along the step, two columns wide: ground reaction force, friction ratio
    (clipped where F^v -> 0 so the curves stay readable; the clipped part is marked), joint
    torques, swing-foot height, and the impact impulse per case with its friction ratio.

    ``profiles[i]``: dict with ``alpha`` [rad], ``F1`` (g, 2) [N], ``ratio`` (g,), ``torque``
    (g, N-1) [N m] or None (no orbit). ``values``: the swept thrust [N] (colour bar) or None for
    a single schedule. ``impacts[i]``: ``{"impulse": (h, v) [N s] or None, "ratio": float or
    None}``.
    """
    with style():
        fig, axs = plt.subplots(3, 2, figsize=(PAGE, 6.2), layout="constrained")
        (a_f, a_r), (a_u, a_h), (a_i, a_k) = axs
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
        top = 2.5 * mu  # the friction-ratio axis ends here
        clipped = False
        for i in idx:
            p = profiles[i]
            a = p["alpha"]
            a_f.plot(a, p["F1"][:, 1], color=colour[i], lw=0.8)
            a_f.plot(a, p["F1"][:, 0], color=colour[i], lw=0.8, ls="--")
            r = np.where(np.isfinite(p["ratio"]), p["ratio"], np.nan)
            clipped |= bool(np.nanmax(r, initial=0.0) > top) or bool(np.isnan(r).any())
            a_r.plot(a, np.where(r > top, np.nan, r), color=colour[i], lw=0.8)
            for j in range(p["torque"].shape[1]):
                a_u.plot(a, p["torque"][:, j], color=colour[i], lw=0.8,
                         ls=dashes[j % len(dashes)])
        a_f.axhline(eps, color="firebrick", lw=0.6, ls=":")
        a_f.set_ylabel(r"ground force $F_1$ [N]")
        a_f.legend([Line2D([], [], color="k", lw=0.8), Line2D([], [], color="k", ls="--", lw=0.8),
                    Line2D([], [], color="firebrick", ls=":", lw=0.6)],
                   [r"vertical $F_1^v$", r"horizontal $F_1^h$", rf"minimum $F_1^v$ = {eps:g} N"],
                   loc="best")
        a_r.axhline(mu, color="firebrick", lw=0.8)
        a_r.axhline(mu / np.sqrt(2), color="firebrick", lw=0.6, ls=":")
        a_r.set_ylim(0.0, top)
        a_r.set_ylabel(r"friction ratio $|F_1^h|/F_1^v$ [-]")
        labels = ["along the step", rf"cone $\mu$ = {mu:g}",
                  r"inscribed pyramid $\mu/\sqrt{2}$ (not used)"]
        if clipped:
            labels[0] += rf" (clipped at {top:g})"
        a_r.legend([Line2D([], [], color="k", lw=0.8), Line2D([], [], color="firebrick", lw=0.8),
                    Line2D([], [], color="firebrick", ls=":", lw=0.6)], labels, loc="best")
        a_u.set_ylabel(r"joint torque $u$ [N m]")
        a_u.legend([Line2D([], [], color="k", ls=dashes[j % len(dashes)], lw=0.8)
                    for j in range(len(joint_names))], joint_names, loc="best")
        a_h.plot(swing["alpha"], 1e3 * swing["height"], color="k", lw=0.8, label="swing foot")
        a_h.axhline(0.0, color="firebrick", lw=0.6, ls=":", label="ground")
        a_h.set_ylabel("swing-foot height [mm]")
        a_h.legend(loc="best")
        for ax in (a_f, a_r, a_u, a_h):
            ax.set_xlabel(r"$\alpha$ [rad]")
        _impact_panels(a_i, a_k, impacts or [], values, colour, mu)
        if sweep:
            sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
            cb = fig.colorbar(sm, ax=axs, pad=0.01, fraction=0.03, aspect=40)
            cb.set_label(value_label)
        if title:
            fig.suptitle(title)
        missing = [i for i in range(len(profiles)) if profiles[i] is None]
        if missing and values is not None:
            corner_note(a_f, missing_note([values[i] for i in missing]))
    return fig


def _impact_panels(a_i, a_k, impacts, values, colour, mu) -> None:
    """Impact impulse F_2 [N s] (horizontal, vertical) and its friction ratio per case."""
    x = (np.asarray(values, float) if values is not None and len(values) == len(impacts)
         else np.arange(len(impacts), dtype=float))
    have = [i for i, imp in enumerate(impacts) if imp.get("impulse") is not None]
    for i in have:
        h, v = impacts[i]["impulse"]
        a_i.plot([x[i]], [v], "o", ms=3.5, color=colour[i], mec="k", mew=0.3)
        a_i.plot([x[i]], [h], "s", ms=3.0, color=colour[i], mec="k", mew=0.3)
    a_i.axhline(0.0, color="0.5", lw=0.5)
    a_i.set_ylabel(r"impact impulse $F_2$ [N s]")
    a_i.legend([Line2D([], [], marker="o", ls="none", color="0.6", mec="k", ms=3.5),
                Line2D([], [], marker="s", ls="none", color="0.6", mec="k", ms=3.0)],
               [r"vertical $F_2^v$", r"horizontal $F_2^h$"], loc="best")
    ratios = [(x[i], impacts[i]["ratio"]) for i in have if impacts[i].get("ratio") is not None]
    if ratios:
        a_k.plot(*zip(*ratios), "o-", ms=3.0, color="k", lw=0.6)
    a_k.axhline(mu, color="firebrick", lw=0.8, label=rf"cone $\mu$ = {mu:g}")
    a_k.set_ylim(0.0, max([mu * 1.3] + [r for _, r in ratios]))
    a_k.set_ylabel(r"impact $|F_2^h|/F_2^v$ [-]")
    a_k.legend(loc="best")
    xl = "thrust [N]" if values is not None and len(values) == len(impacts) else "case"
    for ax in (a_i, a_k):
        ax.set_xlabel(xl)
        if not have:
            ax.text(0.5, 0.5, "no periodic orbit", transform=ax.transAxes, ha="center",
                    color="firebrick")


def region_figure(region, *, scale_label: str, mu: float, eps: float,
                  cases: Sequence[tuple[float, float | None]] = (), title: str = ""):
    """Feasible region over (scale, zeta^-), one column wide: colour = worst friction ratio
    along the step where it completes with F^v > 0 (colour bar extended beyond its top);
    grey = the walker stops; hatched = unilateral contact lost (F^v <= 0); cyan = the boundary
    of each contact condition (contours of continuous fields, no grid staircase); the
    fixed-point curve (solid where feasible), the nominal point and the evaluated cases. The
    legend sits below the axes, off the data."""
    with style():
        fig, ax = plt.subplots(figsize=(COLUMN, 3.6))
        S, Z = np.meshgrid(region.scale, region.zeta, indexing="ij")
        minz = (region.min_zeta if region.min_zeta is not None
                else np.where(region.completes, 1.0, -1.0))
        lost = region.min_vertical <= 0
        # the colour field is continuous everywhere (no masked cells, so no white staircase);
        # the regions where it does not apply are painted over it
        ratio = np.where(np.isfinite(region.max_ratio), region.max_ratio, np.inf)
        vmax = max(1.5 * mu, 1e-3)
        levels = np.linspace(0.0, vmax, 16)
        cs = ax.contourf(S, Z, np.minimum(ratio, vmax * 1.2), levels=levels, cmap="magma_r",
                         extend="max")
        cb = fig.colorbar(cs, ax=ax, pad=0.02)
        cb.set_label(r"worst friction ratio $|F_1^h|/F_1^v$ [-]")
        cb.ax.axhline(mu, color="c", lw=1.0)
        grey = matplotlib.colormaps["Greys"](0.45)
        pale = "#d6e6f4"
        if lost.any():
            fv = region.min_vertical
            ax.contourf(S, Z, fv, levels=[fv.min() - 1.0, 0.0], colors=[pale])
            ax.contourf(S, Z, fv, levels=[fv.min() - 1.0, 0.0], colors="none",
                        hatches=["////"])
        if (minz <= 0).any():
            ax.contourf(S, Z, minz, levels=[minz.min() - 1.0, 0.0], colors=[grey])
        handles = [matplotlib.patches.Patch(color=grey, label="walker stops"),
                   matplotlib.patches.Patch(facecolor=pale, edgecolor="0.3", hatch="////",
                                            label="contact lost ($F_1^v \\leq 0$)")]
        ok = minz > 0
        for field_, level in ((np.where(ok, region.max_ratio, np.nan), mu),
                              (np.where(ok, region.min_vertical, np.nan), eps)):
            f = np.ma.masked_invalid(np.where(np.isfinite(field_), field_, np.nan))
            if f.count() and f.min() < level < f.max():
                ax.contour(S, Z, f, levels=[level], colors="c", linewidths=1.2)
        handles.append(Line2D([], [], color="c", lw=1.2, label=rf"contact limits ($\mu$ = "
                              rf"{mu:g}, $F_1^v \geq$ {eps:g} N)"))
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
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2,
                  fontsize=6)
        if not region.impact_ok:
            ax.text(0.5, 0.02, "impact inadmissible everywhere", transform=ax.transAxes,
                    ha="center", color="firebrick", fontsize=7)
        if title:
            ax.set_title(title)
        fig.tight_layout()
    return fig
