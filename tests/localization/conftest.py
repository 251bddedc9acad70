"""Shared fixtures: a small simulated episode and hand-built beacon logs."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.beacon_log import BeaconLog, episode_config_json
from aoass_env.config import AOASSConfig
from aoass_env.simulator import Simulator


def make_log(nodes: np.ndarray, beacons_xy: np.ndarray, receptions: np.ndarray,
             node_links: np.ndarray, *, field: float = 100.0,
             radio_range: float = 25.0, doi: float = 0.0) -> BeaconLog:
    """A minimal valid log without obstacles; beacons one second apart."""
    n, b = len(nodes), len(beacons_xy)
    return BeaconLog(
        config_json=episode_config_json(AOASSConfig(field_size=field, radio_range=radio_range,
                                                    doi=doi),
                                        seed=0, method="test"),
        field=np.array([field, field]), obstacle_vertices=np.zeros((0, 2)),
        obstacle_offsets=np.zeros(1, np.int64), nodes=np.asarray(nodes, float),
        beacons=np.column_stack([np.arange(b, dtype=float), beacons_xy]).reshape(-1, 3),
        receptions=np.asarray(receptions, np.int64).reshape(-1, 2),
        node_links=np.asarray(node_links, np.int64).reshape(-1, 2),
        anchor_path=np.zeros((1, 3)), node_energy=np.zeros(n), anchor_energy=0.0,
        radio_range=radio_range, collisions=0)


@pytest.fixture(scope="session")
def small_sim() -> Simulator:
    """A finished 40 x 40 m episode with 30 nodes and a few obstacles."""
    config = AOASSConfig(field_size=40.0, n_nodes=30, obstacle_density=0.1,
                         n_moving_obstacles=0)
    sim = Simulator(config, np.random.default_rng(1), seed=1)
    sim.run()
    return sim


@pytest.fixture(scope="session")
def small_log(small_sim: Simulator) -> BeaconLog:
    return small_sim.finish()


@pytest.fixture(scope="session")
def doi_sim() -> Simulator:
    """A finished 40 x 40 m episode with 60 nodes, a few obstacles and DOI 0.15."""
    config = AOASSConfig(field_size=40.0, n_nodes=60, obstacle_density=0.1,
                         n_moving_obstacles=0, doi=0.15)
    sim = Simulator(config, np.random.default_rng(2), seed=2)
    sim.run()
    return sim
