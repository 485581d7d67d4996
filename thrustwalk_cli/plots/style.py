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
