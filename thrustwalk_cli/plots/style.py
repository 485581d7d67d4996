"""The shared figure style (``thrustwalk.mplstyle``) and small helpers of every figure."""

from __future__ import annotations

import io
import sys
from collections.abc import Sequence
from pathlib import Path

import matplotlib.style
import numpy as np

STYLE = Path(__file__).with_name("thrustwalk.mplstyle")
COLUMN = 3.5  # [in] one column of a two-column IEEE paper
PAGE = 7.16  # [in] both columns
FORMATS = ("png", "pdf")


def render(fig, fmt: str, creator: str = "thrustwalk") -> bytes:
    """The figure as PNG or PDF bytes, at its own size (one or two IEEE columns wide: no
    tight bounding box), with the package style in force while saving, so that PDFs embed
    TrueType (Type 42) fonts; the PDF creation date follows ``SOURCE_DATE_EPOCH`` when set
    (reproducible files)."""
    buf = io.BytesIO()
    with style():
        fig.savefig(buf, format=fmt, metadata={"Creator": creator} if fmt == "pdf" else None)
    return buf.getvalue()


def close(fig) -> None:
    """Release a figure once it has been saved. The figures of this package are plain
    :class:`matplotlib.figure.Figure` objects that pyplot never holds (freed with their last
    reference); only a figure made through pyplot elsewhere needs pyplot to let it go."""
    pyplot = sys.modules.get("matplotlib.pyplot")
    if pyplot is not None:
        pyplot.close(fig)


def style():
    """Context manager applying the package style."""
    return matplotlib.style.context(str(STYLE))


def corner_note(ax, text: str) -> None:
    """A small red note in the lower-left corner of ``ax`` (missing orbits, warnings); none
    when ``text`` is empty."""
    if text:
        ax.text(0.01, 0.01, text, transform=ax.transAxes, fontsize=6, va="bottom",
                color="firebrick")


def missing_note(labels: Sequence, unit: str = "") -> str:
    """``no orbit for -3, -4`` for a few values; ``no orbit for 812 values (-3 ... -100 N)``
    for many, so a long sweep never floods a figure."""
    texts = [f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in labels]
    if not texts:
        return ""
    if len(texts) <= 6:
        return "no orbit for " + ", ".join(texts)
    unit = f" {unit}" if unit else ""
    return f"no orbit for {len(texts)} values ({texts[0]} ... {texts[-1]}{unit})"


def is_multiple(value: float, every: float) -> bool:
    return every > 0 and abs(value / every - round(value / every)) < 1e-9


def black_step(values, unit: str = "") -> float | None:
    """The spacing of the black lines in a swept family (the paper: a 2 N sweep, black every
    10 N): the smallest round number (1, 2, 2.5 or 5 times a power of ten) that is a multiple of
    the sweep's spacing, at least twice it, and leaves at most about six black lines. None when
    the sweep is too coarse or too short for black lines to single out anything."""
    v = np.unique(np.round(np.asarray([x for x in values if x is not None], float), 12))
    if v.size < 6:
        return None
    d = float(np.min(np.diff(v)))
    span = float(v[-1] - v[0])
    if d <= 0 or span <= 0:
        return None
    for k in range(int(np.floor(np.log10(d))) - 1, int(np.ceil(np.log10(span))) + 2):
        for m in (1.0, 2.0, 2.5, 5.0):
            step = m * 10.0**k
            if step >= 2 * d * (1 - 1e-9) and step >= span / 6 * (1 - 1e-9) \
                    and is_multiple(step, d) and np.all([is_multiple(x - v[0], d) for x in v]):
                return step
    return None


# --- drawing many curves and placing legends cheaply ------------------------------------------

# matplotlib's legend location codes other than "best" (0), in its order of preference
LEGEND_CODES = {1: "upper right", 2: "upper left", 3: "lower left", 4: "lower right",
                5: "right", 6: "center left", 7: "center right", 8: "lower center",
                9: "upper center", 10: "center"}
_ANCHOR = {1: (1.0, 1.0), 2: (0.0, 1.0), 3: (0.0, 0.0), 4: (1.0, 0.0), 5: (1.0, 0.5),
           6: (0.0, 0.5), 7: (1.0, 0.5), 8: (0.5, 0.0), 9: (0.5, 1.0), 10: (0.5, 0.5)}


def curve_family(ax, curves: Sequence[tuple], colors: Sequence, *, lw: float,
                 zorder: float = 2, ls="-", **kw):
    """Many curves ``[(x, y), ...]`` (data units) drawn as one
    :class:`~matplotlib.collections.LineCollection`, ``colors[i]`` for curve i, all of width
    ``lw`` [pt] and line style ``ls`` at ``zorder``: what one ``ax.plot`` per curve draws
    (curves in the given order, the same cap and join styles as a plotted line), drawn as
    one artist. Returns the collection (None when ``curves`` is empty). The data limits grow
    to hold every vertex, as with ``ax.plot``."""
    from matplotlib.collections import LineCollection

    if not len(curves):
        return None
    segs = [np.column_stack([np.asarray(x, float), np.asarray(y, float)]) for x, y in curves]
    solid = ls in ("-", "solid")
    rc = matplotlib.rcParams
    coll = LineCollection(
        segs, colors=list(colors), linewidths=lw, linestyles=ls, zorder=zorder,
        capstyle=rc["lines.solid_capstyle"] if solid else rc["lines.dash_capstyle"],
        joinstyle=rc["lines.solid_joinstyle"] if solid else rc["lines.dash_joinstyle"], **kw)
    ax.add_collection(coll, autolim=False)
    pts = np.concatenate(segs)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.size:
        ax.update_datalim(pts)
        ax.autoscale_view()
    return coll


def _legend_obstacles(ax, renderer):
    """What a legend placed "best" in ``ax`` should not cover, in display units [px]: the
    vertices of every line, line collection, polygon and patch (a list of (n, 2) arrays, one
    per path), the points of other collections (markers), and the boxes of texts and
    rectangles: matplotlib's own list (``Legend._auto_legend_data``) with the curves of a
    :class:`~matplotlib.collections.LineCollection`, which matplotlib leaves out."""
    from matplotlib.collections import Collection, LineCollection, PolyCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle
    from matplotlib.text import Text

    paths, points, boxes = [], [], []
    for artist in (*ax.lines, *ax.patches, *ax.collections, *ax.texts, *ax.artists):
        if isinstance(artist, Line2D):
            paths.append(artist.get_transform().transform_path(artist.get_path()).vertices)
        elif isinstance(artist, Rectangle):
            boxes.append(artist.get_bbox().transformed(artist.get_data_transform()).extents)
        elif isinstance(artist, Patch):
            paths.append(artist.get_transform().transform_path(artist.get_path()).vertices)
        elif isinstance(artist, LineCollection):
            tr = artist.get_transform()
            paths.extend(tr.transform(np.asarray(s, float)) for s in artist.get_segments()
                         if len(s))
        elif isinstance(artist, PolyCollection):
            tr = artist.get_transform()
            paths.extend(tr.transform_path(p).vertices for p in artist.get_paths())
        elif isinstance(artist, Collection):
            offs = np.asarray(artist.get_offsets(), float)
            if offs.size:
                points.append(artist.get_offset_transform().transform(offs))
        elif isinstance(artist, Text):
            boxes.append(artist.get_window_extent(renderer).extents)
    return paths, points, boxes


def best_legend_loc(legend, renderer) -> int:
    """The location code (1-10) where ``legend`` covers the least of its axes' data, by
    matplotlib's rule for ``loc="best"`` (``Legend._find_best_position``): for each standard
    location in turn, the number of data vertices and marker points inside the legend's box,
    of text boxes it overlaps and of curves crossing its edge; the first location with none,
    else the least (the lower code on a tie). Computed on all curves at once, line collections
    included (matplotlib's own search takes one path at a time and ignores them)."""
    ax = legend.axes
    paths, points, boxes = _legend_obstacles(ax, renderer)
    frame = legend.get_window_extent(renderer)
    w, h = frame.width, frame.height
    parent = legend.get_bbox_to_anchor()
    pad = legend.borderaxespad * renderer.points_to_pixels(legend.prop.get_size_in_points())
    x0, y0 = parent.x0 + pad, parent.y0 + pad
    cw, ch = parent.width - 2 * pad, parent.height - 2 * pad
    verts = np.concatenate(paths) if paths else np.zeros((0, 2))
    # segments between consecutive vertices of one path, and the path each belongs to
    if paths:
        n = np.array([len(p) for p in paths])
        owner = np.repeat(np.arange(len(paths)), n)
        keep = np.ones(len(verts), bool)
        keep[np.cumsum(n)[n > 0] - 1] = False  # no segment from a path's last vertex onwards
        i = np.flatnonzero(keep)
        a, b, seg_owner = verts[i], verts[i + 1], owner[i]
        ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
        a, b, seg_owner = a[ok], b[ok], seg_owner[ok]
    else:
        a = b = np.zeros((0, 2))
        seg_owner = np.zeros(0, int)
    pts = np.concatenate(points) if points else np.zeros((0, 2))
    bx = np.asarray(boxes, float).reshape(-1, 4)
    best = None
    for code in range(1, 11):
        fx, fy = _ANCHOR[code]
        l, bot = x0 + fx * (cw - w), y0 + fy * (ch - h)
        r, top = l + w, bot + h
        bad = int(_inside(verts, l, bot, r, top).sum()) + int(_inside(pts, l, bot, r, top).sum())
        bad += int(((bx[:, 0] < r) & (bx[:, 2] > l) & (bx[:, 1] < top) & (bx[:, 3] > bot)).sum())
        hit = _segments_cross_box(a, b, l, bot, r, top)
        bad += int(np.unique(seg_owner[hit]).size)
        if best is None or bad < best[0]:
            best = (bad, code)
        if bad == 0:
            break
    return best[1]


def _segments_cross_box(a: np.ndarray, b: np.ndarray, l: float, bot: float, r: float,
                        top: float) -> np.ndarray:
    """Which segments a-b meet the edge of the box [l, r] x [bot, top]: those that meet the
    closed box without lying strictly inside it (matplotlib's ``intersects_bbox(filled=False)``
    for straight segments)."""
    if not len(a):
        return np.zeros(0, bool)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    near = (lo[:, 0] <= r) & (hi[:, 0] >= l) & (lo[:, 1] <= top) & (hi[:, 1] >= bot)
    d = b - a
    side = [d[:, 0] * (cy - a[:, 1]) - d[:, 1] * (cx - a[:, 0])
            for cx, cy in ((l, bot), (r, bot), (r, top), (l, top))]
    side = np.stack(side)
    straddle = ~((side > 0).all(axis=0) | (side < 0).all(axis=0))
    return near & straddle & ~(_inside(a, l, bot, r, top) & _inside(b, l, bot, r, top))


def _inside(p: np.ndarray, l: float, bot: float, r: float, top: float) -> np.ndarray:
    """Which points (n, 2) lie strictly inside the box (matplotlib's ``count_contains``)."""
    return (p[:, 0] > l) & (p[:, 0] < r) & (p[:, 1] > bot) & (p[:, 1] < top)


def _best_legends(fig) -> list:
    """The axes legends of ``fig`` placed "best" (found by location, not drawn)."""
    out = []
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is not None and getattr(leg, "_loc", None) == 0:
            out.append(leg)
    return out


def _set_loc(legend, code: int) -> None:
    if hasattr(legend, "set_loc"):  # matplotlib >= 3.8
        legend.set_loc(LEGEND_CODES[code])
    else:
        legend._loc = code


def layout(fig, **tight) -> None:
    """Lay ``fig`` out once and fix every "best" legend, so that saving it (in each format)
    neither lays it out again nor searches for the legends' places again.

    A figure made with ``layout="constrained"`` is laid out once by its engine and then kept
    as it is (no engine); any other gets ``fig.tight_layout(**tight)``. A legend asked for at
    ``loc="best"`` waits in the upper right corner meanwhile (inside its axes: the layout is the
    same) and is then put where :func:`best_legend_loc` finds it covers the least data, once,
    on the final layout."""
    legends = _best_legends(fig)
    for leg in legends:
        _set_loc(leg, 1)
    engine = fig.get_layout_engine()
    dpi = fig.dpi
    saved = matplotlib.rcParams["savefig.dpi"]
    try:
        # at the PNG's resolution: the text laid out (mathtext parsed) is then the text drawn
        if isinstance(saved, (int, float)):
            fig.set_dpi(saved)
        if engine is not None and type(engine).__name__ == "ConstrainedLayoutEngine":
            engine.execute(fig)
            fig.set_layout_engine("none")
        else:
            fig.tight_layout(**tight)
        place_legends(fig, legends)
    finally:
        fig.set_dpi(dpi)


def place_legends(fig, legends: Sequence | None = None) -> None:
    """Fix each "best" legend of ``fig`` (or each of ``legends``) at the location
    :func:`best_legend_loc` finds on the figure as it is laid out now: drawing the figure
    later (each saved format) searches no more. For a legend added after :func:`layout`."""
    legends = _best_legends(fig) if legends is None else legends
    if legends:
        renderer = fig._get_renderer()
        for leg in legends:
            _set_loc(leg, best_legend_loc(leg, renderer))
