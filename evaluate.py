"""Benchmark runner: every method over a preset's grid of test maps, node counts and seeds.

    python3 evaluate.py                              # preset "quick" (a few minutes on 2 cores)
    python3 evaluate.py --preset fig2 --workers 16   # Figure 2's grid, 30 seeds
    python3 evaluate.py --methods aoass spiral scan --seeds 3 --out out/run1 --save-logs
    python3 evaluate.py --logs out/run1/logs --out out/relocalized

``python3 evaluate.py --help`` lists presets, methods and localizers; docs/evaluation.md
describes the outputs (episodes.csv, summary.csv, summary.md, fig2-4.png) and resuming.
"""

import sys

from aoass_env.evaluation.cli import main

if __name__ == "__main__":
    sys.exit(main())
