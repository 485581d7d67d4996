"""Figure of ``thrustwalk optimize`` (SPEC 6): nominal vs optimal orbit, the schedule and the
contact margins. Plain data in."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from .style import layout, style


def optimal_figure(nominal: dict | None, optimal: dict, knots: np.ndarray, values: np.ndarray,
                   *, unit: str, profile: dict, mu: float, title: str = ""):
    """Optimised orbit: phase plane (nominal vs optimal), thrust schedule, friction ratio.

    ``nominal``/``optimal``: dicts with ``alpha`` [rad] and ``alpha_dot`` [rad/s] (plus the impact
    jump ``jump`` = (alpha_f, alpha'^-, alpha_i, alpha'^+)); ``profile``: contact profile."""
    with style():
        fig = Figure(figsize=(7.0, 2.5))
        (a1, a2, a3) = fig.subplots(1, 3)
        for orb, lab, col in ((nominal, "nominal (no thrust)", "0.5"),
                              (optimal, "optimal schedule", "C0")):
            if orb is None:
                continue
            a1.plot(orb["alpha"], orb["alpha_dot"], color=col, label=lab)
            j = orb["jump"]
            a1.plot([j[0], j[2]], [j[1], j[3]], color=col, ls="--", lw=0.6)
        a1.set_xlabel(r"$\alpha$ [rad]")
        a1.set_ylabel(r"$\dot\alpha$ [rad/s]")
        a1.legend(loc="best")
        a2.stairs(values, knots, color="C0", lw=1.2, baseline=None,
                  label="thrust per interval")
        for k in knots:
            a2.axvline(k, color="0.7", lw=0.4)
        a2.axhline(0.0, color="k", lw=0.4)
        a2.set_xlabel(r"$\alpha$ [rad]")
        a2.set_ylabel(f"thrust [{unit}]")
        a2.legend(loc="best")
        r = np.where(np.isfinite(profile["ratio"]), profile["ratio"], np.nan)
        a3.plot(profile["alpha"], r, color="C0", label=r"$|F_1^h|/F_1^v$")
        a3.axhline(mu, color="firebrick", lw=0.8, label=rf"$\mu$ = {mu:g}")
        a3.set_xlabel(r"$\alpha$ [rad]")
        a3.set_ylabel("friction ratio [-]")
        a3.legend(loc="best")
        if title:
            fig.suptitle(title)
        layout(fig)
    return fig
