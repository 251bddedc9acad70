import numpy as np
import pytest

from aoass_env.beacon_log import BeaconLog
from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap, load_map
from aoass_env.network import Network
from aoass_env.planning.classical import CLASSICAL_METHODS
from aoass_env.planning.square_spiral import episode_spiral
from aoass_env.radio import Radio
from aoass_env.simulator import Simulator
from aoass_env.trajectory import beacons_along


@pytest.mark.parametrize("size", [100.0, 200.0, 49.75, 96.25, 143.5, 190.0, 237.0])
def test_default_spiral_covers_every_node_of_an_empty_field(size):
    """Eq. 18 coverage of 100 % along the ideal spiral at the default spacing. (The sizes after
    the defaults fitted a spacing within decimetres of the passes' bound, sqrt(R^2 - Δs^2) -
    margin, and the corner where the spiral stops heard only its border pass.)"""
    config = AOASSConfig(field_size=size, n_nodes=3000)
    empty = ObstacleMap(size, size)
    rng = np.random.default_rng(7)
    nodes = rng.uniform(0, size, size=(config.n_nodes, 2))
    # the field's corners and border midpoints are the hardest places
    nodes[:8] = [[0, 0], [size, 0], [0, size], [size, size],
                 [size / 2, 0], [0, size / 2], [size, size / 2], [size / 2, size]]
    spiral = episode_spiral(config, empty)
    path = np.c_[spiral.arc_length, spiral.waypoints]
    beacons, _ = beacons_along(path, 0.0, config.beacon_interval)
    beacons = np.r_[path[:1], beacons]
    radio = Radio(nodes, empty, config.radio_range)
    net = Network(config.n_nodes, config)
    for _, x, y in beacons:
        net.record_beacon(np.array([x, y]), radio.receivers(np.array([x, y])))
    assert net.coverage_ratio == 1.0


def test_simulated_episode_in_empty_field_covers_all_nodes():
    config = AOASSConfig(obstacle_density=0.0, n_nodes=300, n_moving_obstacles=0)
    sim = Simulator(config, np.random.default_rng(3))
    log = sim.run()
    assert sim.network.coverage_ratio == 1.0
    assert sim.collisions == 0
    # the path is the spiral, within the follower's corner cutting
    assert sim.network.distance_travelled == pytest.approx(sim.spiral.length, rel=0.02)
    # one beacon at the start, then one per interval travelled
    assert log.n_beacons == 1 + int(sim.network.distance_travelled // config.beacon_interval)
    gaps = np.linalg.norm(np.diff(log.beacons[:, 1:], axis=0), axis=1)
    assert gaps.max() <= config.beacon_interval + 1e-9


def _episode(seed):
    config = AOASSConfig(obstacle_density=0.2, n_nodes=150, n_moving_obstacles=2)
    sim = Simulator(config, np.random.default_rng(seed), seed=seed)
    return sim, sim.run(max_steps=400)


def test_same_seed_same_map_nodes_and_log():
    (s1, a), (s2, b) = _episode(11), _episode(11)
    assert s1.map.polygons and len(s1.map.polygons) == len(s2.map.polygons)
    for p, q in zip(s1.map.polygons, s2.map.polygons, strict=True):
        np.testing.assert_array_equal(p, q)
    for key, value in a.arrays().items():
        np.testing.assert_array_equal(value, b.arrays()[key], err_msg=key)
    _, c = _episode(12)
    assert not np.array_equal(a.nodes, c.nodes)


def test_log_is_consistent_with_the_ledger_and_round_trips(tmp_path):
    sim, log = _episode(5)
    net = sim.network
    assert log.anchor_energy == pytest.approx(net.anchor_energy)
    np.testing.assert_allclose(log.node_energy,
                               np.bincount(log.receptions[:, 1], minlength=log.n_nodes)
                               * net.rx_energy_per_beacon)
    assert log.collisions == sim.collisions
    assert len(log.anchor_path) == 401
    assert log.config["seed"] == 5 and log.config["method"] == "spiral"
    log.save(tmp_path / "ep.npz")
    again = BeaconLog.load(tmp_path / "ep.npz")
    for key, value in log.arrays().items():
        np.testing.assert_array_equal(value, again.arrays()[key], err_msg=key)


def test_nominal_follower_goes_around_obstacles():
    config = AOASSConfig(obstacle_density=0.3, n_nodes=200, n_moving_obstacles=0)
    sim = Simulator(config, np.random.default_rng(2))
    sim.run()
    # detours make the path longer than the ideal spiral, but coverage stays high
    assert sim.network.distance_travelled > sim.spiral.length
    assert sim.network.coverage_ratio >= 0.9


def test_a_given_path_is_swept_instead_of_the_spiral():
    """A planner's path replaces the spiral: the anchor starts on its first free waypoint and
    the follower tracks it to the end."""
    from aoass_env.planning import polyline_path

    config = AOASSConfig(field_size=40.0, obstacle_density=0.0, n_nodes=50,
                         n_moving_obstacles=0)
    block = ObstacleMap(40.0, 40.0, [np.array([[2.0, 2.0], [8.0, 2.0], [8.0, 8.0], [2.0, 8.0]])])
    path = polyline_path(np.array([[5.0, 5.0], [5.0, 35.0], [35.0, 35.0]]), 1.0)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=block, path=path)
    assert sim.path.blocked[0] and not sim.path.blocked[-1]
    first_free = sim.path.waypoints[np.flatnonzero(~sim.path.blocked)[0]]
    np.testing.assert_allclose(sim.world.position, first_free, atol=1e-9)
    log = sim.run()
    assert np.linalg.norm(log.anchor_path[-1, 1:] - [35.0, 35.0]) < 1.0
    np.testing.assert_array_equal(sim.path.waypoints, path.waypoints)
    assert sim.path.length == path.length
    assert sim.path.nominal_time(config.anchor_nominal_speed) == pytest.approx(
        path.length / config.anchor_nominal_speed)


def test_step_limit_rounds_once_as_the_env_does():
    """``time_limit_factor`` x the path's nominal duration, rounded up once: the env's formula
    (it was ``factor x ceil(T / dt)`` here, up to factor - 1 periods more: 12 935 against the
    env's 12 934 at dt = 0.3 s)."""
    from aoass_env.env import max_episode_steps
    from aoass_env.planning import polyline_path

    config = AOASSConfig(field_size=100.0, obstacle_density=0.0, n_nodes=20,
                         n_moving_obstacles=0, dt=0.3)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=ObstacleMap(100.0, 100.0))
    assert sim.step_limit() == max_episode_steps(config) == 12934
    path = polyline_path(np.array([[5.0, 5.0], [5.0, 66.0]]), 1.0)       # 61 m: 406.7 periods
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=ObstacleMap(100.0, 100.0),
                    path=path)
    nominal = 61.0 / config.anchor_nominal_speed / config.dt
    assert sim.step_limit() == int(np.ceil(config.time_limit_factor * nominal))
    assert sim.step_limit() < config.time_limit_factor * np.ceil(nominal)   # the old formula


def test_run_drives_a_given_controller():
    class Straight:
        """Drive east at 1 m/s for 10 periods."""

        def __init__(self) -> None:
            self.calls = 0

        @property
        def done(self) -> bool:
            return self.calls > 10

        def command(self, position, heading, dt):
            self.calls += 1
            return 1.0, 0.0

    config = AOASSConfig(field_size=40.0, obstacle_density=0.0, n_nodes=20,
                         n_moving_obstacles=0)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=ObstacleMap(40.0, 40.0))
    x0 = sim.world.position[0]
    sim.run(controller=Straight())
    assert sim.world.time == pytest.approx(10 * config.dt)   # the 11th command said done
    assert sim.world.position[0] > x0 + 3.0


@pytest.mark.parametrize("method, map_name", [("hilbert", "test/d0.50_f100_s514"),
                                              ("scan", "test/d0.60_f100_s517")])
def test_the_anchor_starts_where_the_field_is_reachable(method, map_name):
    """Regression: these paths' first free waypoints lie in a pocket (HILBERT) and wedged
    against an obstacle's corner (SCAN); the anchor used to end there at once or stay there the
    whole episode (coverage 0). It now starts on a later waypoint and sweeps."""
    obstacle_map = load_map(map_name)
    config = AOASSConfig(field_size=100.0, n_nodes=100, map=map_name)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=obstacle_map, method=method,
                    path=CLASSICAL_METHODS[method].plan(obstacle_map, config))
    assert sim.start_index > np.flatnonzero(~sim.path.blocked)[0]
    np.testing.assert_array_equal(sim.world.position, sim.path.waypoints[sim.start_index])
    sim.run(max_steps=400)
    assert sim.network.distance_travelled > 100.0


def test_the_anchor_does_not_start_in_a_nook_whose_exit_only_the_planners_grid_sees_open():
    """Regression (a fresh robustness map, seed 760045): the spiral's first free waypoint that
    reached the main region lay in a nook whose exit passes 0.59 m from the obstacle (the grid
    missed the obstacle's thin part there), below the planner's 0.8 m; inside the safety stack
    the anchor never left it (coverage 0). The start then skipped it by exact clearance
    (``leads_out``); since the planner's free cells are exact too, its grid sees the nook shut:
    the first waypoint that reaches the main region leads out, the anchor starts on it, and
    the stack sweeps from there."""
    from aoass_env.maps import generate_map
    from aoass_env.wrappers import make_safe_env
    nook_map = generate_map(100.0, 0.5, np.random.default_rng([20261117, 50, 45]),
                            clearance=2.5)
    config = AOASSConfig()
    sim = Simulator(config, np.random.default_rng(760045), obstacle_map=nook_map, seed=760045)
    nook = np.array([66.16666667, 66.0])
    nook_index = int(np.flatnonzero(np.hypot(*(sim.path.waypoints - nook).T) < 1e-6)[0])
    assert not sim.path.blocked[nook_index]
    assert not sim.planner.can_start(nook, config.anchor_radius)
    reaching = [i for i in np.flatnonzero(~sim.path.blocked)
                if sim.planner.can_start(sim.path.waypoints[i], config.anchor_radius)]
    assert reaching[0] > nook_index
    assert sim.planner.leads_out(sim.path.waypoints[reaching[0]])
    assert sim.start_index == reaching[0]
    assert sim.planner.leads_out(sim.world.position)
    env = make_safe_env(config=config, action_type="adaptive")
    env.reset(seed=760045, options={"map": nook_map})
    start = np.array(env.unwrapped.sim.world.position)
    action = np.zeros(env.action_space.shape, np.float32)
    for _ in range(300):
        env.step(action)
    assert np.hypot(*(np.array(env.unwrapped.sim.world.position) - start)) > 5.0
    assert env.unwrapped.sim.network.distance_travelled > 100.0


def test_a_shipped_map_below_its_certified_clearance_says_why():
    """At map_clearance 2.0 a shipped map (made and checked at 2.5 m) has room 2.0-2.5 m wide
    behind narrower necks: cut off at 2.0, absent at 2.5. The refusal says so."""
    from aoass_env.maps import MapError
    name = "train/d0.50_f100_s022"
    Simulator(AOASSConfig(map=name), np.random.default_rng(530011))      # fine at 2.5
    with pytest.raises(MapError, match=r"d0.50_f100_s022.*passages narrower than clearance=2 m"
                                       r".*shipped maps are made and checked at "
                                       r"map_clearance=2.5 m"):
        Simulator(AOASSConfig(map=name, map_clearance=2.0), np.random.default_rng(530011))
    # above the certified clearance the map may fail too (its passages are 2.5 m): no note
    with pytest.raises(MapError) as err:
        Simulator(AOASSConfig(map=name, map_clearance=3.5), np.random.default_rng(530011))
    assert "shipped maps" not in str(err.value)
