"""Test-session settings: OpenBLAS's Haswell kernels on x86-64 machines that have them (before
anything loads NumPy); one torch thread (tiny networks; the CI machine has 2 cores); the
``train_script`` fixture.

OpenBLAS picks its kernels by CPU at load, and kernels of different CPUs sum small matrix
products in different orders, so the last bits of a product can depend on the machine. The
episode fingerprints (tests/safety/test_safe_fingerprint.py: the Kalman tracker and the fuzzy
controller's centroid are such products) pin bits that were recorded with the Haswell kernels
(the AVX2 ones; OpenBLAS also gives them to AMD Zen). On an AVX-512 machine OpenBLAS would pick
its SkylakeX kernels, and the hashes would differ though the code did not change. An
``OPENBLAS_CORETYPE`` already set is kept.
"""

import importlib.util
import os
import platform
import sys
from pathlib import Path


def _has_avx2() -> bool:
    """Whether this is an x86-64 Linux machine whose CPU has AVX2 and FMA (what OpenBLAS's
    Haswell kernels run on)."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return False
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as info:
            flags = next((line.split(":", 1)[1].split() for line in info
                          if line.startswith("flags")), [])
    except OSError:
        return False
    return "avx2" in flags and "fma" in flags


if _has_avx2():
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")

import pytest  # noqa: E402  (after OPENBLAS_CORETYPE, above)
import torch  # noqa: E402

torch.set_num_threads(1)


@pytest.fixture(scope="session")
def train_script():
    """``train.py`` loaded as a module (a script at the top level, not in a package)."""
    path = Path(__file__).resolve().parent.parent / "train.py"
    spec = importlib.util.spec_from_file_location("aoass_train_script", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
