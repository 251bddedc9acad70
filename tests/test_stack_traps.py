"""Regression tests: the AOASS safety stack ends its sweep by itself in traps.

Each scenario is a 40 m field (N = 100) whose first spiral leg (from the centre toward +x) runs
into a trap. The zero-action stack (Kalman tracks + fuzzy-ORCA) must end the sweep by itself
(path complete), with its coverage and no static contact; where the scenario traps the stack
for good without the follower's progress watchdog (``watchdog_time`` beyond the episode), that
is checked too, so the trap is known to be a real one.
"""

import numpy as np
import pytest

import aoass_env
from aoass_env.config import AOASSConfig
from aoass_env.evaluation.methods import METHODS, RunOptions
from aoass_env.maps import ObstacleMap, generate_map
from aoass_env.safety.config import SafetyConfig


def _wall(a, b, width):
    """A straight wall of ``width`` (m) from a to b, as a 4-gon."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]]) * width / 2
    return np.array([a + n, b + n, b - n, a - n])


TRAPS = {
    # two thin walls converging to a V whose apex (a 0.6 m gap) points along the first leg
    "v_wedge": [np.array([(23.0, 15.0), (28.6, 19.7), (23.4, 14.6)]),
                np.array([(23.0, 25.0), (28.6, 20.3), (23.4, 25.4)])],
    # a U pocket open toward the anchor, its back wall across the first leg
    "u_pocket": [_wall((26, 18.55), (30, 18.55), 1.0), _wall((26, 21.45), (30, 21.45), 1.0),
                 _wall((30.5, 18.05), (30.5, 21.95), 1.0)],
    # a dead-end corridor 1.9 m wide and 11 m long along the first leg
    "dead_end": [_wall((23, 18.55), (34, 18.55), 1.0), _wall((23, 21.45), (34, 21.45), 1.0),
                 _wall((34.5, 18.0), (34.5, 22.0), 1.0)],
    # a 4 m passage along the first leg; a moving obstacle parks in its middle
    "parked": [_wall((24, 17.0), (32, 17.0), 2.0), _wall((24, 23.0), (32, 23.0), 2.0)],
}
#: Scenarios that hold the stack until the time limit when the watchdog is off. The V and the
#: dead end did until the detour planner's free cells became exact (2026-11-30): its grid had
#: read the V's thin walls as open and snapped an anchor in the corridor to a cell behind its
#: wall; it now routes round both, and the stack sweeps them without a recovery.
REAL_TRAPS = ("parked",)
#: Scenarios the planner now routes round by itself (no recovery needed).
ROUTED = ("v_wedge", "dead_end")


def _sweep(trap: str, watchdog_time: float = 8.0, safety=None) -> tuple[bool, dict]:
    kw = dict(field_size=40.0, n_nodes=100, map_clearance=1.0, watchdog_time=watchdog_time)
    if trap == "parked":     # one obstacle that never moves, placed in the passage below
        kw.update(n_moving_obstacles=1, moving_obstacle_speed=(0.0, 0.0),
                  moving_obstacle_turn_rate=0.0)
    else:
        kw.update(n_moving_obstacles=0)
    env = aoass_env.make_safe_env(config=AOASSConfig(**kw), safety=safety)
    env.reset(seed=1, options={"map": ObstacleMap(40.0, 40.0, tuple(TRAPS[trap]))})
    if trap == "parked":
        world = env.unwrapped.sim.world
        world._mpos[0] = (28.0, 20.0)
        world._mbodies[0].position = (28.0, 20.0)
    zero = np.zeros(2, np.float32)
    while True:
        _, _, terminated, truncated, info = env.step(zero)
        if terminated or truncated:
            env.close()
            return terminated, info


@pytest.mark.parametrize("trap", list(TRAPS))
def test_stack_ends_the_sweep_by_itself_in_a_trap(trap):
    complete, info = _sweep(trap)
    assert complete, f"{trap}: the sweep was cut by the time limit"
    assert info["coverage"] >= 0.95
    assert info["static_contacts"] == 0 and info["wall_contacts"] == 0
    if trap in REAL_TRAPS:
        assert info["recoveries"] >= 1
    if trap in ROUTED:
        assert info["recoveries"] == 0


@pytest.mark.parametrize("trap", REAL_TRAPS)
def test_without_the_watchdog_the_trap_holds_the_stack(trap):
    # "parked" was built for the ORCA-only filter: the look-ahead (issue 24) backs away from
    # the parked obstacle by itself and covers more of the field without the watchdog (0.56
    # of the nodes; still not the whole spiral, and without a contact)
    complete, info = _sweep(trap, watchdog_time=1e4, safety=SafetyConfig.orca_only())
    assert not complete and info["coverage"] < 0.5
    complete, info = _sweep(trap, watchdog_time=1e4)
    assert not complete and info["moving_contacts"] == 0 and info["static_contacts"] == 0


@pytest.mark.parametrize("method", ["aoass-scripted", "aoass"])
def test_the_reported_v_trap_map_is_swept(method):
    """The fresh map on which both stacks used to stay in the apex of a V near (52, 53) for
    the whole time limit (coverage 0.18-0.20); the plain spiral covers 0.973 there."""
    obstacle_map = generate_map(100.0, 0.15, np.random.default_rng(7300))
    run = METHODS[method].runner(AOASSConfig(n_nodes=150), obstacle_map, 9300, RunOptions())
    assert run.complete
    assert run.sim.network.coverage_ratio >= 0.95
    assert run.sim.world.static_contacts == 0 and run.sim.world.wall_contacts == 0
