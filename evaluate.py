"""Benchmark runner: every method over a preset's grid of test maps, node counts and seeds.

    python3 evaluate.py                              # preset "quick" (a few minutes on 2 cores)
    python3 evaluate.py --preset fig2 --workers 16   # Figure 2's grid, 30 seeds
    python3 evaluate.py --methods aoass spiral scan --seeds 3 --out out/run1 --save-logs
    python3 evaluate.py --logs out/run1/logs --out out/relocalized

``python3 evaluate.py --help`` lists presets, methods and localizers; docs/evaluation.md
describes the outputs (episodes.csv, summary.csv, summary.md, fig2-4.png) and resuming.

Before anything loads NumPy, this script pins OpenBLAS's Haswell (AVX2) kernels on every x86-64
Linux machine that has them (:func:`pin_blas_kernels`), so that its episodes are the same bit
for bit on every such machine, AVX-512 or not (docs/evaluation.md, "Across machines").
"""

import os
import platform
import sys

#: The OpenBLAS kernels evaluate.py pins: the AVX2 ones, which every x86-64 CPU with AVX2 and
#: FMA runs (OpenBLAS would pick SkylakeX's on an AVX-512 CPU, whose small products sum in
#: another order). The tests pin the same (tests/conftest.py).
BLAS_CORETYPE = "Haswell"


def pin_blas_kernels(cpuinfo: str = "/proc/cpuinfo") -> str | None:
    """Set ``OPENBLAS_CORETYPE`` to :data:`BLAS_CORETYPE` on an x86-64 Linux machine whose CPU
    (``cpuinfo``'s flags) has AVX2 and FMA, unless it is set already; return the value in force
    (None where nothing is pinned: another machine, or no cpuinfo to read). OpenBLAS reads it
    once, when NumPy loads, so this must run first; forcing kernels a CPU lacks would crash,
    hence the check."""
    if "OPENBLAS_CORETYPE" in os.environ:
        return os.environ["OPENBLAS_CORETYPE"]
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    try:
        with open(cpuinfo, encoding="ascii", errors="replace") as info:
            flags = next((line.split(":", 1)[1].split() for line in info
                          if line.startswith("flags")), [])
    except OSError:
        return None
    if "avx2" not in flags or "fma" not in flags:
        return None
    os.environ["OPENBLAS_CORETYPE"] = BLAS_CORETYPE
    return BLAS_CORETYPE


pin_blas_kernels()      # on import too: scripts/make_results.py and the tests import this first

if __name__ == "__main__":
    from aoass_env.evaluation.cli import main

    sys.exit(main())
