"""Keep the key tables of ``docs/files.md`` in sync with the schema tables (``make docs``)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from .gait_file import GAIT_SCHEMA
from .output import write_text_atomic
from .robot_file import ROBOT_SCHEMA
from .schema import markdown_table
from .sweep_file import STUDY_PARAMETERS, SWEEP_SCHEMA
from .terrain_file import TERRAIN_SCHEMA
from .uncertainty_file import UNCERTAINTY_SCHEMA
from .urdf_file import URDF_SIDE_SCHEMA

SECTIONS = {"robot-keys": ROBOT_SCHEMA, "gait-keys": GAIT_SCHEMA, "sweep-keys": SWEEP_SCHEMA,
            **{f"sweep-{study}-settings": kind for study, kind in STUDY_PARAMETERS.items()},
            "uncertainty-keys": UNCERTAINTY_SCHEMA, "urdf-side-keys": URDF_SIDE_SCHEMA,
            "terrain-keys": TERRAIN_SCHEMA}


def render(text: str) -> str:
    """Replace every ``<!-- NAME:start -->...<!-- NAME:end -->`` block by its table."""
    for name, schema in SECTIONS.items():
        pattern = re.compile(rf"(<!-- {name}:start -->\n).*?(<!-- {name}:end -->)", re.S)
        if not pattern.search(text):
            raise ValueError(f"the document has no {name} block")
        text = pattern.sub(lambda m, s=schema: m.group(1) + markdown_table(s) + m.group(2),
                           text)
    return text


def main() -> None:
    """``python -m thrustwalk_cli.files.schema_docs [docs/files.md]``: rewrite the tables."""
    path = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/files.md")
    write_text_atomic(path, render(path.read_text()))


if __name__ == "__main__":
    main()
