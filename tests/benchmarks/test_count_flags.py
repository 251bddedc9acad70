"""The benchmark scripts refuse a count below its minimum in one line naming the flag, before
any work (they crashed with a ZeroDivisionError or an empty median after running)."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.benchmarks.conftest import ROOT

#: (script, flag, bad value, minimum) of counts read with ``argparse_number``
CASES = [
    ("fuzzy", "--calls", "0", 1), ("fuzzy", "--batch", "0", 1),
    ("kalman", "--targets", "0", 1), ("kalman", "--steps", "0", 1), ("kalman", "--seed", "-1", 0),
    ("maps", "--seeds", "0", 1),
    ("orca", "--calls", "0", 1), ("orca", "--repeats", "0", 1), ("orca", "--seed", "-1", 0),
    ("radio", "--nodes", "0", 1), ("radio", "--beacons", "0", 1),
    ("radio", "--reference-beacons", "0", 1), ("radio", "--seed", "-3", 0),
    ("coverage_map", "--steps", "0", 1), ("coverage_map", "--rounds", "0", 1),
    ("step_parts_speed", "--steps", "-1", 0), ("step_parts_speed", "--calls", "0", 1),
    ("recurrent_td3_speed", "--steps", "1", 2), ("recurrent_td3_speed", "--repeats", "0", 1),
    ("import_time", "--repeats", "0", 1),
    ("pendulum_memory", "--steps", "0", 1), ("pendulum_memory", "--seeds", "-2", 0),
    ("pendulum_memory", "--eval-freq", "-1", 0),
    ("safety", "--episodes", "0", 1), ("safety", "--zero-seeds", "0", 1),
    ("safety", "--kalman-steps", "0", 1), ("safety", "--speed-steps", "0", 1),
    ("safety", "--jobs", "0", 1), ("safety", "--cost-episodes", "0", 1),
    ("safety", "--first-seed", "-1", 0), ("safety", "--cost-first-seed", "-1", 0),
    ("step_speedup", "--steps", "0", 1), ("step_speedup", "--seeds", "0", 1),
    ("step_speedup", "--rounds", "0", 1),
    ("safety_speedup", "--steps", "0", 1), ("safety_speedup", "--seeds", "0", 1),
    ("safety_speedup", "--rounds", "0", 1),
    ("vector_envs", "--steps", "0", 1), ("vector_envs", "--envs", "0", 1),
    ("vector_envs", "--warm-up", "0", 1), ("vector_envs", "--seed", "-1", 0),
    ("rays", "--steps", "0", 1), ("rays", "--seed", "-1", 0),
    ("safety_contacts", "--first-seed", "-5", 0),
]

#: one interpreter runs every case (some scripts set thread variables when imported): each
#: script is loaded, its main() called with the bad flag, and argparse's exit recorded; the
#: scripts' folder first on the path, as when a script is run by path (their sibling imports)
_DRIVER = """
import contextlib, importlib.util, io, json, sys
sys.path.insert(0, "benchmarks")
out = []
for script, flag, value in json.loads(sys.argv[1]):
    spec = importlib.util.spec_from_file_location("bench_" + script, f"benchmarks/{script}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sys.argv = [f"{script}.py", flag, value]
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            module.main()
            code = None
        except SystemExit as exit:
            code = exit.code
    out.append([code, err.getvalue().strip().splitlines()[-1:]])
print(json.dumps(out))
"""


def test_counts_below_their_minimum_are_refused_in_one_line_naming_the_flag():
    cases = [[script, flag, value] for script, flag, value, _ in CASES]
    run = subprocess.run([sys.executable, "-c", _DRIVER, json.dumps(cases)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    results = json.loads(run.stdout.strip().splitlines()[-1])
    for (script, flag, value, low), (code, last) in zip(CASES, results, strict=True):
        assert code == 2, (script, flag, code)
        assert last == [f"{script}.py: error: argument {flag}: must be an integer >= {low}, "
                        f"got {value!r}"], (script, flag, last)


def test_first_run_takes_no_options():
    run = subprocess.run([sys.executable, "benchmarks/first_run.py", "--steps", "5"], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert run.stderr.strip().splitlines()[-1] == \
        "first_run.py: error: unrecognized arguments: --steps 5"
