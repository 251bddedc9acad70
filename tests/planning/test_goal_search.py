"""The compiled goal search against scipy's dijkstra (the oracle): the goal's distance to the
bit, the forced test against scipy's own tree, and the forced path against scipy's path."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import coo_matrix, diags
from scipy.sparse.csgraph import dijkstra

from aoass_env.maps import generate_map
from aoass_env.planning.detour import KEEPOUT_COST, DetourPlanner
from aoass_env.planning.goal_search import FORCED, TIE, UNREACHABLE, forced_path


def _scipy_path(pred: np.ndarray, s: int, g: int) -> list[int]:
    cells = [g]
    while cells[-1] != s:
        cells.append(int(pred[cells[-1]]))
    return cells


def _forced_in(graph, dist: np.ndarray, cells: list[int]) -> bool:
    """Every cell of ``cells`` but the last (the start) has exactly one neighbour u with
    dist[u] + w(u, v) == dist[v]."""
    for v in cells[:-1]:
        lo, hi = graph.indptr[v], graph.indptr[v + 1]
        ways = dist[graph.indices[lo:hi]] + graph.data[lo:hi] == dist[v]
        if np.count_nonzero(ways) != 1:
            return False
    return True


def _check(graph, base, s, g, **kwargs):
    """forced_path on ``base`` with ``kwargs`` (the A* key's xy and slope; the cells ``near``
    reweighted by ``factor``) against scipy on ``graph`` (the reweighted graph itself);
    returns the status."""
    status, cells, cost = forced_path(base.indptr, base.indices, base.data, s, g, **kwargs)
    dist, pred = dijkstra(graph, indices=s, return_predecessors=True)
    if not np.isfinite(dist[g]):
        assert status == UNREACHABLE and cost == np.inf and len(cells) == 0
        return status
    assert cost == dist[g]                                  # to the bit
    ref = _scipy_path(pred, s, g)
    assert (status == FORCED) == _forced_in(graph, dist, ref)
    if status == FORCED:
        assert cells.tolist() == ref
    else:
        assert status == TIE and len(cells) == 0
    return status


def test_against_scipy_on_a_generated_map_with_and_without_keepouts():
    m = generate_map(100.0, 0.4, np.random.default_rng(2))
    p = DetourPlanner(m, 0.8)
    rng = np.random.default_rng(3)
    factor = np.sqrt(KEEPOUT_COST)
    seen = set()
    key = dict(xy=p.centres, slope=p._slope)           # the planner's A* key
    for k in range(60):
        a, b = m.sample_free_points(2, rng)
        if k % 3 == 0:
            b = np.clip(a + rng.normal(scale=4.0, size=2), 0.5, 99.5)
        s, g = p._cell(a), p._cell(b)
        if k % 2:
            near = p._near((a + b) / 2 + rng.normal(size=(2, 2)), 2.0)
            seen.add(_check(p._reweighted(near, factor), p._graph, s, g, near=near,
                            factor=factor, **key))
        else:
            seen.add(_check(p._graph, p._graph, s, g, **key))
            _check(p._graph, p._graph, s, g)               # Dijkstra's key
    assert {FORCED, TIE} <= seen
    # a goal the disc cannot reach (the map's free cells outside the main region)
    outside = np.flatnonzero(p.free.ravel() & ~p._main)
    assert len(outside)
    start = int(np.flatnonzero(p._main)[0])
    assert _check(p._graph, p._graph, start, int(outside[0]), **key) == UNREACHABLE


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 40), p=st.floats(0.05, 0.5),
       levels=st.integers(1, 4), scaled=st.booleans(), astar=st.booleans())
def test_against_scipy_on_random_graphs_with_many_ties(seed, n, p, levels, scaled, astar):
    """Symmetric graphs on lattice points whose weights are half metres, at least the edge's
    length plus half a metre (ties everywhere), with Dijkstra's key or the A* key of slope
    0.999, and a mask of cells whose edges are scaled, against scipy on the same weights."""
    rng = np.random.default_rng(seed)
    xy = rng.integers(0, 6, (n, 2)).astype(float)
    upper = np.triu(rng.random((n, n)) < p, 1)
    i, j = np.nonzero(upper)
    length = np.hypot(*(xy[i] - xy[j]).T)
    w = np.ceil(length) + rng.integers(1, levels + 1, len(i)) * 0.5
    base = coo_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))),
                      shape=(n, n)).tocsr()
    kwargs = dict(xy=xy, slope=0.999) if astar else {}
    graph = base
    if scaled:
        kwargs.update(near=rng.random(n) < 0.3, factor=5.0)
        f = diags(np.where(kwargs["near"], 5.0, 1.0))
        graph = (f @ base @ f).tocsr()
    for s, g in rng.integers(0, n, (5, 2)):
        _check(graph, base, int(s), int(g), **kwargs)


def test_the_start_is_its_own_forced_path():
    m = generate_map(40.0, 0.2, np.random.default_rng(5))
    p = DetourPlanner(m, 0.8)
    s = int(np.flatnonzero(p._main)[0])
    status, cells, cost = forced_path(p._graph.indptr, p._graph.indices, p._graph.data, s, s)
    assert status == FORCED and cells.tolist() == [s] and cost == 0.0
