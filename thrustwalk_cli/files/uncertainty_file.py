"""Uncertainty files: robot parameters as distributions (the uncertainty schema table).

```yaml
description: torso mass 10 kg +- 10 % (one standard deviation)
seed: 7
parameters:                    # numbers of the robot file's parameters: section
  MT: {distribution: normal, mean: 10.0, std: 1.0, unit: kg}
  MH: {distribution: uniform, low: 13.5, high: 16.5, unit: kg}
```

Every problem is reported as ``file:line: key.path: message``; whether each name is a
parameter of the robot is checked against the robot (:class:`UncertaintySource`).
"""

from __future__ import annotations

from pathlib import Path

from ..description.sweep import Axis
from ..description.uncertainty import Uncertainty
from ..errors import InputError, Problem
from .schema import (
    ValidationResult,
    check,
    dict_of,
    field,
    integer,
    kind_check,
    mapping,
    string,
)
from .sweep_file import RANDOM_AXIS, _random_axis
from .yamlio import load_yaml

MAX_PARAMETERS = 100

UNCERTAINTY_SCHEMA = mapping(
    field("description", string(nonempty=False), "free text", default=""),
    field("seed", integer("1", ge=0), "seed of numpy's default_rng (the draws are reproducible "
          "from it)", default=0),
    field("parameters", dict_of(RANDOM_AXIS, key_name="parameter"), "robot-file parameters "
          "(the robot's parameters: section) and their distributions, drawn in file order"),
)


class UncertaintySource:
    """Validated uncertainty data kept for the checks against the robot (line numbers)."""

    def __init__(self, res: ValidationResult):
        self.res = res

    def where(self, key: tuple, message: str) -> Problem:
        return self.res.problem(key, message)


def load_uncertainty(ref: str | Path) -> tuple[Uncertainty, UncertaintySource]:
    """Read and validate an uncertainty file; raises :class:`InputError` with every problem."""
    path = Path(ref)
    doc = load_yaml(path, expect=kind_check("uncertainty", UNCERTAINTY_SCHEMA))
    res = check(doc, UNCERTAINTY_SCHEMA, parameters_path=None)
    res.raise_if_problems()
    d = res.data
    problems: list[Problem] = []
    axes = []
    if not d["parameters"]:
        problems.append(res.problem(("parameters",), "no parameter to draw"))
    if len(d["parameters"]) > MAX_PARAMETERS:
        problems.append(res.problem(("parameters",), f"{len(d['parameters'])} parameters: the "
                                                     f"limit is {MAX_PARAMETERS}"))
    for name, a in d["parameters"].items():
        key = ("parameters", name)
        par = _random_axis(name, a, key, res, problems)
        if par is not None:
            axes.append(Axis(f"robot.{name}", a["unit"] or "", "random", (), a["distribution"],
                             par))
    if problems:
        raise InputError(sorted(problems, key=lambda p: p.line or 0))
    return (Uncertainty(tuple(axes), d["seed"], d["description"], str(path), doc.sha256),
            UncertaintySource(res))
