"""Test-session settings: one torch thread (tiny networks; the CI machine has 2 cores)."""

import torch

torch.set_num_threads(1)
