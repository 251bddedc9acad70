"""Tests of aoass_env.safety.filter_period: one compiled call for a period of the velocity
filter gives the wrapper's own path's floats, and hands the periods it does not decide back."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env import wrappers
from aoass_env.safety import filter_period as period
from aoass_env.safety.config import SafetyConfig

pytestmark = pytest.mark.skipif(not period.fused(),
                                reason="compiled trigonometry, atan2 or hypot unlike math's")

#: a dense field with many fast moving obstacles: with the look-ahead on, ORCA's moving lines
#: hand about half the periods back; without it, the braking envelope's caps hand back a few
#: of the periods on the smaller field
BUSY = {"field_size": 60.0, "obstacle_density": 0.35, "n_moving_obstacles": 16,
        "moving_obstacle_speed": (0.5, 1.5)}
CRAMPED = dict(BUSY, field_size=40.0)


def _episode(fused: bool, field: dict, safety: SafetyConfig | None, seed: int, steps: int,
             monkeypatch: pytest.MonkeyPatch) -> tuple[list, dict[str, int]]:
    """What each step of a seeded random-action AOASS-Safe-v0 episode returns (observation,
    reward, flags, the safety report) with the fused call on or off, and how the calls went."""
    calls = {"done": 0, "handed back": 0}
    compiled = period.filter_period

    def counted(*args):
        out = compiled(*args)
        calls["done" if out[0] else "handed back"] += 1
        return out

    monkeypatch.setattr(wrappers, "filter_period", counted)
    env = wrappers.make_safe_env(**field, safety=safety)
    safe = env
    while not isinstance(safe, wrappers.FuzzyORCASafety):
        safe = safe.env
    safe._fused = fused
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(steps):
        observation, reward, terminated, truncated, info = env.step(
            rng.uniform(-1.0, 1.0, 2).astype(np.float32))
        out.append((observation.tobytes(), reward, terminated, truncated,
                    sorted(info["safety"].items())))
        if terminated or truncated:
            env.reset()
    return out, calls


@pytest.mark.parametrize(("field", "safety", "seed", "least"),
                         [(BUSY, None, 31, 100),
                          (CRAMPED, SafetyConfig(look_ahead=False), 32, 5)],
                         ids=["look-ahead", "caps"])
def test_the_fused_period_is_the_wrappers_path(monkeypatch, field, safety, seed, least):
    """Bit for bit over busy seeded episodes: every observation, reward and safety report
    (v*, the command, the line and active counts, types included) is the same with the
    fused call as without; the call decides many periods and hands at least ``least`` back
    (the look-ahead's; without it, the caps': 13 with seed 32, 4 with seed 31 since the
    world's contact fixes of 2026-11-30)."""
    want, off = _episode(False, field, safety, seed, 500, monkeypatch)
    got, calls = _episode(True, field, safety, seed, 500, monkeypatch)
    assert off == {"done": 0, "handed back": 0}
    assert len(got) == len(want)
    for step, (g, w) in enumerate(zip(got, want, strict=True)):
        assert g == w, step
        assert [type(v) for _, v in g[4]] == [type(v) for _, v in w[4]], step
    assert calls["done"] > 100 and calls["handed back"] >= least, calls


def test_the_fused_period_needs_the_maths_probes(monkeypatch):
    """Where compiled atan2 or hypot are not math's, the wrapper never calls it."""
    monkeypatch.setattr(period, "compiled_polar", lambda: False)
    assert period.fused() is False
    monkeypatch.setattr(wrappers, "fused", period.fused)
    calls = []
    monkeypatch.setattr(wrappers, "filter_period", lambda *args: calls.append(args))
    env = wrappers.make_safe_env(**BUSY)
    env.reset(seed=32)
    for _ in range(20):
        env.step(env.action_space.sample())
    assert calls == []


def test_bad_moving_obstacles_are_named_as_orca_names_them():
    """The call checks the moving discs as ORCA does: a NaN, a wrong shape or a negative
    radius is a one-line error naming moving_obstacles, never a silent command."""
    from aoass_env.maps import generate_map
    from aoass_env.safety.orca import OrcaAgent, StaticObstacles
    static = StaticObstacles.from_loops(generate_map(30.0, 0.2, np.random.default_rng(60))
                                        .free_space_loops)
    agent = OrcaAgent(0.7, 1.0, 4.0, 2.5, 0.5)
    settings = period.PeriodSettings(agent, max_turn=0.3, max_dv=0.5, reach=4.0,
                                     max_accel=1.0, dt=0.5)
    for bad, what in ((np.array([[5.0, 5.0, np.nan, 0.0, 1.0]]), "finite"),
                      (np.zeros((2, 4)), "shape"),
                      (np.array([[5.0, 5.0, 0.0, 0.0, -1.0]]), "radii")):
        with pytest.raises(ValueError, match=f"moving_obstacles.*{what}"):
            period.filter_period(static, bad, settings, (15.0, 15.0), (0.0, 0.0), (0.5, 0.0),
                                 0.0, 0.0, 0.0, True)
    done, rows, *_ = period.filter_period(static, None, settings, (15.0, 15.0), (0.0, 0.0),
                                          (0.5, 0.0), 0.0, 0.0, 0.0, True)
    assert isinstance(done, bool) and rows.shape[1] == 4
    # float64 tracks take the compiled check, anything else ORCA's: the same period
    discs = np.array([[16, 15, -1, 0, 1], [10, 12, 0, 1, 1]])
    assert period._discs_ok(discs.astype(float)) and not period._discs_ok(
        np.array([[16.0, 15.0, -np.inf, 0.0, 1.0]]))
    args = (settings, (15.0, 15.0), (0.5, 0.0), (0.5, 0.0), 0.0, 0.5, 0.0, False)
    fast = period.filter_period(static, discs.astype(float), *args)
    other = period.filter_period(static, discs.tolist(), *args)
    assert fast[0] == other[0] and np.array_equal(fast[1], other[1]) and fast[2:] == other[2:]
    assert len(fast[1]) > fast[2]                      # the discs made lines
