"""The Makefile's set-up against pyproject.toml: `make test` installs the simulation kernel's
dependencies first (so that the kernel compiles while pip installs the rest); they must be
exactly pyproject's specifiers for those packages, or the two installs could disagree."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_kernel_dependencies_are_pyprojects():
    make = (REPO / "Makefile").read_text()
    line = re.search(r"^KERNEL_DEPS\s*:=\s*(.+)$", make, re.M)
    assert line, "no KERNEL_DEPS in the Makefile"
    kernel = re.findall(r'"([^"]+)"', line.group(1))
    pyproject = (REPO / "pyproject.toml").read_text()
    block = re.search(r"^dependencies = \[(.*?)^\]", pyproject, re.M | re.S).group(1)
    deps = {re.split(r"[<>=!~ ]", d, maxsplit=1)[0].lower(): d
            for d in re.findall(r'"([^"]+)"', block)}
    assert kernel and all(re.split(r"[<>=!~ ]", k, maxsplit=1)[0].lower() in deps
                          for k in kernel), (kernel, deps)
    for spec in kernel:
        name = re.split(r"[<>=!~ ]", spec, maxsplit=1)[0].lower()
        assert deps[name] == spec, (spec, deps[name])
