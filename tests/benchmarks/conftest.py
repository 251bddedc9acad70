"""Shared fixtures of the benchmark scripts' tests."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]


def load_benchmark(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` loaded as a module (the scripts are not a package), their
    folder on ``sys.path`` as when run by path (their shared module ``git_history``)."""
    folder = str(ROOT / "benchmarks")
    if folder not in sys.path:
        sys.path.append(folder)
    spec = importlib.util.spec_from_file_location(f"aoass_bench_{name}",
                                                  ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def refused(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture, name: str,
            *argv: str, module: ModuleType | None = None) -> str:
    """The one-line error of ``benchmarks/<name>.py argv`` (``module``: the script already
    loaded): its ``main`` exits with argparse's status 2, no traceback, and the last line of
    stderr is ``<prog>: error: <message>``; returns the message."""
    module = load_benchmark(name) if module is None else module
    monkeypatch.setattr(sys, "argv", [f"{name}.py", *argv])
    with pytest.raises(SystemExit) as exit_:
        module.main()
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert ": error: " in last, last
    return last.split(": error: ", 1)[1]


@pytest.fixture
def one_thread_scripts():
    """For the scripts that set one thread when imported (``*_NUM_THREADS``, torch's threads):
    what this process had is put back after the test."""
    import torch

    names = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
    saved, threads = {name: os.environ.get(name) for name in names}, torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
    for name, value in saved.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value
