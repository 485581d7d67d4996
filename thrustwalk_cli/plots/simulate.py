"""Figures of ``thrustwalk simulate`` (SPEC 8 figures 1-2), rendered from figure data built by
:func:`simulate_records.figure_data` and :func:`simulate_records.animation_frames`."""

from __future__ import annotations

import io

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from .style import is_multiple, style


def _sweep_colors(values: list[float | None], black_every: float | None):
    vals = np.array([0.0 if v is None else v for v in values], float)
    lo, hi = (vals.min(), vals.max()) if vals.size else (0.0, 1.0)
    norm = matplotlib.colors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1)
    cmap = matplotlib.colormaps["viridis"]
    colors = []
    for v in vals:
        black = black_every is not None and is_multiple(v, black_every)
        colors.append("k" if black else cmap(norm(v)))
    return norm, cmap, colors


def thrust_time(data: dict, *, black_every: float | None = 10.0, title: str = ""):
    """F_T(t) of every run [N vs s] (the paper's slow-thruster figure): one line per F_ss,
    black at multiples of ``black_every``, a colour bar for the sweep. Piecewise thrust: one
    line per thruster, or the generalised force T [N m] in generalised mode."""
    runs = data["runs"]
    with style():
        fig, ax = plt.subplots(figsize=(3.5, 2.6))
        unit = "N"
        if data["kind"] == "piecewise" and data.get("generalized"):
            r = runs[0]
            ax.plot(r["t"], r["T"], color="k", label="generalised force T on $q_N$")
            ax.legend(loc="best")
            unit = "N m"
        elif data["kind"] == "piecewise":
            r = runs[0]
            for j, name in enumerate(data["thruster_names"]):
                if r["thrust"].size:
                    ax.plot(r["t"], r["thrust"][:, j], label=name)
            ax.legend(loc="best")
        else:
            norm, cmap, colors = _sweep_colors([r["value"] for r in runs], black_every)
            for r, col in zip(runs, colors):
                if r["t"].size:
                    ax.plot(r["t"], r["thrust"], color=col, lw=0.9 if col == "k" else 0.7,
                            ls=":" if r["failed"] else "-")
            sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
            cb = fig.colorbar(sm, ax=ax, pad=0.02)
            cb.set_label(r"$F_{ss}$ [N]")
            handles = [matplotlib.lines.Line2D([], [], color="k", lw=0.9)]
            labels = [f"every {black_every:g} N" if black_every else "run"]
            if any(r["failed"] for r in runs):
                handles.append(matplotlib.lines.Line2D([], [], color="gray", ls=":", lw=0.7))
                labels.append("run stopped (see simulation.json)")
            ax.legend(handles, labels, loc="best")
        driven = ", ".join(data["driven"]) or "schedule"
        ax.set_xlabel("time $t$ [s]")
        ax.set_ylabel(f"thrust $F_T$ ({driven}) [{unit}]" if unit == "N"
                      else f"schedule $T$ [{unit}]")
        ax.set_title(title or f"thrust history ({data['kind']})")
        fig.tight_layout()
    return fig


def phase_portrait(data: dict, *, black_every: float | None = 10.0, title: str = ""):
    """alpha' vs alpha [rad/s vs rad] over all steps of every run (impacts dashed), with the
    zero-dynamics limit cycle each run should converge to (grey dotted)."""
    runs = data["runs"]
    with style():
        fig, ax = plt.subplots(figsize=(3.5, 2.7))
        norm, cmap, colors = _sweep_colors([r["value"] for r in runs], black_every)
        for r, col in zip(runs, colors):
            if r["predicted"] is not None:
                ax.plot(r["predicted"]["alpha"], r["predicted"]["alpha_dot"], color="0.55",
                        ls=":", lw=0.8, zorder=1)
            prev = None
            for st in r["steps"]:
                ax.plot(st["alpha"], st["alpha_dot"], color=col,
                        lw=0.8 if col == "k" else 0.6, zorder=3 if col == "k" else 2)
                if prev is not None:
                    ax.plot([prev[0], st["alpha"][0]], [prev[1], st["alpha_dot"][0]],
                            color=col, ls="--", lw=0.4, alpha=0.5, zorder=1)
                prev = (st["alpha"][-1], st["alpha_dot"][-1])
        if data["kind"] != "piecewise":
            sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
            cb = fig.colorbar(sm, ax=ax, pad=0.02)
            cb.set_label(r"$F_{ss}$ [N]")
        handles = [matplotlib.lines.Line2D([], [], color="k", lw=0.8),
                   matplotlib.lines.Line2D([], [], color="gray", ls="--", lw=0.4),
                   matplotlib.lines.Line2D([], [], color="0.55", ls=":", lw=0.8)]
        labels = [f"{data['model']} simulation", "impact", "zero-dynamics orbit at $F_{ss}$"]
        ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=3,
                  fontsize=6, handlelength=1.5, columnspacing=1.0)
        ax.set_xlabel(r"$\alpha$ [rad]")
        ax.set_ylabel(r"$\dot\alpha$ [rad/s]")
        ax.set_title(title or "limit cycles under the thrust history")
        fig.tight_layout()
    return fig


def animate(frames: dict, fps: float = 20.0) -> bytes:
    """Stick-figure GIF of the walker [m] with thrust arrows (the largest thrust drawn 0.3 m
    long; the scale is in the title); needs Pillow (a matplotlib dependency). Returns the
    GIF bytes (rendered in memory, frame by frame, as matplotlib's PillowWriter does)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    links, pts, vec = frames["links"], frames["points"], frames["thrust"]
    big = float(np.abs(vec).max()) if vec.size else 0.0
    scale = 0.3 / big if big > 0 else 0.0  # m per N
    xs = np.concatenate([links[..., 0].ravel(), (pts[..., 0] + scale * vec[..., 0]).ravel()])
    ys = np.concatenate([links[..., 1].ravel(), (pts[..., 1] + scale * vec[..., 1]).ravel()])
    with style():
        fig, ax = plt.subplots(figsize=(5.0, 2.8))
        ax.set_aspect("equal")
        ax.set_xlim(xs.min() - 0.2, xs.max() + 0.2)
        ax.set_ylim(min(ys.min(), 0.0) - 0.1, ys.max() + 0.2)
        ax.axhline(0.0, color="0.3", lw=0.8)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        lines = [ax.plot([], [], color="k", lw=1.6, solid_capstyle="round")[0]
                 for _ in range(links.shape[1])]
        arrows = [ax.annotate("", xy=(0, 0), xytext=(0, 0),
                              arrowprops={"arrowstyle": "->", "color": "tab:red", "lw": 1.2})
                  for _ in range(pts.shape[1])]
        label = ax.text(0.01, 0.97, "", transform=ax.transAxes, va="top", fontsize=7)
        ax.set_title(f"{frames['title']} (thrust arrows: {100 * scale:.3g} cm per N)"
                     if scale else frames["title"])
        fig.tight_layout()

        def draw(i):
            for ln, seg in zip(lines, links[i]):
                ln.set_data(seg[:, 0], seg[:, 1])
            for ar, p, v in zip(arrows, pts[i], vec[i]):
                ar.xy = (p[0] + scale * v[0], p[1] + scale * v[1])
                ar.set_position((p[0], p[1]))
            label.set_text(f"t = {frames['t'][i]:.2f} s")
            return lines + arrows + [label]

        fig.set_dpi(80)
        canvas = FigureCanvasAgg(fig)
        images = []
        try:
            for i in range(len(frames["t"])):
                draw(i)
                canvas.draw()
                images.append(Image.frombuffer("RGBA", canvas.get_width_height(),
                                               canvas.buffer_rgba()).copy())
        finally:
            plt.close(fig)
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:],
                   duration=int(1000 / fps), loop=0)
    return buf.getvalue()
