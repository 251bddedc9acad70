"""Test-session settings: OpenBLAS's Haswell kernels on x86-64 machines that have them (before
anything loads NumPy); one torch thread (tiny networks; the CI machine has 2 cores); the
``train_script`` fixture.

OpenBLAS picks its kernels by CPU at load, and kernels of different CPUs sum small matrix
products in different orders, so the last bits of a product can depend on the machine. The
episode fingerprints (tests/safety/test_safe_fingerprint.py: the Kalman tracker and the fuzzy
controller's centroid are such products) and the shipped results the tests replay
(docs/results-data) were made with the Haswell kernels (the AVX2 ones), which evaluate.py pins
the same way: loading it runs its ``pin_blas_kernels`` (on an AVX-512 machine OpenBLAS would
pick its SkylakeX kernels, and the hashes would differ though the code did not change). An
``OPENBLAS_CORETYPE`` already set is kept.
"""

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

_ROOT = Path(__file__).resolve().parent.parent


def _script(name: str, module: str) -> ModuleType:
    """The top-level script ``name`` (not in a package) loaded as the module ``module``."""
    spec = importlib.util.spec_from_file_location(module, _ROOT / name)
    loaded = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = loaded
    spec.loader.exec_module(loaded)
    return loaded


_script("evaluate.py", "aoass_evaluate_script")     # pins the kernels; it loads no NumPy

import pytest  # noqa: E402  (after OPENBLAS_CORETYPE, above)
import torch  # noqa: E402

torch.set_num_threads(1)


@pytest.fixture(scope="session")
def train_script():
    """``train.py`` loaded as a module (a script at the top level, not in a package)."""
    return _script("train.py", "aoass_train_script")
