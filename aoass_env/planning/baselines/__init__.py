"""The reconstructed baselines (OHM, FDPP and M-ANCHORO from the AOASS paper, and OTPP),
rebuilt from their publications.

See docs/baselines.md for what each publication says and what was rebuilt.
"""

from __future__ import annotations

from aoass_env.planning.baselines.fdpp import FDPP
from aoass_env.planning.baselines.m_anchoro import M_ANCHORO
from aoass_env.planning.baselines.ohm import OHM
from aoass_env.planning.baselines.otpp import OTPP
from aoass_env.planning.sweep import PlannedMethod

#: The reconstructed baselines by command-line name.
BASELINE_METHODS: dict[str, PlannedMethod] = {m.name: m for m in (OHM, FDPP, M_ANCHORO, OTPP)}
