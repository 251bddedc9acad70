"""Rewrite the parameter table of docs/config.md from AOASSConfig's metadata.

Run: ``python3 scripts/make_config_doc.py`` (tests/test_config.py checks the two agree).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from aoass_env.atomic import write_text_atomic
from aoass_env.config import AOASSConfig

DOC = Path(__file__).resolve().parents[1] / "docs" / "config.md"


#: the first line of the table the script rewrites
HEADER = "| parameter | default"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.parse_args(argv)  # no options
    try:        # a missing file was a FileNotFoundError traceback, a missing table StopIteration
        lines = DOC.read_text().split("\n")
    except (OSError, UnicodeDecodeError) as err:
        parser.error(f"{DOC}: cannot read it ({getattr(err, 'strerror', None) or err})")
    start = next((i for i, line in enumerate(lines) if line.startswith(HEADER)), None)
    if start is None:
        parser.error(f"{DOC}: holds no parameter table (a line starting {HEADER!r}) to rewrite")
    end = start
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    lines[start:end] = AOASSConfig.markdown().split("\n")
    write_text_atomic(DOC, "\n".join(lines))


if __name__ == "__main__":
    main()
