"""Mean first passage time on rough ground (SPEC 14), the mathematics without a walker: the
Monte-Carlo estimate of censored runs and the mesh Markov chain's MFPT. numpy and scipy only.

**The MFPT** here is the expected number of steps *attempted* up to and including the one that
fails (steps completed + 1). For a walker that fails each step with probability ``p``
independently (the geometric model) it is ``1/p``; for a chain whose non-failed states carry
the sub-stochastic transition matrix ``Q`` it is ``1/(1 - lambda_2)`` in the chain's steady
regime (``lambda_2``: the largest eigenvalue of ``Q``, the second largest of the full chain whose
absorbing failure state has eigenvalue 1; Byl and Tedrake, IJRR 2009) and ``m = (I - Q)^-1 1``
from a given start (``m_i``: expected visits of non-failed states, i.e. steps attempted).

**Monte-Carlo** (geometric model, censoring): ``n`` runs, run ``r`` attempts ``a_r`` steps and
either fails on its last one or reaches the cap (censored: all ``a_r`` steps completed, never
dropped). The likelihood is ``p^F (1 - p)^(T - F)`` with ``F`` failures in the exposure ``T =
sum a_r`` steps attempted, so the maximum-likelihood estimate is ``p = F / T`` and ``MFPT =
T / F``. The 95 % interval is the Clopper-Pearson (exact binomial) interval of ``p`` for ``F``
failures in ``T`` Bernoulli steps, inverted: ``p_lo = B(0.025; F, T - F + 1)``, ``p_hi =
B(0.975; F + 1, T - F)`` (``B`` the beta quantile), ``MFPT in [1/p_hi, 1/p_lo]``. With no
failure the estimate does not exist (``MFPT > 1/p_hi``, the upper end unbounded).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEVEL = 0.95  # confidence of the Monte-Carlo interval
NO_FAILURE = 1e-12  # 1 - lambda_2 below this: no failure reachable (rounding)


@dataclass(frozen=True)
class MCEstimate:
    """The geometric-model estimate (module docstring): ``failures`` F, ``exposure`` T
    [steps attempted], ``mfpt`` [steps] (None without a failure), ``ci`` ``(lower, upper)``
    [steps] (upper None when unbounded), ``p`` the per-step failure probability [1]."""

    failures: int
    exposure: int
    mfpt: float | None
    ci: tuple[float | None, float | None]
    p: float | None
    level: float = LEVEL

    def document(self) -> dict:
        return {"mfpt": self.mfpt, "ci_lower": self.ci[0], "ci_upper": self.ci[1],
                "level": self.level, "failures": self.failures, "exposure": self.exposure,
                "failure_probability": self.p,
                "estimator": "geometric MLE T/F (censored runs count their steps), "
                             "Clopper-Pearson interval of p = F/T inverted"}


def mc_estimate(failures: int, exposure: int, level: float = LEVEL) -> MCEstimate:
    """MFPT [steps] and its ``level`` interval from ``failures`` runs that failed and the
    ``exposure`` (steps attempted by every run, censored ones included): module docstring."""
    from scipy.stats import beta

    F, T = int(failures), int(exposure)
    if F < 0 or T < F:
        raise ValueError(f"need 0 <= failures <= exposure (got {F}, {T})")
    a = 0.5 * (1.0 - level)
    if T == 0:
        return MCEstimate(F, T, None, (None, None), None, level)
    p_hi = float(beta.ppf(1.0 - a, F + 1, T - F)) if F < T else 1.0
    if F == 0:
        return MCEstimate(F, T, None, (1.0 / p_hi, None), 0.0, level)
    p_lo = float(beta.ppf(a, F, T - F + 1))
    return MCEstimate(F, T, T / F, (1.0 / p_hi, 1.0 / p_lo), F / T, level)


@dataclass(frozen=True)
class ChainMFPT:
    """The chain's MFPT (module docstring): ``lambda2`` [1], ``mfpt`` ``1/(1 - lambda_2)``
    [steps] (None when ``1 - lambda_2 < NO_FAILURE``: no failure reachable), ``from_start``
    ``w . (I - Q)^-1 1`` [steps] from the start distribution ``w`` (None likewise), ``reason``
    when they are None."""

    lambda2: float
    mfpt: float | None
    from_start: float | None
    reason: str = ""


def chain_mfpt(Q: np.ndarray, start: np.ndarray | None = None) -> ChainMFPT:
    """``lambda_2`` (the Perron root of the non-negative ``Q``), ``1/(1 - lambda_2)`` and the
    expected steps attempted from the distribution ``start`` over the states (default: the
    first state) by solving ``(I - Q) m = 1``."""
    Q = np.asarray(Q, float)
    n = Q.shape[0]
    w = np.zeros(n) if start is None else np.asarray(start, float)
    if start is None:
        w[0] = 1.0
    # the Perron root of a non-negative matrix is its spectral radius
    lam = float(np.max(np.abs(np.linalg.eigvals(Q)))) if n else 0.0
    if 1.0 - lam < NO_FAILURE:
        return ChainMFPT(lam, None, None, f"1 - lambda_2 = {1.0 - lam:.3g} < {NO_FAILURE:g}: "
                                          "no failure is reachable on the mesh (the MFPT "
                                          "is effectively infinite)")
    try:
        m = np.linalg.solve(np.eye(n) - Q, np.ones(n))
        from_start = float(w @ m)
    except np.linalg.LinAlgError:
        from_start = None
    return ChainMFPT(lam, 1.0 / (1.0 - lam), from_start)


def interpolation_weights(grid: np.ndarray, values: np.ndarray) -> tuple[np.ndarray,
                                                                         np.ndarray,
                                                                         np.ndarray]:
    """Linear (barycentric) weights of ``values`` on the sorted ``grid``: ``(lower index,
    weight of the upper point, clipped)``; values beyond the ends go to the end point
    (``clipped`` true). The weights keep the mean of a value inside the grid."""
    g = np.asarray(grid, float)
    v = np.asarray(values, float)
    clipped = (v < g[0]) | (v > g[-1])
    vc = np.clip(v, g[0], g[-1])
    i = np.clip(np.searchsorted(g, vc, side="right") - 1, 0, g.size - 2)
    t = (vc - g[i]) / (g[i + 1] - g[i])
    return i, t, clipped
