"""Figures of ``thrustwalk simulate`` (SPEC 8 figures 1-2), rendered from figure data built by
:func:`thrustwalk_cli.studies.simulate_result.figure_data` and
:func:`thrustwalk_cli.studies.simulate_result.animation_frames`."""

from __future__ import annotations

import io

import matplotlib
import numpy as np
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from .style import COLUMN, black_step, curve_family, is_multiple, layout, style


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


def _black(data: dict, black_every: float | None | str) -> float | None:
    if black_every == "auto":
        return black_step([r["value"] for r in data["runs"]])
    return black_every


def thrust_time(data: dict, *, black_every: float | None | str = "auto", title: str = ""):
    """F_T(t) of every run [N vs s] (the paper's slow-thruster figure 1): one line per F_ss,
    coloured by it (colour bar), black at round values of a fine sweep (``black_every``:
    ``"auto"`` picks it from the sweep's spacing). Piecewise thrust: one line per thruster, or
    the generalised force T [N m] in generalised mode."""
    runs = data["runs"]
    black_every = _black(data, black_every)
    with style():
        fig = Figure(figsize=(COLUMN, 2.6))
        ax = fig.subplots()
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
            handles, labels = [], []
            if black_every:
                handles.append(matplotlib.lines.Line2D([], [], color="k", lw=0.9))
                labels.append(f"every {black_every:g} N")
            if any(r["failed"] for r in runs):
                handles.append(matplotlib.lines.Line2D([], [], color="gray", ls=":", lw=0.7))
                labels.append("run stopped (see simulation.json)")
            if handles:
                ax.legend(handles, labels, loc="best")
        driven = ", ".join(data["driven"]) or "schedule"
        ax.set_xlabel("time $t$ [s]")
        ax.set_ylabel(f"thrust $F_T$ ({driven}) [{unit}]" if unit == "N"
                      else f"schedule $T$ [{unit}]")
        if title:
            ax.set_title(title)
        layout(fig)
    return fig


def phase_portrait(data: dict, *, black_every: float | None | str = "auto", title: str = "",
                   settled: int = 3):
    """alpha' vs alpha [rad/s vs rad] of every run (the paper's figure 2): each run in the
    colour of its F_ss (black at round values of a fine sweep), the transient faint and the
    last ``settled`` steps solid, so the convergence shows; the zero-dynamics limit cycle of
    each F_ss dashed in the same colour; impacts as thin lines."""
    runs = data["runs"]
    black_every = _black(data, black_every)
    with style():
        fig = Figure(figsize=(COLUMN, 2.9))
        ax = fig.subplots()
        norm, cmap, colors = _sweep_colors([r["value"] for r in runs], black_every)
        # four families, each one artist, in run order within it: the transient steps (faint,
        # bottom), the impacts between settled steps, the settled steps, the predicted orbits
        family = {name: ([], []) for name in ("transient", "impact", "settled", "predicted")}

        def add(name, x, y, colour, alpha=1.0):
            family[name][0].append((x, y))
            family[name][1].append(to_rgba(colour, alpha))

        for r, col in zip(runs, colors):
            steps = r["steps"]
            n = len(steps)
            if r["predicted"] is not None:
                add("predicted", r["predicted"]["alpha"], r["predicted"]["alpha_dot"], col)
            prev = None
            for k, st in enumerate(steps):
                last = k >= n - settled
                add("settled" if last else "transient", st["alpha"], st["alpha_dot"], col,
                    1.0 if last else 0.18)
                if prev is not None and last:
                    add("impact", [prev[0], st["alpha"][0]], [prev[1], st["alpha_dot"][0]],
                        col, 0.6)
                prev = (st["alpha"][-1], st["alpha_dot"][-1])
        for name, lw, zorder, ls in (("transient", 0.5, 1, "-"), ("impact", 0.4, 2, "-"),
                                     ("settled", 0.9, 3, "-"),
                                     ("predicted", 0.7, 4, (0, (3, 2)))):
            curve_family(ax, *family[name], lw=lw, zorder=zorder, ls=ls)
        if data["kind"] != "piecewise":
            sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
            cb = fig.colorbar(sm, ax=ax, pad=0.02)
            cb.set_label(r"$F_{ss}$ [N]")
        handles = [matplotlib.lines.Line2D([], [], color="0.3", lw=0.5, alpha=0.3),
                   matplotlib.lines.Line2D([], [], color="0.3", lw=0.9),
                   matplotlib.lines.Line2D([], [], color="0.3", ls=(0, (3, 2)), lw=0.7)]
        labels = ["transient", f"last {settled} steps", "zero-dynamics orbit"]
        if black_every:
            handles.append(matplotlib.lines.Line2D([], [], color="k", lw=0.9))
            labels.append(f"every {black_every:g} N")
        ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.2),
                  ncol=len(labels), fontsize=6, handlelength=1.6, columnspacing=0.8)
        ax.set_xlabel(r"$\alpha$ [rad]")
        ax.set_ylabel(r"$\dot\alpha$ [rad/s]")
        if title:
            ax.set_title(title)
        layout(fig)
    return fig


ROLE_COLOURS = {"stance": "tab:blue", "swing": "tab:red", "body": "k"}


def animate(frames: dict, fps: float = 20.0, width_px: int = 960) -> bytes:
    """Stick-figure GIF of the walker [m], ``width_px`` wide (at least 800 px): the camera
    follows the hip, stance-leg links blue, swing-leg links red, the body black, thrust arrows
    (the largest thrust drawn 0.3 m long; the scale in the caption). Needs Pillow (a
    matplotlib dependency). Returns the GIF bytes, rendered in memory frame by frame."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    links, pts, vec = frames["links"], frames["points"], frames["thrust"]
    roles = frames.get("roles") or ["body"] * links.shape[1]
    hip = frames.get("hip")
    if hip is None:
        hip = links[..., 0].mean(axis=(1, 2))[:, None] * np.array([1.0, 0.0])
    big = float(np.abs(vec).max()) if vec.size else 0.0
    scale = 0.3 / big if big > 0 else 0.0  # m per N
    ys = np.concatenate([links[..., 1].ravel(), (pts[..., 1] + scale * vec[..., 1]).ravel()])
    rel = links[..., 0] - hip[:, None, None, 0]
    half = max(float(np.abs(rel).max()) + 0.3, 0.8)  # half the window width [m]
    dpi = 100
    with style():
        fig = Figure(figsize=(width_px / dpi, 0.42 * width_px / dpi), dpi=dpi)
        ax = fig.subplots()
        ax.set_aspect("equal")
        y0, y1 = min(ys.min(), 0.0) - 0.1, ys.max() + 0.15
        ax.set_ylim(y0, y1)
        half = max(half, 0.5 * (y1 - y0) * 2.1)  # fill the wide frame (aspect about 2.4)
        ax.axhline(0.0, color="0.3", lw=1.0)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        lines = [ax.plot([], [], color=ROLE_COLOURS[role], lw=2.4, solid_capstyle="round",
                         zorder=3)[0] for role in roles]
        ticks = ax.plot([], [], "|", color="0.4", ms=6)[0]
        arrows = [ax.annotate("", xy=(0, 0), xytext=(0, 0),
                              arrowprops={"arrowstyle": "->", "color": "darkorange", "lw": 1.6})
                  for _ in range(pts.shape[1])]
        label = ax.text(0.01, 0.96, "", transform=ax.transAxes, va="top", fontsize=8)
        caption = frames["title"] + (f"; thrust arrows {100 * scale:.3g} cm per N"
                                     if scale else "")
        ax.set_title(caption + "; stance leg blue, swing leg red", fontsize=8)
        fig.tight_layout()

        def draw(i):
            cx = float(hip[i, 0])
            ax.set_xlim(cx - half, cx + half)
            marks = np.arange(np.floor(cx - half), np.ceil(cx + half) + 0.01, 0.25)
            ticks.set_data(marks, np.zeros_like(marks))
            for ln, seg in zip(lines, links[i]):
                ln.set_data(seg[:, 0], seg[:, 1])
            for ar, p, v in zip(arrows, pts[i], vec[i]):
                ar.xy = (p[0] + scale * v[0], p[1] + scale * v[1])
                ar.set_position((p[0], p[1]))
            label.set_text(f"t = {frames['t'][i]:.2f} s")

        canvas = FigureCanvasAgg(fig)
        images = []
        for i in range(len(frames["t"])):
            draw(i)
            canvas.draw()
            images.append(Image.frombuffer("RGBA", canvas.get_width_height(),
                                           canvas.buffer_rgba()).copy())
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:],
                   duration=int(1000 / fps), loop=0)
    return buf.getvalue()
