"""Figures of ``thrustwalk control`` (SPEC 11), from the figure data of
:meth:`thrustwalk_cli.studies.control_result.ControlResult.figure_data`: speed per step against the
reference, thrust against time (commanded and delivered), and the contact margins (friction
ratio and vertical force against time, predicted and realised, with the cone)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from .style import COLUMN, corner_note, layout, style

CTRL, FREE, NAIVE = "tab:blue", "0.55", "tab:orange"


def _pushes(ax, d: dict, x_of_step=None) -> None:
    for k in d["pushes"]:
        ax.axvline(k if x_of_step is None else x_of_step(k), color="tab:red", lw=0.6, ls=":")


def speed_tracking(d: dict, title: str = ""):
    """Average speed of each step [m/s] (step length over step time) against the reference,
    the controlled walker, the uncontrolled one and, for slow thrusters, the controller that
    ignores the lag; pushes dotted red, saturated steps marked."""
    with style():
        fig = Figure(figsize=(COLUMN, 2.5))
        ax = fig.subplots()
        c = d["controlled"]
        if d["reference_speed"] is not None:
            k = np.arange(1, len(d["reference_speed"]) + 1)
            ax.step(k, d["reference_speed"], where="mid", color="k", lw=0.8, label="reference")
        ax.plot(c["step"], c["speed"], "o-", color=CTRL, ms=2.5, lw=0.8, label="controlled")
        u = d["uncontrolled"]
        if u is not None:
            ax.plot(u["step"], u["speed"], "s--", color=FREE, ms=2, lw=0.7,
                    label="uncontrolled" + (" (fell)" if u["failed"] else ""))
        n = d["naive"]
        if n is not None:
            ax.plot(n["step"], n["speed"], "^:", color=NAIVE, ms=2, lw=0.7,
                    label="lag ignored")
        sat = set(c["saturated"])
        if sat:
            ks = [k for k in c["step"] if k in sat]
            vs = [v for k, v in zip(c["step"], c["speed"]) if k in sat]
            ax.plot(ks, vs, "x", color="tab:red", ms=4, label="saturated / infeasible")
        _pushes(ax, d)
        ax.set_xlabel("step $k$")
        ax.set_ylabel("average speed [m/s]")
        ax.legend(loc="best", fontsize=6)
        if c["failed"]:
            corner_note(ax, "controlled run stopped: " + c["reason"][:60])
        if title:
            ax.set_title(title)
        layout(fig)
    return fig


def thrust_schedule(d: dict, title: str = ""):
    """Thrust of the driven thruster(s) against time [N]: delivered (solid) and, for a
    thruster with dynamics, the commanded setpoint (dashed) and the delivered thrust of the
    controller that ignores the lag (dotted); the uncontrolled walker's thrust in grey."""
    with style():
        fig = Figure(figsize=(COLUMN, 2.5))
        ax = fig.subplots()
        names = d["thruster_names"]
        dyn = d["thrust_model"] != "ideal"
        for i, t_ in enumerate(d["driven"]):
            c = d["controlled"]
            lab = names[t_]
            ax.plot(np.concatenate(c["t"]), np.concatenate([F[:, t_] for F in c["F"]]),
                    color=CTRL if i == 0 else f"C{i + 2}", lw=0.9,
                    label=f"{lab} delivered" if dyn else lab)
            if dyn:
                md = len(d["driven"])
                for j, (t0, t1, u) in enumerate(c["commanded"]):
                    ax.hlines(np.asarray(u).reshape(-1, md)[0, i], t0, t1, color="k", lw=0.7,
                              ls="--", label=f"{lab} commanded" if j == 0 else None)
                n = d["naive"]
                if n is not None and n["t"]:
                    ax.plot(np.concatenate(n["t"]), np.concatenate([F[:, t_] for F in n["F"]]),
                            color=NAIVE, lw=0.8, ls=":", label=f"{lab}, lag ignored")
        ax.axhline(0.0, color=FREE, lw=0.6)
        ax.set_xlabel("time $t$ [s]")
        ax.set_ylabel("thrust $F_T$ [N]")
        ax.legend(loc="best", fontsize=6)
        if title:
            ax.set_title(title)
        layout(fig)
    return fig


def contact_margin(d: dict, title: str = ""):
    """Friction ratio ``|F^h|/F^v`` [1] with the cone ``mu`` and vertical ground force
    ``F^v`` [N] with its minimum against time: realised (solid), predicted by the QP's model
    (dashed), the uncontrolled walker (grey)."""
    with style():
        fig = Figure(figsize=(COLUMN, 3.6))
        (a1, a2) = fig.subplots(2, 1, sharex=True)
        for run, color, lab, pred in ((d["uncontrolled"], FREE, "uncontrolled", False),
                                      (d["controlled"], CTRL, "realised", True)):
            if run is None or not run["t"]:
                continue
            t = np.concatenate(run["t"])
            F1 = np.concatenate(run["F1"])
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.where(F1[:, 1] > 0, np.abs(F1[:, 0]) / F1[:, 1], np.nan)
            a1.plot(t, r, color=color, lw=0.8, label=lab)
            a2.plot(t, F1[:, 1], color=color, lw=0.8, label=lab)
            if pred and run["F1_predicted"] and run["F1_predicted"][0] is not None:
                P = np.concatenate(run["F1_predicted"])
                with np.errstate(divide="ignore", invalid="ignore"):
                    rp = np.where(P[:, 1] > 0, np.abs(P[:, 0]) / P[:, 1], np.nan)
                a1.plot(t, rp, color="k", lw=0.6, ls="--", label="predicted")
                a2.plot(t, P[:, 1], color="k", lw=0.6, ls="--", label="predicted")
        a1.axhline(d["mu"], color="tab:red", lw=0.8, label=f"cone $\\mu$ = {d['mu']:g}")
        a2.axhline(d["eps"], color="tab:red", lw=0.8, label="minimum")
        a1.set_ylabel(r"$|F^h|/F^v$ [1]")
        a2.set_ylabel(r"$F^v$ [N]")
        a2.set_xlabel("time $t$ [s]")
        a1.legend(loc="best", fontsize=6)
        flagged = d["controlled"]["flagged"]
        if flagged:
            corner_note(a2, f"outside the prediction's bound at {len(flagged)} step(s)")
        if title:
            a1.set_title(title)
        layout(fig)
    return fig
