"""The field's classical static sweep paths, run with the common obstacle rule.

Filled in by the classical-paths work (issue 7); see docs/planning.md.
"""

from __future__ import annotations

from aoass_env.planning.path import PlannedMethod

#: The classical paths by command-line name.
CLASSICAL_METHODS: dict[str, PlannedMethod] = {}
