"""evaluate.py: the OpenBLAS kernels it pins before NumPy loads (the sweeps themselves are
tests/evaluation's)."""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("evaluate_under_test", ROOT / "evaluate.py")
evaluate = importlib.util.module_from_spec(spec)
spec.loader.exec_module(evaluate)

AVX2 = "processor\t: 0\nflags\t\t: fpu sse2 avx fma avx2 bmi2\n"


@pytest.fixture
def unset(monkeypatch):
    """No OPENBLAS_CORETYPE in the environment, on an x86-64 machine."""
    monkeypatch.delenv("OPENBLAS_CORETYPE", raising=False)
    monkeypatch.setattr(evaluate.platform, "machine", lambda: "x86_64")
    return monkeypatch


def test_an_avx2_machine_gets_the_haswell_kernels(unset, tmp_path):
    (tmp_path / "cpuinfo").write_text(AVX2)
    assert evaluate.pin_blas_kernels(str(tmp_path / "cpuinfo")) == "Haswell"
    assert os.environ["OPENBLAS_CORETYPE"] == "Haswell"


@pytest.mark.parametrize("flags", ["fpu sse2 avx fma", "fpu sse2 avx avx2", ""])
def test_a_cpu_without_avx2_and_fma_keeps_its_own_kernels(unset, tmp_path, flags):
    """Forcing kernels a CPU lacks would crash OpenBLAS at load (illegal instructions)."""
    (tmp_path / "cpuinfo").write_text(f"processor\t: 0\nflags\t\t: {flags}\n")
    assert evaluate.pin_blas_kernels(str(tmp_path / "cpuinfo")) is None
    assert "OPENBLAS_CORETYPE" not in os.environ


def test_another_machine_or_no_cpuinfo_pins_nothing(unset, tmp_path):
    assert evaluate.pin_blas_kernels(str(tmp_path / "missing")) is None
    (tmp_path / "cpuinfo").write_text(AVX2)
    unset.setattr(evaluate.platform, "machine", lambda: "aarch64")
    assert evaluate.pin_blas_kernels(str(tmp_path / "cpuinfo")) is None
    assert "OPENBLAS_CORETYPE" not in os.environ


def test_kernels_the_user_chose_are_kept(unset, tmp_path):
    (tmp_path / "cpuinfo").write_text(AVX2)
    unset.setenv("OPENBLAS_CORETYPE", "SkylakeX")
    assert evaluate.pin_blas_kernels(str(tmp_path / "cpuinfo")) == "SkylakeX"
    assert os.environ["OPENBLAS_CORETYPE"] == "SkylakeX"


def test_loading_the_script_gives_numpy_the_pinned_kernels():
    """In a fresh interpreter without OPENBLAS_CORETYPE, loading evaluate.py before NumPy gives
    NumPy's OpenBLAS the pinned kernels (what evaluate.py records in inputs.json), whichever the
    CPU would pick; on a machine where nothing is pinned, its own."""
    code = ("import importlib.util, sys; "
            "s = importlib.util.spec_from_file_location('e', sys.argv[1]); "
            "e = importlib.util.module_from_spec(s); s.loader.exec_module(e); "
            "from aoass_env.evaluation.store import blas_kernels; "
            "print(e.pin_blas_kernels(), blas_kernels(), sep='|')")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    out = subprocess.run([sys.executable, "-c", code, str(ROOT / "evaluate.py")], env=env,
                         capture_output=True, text=True, check=True).stdout.strip()
    pinned, kernels = out.split("|")
    if pinned == "None":
        pytest.skip(f"nothing is pinned on this machine (kernels: {kernels})")
    assert kernels == f"openblas {pinned}" == "openblas Haswell"
