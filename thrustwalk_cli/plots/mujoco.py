"""Figures of ``thrustwalk mujoco`` from plain data
(:meth:`thrustwalk_cli.studies.mujoco.MujocoResult.figure_data`): the phase portraits of MuJoCo
and of the rigid model, and the GIF of rendered frames."""

from __future__ import annotations

import io
from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from .style import PAGE, layout, style


def phase_portraits(data: dict, *, title: str = "", settled: int = 3):
    """alpha' vs alpha [rad/s vs rad], two panels: MuJoCo (left; the transient faint, the
    last ``settled`` steps solid) and the rigid model (right; the reduced cascade from the same
    start), each run in its own colour, the zero-dynamics limit cycle dashed black on both."""
    runs = data["runs"]
    cmap = matplotlib.colormaps["viridis"]
    with style():
        fig = Figure(figsize=(PAGE, 2.9))
        axes = fig.subplots(1, 2, sharex=True, sharey=True)
        for i, r in enumerate(runs):
            col = cmap(0.5 if len(runs) == 1 else i / (len(runs) - 1) * 0.9)
            label = "schedule" if r["value"] is None else f"{r['value']:g} N"
            for ax, key in zip(axes, ("mujoco", "rigid")):
                steps = r[key]
                n = len(steps)
                for k, st in enumerate(steps):
                    last = k >= n - settled
                    ax.plot(st["alpha"], st["alpha_dot"], color=col,
                            lw=0.9 if last else 0.5, alpha=1.0 if last else 0.25,
                            ls=":" if r["failed"] and key == "mujoco" else "-",
                            label=label if (k == n - 1) else None)
                if r["orbit"] is not None:
                    ax.plot(r["orbit"]["alpha"], r["orbit"]["alpha_dot"], color="k",
                            ls=(0, (3, 2)), lw=0.6, zorder=4)
        axes[0].set_title(f"MuJoCo ({data['contact']}, mu = {data['mu']:g})", fontsize=8)
        axes[1].set_title("rigid model (impacts, zeroed outputs)", fontsize=8)
        for ax in axes:
            ax.set_xlabel(r"$\alpha$ [rad]")
        axes[0].set_ylabel(r"$\dot\alpha$ [rad/s]")
        handles, labels = axes[0].get_legend_handles_labels()
        handles.append(matplotlib.lines.Line2D([], [], color="k", ls=(0, (3, 2)), lw=0.6))
        labels.append("zero-dynamics orbit")
        axes[1].legend(handles, labels, loc="best", fontsize=6)
        if title:
            fig.suptitle(title)
        layout(fig)
    return fig


def gif(images: Sequence[np.ndarray], fps: float) -> bytes:
    """An animated GIF of RGB frames ``(height, width, 3)`` uint8 at ``fps`` frames per second
    (Pillow, a matplotlib dependency)."""
    from PIL import Image

    frames = [Image.fromarray(np.asarray(im, np.uint8)) for im in images]
    buf = io.BytesIO()
    frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:],
                   duration=int(round(1000 / fps)), loop=0)
    return buf.getvalue()
