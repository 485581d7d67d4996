"""Summaries of robustness maps (SPEC 12): survivable pushes from a push map, the converging
fraction of a basin slice and its agreement with the reduced basin, the spread of a
Monte-Carlo sample. Plain numbers in, plain numbers out (SI units)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def survivable(impulses: Sequence[float], outcomes: Sequence[str | None], sign: float
               ) -> tuple[float | None, str]:
    """The largest survivable push in one direction at one phase: the largest grid impulse
    ``|P|`` (``P`` of sign ``sign``) such that every grid impulse of that sign with ``|p| <=
    |P|`` recovered [N s]; 0 when the smallest one did not. Returns ``(value, bound)``:
    ``bound`` is ``"failed"`` (the next grid impulse failed: the true value lies below it),
    ``"grid edge"`` (every impulse of the grid recovered: at least this), ``"error"`` or
    ``"not run"`` (the scan stopped at a trial that could not be computed or has no record:
    at least this). ``(None, "none")`` when the grid has no impulse of that sign."""
    pairs = sorted((abs(p), o) for p, o in zip(impulses, outcomes) if p * sign > 0)
    if not pairs:
        return None, "none"
    best = 0.0
    for mag, out in pairs:
        if out is None:
            return best, "not run"
        if out == "error":
            return best, "error"
        if out != "recovered":
            return best, "failed"
        best = mag
    return best, "grid edge"


def summary_impulse(forward: Sequence[float | None], backward: Sequence[float | None]
                    ) -> float | None:
    """``mean over phases of (P_fwd + P_bwd) / 2`` [N s], each phase averaging the directions
    the grid has (None when it has neither)."""
    per = []
    for f, b in zip(forward, backward):
        vals = [v for v in (f, b) if v is not None]
        if vals:
            per.append(sum(vals) / len(vals))
    return float(np.mean(per)) if per else None


def mean_of(values: Sequence[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.mean(vals)) if vals else None


def outcome_counts(outcomes: Sequence[str | None], names: Sequence[str]) -> dict[str, int]:
    """How many trials had each outcome (``not run``: no record)."""
    out = {n: 0 for n in names}
    out["not run"] = 0
    for o in outcomes:
        out["not run" if o is None else o] += 1
    return out


def spread(values: Sequence[float]) -> dict | None:
    """Mean, standard deviation (ddof 1), min, max and 5/50/95 % percentiles [same unit]."""
    v = np.asarray(values, float)
    if v.size == 0:
        return None
    p5, p50, p95 = np.percentile(v, [5, 50, 95])
    return {"count": int(v.size), "mean": float(v.mean()),
            "std": float(v.std(ddof=1)) if v.size > 1 else 0.0, "min": float(v.min()),
            "max": float(v.max()), "p05": float(p5), "median": float(p50), "p95": float(p95)}


def single_outcome(impulses: Sequence[float], outcomes: Sequence[str | None], sign: float
                   ) -> tuple[str | None, int]:
    """The outcome that covers every recorded push of sign ``sign`` (all phases), when the
    grid has at least two sizes of that sign (else one size would say nothing about the
    others); ``(None, trials)`` when the outcomes differ, or there are too few.
    ``outcomes`` pairs with ``impulses`` [N s] (None: not run, left out)."""
    done = [(abs(p), o) for p, o in zip(impulses, outcomes) if p * sign > 0 and o is not None]
    if len({m for m, _ in done}) < 2:
        return None, len(done)
    kinds = {o for _, o in done}
    return (kinds.pop() if len(kinds) == 1 else None), len(done)
