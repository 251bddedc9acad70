"""Hop counts against a brute-force breadth-first search."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.beacon_log import BeaconLogError
from aoass_env.localization.hops import hop_counts
from tests.localization.conftest import make_log


def _bfs(adj: list[set[int]], source: int, limit: int, n_nodes: int) -> np.ndarray:
    """Breadth-first distances from ``source`` in which only nodes (vertices < ``n_nodes``)
    and the source itself pass the flood on: another beacon is reached, never crossed."""
    dist = np.full(len(adj), np.inf)
    dist[source] = 0
    queue = deque([source])
    while queue:
        u = queue.popleft()
        if u >= n_nodes and u != source:
            continue
        for v in adj[u]:
            if dist[v] == np.inf and dist[u] + 1 <= limit:
                dist[v] = dist[u] + 1
                queue.append(v)
    return dist


@st.composite
def graphs(draw: st.DrawFn) -> tuple[int, int, np.ndarray, np.ndarray]:
    n = draw(st.integers(1, 8))
    b = draw(st.integers(1, 6))
    rec = draw(st.lists(st.tuples(st.integers(0, b - 1), st.integers(0, n - 1)), max_size=20,
                        unique=True))
    links = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1))
                          .filter(lambda p: p[0] < p[1]), max_size=15, unique=True))
    return n, b, np.array(rec, np.int64).reshape(-1, 2), np.array(links, np.int64).reshape(-1, 2)


@settings(max_examples=60, deadline=None)
@given(graphs(), st.integers(2, 6))
def test_hop_counts_match_bfs(graph: tuple, limit: int) -> None:
    n, b, rec, links = graph
    rng = np.random.default_rng(0)
    log = make_log(rng.uniform(0, 100, (n, 2)), rng.uniform(0, 100, (b, 2)), rec, links)
    adj: list[set[int]] = [set() for _ in range(n + b)]
    for beacon, node in rec:
        adj[n + beacon].add(node)
        adj[node].add(n + beacon)
    for i, j in links:
        adj[i].add(j)
        adj[j].add(i)
    hops = hop_counts(log, limit)
    assert hops.flood_limit == limit
    for beacon in range(b):
        expected = _bfs(adj, n + beacon, limit, n)
        np.testing.assert_array_equal(hops.beacon_node[beacon], expected[:n])
        np.testing.assert_array_equal(hops.beacon_beacon[beacon], expected[n:])



def test_a_beacon_passes_no_other_beacons_flood_on() -> None:
    """Nodes 0 and 1 do not hear each other; beacon 0 is heard by node 0, beacon 1 by both. A
    virtual anchor is the anchor at another time and relays no flood: node 1 is out of beacon
    0's reach (a search through beacon 1's vertex gave it 3 hops), and the two beacons are 2
    hops apart, through node 0."""
    nodes = np.array([[10.0, 0.0], [50.0, 0.0]])
    log = make_log(nodes, np.array([[0.0, 0.0], [30.0, 0.0]]), [[0, 0], [1, 0], [1, 1]], [])
    hops = hop_counts(log)
    np.testing.assert_array_equal(hops.beacon_node, [[1, np.inf], [1, 1]])
    np.testing.assert_array_equal(hops.beacon_beacon, [[0, 2], [2, 0]])

def test_direct_reception_is_one_hop(small_log) -> None:
    hops = hop_counts(small_log)
    rec = small_log.receptions
    assert np.all(hops.beacon_node[rec[:, 0], rec[:, 1]] == 1)
    assert (hops.beacon_node == 1).sum() == len(rec)


def test_no_beacons_is_a_clear_error() -> None:
    log = make_log(np.zeros((2, 2)), np.zeros((0, 2)), [], [])
    with pytest.raises(BeaconLogError, match="no beacons"):
        hop_counts(log)


@pytest.mark.parametrize("limit", [0, -1, 1, 1.5, True])
def test_bad_flood_limit(small_log, limit) -> None:
    with pytest.raises(ValueError, match="flood_limit"):
        hop_counts(small_log, limit)


def test_default_flooding_limit_is_the_documented_three_hops() -> None:
    """docs/localization.md: the flood travels 3 hops by default. On a chain beacon 0 -> node 0
    -> node 1 -> node 2 -> node 3 <- beacon 1, node 2 is 3 hops from beacon 0, node 3 is
    beyond the limit (4 hops), and the two beacons (5 hops apart) do not reach each other."""
    nodes = np.array([[10.0, 0.0], [20.0, 0.0], [30.0, 0.0], [40.0, 0.0]])
    log = make_log(nodes, np.array([[0.0, 0.0], [50.0, 0.0]]), [[0, 0], [1, 3]],
                   [[0, 1], [1, 2], [2, 3]])
    hops = hop_counts(log)
    assert hops.flood_limit == 3
    np.testing.assert_array_equal(hops.beacon_node, [[1, 2, 3, np.inf], [np.inf, 3, 2, 1]])
    np.testing.assert_array_equal(hops.beacon_beacon, [[0, np.inf], [np.inf, 0]])
    np.testing.assert_array_equal(hop_counts(log, 5).beacon_beacon, [[0, 5], [5, 0]])


def test_hop_counts_are_read_only(small_log) -> None:
    """An episode caches its hop counts for every localizer: writing into them must fail
    instead of changing what the next localizer reads."""
    hops = hop_counts(small_log)
    for counts in (hops.beacon_node, hops.beacon_beacon):
        with pytest.raises(ValueError, match="read-only"):
            counts[0, 0] = 7.0
