"""Cost of ``import aoass_env`` against ``import gymnasium``, each in a fresh interpreter.

    python3 benchmarks/import_time.py [--repeats 7]

``import aoass_env`` registers the environments and nothing more: its public names, the
localizer (torch) and the safety stack (filterpy, which pulls in scipy.stats) load on first use.
Prints the median wall time of each import over ``--repeats`` fresh interpreters (taken in
turn, so both see the same machine load), the ratio against the 2.5x target, the modules each
leaves in ``sys.modules``, and the same for the lightest useful imports (``aoass_env.metrics``,
``aoass_env.localization.dvhop``) and for ``gymnasium.make("AOASS-v0")``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

from aoass_env.validators import argparse_number

TARGET = 2.5

_PROBE = """
import json, sys, time
t = time.perf_counter()
{statement}
print(json.dumps({{"seconds": time.perf_counter() - t, "modules": len(sys.modules),
                  "torch": "torch" in sys.modules, "filterpy": "filterpy" in sys.modules}}))
"""

CASES = {
    "import gymnasium": "import gymnasium",
    "import aoass_env": "import aoass_env",
    "import aoass_env.metrics": "import aoass_env.metrics",
    "import aoass_env.localization.dvhop": "import aoass_env.localization.dvhop",
    'gymnasium.make("AOASS-v0")': "import gymnasium, aoass_env; gymnasium.make('AOASS-v0')",
}


def probe(statement: str) -> dict:
    """Seconds, module count and heavy imports of ``statement`` in a fresh interpreter."""
    out = subprocess.run([sys.executable, "-c", _PROBE.format(statement=statement)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=argparse_number(int, 1),
                        default=7, help="fresh interpreters per case")
    args = parser.parse_args()
    runs: dict[str, list[dict]] = {name: [] for name in CASES}
    for _ in range(args.repeats):
        for name, statement in CASES.items():
            runs[name].append(probe(statement))
    median = {name: statistics.median(r["seconds"] for r in rs) for name, rs in runs.items()}
    reference = median["import gymnasium"]
    print(f"{'statement':38s} {'median s':>9s} {'x gymnasium':>12s} {'modules':>8s}  heavy")
    for name, rs in runs.items():
        heavy = [m for m in ("torch", "filterpy") if rs[-1][m]]
        print(f"{name:38s} {median[name]:9.3f} {median[name] / reference:12.2f} "
              f"{rs[-1]['modules']:8d}  {', '.join(heavy) or '-'}")
    ratio = median["import aoass_env"] / reference
    verdict = "met" if ratio <= TARGET else "MISSED"
    print(f"\nimport aoass_env costs {ratio:.2f}x import gymnasium (target <= {TARGET}x: "
          f"{verdict}; {args.repeats} fresh interpreters each)")


if __name__ == "__main__":
    main()
