"""The episode and localization columns against values computed by hand."""

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from aoass_env.beacon_log import BeaconLogRecorder, episode_config_json
from aoass_env.config import AOASSConfig
from aoass_env.evaluation import episode as episode_module
from aoass_env.evaluation.episode import episode_metrics, localization_row, localize_log
from aoass_env.evaluation.methods import MethodRun
from aoass_env.evaluation.store import EpisodeKey
from aoass_env.maps import ObstacleMap

NODES = np.array([[1.0, 1.0], [4.0, 5.0], [9.0, 9.0]])


def hand_log(seed: int | None = 7):
    """A 10 m field with one 2 x 5 m obstacle (density 0.1), three nodes, three beacons."""
    field = ObstacleMap(10.0, 10.0, [np.array([[6.0, 0.0], [8.0, 0.0], [8.0, 5.0], [6.0, 5.0]])])
    rec = BeaconLogRecorder(
        config_json=episode_config_json(AOASSConfig(field_size=10.0, n_nodes=3), seed=seed,
                                        method="hand"),
        obstacle_map=field, nodes=NODES, radio_range=25.0)
    for t, (x, y) in enumerate([(1.0, 3.0), (3.0, 3.0), (3.0, 1.0)]):
        rec.add_path_point(float(t), np.array([x, y]))
        rec.add_beacon(float(t), np.array([x, y]), np.array([0, 1]))
    return rec.finish(node_energy=np.array([0.1, 0.1, 0.0]), anchor_energy=3.2, collisions=0,
                      node_links=np.array([[0, 1]]))


def test_episode_columns_follow_eq_16_to_19():
    network = SimpleNamespace(coverage_ratio=0.75, beacons_sent=50, distance_travelled=120.0,
                              energy_total=80.0)
    world = SimpleNamespace(time=150.0, static_contacts=2, wall_contacts=1, moving_contacts=4)
    path = SimpleNamespace(length=100.0, nominal_time=lambda speed: 100.0 / speed)
    sim = SimpleNamespace(network=network, world=world, path=path, collisions=7,
                          config=AOASSConfig(anchor_nominal_speed=0.5))
    m = episode_metrics(MethodRun(sim, log=None, complete=True, safety_intervention=0.3))
    assert m["ideal_length"] == 100.0 and m["ideal_time"] == 200.0      # 100 m at 0.5 m/s
    assert m["eta_traj"] == pytest.approx((100 / 120) * (200 / 150))   # Eq. 19
    assert m["e_norm"] == pytest.approx(80 / 50)                       # Eq. 16, J per beacon
    assert m["eer"] == pytest.approx(50 / 80)                          # Eq. 17, beacons per J
    assert (m["coverage"], m["beacons"], m["path_length"], m["travel_time"]) == (
        0.75, 50, 120.0, 150.0)
    assert (m["collisions"], m["collisions_static"], m["collisions_moving"]) == (7, 3, 4)
    assert m["energy_total"] == 80.0 and m["safety_intervention"] == 0.3
    assert m["path_complete"] == 1


def test_rmse_is_over_the_localized_nodes_with_the_fraction_beside_it(monkeypatch):
    estimates = np.array([[4.0, 1.0], [4.0, 5.0], [np.nan, np.nan]])   # errors 3 m, 0 m, none
    monkeypatch.setattr(episode_module, "localize", lambda log, method: estimates)
    row = localization_row(hand_log(), "dvhop")
    assert row["rmse"] == pytest.approx(math.sqrt((3.0**2 + 0.0**2) / 2))   # Eq. 15
    assert row["localized"] == pytest.approx(2 / 3)
    assert row["localizer"] == "dvhop" and row["localize_seconds"] >= 0


def test_a_log_from_elsewhere_takes_its_key_from_its_config(monkeypatch, tmp_path: Path):
    monkeypatch.setattr(episode_module, "localize",
                        lambda log, method: np.full((3, 2), np.nan))
    path = tmp_path / "my_episode.npz"
    hand_log(seed=None).save(path)
    (row,) = localize_log(path, ("olstm-dvhop",))
    key = EpisodeKey("hand", "my_episode", 10.0, 3, 0.1, -1)
    assert {k: row[k] for k in ("method", "map", "field_size", "n_nodes", "obstacle_density",
                                "seed")} == key.__dict__
    assert math.isnan(row["rmse"]) and row["localized"] == 0.0       # nobody localized
    assert row["coverage"] is None and row["eta_traj"] is None       # not in such a log


def test_a_log_whose_key_episodes_csv_cannot_hold_is_refused_before_localizing(tmp_path: Path):
    """A seed of -5 (or a method name with a line break) passed log_key and failed only when
    the row was appended, after the localization, in a traceback (exit 1)."""
    from aoass_env.beacon_log import BeaconLogError
    from aoass_env.evaluation.episode import log_key
    path = tmp_path / "odd.npz"
    hand_log(seed=-5).save(path)
    with pytest.raises(BeaconLogError, match=r"its episode key does not fit episodes.csv "
                                             r"\(seed='-5' must be"):
        log_key(path)
