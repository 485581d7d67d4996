"""Points of a sweep from its axes (:class:`~thrustwalk_cli.description.sweep.SweepSpec`).

The points are the product grid x zip x random, in this order (the last grid axis varies
fastest, then the zip index, then the random sample). Random axes are drawn once, axis after
axis in file order, ``samples`` values each, from ``numpy.random.default_rng(seed)``:
``uniform(low, high)``, ``normal(mean, std)`` and log-uniform ``exp(uniform(ln low, ln high))``;
the same samples are combined with every grid and zip point (common random numbers).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from ..description.sweep import Axis, SweepSpec


def draw(axis: Axis, rng: np.random.Generator, samples: int) -> tuple[float, ...]:
    """``samples`` values of a random axis (in its unit)."""
    a, b = axis.parameters
    if axis.distribution == "uniform":
        v = rng.uniform(a, b, samples)
    elif axis.distribution == "normal":
        v = rng.normal(a, b, samples)
    else:  # log-uniform
        v = np.exp(rng.uniform(math.log(a), math.log(b), samples))
    return tuple(float(x) for x in v)


def random_values(spec: SweepSpec) -> dict[str, tuple[float, ...]]:
    """The drawn values of every random axis (axis name -> ``samples`` values)."""
    rng = np.random.default_rng(spec.seed)
    return {a.name: draw(a, rng, spec.samples) for a in spec.group("random")}


def expand(spec: SweepSpec) -> list[dict[str, float]]:
    """Every point as ``{axis name: value}`` (module docstring for the order)."""
    grid = spec.group("grid")
    zipped = spec.group("zip")
    drawn = random_values(spec)
    zip_rows = list(zip(*(a.values for a in zipped))) if zipped else [()]
    rnd_rows = list(zip(*drawn.values())) if drawn else [()]
    out = []
    for g in itertools.product(*(a.values for a in grid)):
        for z in zip_rows:
            for r in rnd_rows:
                point = dict(zip((a.name for a in grid), g))
                point.update(zip((a.name for a in zipped), z))
                point.update(zip(drawn, r))
                out.append({k: float(v) for k, v in point.items()})
    return out


def grid_coordinates(spec: SweepSpec) -> list[tuple[tuple[int, ...], int]]:
    """Per point (in :func:`expand` order): its index along every grid axis and the index of
    its zip/random combination."""
    grid = spec.group("grid")
    rest = (len(spec.group("zip")[0].values) if spec.group("zip") else 1) * \
        (spec.samples if spec.group("random") else 1)
    return [(g, r) for g in itertools.product(*(range(len(a.values)) for a in grid))
            for r in range(rest)]


def neighbours(spec: SweepSpec) -> list[int | None]:
    """For continuation: the point each point starts from, or None. Along the last grid axis
    each point follows its predecessor; the first point of such a line follows the point one
    step back along the nearest earlier grid axis that is not at its start (a tree rooted at
    the first grid point; zip and random combinations are separate trees)."""
    coords = grid_coordinates(spec)
    index = {c: i for i, c in enumerate(coords)}
    out: list[int | None] = []
    for g, r in coords:
        j = next((k for k in range(len(g) - 1, -1, -1) if g[k] > 0), None)
        if j is None:
            out.append(None)
            continue
        prev = g[:j] + (g[j] - 1,) + g[j + 1:]
        out.append(index[(prev, r)])
    return out
