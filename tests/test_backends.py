"""aoass_env.backends: the local backend's worker processes."""

from __future__ import annotations

import os
import signal

import pytest

from aoass_env.backends import BackendError, LocalBackend, make_backend


def _work(x: int) -> int:
    if x == 1:                                    # a worker killed while it runs this item
        os.kill(os.getpid(), signal.SIGKILL)
    if x == 5:
        raise ValueError("item 5 fails")
    return 10 * x


def _hung(signum: int, frame: object) -> None:
    raise TimeoutError("the backend hung on a dead worker's item")


def test_a_dead_worker_fails_its_items_instead_of_hanging_the_run():
    """multiprocessing.Pool replaced a killed worker and waited for the item it held forever:
    evaluate.py hung at the last episode. Now the items not done are reported as failed, and
    the run ends (its folder resumes them)."""
    previous = signal.signal(signal.SIGALRM, _hung)
    signal.alarm(60)
    try:
        results = list(LocalBackend(2).run(_work, [0, 1, 2, 3]))
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert sorted(item for item, _, _ in results) == [0, 1, 2, 3]
    failed = {item: error for item, value, error in results if error is not None}
    assert 1 in failed and "worker process died" in failed[1]
    assert all(value == 10 * item for item, value, error in results if error is None)
    # without a death: every result, an exception reported with its traceback
    results = sorted(LocalBackend(2).run(_work, [0, 2, 5, 6]), key=lambda r: r[0])
    assert [(item, value) for item, value, _ in results] == [(0, 0), (2, 20), (5, None),
                                                            (6, 60)]
    assert "ValueError: item 5 fails" in results[2][2]


@pytest.mark.parametrize("workers", [0, False, -1, 1.5])
def test_make_backend_refuses_a_worker_count_below_one_naming_it(workers):
    # 0 (and False) read as "not given" and ran on every core
    with pytest.raises(BackendError, match="workers"):
        make_backend("local", workers=workers)


def test_make_backend_takes_every_core_only_when_no_count_is_given():
    assert make_backend("local").workers == (os.cpu_count() or 1)
    assert make_backend("local", workers=1).workers == 1
