"""First-run cost of the compiled kernels: AOASS-Safe-v0's warm-up on a copy of the package with
an empty numba cache, then again with the cache the first run wrote.

    python3 benchmarks/first_run.py

The package (``aoass_env/``, without its ``__pycache__`` folders) and ``benchmarks/`` are
copied to a temporary folder; a fresh interpreter imports them from there and times
``env_throughput.warm_up_env`` (random steps of AOASS-Safe-v0 until, after its first look-ahead
and an episode's end, 2 000 steps in a row compiled nothing): the first time every kernel it
reaches compiles, the second time they load from numba's cache.
Prints the import time and the two warm-ups (wall seconds), and their ratio cold / warm: the
reference is the same warm-up on the same copy, measured by the same script, so the ratio (what
a machine's first run costs in cached runs) compares across machines and days where the
seconds do not. Each process then runs the same warm-up again on a fresh env (the generator's
map cache emptied), every kernel already in memory: the stepping alone, which the script
subtracts to print what compiling and what loading the cache cost (the cached warm-up is mostly
stepping).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_PROBE = """
import sys, time
sys.path.insert(0, "benchmarks")
t = time.perf_counter()
import gymnasium as gym
import aoass_env
from env_throughput import warm_up_env
imported = time.perf_counter()
warm_up_env(gym.make("AOASS-Safe-v0"))
warmed = time.perf_counter()
from aoass_env.maps.generator import clear_cache
clear_cache()
warm_up_env(gym.make("AOASS-Safe-v0"))
print(f"{imported - t:.4f} {warmed - imported:.4f} {time.perf_counter() - warmed:.4f}")
"""


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args(argv)  # no options
    with tempfile.TemporaryDirectory(prefix="aoass_first_run_") as folder:
        for part in ("aoass_env", "benchmarks"):
            shutil.copytree(ROOT / part, Path(folder) / part,
                            ignore=shutil.ignore_patterns("__pycache__"))
        # this machine's environment, but the copy on the path and numba's default cache
        # (beside the copy's sources: empty the first time)
        env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
        env["PYTHONPATH"] = folder
        times = []
        for _ in range(2):
            out = subprocess.run([sys.executable, "-c", _PROBE], cwd=folder, check=True,
                                 capture_output=True, text=True, env=env).stdout
            times.append([float(x) for x in out.split()])
    (imp1, first, again1), (imp2, cached, again2) = times
    print(f"import aoass_env and gymnasium: {imp1:.1f} s, {imp2:.1f} s")
    print(f"AOASS-Safe-v0 warm-up until no kernel compiles: {first:.1f} s with an empty numba "
          f"cache (every kernel compiles), {cached:.1f} s with the cache it wrote; ratio "
          f"cold / warm {first / cached:.1f}")
    print(f"the same warm-up again in each process, every kernel in memory (the stepping "
          f"alone): {again1:.1f} s, {again2:.1f} s; so compiling took {first - again1:.1f} s "
          f"and loading the cache {cached - again2:.1f} s")


if __name__ == "__main__":
    main()
