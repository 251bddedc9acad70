"""Cost of ``import aoass_env`` against ``import gymnasium``, each in a fresh interpreter.

    python3 benchmarks/import_time.py [--repeats 7]

``import aoass_env`` registers the environments and nothing more: its public names, the
localizer (torch) and the safety stack (filterpy, which pulls in scipy.stats) load on first use.
Each of ``--repeats`` rounds runs every case once in a fresh interpreter, the order rotated by
one case each round (``git_history.in_turn``: each case leads one round in five; ``import
gymnasium`` used to lead every round, so whatever leading costs fell on the reference alone,
and ``import aoass_env``, which imports gymnasium, came out at 0.64-0.80x of it). Prints the
median wall time of each case, its ratio to ``import gymnasium``'s and the modules each leaves
in ``sys.modules``; for the 2.5x target, the paired figures of ``import aoass_env``: the median
of the rounds' own ratios and differences to that round's ``import gymnasium``, with their
range. ``import aoass_env`` adds two modules to gymnasium's 323, less than a fresh
interpreter's scatter on a shared machine: a ratio below 1 is that scatter, which the range
shows, and fewer rounds than cases (five) are warned about. The cases: ``import gymnasium``,
``import aoass_env``, the lightest useful imports (``aoass_env.metrics``,
``aoass_env.localization.dvhop``) and ``gymnasium.make("AOASS-v0")``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

from git_history import in_turn

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


def paired(runs: dict[str, list[dict]], case: str, reference: str = "import gymnasium"
           ) -> tuple[list[float], list[float]]:
    """(ratios, differences in seconds) of ``case`` to ``reference``, round by round."""
    pairs = list(zip(runs[case], runs[reference], strict=True))
    return ([a["seconds"] / b["seconds"] for a, b in pairs],
            [a["seconds"] - b["seconds"] for a, b in pairs])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=argparse_number(int, 1), default=7,
                        help=f"rounds of fresh interpreters, one per case; >= {len(CASES)} for "
                             f"each case to lead one")
    args = parser.parse_args()
    runs: dict[str, list[dict]] = {name: [] for name in CASES}
    for i in range(args.repeats):
        for name in in_turn(i, *CASES):
            runs[name].append(probe(CASES[name]))
    median = {name: statistics.median(r["seconds"] for r in rs) for name, rs in runs.items()}
    reference = median["import gymnasium"]
    print(f"{'statement':38s} {'median s':>9s} {'x gymnasium':>12s} {'modules':>8s}  heavy")
    for name, rs in runs.items():
        heavy = [m for m in ("torch", "filterpy") if rs[-1][m]]
        print(f"{name:38s} {median[name]:9.3f} {median[name] / reference:12.2f} "
              f"{rs[-1]['modules']:8d}  {', '.join(heavy) or '-'}")
    ratios, differences = paired(runs, "import aoass_env")
    ratio = statistics.median(ratios)
    verdict = "met" if ratio <= TARGET else "MISSED"
    print(f"\nimport aoass_env costs {ratio:.2f}x import gymnasium (median of {args.repeats} "
          f"rounds' ratios, range {min(ratios):.2f}-{max(ratios):.2f}; target <= {TARGET}x: "
          f"{verdict}), {1e3 * statistics.median(differences):+.0f} ms (range "
          f"{1e3 * min(differences):+.0f} to {1e3 * max(differences):+.0f})")
    if args.repeats < len(CASES):
        print(f"warning: --repeats {args.repeats} < {len(CASES)}: not every case led a round, "
              f"and a fresh interpreter scatters by more than the two imports differ; a ratio "
              f"below 1 is that scatter")


if __name__ == "__main__":
    main()
