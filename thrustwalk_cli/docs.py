"""Keep the README's key tables in sync with the schema tables (``make docs``)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from .robot_io import GAIT_SCHEMA, ROBOT_SCHEMA
from .schema import markdown_table

SECTIONS = {"robot-keys": ROBOT_SCHEMA, "gait-keys": GAIT_SCHEMA}


def render(readme: str) -> str:
    """Replace every ``<!-- NAME:start -->...<!-- NAME:end -->`` block by its table."""
    for name, schema in SECTIONS.items():
        pattern = re.compile(rf"(<!-- {name}:start -->\n).*?(<!-- {name}:end -->)", re.S)
        if not pattern.search(readme):
            raise ValueError(f"README has no {name} block")
        readme = pattern.sub(lambda m, s=schema: m.group(1) + markdown_table(s) + m.group(2),
                             readme)
    return readme


def main() -> None:
    path = Path(sys.argv[1] if len(sys.argv) > 1 else "README.md")
    path.write_text(render(path.read_text()))


if __name__ == "__main__":
    main()
