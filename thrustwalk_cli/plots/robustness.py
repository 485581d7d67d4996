"""Figures of ``thrustwalk robustness`` (SPEC 12), from the figure data of
:meth:`thrustwalk_cli.studies.robustness_result.RobustnessResult.figure_data`: the outcome of every
push trial over (phase, impulse) per strategy, the largest survivable push against phase, the
basins of attraction (reduced and full-order slices) and the spread of the converged speed
under parameter uncertainty. Colours that encode a category come with a legend."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from .style import COLUMN, PAGE, corner_note, layout, style

OUTCOME_COLOURS = {
    "recovered": "#2ca02c", "unsettled": "#bcbd22", "fell": "#8c1c13", "slipped": "#ff7f0e",
    "lifted": "#9467bd", "scuffed": "#8c564b", "stopped": "#1f77b4", "error": "0.55",
    "not run": "white",
}
STRATEGY_COLOURS = ("k", "tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange",
                    "tab:brown", "tab:pink")


def _edges(v) -> np.ndarray:
    """Cell edges around grid values (midpoints; the ends half a spacing out)."""
    v = np.asarray(v, float)
    if v.size == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _category_mesh(ax, x, y, grid, names):
    """Cells of ``grid`` (rows along ``x``, columns along ``y``) coloured by category;
    returns the categories present."""
    index = {n: i for i, n in enumerate(names)}
    codes = np.array([[index["not run" if o is None else o] for o in row] for row in grid],
                     float)
    cmap = ListedColormap([OUTCOME_COLOURS[n] for n in names])
    ax.pcolormesh(_edges(x), _edges(y), codes.T, cmap=cmap, vmin=-0.5,
                  vmax=len(names) - 0.5, shading="flat", edgecolors="face", lw=0)
    return {names[int(c)] for c in np.unique(codes)}


def _legend(fig, present, names, ncol):
    handles = [Patch(facecolor=OUTCOME_COLOURS[n], edgecolor="0.3", lw=0.4, label=n)
               for n in names if n in present]
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=6, frameon=False)


def push_map(d: dict, title: str = ""):
    """Outcome of every push trial over phase s [1] (x) and impulse [N s] (y, positive along
    the push direction), one panel per strategy."""
    names = list(d["outcomes"]) + ["not run"]
    n = len(d["labels"])
    with style():
        fig = Figure(figsize=(COLUMN if n == 1 else PAGE, 2.7))
        axes = fig.subplots(1, n, sharey=True, squeeze=False)
        present: set[str] = set()
        for k, ax in enumerate(axes[0]):
            present |= _category_mesh(ax, d["phases"], d["impulses"], d["push_maps"][k], names)
            ax.axhline(0.0, color="k", lw=0.4)
            ax.set_xlabel("push phase $s$ [1]")
            s = d["summary"][k]
            ax.set_title(f"{d['labels'][k]}" + (f" (mean {s:.3g} N s)" if s is not None
                                                 else ""), fontsize=7)
        axes[0][0].set_ylabel("impulse [N s]")
        _legend(fig, present, names, ncol=min(len(present), 5))
        if title:
            fig.suptitle(title)
        layout(fig, rect=(0, 0.1, 1, 1))
    return fig


def push_energy(d: dict, title: str = ""):
    """Energy spent per recovered push trial [J] over phase s [1] (x) and impulse [N s] (y),
    one panel per strategy on one colour scale (colour bar in J): the total energy (joints'
    electrical + thrusters' input) when every model is given, else the mechanical one
    (positive work of joints and thrusters), SPEC 15; blank where the trial did not recover
    (the push map says why). The panel's title gives the mean per recovered push."""
    n = len(d["labels"])
    grids = [np.array([[np.nan if v is None else v for v in row] for row in g], float)
             .reshape(len(d["phases"]), len(d["impulses"])) for g in d["push_energy"]]
    finite = np.concatenate([g[np.isfinite(g)] for g in grids]) if grids else np.zeros(0)
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5
    with style():
        fig = Figure(figsize=(COLUMN if n == 1 else PAGE, 2.7))
        axes = fig.subplots(1, n, sharey=True, squeeze=False)
        mesh = None
        for k, ax in enumerate(axes[0]):
            mesh = ax.pcolormesh(_edges(d["phases"]), _edges(d["impulses"]),
                                 np.ma.masked_invalid(grids[k]).T, cmap="viridis", vmin=lo,
                                 vmax=hi, shading="flat", edgecolors="face", lw=0)
            ax.axhline(0.0, color="k", lw=0.4)
            ax.set_xlabel("push phase $s$ [1]")
            e = d["energy_mean"][k]
            ax.set_title(f"{d['labels'][k]}" + (f" (mean {e:.3g} J)" if e is not None
                                                 else " (none recovered)"), fontsize=7)
            if not np.isfinite(grids[k]).any():
                corner_note(ax, "no recovered push")
        axes[0][0].set_ylabel("impulse [N s]")
        if title:
            fig.suptitle(title)
        layout(fig, rect=(0, 0, 0.88, 1))
        if mesh is not None:
            bar = fig.colorbar(mesh, cax=fig.add_axes((0.9, 0.2, 0.015, 0.65)))
            bar.set_label(f"{d['energy_kind']} energy per recovered push [J]")
    return fig


def survivable_push(d: dict, title: str = ""):
    """Largest survivable push [N s] against phase [1], forward (above 0) and backward (below,
    as a negative impulse), one colour per strategy; open triangles where the value is only a
    lower bound (the scan reached the grid's edge), crosses where it stopped at a trial that
    could not be computed or was not run."""
    with style():
        fig = Figure(figsize=(COLUMN, 2.8))
        ax = fig.subplots()
        ph = np.asarray(d["phases"], float)
        for k, label in enumerate(d["labels"]):
            c = STRATEGY_COLOURS[k % len(STRATEGY_COLOURS)]
            rows = d["survivable"][k]
            s = d["summary"][k]
            lab = label + (f" (mean {s:.3g} N s)" if s is not None else "")
            for key, sign in (("forward", 1.0), ("backward", -1.0)):
                v = np.array([np.nan if r[key] is None else sign * r[key] for r in rows])
                if np.all(np.isnan(v)):
                    continue
                ax.plot(ph, v, "-", color=c, lw=0.9, label=lab)
                lab = None
                edge = np.array([r[f"{key}_bound"] == "grid edge" for r in rows])
                stop = np.array([r[f"{key}_bound"] in ("error", "not run") for r in rows])
                if edge.any():
                    ax.plot(ph[edge], v[edge], "^" if sign > 0 else "v", mfc="none", color=c,
                            ms=3)
                if stop.any():
                    ax.plot(ph[stop], v[stop], "x", color=c, ms=3)
        ax.axhline(0.0, color="0.5", lw=0.5)
        ax.set_xlabel("push phase $s$ [1]")
        ax.set_ylabel("survivable impulse [N s]")
        ax.text(0.01, 0.98, "forward", transform=ax.transAxes, ha="left", va="top",
                fontsize=6, color="0.4")
        ax.text(0.01, 0.02, "backward", transform=ax.transAxes, ha="left", va="bottom",
                fontsize=6, color="0.4")
        fig.legend(loc="lower center", ncol=min(3, len(d["labels"])), fontsize=6,
                   frameon=False)
        if title:
            ax.set_title(title)
        layout(fig, rect=(0, 0.1, 1, 1))
    return fig


def basin(d: dict, title: str = ""):
    """Top: the reduced basin of each strategy, the interval of zeta^- [kg^2 m^4/s^2] of the
    impact that starts a step from which the reduced walker converges (SPEC 12; log axis), with
    its fixed point. Bottom (with a slice): per strategy the full-order trials started off the
    orbit, over the relative change of sigma_N^+ [1] and the rate of one output [rad/s],
    converging or not; dashed: the reduced basin's ends at zero rate."""
    slices = d["slices"]
    n = max(1, len(slices))
    with style():
        fig = Figure(figsize=(COLUMN if n == 1 else PAGE, 2.0 + (2.3 if slices else 0)))
        gs = fig.add_gridspec(2 if slices else 1, n, height_ratios=[1, 1.6] if slices else [1])
        ax = fig.add_subplot(gs[0, :])
        notes = []
        for k, r in enumerate(d["reduced"]):
            c = STRATEGY_COLOURS[k % len(STRATEGY_COLOURS)]
            lo, hi = r["lower"]["zeta_minus"], r["upper"]["zeta_minus"]
            zs = r["zeta_star"]
            if r["exists"] and lo is not None and hi is not None:
                ax.plot([max(lo, 1e-9), hi], [k, k], "-", color=c, lw=4, solid_capstyle="butt")
                ax.text(hi, k, f"  {r['upper']['family']}", va="center", fontsize=5)
            else:
                notes.append(f"{r['label']}: no basin")
            if zs:
                ax.plot([zs], [k], "o", color="w", mec="k", ms=3.5, zorder=3)
        ax.set_yticks(range(len(d["reduced"])), [r["label"] for r in d["reduced"]],
                      fontsize=6)
        ax.set_ylim(-0.6, len(d["reduced"]) - 0.4)
        ax.set_xscale("log")
        ax.set_xlabel(r"$\zeta^-$ of the impact starting a step [kg$^2$ m$^4$/s$^2$]"
                      " (o: fixed point)")
        corner_note(ax, "; ".join(notes))
        names = ["converging", "not converging", "error", "not run"]
        colours = {"converging": OUTCOME_COLOURS["recovered"], "not converging": "#f4b6b6",
                   "error": OUTCOME_COLOURS["error"], "not run": "white"}
        for k, sl in enumerate(slices):
            axs = fig.add_subplot(gs[1, k])
            grid = [[("not run" if o is None else "error" if o == "error" else
                      "converging" if c else "not converging")
                     for o, c in zip(orow, crow)]
                    for orow, crow in zip(sl["outcomes"], sl["converging"])]
            index = {nm: i for i, nm in enumerate(names)}
            codes = np.array([[index[g] for g in row] for row in grid], float)
            axs.pcolormesh(_edges(d["sigmas"]), _edges(d["rates"]), codes.T,
                           cmap=ListedColormap([colours[nm] for nm in names]), vmin=-0.5,
                           vmax=len(names) - 0.5, shading="flat")
            for v in sl["reduced_sigma"]:
                if v is not None and sl["basin_exists"]:
                    axs.axvline(v, color="k", ls="--", lw=0.7)
            frac = sl["fraction"]
            axs.set_title(f"{sl['label']}: {frac:.0%} converge" if frac is not None
                          else sl["label"], fontsize=7)
            axs.set_xlabel(r"change of $\sigma_N^+$ [1]")
            if k == 0:
                axs.set_ylabel(f"rate of output {d['joint']} [rad/s]")
        if slices:
            fig.legend(handles=[Patch(facecolor=colours[nm], edgecolor="0.3", lw=0.4,
                                      label=nm) for nm in names[:3]]
                       + [Line2D([], [], color="k", ls="--", lw=0.7,
                                     label="reduced basin")],
                       loc="lower center", ncol=4, fontsize=6, frameon=False)
        if title:
            fig.suptitle(title)
        layout(fig, rect=(0, 0.06 if slices else 0, 1, 1))
    return fig


def uncertainty(d: dict, title: str = ""):
    """Left: the converged average speed of the samples that walk relative to the nominal
    robot's under the same strategy [%], per strategy (box: quartiles, whiskers: 5-95 %,
    points: samples). Right: the fraction of samples that walk [1] per strategy."""
    with style():
        fig = Figure(figsize=(PAGE, 2.4))
        (ax, ax2) = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.2, 1]})
        rng = np.random.default_rng(0)  # jitter of the sample markers only
        labels = [s["label"] for s in d["uncertainty"]]
        notes = []
        for k, s in enumerate(d["uncertainty"]):
            c = STRATEGY_COLOURS[k % len(STRATEGY_COLOURS)]
            nom = d["nominal_speed"][k]
            if not s["speeds"] or not nom:
                notes.append(f"{s['label']}: no sample walks" if not s["speeds"] else
                             f"{s['label']}: no nominal orbit")
                continue
            rel = 100.0 * (np.asarray(s["speeds"], float) / nom - 1.0)
            ax.boxplot([rel], positions=[k], widths=0.5, whis=(5, 95), showfliers=False,
                       medianprops={"color": c}, boxprops={"color": c},
                       whiskerprops={"color": c}, capprops={"color": c})
            ax.plot(k + rng.uniform(-0.18, 0.18, rel.size), rel, ".", color=c, ms=2,
                    alpha=0.5)
        ax.axhline(0.0, color="0.5", lw=0.5)
        ax.set_xticks(range(len(labels)), labels, fontsize=6)
        ax.set_xlim(-0.6, len(labels) - 0.4)
        ax.set_ylabel("converged speed vs nominal [%]")
        corner_note(ax, "; ".join(notes))
        rates = [np.nan if s["rate"] is None else s["rate"] for s in d["uncertainty"]]
        ax2.bar(range(len(rates)), rates, color=[STRATEGY_COLOURS[k % len(STRATEGY_COLOURS)]
                                                 for k in range(len(rates))])
        for k, s in enumerate(d["uncertainty"]):
            ax2.text(k, 0.02, f"n = {s['valid']}", ha="center", va="bottom", fontsize=5,
                     color="w")
        ax2.set_xticks(range(len(rates)), labels, fontsize=6)
        ax2.set_ylim(0, 1.05)
        ax2.set_ylabel("fraction that walks [1]")
        if title:
            fig.suptitle(title)
        layout(fig)
    return fig
