"""Rewrite the parameter table of docs/config.md from AOASSConfig's metadata.

Run: ``python3 scripts/make_config_doc.py`` (tests/test_config.py checks the two agree).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from aoass_env.atomic import write_text_atomic
from aoass_env.config import AOASSConfig

DOC = Path(__file__).resolve().parents[1] / "docs" / "config.md"


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args(argv)  # no options
    lines = DOC.read_text().split("\n")
    start = next(i for i, line in enumerate(lines) if line.startswith("| parameter | default"))
    end = start
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    lines[start:end] = AOASSConfig.markdown().split("\n")
    write_text_atomic(DOC, "\n".join(lines))


if __name__ == "__main__":
    main()
