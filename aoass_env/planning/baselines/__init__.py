"""The AOASS paper's baselines (OHM, FDPP, M-ANCHORO), reconstructed from their publications.

Filled in by the baselines work (issue 7); see docs/baselines.md.
"""

from __future__ import annotations

from aoass_env.planning.path import PlannedMethod

#: The reconstructed baselines by command-line name.
BASELINE_METHODS: dict[str, PlannedMethod] = {}
