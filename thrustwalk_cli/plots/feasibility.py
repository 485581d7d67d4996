"""Figures of ``thrustwalk feasibility`` (SPEC 5): ground forces along the step and the
feasible region. Plain data in."""

from __future__ import annotations

from collections.abc import Sequence

import contourpy  # matplotlib's own contouring library (a dependency of matplotlib >= 3.6)
import matplotlib
import numpy as np
from matplotlib import patheffects
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from .style import COLUMN, PAGE, corner_note, layout, missing_note, style

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

    The torque panel draws one curve per actuated joint whatever the number of cases (at most
    N-1 curves): for one case its signed torque u_j(alpha) [N m]; for several cases the worst
    case, the envelope ``max_cases |u_j(alpha)|`` over every case with an orbit (not only the
    cases drawn in the other panels), with its peak and the thrust that reaches it in the
    legend. Per-case peaks are in the JSON (``max_abs_torque``).

    ``profiles[i]``: dict with ``alpha`` [rad], ``F1`` (g, 2) [N], ``ratio`` (g,), ``torque``
    (g, N-1) [N m] or None (no orbit). ``values``: the swept thrust [N] (colour bar) or None for
    a single schedule. ``impacts[i]``: ``{"impulse": (h, v) [N s] or None, "ratio": float or
    None}``.
    """
    with style():
        fig = Figure(figsize=(PAGE, 6.2), layout="constrained")
        axs = fig.subplots(3, 2)
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
        _torque_panel(a_u, profiles, values, joint_names, dashes)
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
        layout(fig)  # constrained, once: not again for every saved format
    return fig


def _on_grid(a: np.ndarray, alpha, values) -> np.ndarray:
    """``values`` (g, k) sampled at ``alpha``, on the grid ``a`` (linear interpolation; the
    samples themselves when the grids agree)."""
    alpha, values = np.asarray(alpha, float), np.asarray(values, float)
    if alpha.shape == a.shape and np.allclose(alpha, a, rtol=0.0, atol=1e-12):
        return values
    order = np.argsort(alpha)
    return np.column_stack([np.interp(a, alpha[order], values[order, j])
                            for j in range(values.shape[1])])


def _torque_panel(ax, profiles, values, joint_names, dashes) -> None:
    """One curve per joint: the signed torque u_j [N m] of a single case, or the envelope
    ``max_cases |u_j(alpha)|`` [N m] over several (on the first case's alpha grid)."""
    have = [i for i, p in enumerate(profiles) if p is not None]
    ls = [dashes[j % len(dashes)] for j in range(len(joint_names))]
    colour = ["k" if j < len(dashes) else "0.55" for j in range(len(joint_names))]
    if not have:
        ax.set_ylabel(r"joint torque $u$ [N m]")
        ax.text(0.5, 0.5, "no periodic orbit", transform=ax.transAxes, ha="center",
                color="firebrick")
        return
    a = np.asarray(profiles[have[0]]["alpha"], float)
    if len(have) == 1:
        u = np.asarray(profiles[have[0]]["torque"], float)
        for j, name in enumerate(joint_names):
            ax.plot(a, u[:, j], color=colour[j], ls=ls[j], lw=0.8, label=name)
        ax.set_ylabel(r"joint torque $u$ [N m]")
        ax.legend(loc="best")
        return
    absu = np.stack([np.abs(_on_grid(a, profiles[i]["alpha"], profiles[i]["torque"]))
                     for i in have])  # (cases, g, joints)
    env = absu.max(axis=0)
    for j, name in enumerate(joint_names):
        k = int(np.argmax(env[:, j]))
        case = have[int(np.argmax(absu[:, k, j]))]
        at = (f" at {values[case]:g} N" if values is not None and len(values) == len(profiles)
              else f" (case {case + 1})")
        ax.plot(a, env[:, j], color=colour[j], ls=ls[j], lw=0.8,
                label=f"{name}: peak {env[k, j]:.3g} N m{at}")
    ax.set_ylim(0.0, 1.5 * max(float(env.max()), 1e-9))  # headroom for the legend
    ax.set_ylabel(r"worst joint torque $\max|u|$ [N m]")
    ax.legend(loc="upper center", ncol=2, fontsize=6, title_fontsize=6,
              title=f"max over the {len(have)} cases, each joint")


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


# the infeasible regions of the feasible-region figure, painted in this order (later on top):
# (face colour, hatch, hatch colour) per condition; every one is hatched
LIMITS_STYLE = ("none", "\\\\\\\\", "0.7")  # friction cone / F^v >= eps / impact: over the colours
LOST_STYLE = ("#d6e6f4", "////", "0.3")  # unilateral contact lost, F^v <= 0
STOPS_STYLE = (matplotlib.colors.to_hex(matplotlib.colormaps["Greys"](0.45)), "xxx", "0.25")
BOUNDARY = {"colors": "c", "linewidths": 1.2}  # the contact-limit contours
HALO = [patheffects.withStroke(linewidth=2.6, foreground="w")]  # fixed points over dark colours


def _hatch_where_negative(ax, x, y, field, style_, zorder: float, label: str) -> list:
    """Hatched patches over ``{field <= 0}`` of a continuous field on the (x, y) grid (its
    linear-interpolation contour at 0, no grid staircase): one PathPatch per polygon (holes
    included), the first one labelled. ``style_``: (face, hatch, hatch colour)."""
    face, hatch, colour = style_
    f = np.ma.masked_invalid(np.asarray(field, float))
    if not f.count() or f.min() > 0:
        return []
    gen = contourpy.contour_generator(x, y, f.T, fill_type="OuterCode")
    points, codes = gen.filled(float(f.min()) - 1.0, 0.0)
    out = []
    for pts, cds in zip(points, codes):
        patch = matplotlib.patches.PathPatch(
            matplotlib.path.Path(pts, cds), facecolor=face, edgecolor=colour, hatch=hatch,
            lw=0.0, zorder=zorder, label=label if not out else "_nolegend_")
        ax.add_patch(patch)
        out.append(patch)
    return out


def region_figure(region, *, scale_label: str, mu: float, eps: float,
                  cases: Sequence[tuple[float, float | None]] = (), title: str = ""):
    """Feasible region over (scale, zeta^-), one column wide (SPEC 5).

    Colour = worst friction ratio |F^h|/F^v [-] along the step (colour bar extended beyond its
    top). Every infeasible cell of ``region.feasible`` lies under a hatched patch, whatever the
    number of disjoint infeasible regions, each hatch naming its condition (painted in this
    order, the later on top): the contact limits (friction cone ``|F^h| <= mu F^v``,
    ``F^v >= eps`` and, when inadmissible, the impact) hatched over the colours; unilateral
    contact lost (``F^v <= 0``, pale); the walker stops (``zeta <= 0`` in the step, grey). The
    boundaries are the 0-contours of continuous margins (no grid staircase); cyan = the
    boundary of each contact condition where the step completes. The fixed-point curve (solid
    where feasible, dotted where not, both outlined in white), the nominal point and the
    evaluated cases. Every legend entry is the drawn artist itself (same colour, line style,
    width, marker, hatch), and only what is drawn has one. The legend sits below the axes.

    ``region``: plain arrays ``scale`` (ns,), ``zeta`` (nz,) [kg^2 m^4/s^2], ``min_vertical``
    [N], ``max_ratio`` [-] (inf where F^v <= 0), ``completes``, ``feasible``, ``min_zeta``
    (ns, nz) or None, ``fixed_point`` (ns,), ``fixed_point_valid``, ``fixed_point_feasible``,
    ``impact_ok``.
    """
    with style():
        fig = Figure(figsize=(COLUMN, 3.6))
        ax = fig.subplots()
        x, y = np.asarray(region.scale, float), np.asarray(region.zeta, float)
        S, Z = np.meshgrid(x, y, indexing="ij")
        minz = (region.min_zeta if region.min_zeta is not None
                else np.where(region.completes, 1.0, -1.0))
        fv = np.asarray(region.min_vertical, float)
        # the colour field is continuous everywhere (no masked cells, so no white staircase);
        # the regions where it does not apply are painted over it
        ratio = np.asarray(region.max_ratio, float)
        ratio = np.where(np.isnan(ratio), np.inf, ratio)  # no ratio: the cone is not met
        vmax = max(1.5 * mu, 1e-3)
        levels = np.linspace(0.0, vmax, 16)
        cs = ax.contourf(S, Z, np.minimum(ratio, vmax * 1.2), levels=levels, cmap="magma_r",
                         extend="max")
        cb = fig.colorbar(cs, ax=ax, pad=0.02)
        cb.set_label(r"worst friction ratio $|F_1^h|/F_1^v$ [-]")
        cb.ax.axhline(mu, color="c", lw=1.0)
        # the contact limits as one continuous margin, <= 0 exactly where F^v <= eps or the
        # ratio >= mu (each term scaled to order one; the ratio is capped, far above mu)
        fscale = max(float(np.max(np.abs(fv))), 1.0)
        limits = np.minimum((fv - eps) / fscale, (mu - np.minimum(ratio, 10.0 * mu)) / mu)
        what = [r"$|F_1^h| > \mu F_1^v$"] + ([rf"$F_1^v <$ {eps:g} N"] if eps > 0 else [])
        if not region.impact_ok:
            limits = np.full_like(limits, -1.0)
            what.append("impact inadmissible")
        handles = []  # the drawn artists themselves (a proxy only for the contours)
        for field_, style_, z, label in (
                (limits, LIMITS_STYLE, 1.5, " or ".join(what)),
                (fv, LOST_STYLE, 1.6, r"contact lost ($F_1^v \leq 0$)"),
                (minz, STOPS_STYLE, 1.7, r"walker stops ($\zeta \leq 0$)")):
            handles += _hatch_where_negative(ax, x, y, field_, style_, z, label)[:1]
        ok = minz > 0
        drawn = False
        for field_, level in ((np.where(ok, ratio, np.nan), mu),
                              (np.where(ok, fv, np.nan), eps)):
            f = np.ma.masked_invalid(np.where(np.isfinite(field_), field_, np.nan))
            if f.count() and f.min() < level < f.max():
                ax.contour(S, Z, f, levels=[level], zorder=2, **BOUNDARY)
                drawn = True
        if drawn:
            handles.append(Line2D([], [], color=BOUNDARY["colors"], lw=BOUNDARY["linewidths"],
                                  label=rf"contact limits ($\mu$ = {mu:g}, $F_1^v \geq$ "
                                        rf"{eps:g} N)"))
        v = np.asarray(region.fixed_point_valid, bool)
        if v.any():
            zs = np.where(v, region.fixed_point, np.nan)
            good = np.asarray(region.fixed_point_feasible, bool)
            if good.any():
                handles += ax.plot(x, np.where(good, zs, np.nan), color="k", lw=1.2,
                                   path_effects=HALO, zorder=3,
                                   label=r"fixed points $\zeta^*$ (feasible)")
            if (v & ~good).any():
                handles += ax.plot(x, np.where(good, np.nan, zs), color="k", lw=1.0, ls=":",
                                   path_effects=HALO, zorder=3,
                                   label=r"fixed points $\zeta^*$ (infeasible)")
        zero = np.argmin(np.abs(x))
        if v[zero] and abs(x[zero]) < 1e-12:
            handles += ax.plot([0.0], [region.fixed_point[zero]], marker="*", color="gold",
                               ms=9, mec="k", ls="none", zorder=4, label="nominal (no thrust)")
        pts = [(s, z) for s, z in cases if z is not None]
        if pts:
            handles += ax.plot(*zip(*pts), marker="o", ms=3.5, color="c", mec="k", ls="none",
                               zorder=4, label="evaluated cases")
        ax.set_xlabel(scale_label)
        ax.set_ylabel(r"pre-impact $\zeta^-$ [kg$^2$ m$^4$/s$^2$]")
        ax.set_xlim(x.min(), x.max())
        ax.set_ylim(y.min(), y.max())
        ax.grid(False)
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2,
                  fontsize=6)
        if not region.impact_ok:
            ax.text(0.5, 0.02, "impact inadmissible everywhere", transform=ax.transAxes,
                    ha="center", color="firebrick", fontsize=7, zorder=5)
        if title:
            ax.set_title(title)
        layout(fig)
    return fig
