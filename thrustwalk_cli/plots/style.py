"""The shared figure style (``thrustwalk.mplstyle``) and small helpers of every figure."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

STYLE = Path(__file__).with_name("thrustwalk.mplstyle")


def close(fig) -> None:
    """Release a figure once it has been saved."""
    plt.close(fig)


def style():
    """Context manager applying the package style."""
    return plt.style.context(str(STYLE))


def corner_note(ax, text: str) -> None:
    """A small red note in the lower-left corner of ``ax`` (missing orbits, warnings); none
    when ``text`` is empty."""
    if text:
        ax.text(0.01, 0.01, text, transform=ax.transAxes, fontsize=6, va="bottom",
                color="firebrick")


def is_multiple(value: float, every: float) -> bool:
    return every > 0 and abs(value / every - round(value / every)) < 1e-9
