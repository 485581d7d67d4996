"""Terrain files (SPEC 14): a slope and the step heights of the full-order simulation (the
terrain schema table).

```yaml
description: one 1 cm step up, then level ground
slope: 0.02                    # [rad], positive uphill (optional)
steps: [0.01]                  # [m] the swing foot of step k lands h_k above its stance foot
s_max: 1.3                     # past this s without a touchdown: missed footing
```

or rough ground, one height per step drawn i.i.d. and seeded:

```yaml
rough: {distribution: normal, sigma: 0.005, seed: 7}      # or uniform with half_width
```

Every problem is reported as ``file:line: key.path: message``.
"""

from __future__ import annotations

import math
from pathlib import Path

from ..description.terrain import DISTRIBUTIONS, S_MAX, Terrain
from ..errors import InputError, Problem
from .schema import (
    check,
    choice,
    field,
    integer,
    kind_check,
    mapping,
    null_or,
    number,
    string,
    vector,
)
from .yamlio import load_yaml

MAX_STEPS = 10_000  # explicit heights (the simulation's step limit)
MAX_HEIGHT = 1.0  # [m] |h| above this is not a step a walker takes

ROUGH_SCHEMA = mapping(
    field("distribution", choice(*DISTRIBUTIONS), "normal (standard deviation `sigma`) or "
          "uniform on [-half_width, half_width]"),
    field("sigma", null_or(number("m", ge=0, le=MAX_HEIGHT)), "standard deviation (normal)",
          default=None),
    field("half_width", null_or(number("m", ge=0, le=MAX_HEIGHT)), "half the width "
          "(uniform)", default=None),
    field("seed", integer("1", ge=0), "seed of numpy's default_rng: the heights are "
          "reproducible from it", default=0),
)

TERRAIN_SCHEMA = mapping(
    field("description", string(nonempty=False), "free text", default=""),
    field("slope", number("rad", gt=-0.5 * math.pi, lt=0.5 * math.pi), "ground angle, "
          "positive uphill (the step heights are normal to it)", default=0.0),
    field("steps", null_or(vector(unit="m", min_len=1, max_len=MAX_STEPS, ge=-MAX_HEIGHT,
                                  le=MAX_HEIGHT)),
          "step heights: the swing foot of step k lands h_k above its stance foot, normal to "
          "the slope; level ground (0) after the list", default=None),
    field("rough", null_or(ROUGH_SCHEMA), "rough ground: one height per step, drawn i.i.d. "
          "(instead of `steps`)", default=None),
    field("s_max", number("1", gt=1, le=3), "past this phase s without a touchdown the "
          "walker has missed its footing (outcome missed_footing); a step-down is met on the "
          "gait's Bezier polynomials continued past s = 1", default=S_MAX),
)


def load_terrain(ref: str | Path) -> Terrain:
    """Read and validate a terrain file; raises :class:`InputError` with every problem."""
    path = Path(ref)
    doc = load_yaml(path, expect=kind_check("terrain", TERRAIN_SCHEMA))
    res = check(doc, TERRAIN_SCHEMA, parameters_path=None)
    res.raise_if_problems()
    d = res.data
    problems: list[Problem] = []
    rough = d["rough"]
    dist, spread, seed = None, 0.0, 0
    if d["steps"] is not None and rough is not None:
        problems.append(res.problem(("rough",), "give either `steps` or `rough`, not both"))
    if rough is not None:
        dist, seed = rough["distribution"], rough["seed"]
        need, other = ("sigma", "half_width") if dist == "normal" else ("half_width", "sigma")
        if rough[other] is not None:
            problems.append(res.problem(("rough", other), f"not a parameter of the {dist} "
                                                          f"distribution (give `{need}`)"))
        elif rough[need] is None:
            problems.append(res.problem(("rough",), f"the {dist} distribution needs "
                                                    f"`{need}` [m]"))
        else:
            spread = float(rough[need])
    if problems:
        raise InputError(sorted(problems, key=lambda p: p.line or 0))
    steps = tuple(float(h) for h in d["steps"]) if d["steps"] is not None else ()
    return Terrain(float(d["slope"]), steps, dist, spread, int(seed), float(d["s_max"]),
                   d["description"], str(path), doc.sha256)
