"""A terrain for the full-order simulation (SPEC 14): a slope and the heights of the steps.

The swing foot of step ``k`` (1-based) lands ``h_k`` [m] above its stance foot, normal to the
mean slope. The heights are an explicit list (``steps``; level ground after its end) or drawn
i.i.d. from a distribution (``rough``: ``normal`` with standard deviation ``sigma``, or
``uniform`` on ``[-half_width, half_width]``) by ``numpy.random.default_rng(seed)``, so a run
is reproducible from the terrain alone. Past ``s = s_max`` without touching the ground the
walker has missed its footing. numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DISTRIBUTIONS = ("normal", "uniform")
S_MAX = 1.3  # [1] default: past it without a touchdown the walker has missed its footing


@dataclass(frozen=True)
class Terrain:
    """``slope`` [rad, positive uphill]; ``steps`` explicit heights [m] (empty: none) or
    ``distribution`` (``normal``/``uniform``, None: none) with ``spread`` [m] (``sigma`` or
    ``half_width``) and ``seed``; ``s_max`` [1] the missed-footing limit."""

    slope: float = 0.0
    steps: tuple[float, ...] = ()
    distribution: str | None = None
    spread: float = 0.0
    seed: int = 0
    s_max: float = S_MAX
    description: str = ""
    source_file: str = "<memory>"
    source_sha256: str = ""

    def heights(self, n: int) -> np.ndarray:
        """The heights [m] of steps 1..n: the explicit list then 0 (level ground), or ``n``
        draws of the distribution (the first ``n`` of the seeded sequence: a longer run
        continues the same terrain)."""
        if self.distribution is None:
            out = np.zeros(n)
            k = min(n, len(self.steps))
            out[:k] = self.steps[:k]
            return out
        rng = np.random.default_rng(self.seed)
        if self.distribution == "normal":
            return rng.normal(0.0, self.spread, n) if self.spread > 0 else np.zeros(n)
        return rng.uniform(-self.spread, self.spread, n) if self.spread > 0 else np.zeros(n)

    def record(self) -> dict:
        """The terrain as a result records it (SI units)."""
        out: dict = {"file": self.source_file, "sha256": self.source_sha256,
                     "description": self.description, "slope": self.slope,
                     "s_max": self.s_max}
        if self.distribution is None:
            out["steps"] = list(self.steps)
            out["after_steps"] = "level ground (height 0)"
        else:
            key = "sigma" if self.distribution == "normal" else "half_width"
            out["rough"] = {"distribution": self.distribution, key: self.spread,
                            "seed": self.seed,
                            "draws": "numpy.random.default_rng(seed), one height per step"}
        return out
