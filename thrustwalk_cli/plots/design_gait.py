"""Figure of ``thrustwalk design-gait`` (SPEC 2): the designed gait as a stick figure over one
step. Plain data in (:func:`thrustwalk_cli.studies.design_gait.stick_frames`)."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from .style import COLUMN, layout, style

ROLE_MAPS = {"stance": "Blues", "swing": "Reds", "body": "Greys"}
ROLE_LABELS = {"stance": "stance leg", "swing": "swing leg", "body": "body"}


def stick_figure(frames: dict, *, title: str = ""):
    """Stick figure over one step, one IEEE column wide, axes in metres at equal scale.

    ``frames``: ``s`` (n,) phases in [0, 1]; ``links`` (n, links, 2, 2) [m], per link its
    frame origin and end point, stance foot at the origin; ``roles`` per link (``stance``,
    ``swing``, ``body``); ``swing_foot`` (n, 2) [m]; ``swing_path`` (P, 2) [m]. Stance-leg links
    are drawn blue, swing-leg links red, the body grey, each darker later in the step
    (s = 0 just after impact, s = 1 just before the next); the swing-foot path dashed, the
    ground line at y = 0 and the stance foot as a triangle at the origin.
    """
    s = np.asarray(frames["s"], float)
    links = np.asarray(frames["links"], float)
    path = np.asarray(frames["swing_path"], float)
    feet = np.asarray(frames["swing_foot"], float)
    roles = frames.get("roles") or ["body"] * links.shape[1]
    with style():
        fig = Figure(figsize=(COLUMN, 2.4))
        ax = fig.subplots()
        shade = 0.35 + 0.6 * s  # later instants darker
        for k in range(s.size):
            for j, role in enumerate(roles):
                colour = colormaps[ROLE_MAPS.get(role, "Greys")](shade[k])
                seg = links[k, j]
                ax.plot(seg[:, 0], seg[:, 1], color=colour, lw=1.1, solid_capstyle="round",
                        zorder=3)
        ax.plot(path[:, 0], path[:, 1], color="tab:red", ls="--", lw=0.7, zorder=2,
                label="swing-foot path")
        ax.plot(feet[[0, -1], 0], feet[[0, -1], 1], "o", color="tab:red", ms=3, zorder=4,
                label="swing foot at s = 0, 1")
        ax.plot([0.0], [0.0], "^", color="tab:blue", ms=5, zorder=4, label="stance foot")
        xs = np.concatenate([links[..., 0].ravel(), path[:, 0]])
        ys = np.concatenate([links[..., 1].ravel(), path[:, 1]])
        pad = 0.05 * max(float(np.ptp(xs)), float(np.ptp(ys)), 0.1)
        ax.axhline(0.0, color="0.3", lw=0.8, zorder=1)
        ax.set_xlim(xs.min() - pad, xs.max() + pad)
        ax.set_ylim(min(ys.min(), 0.0) - pad, ys.max() + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        for role in dict.fromkeys(roles):  # one entry per role: light early, dark late
            cmap = colormaps[ROLE_MAPS.get(role, "Greys")]
            ax.plot([], [], color=cmap(0.95), lw=1.1, label=ROLE_LABELS.get(role, role))
        ax.plot([], [], " ", label="light: s = 0 (after impact)\ndark: s = 1 (before impact)")
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=6, borderaxespad=0)
        if title:
            ax.set_title(title)
        layout(fig)
    return fig
