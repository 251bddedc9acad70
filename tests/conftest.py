"""Test-session settings: one torch thread (tiny networks; the CI machine has 2 cores); the
``train_script`` fixture."""

import importlib.util
import sys
from pathlib import Path

import pytest
import torch

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
