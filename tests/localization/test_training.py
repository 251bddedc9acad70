"""Training pipeline: map split, episode specs, examples, a tiny run lowers the loss."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from aoass_env.beacon_log import BeaconLog
from aoass_env.localization.episode import prepare
from aoass_env.localization.olstm import OLSTM
from aoass_env.localization.training import (
    CachedLogError,
    EpisodeSpec,
    TrainConfig,
    _examples,
    augment,
    draw_episodes,
    episode_specs,
    example,
    gaussian_nll,
    generate_logs,
    map_density,
    pattern_path,
)
from aoass_env.maps import list_maps, validation_split
from tests.localization.conftest import make_log


def test_specs_use_training_maps_and_hold_out_validation_maps() -> None:
    fit, val = validation_split(list_maps("train"))
    assert val and not set(fit) & set(val)
    specs = episode_specs(100, fit, seed=3)
    assert specs == episode_specs(100, fit, seed=3)
    assert all(s.map_name in fit and s.map_name.startswith("train/") for s in specs)
    assert {s.doi for s in specs} == {0.0, 0.05, 0.1, 0.15, 0.2}
    assert {map_density(s.map_name)[1] for s in specs} == {100.0, 200.0}


def test_example_target_and_augmentation(doi_sim) -> None:
    ex = example(prepare(doi_sim.finish()), doi_sim.radio.anchor_pattern)
    assert ex.target.shape == (360,) and float(np.abs(ex.target).max()) <= 1.0
    np.testing.assert_allclose(1 + 0.15 * ex.target, doi_sim.radio.anchor_pattern, atol=1e-6)
    x, y = augment(ex, np.random.default_rng(0))
    assert x.shape == (360, 25)
    assert any(np.array_equal(y, np.roll(ex.target, s)) for s in range(360))


def test_tiny_training_run_lowers_the_loss(doi_sim) -> None:
    torch.manual_seed(0)
    ex = example(prepare(doi_sim.finish()), doi_sim.radio.anchor_pattern)
    rng = np.random.default_rng(0)
    model = OLSTM(hidden=8)
    optim = torch.optim.Adam(model.parameters(), lr=1e-2)
    losses = []
    for _ in range(30):
        pairs = [augment(ex, rng) for _ in range(4)]
        x = torch.from_numpy(np.stack([p[0] for p in pairs]))
        y = torch.from_numpy(np.stack([p[1] for p in pairs]))
        loss = gaussian_nll(*model(x), y)
        optim.zero_grad()
        loss.backward()
        optim.step()
        losses.append(float(loss.detach()))
    assert np.mean(losses[-5:]) < losses[0] - 0.1


@pytest.mark.parametrize("change, error, message", [
    ({"epochs": 0}, ValueError, "epochs=0 must be an integer in [1, inf)"),
    ({"n_train_logs": -3}, ValueError, "n_train_logs=-3 must be an integer in [1, inf)"),
    ({"hidden": 2.5}, ValueError, "hidden=2.5 must be an integer in [1, inf)"),
    ({"batch_size": True}, ValueError, "batch_size=True must be an integer in [1, inf)"),
    ({"learning_rate": float("nan")}, ValueError,
     "learning_rate=nan must be a number in (0, inf)"),
    ({"seed": 2**64}, ValueError,
     "seed=18446744073709551616 must be an integer in [0, 18446744073709551615]"),
    ({"checkpoint": 3}, TypeError, "checkpoint must be a path, got int"),
])
def test_train_config_names_a_bad_setting(change, error, message) -> None:
    with pytest.raises(error) as info:
        TrainConfig(**change)
    assert str(info.value) == message


def test_train_config_reads_whole_floats_as_integers() -> None:
    cfg = TrainConfig(hidden=16.0, epochs=np.int64(3))
    assert cfg.hidden == 16 and type(cfg.hidden) is int and type(cfg.epochs) is int
    assert TrainConfig() == TrainConfig(n_train_logs=240, learning_rate=3e-3)


@pytest.mark.parametrize("change, message", [
    # seed 11 draws one validation episode with DOI 0 (np.stack failed after simulating),
    # seed 10 one training episode with DOI 0 (trained on nothing and wrote a checkpoint)
    ({"n_val_logs": 1, "seed": 11}, "n_val_logs=1: no episode of this draw (seed 11) has DOI > 0"),
    ({"n_train_logs": 1, "seed": 10},
     "n_train_logs=1: no episode of this draw (seed 10) has DOI > 0"),
])
def test_a_draw_without_irregular_radio_is_refused(change, message) -> None:
    with pytest.raises(ValueError) as info:
        draw_episodes(TrainConfig(**change))
    assert str(info.value) == f"{message}, the only ones the OLSTM learns from; draw more"
    assert all(any(spec.doi > 0 for spec in specs) for specs in draw_episodes(TrainConfig())[2:])


def test_localizer_subcommand_refuses_bad_input_before_any_work(tmp_path, train_script,
                                                                monkeypatch, capsys) -> None:
    def no_training(*args, **kwargs):
        raise AssertionError("train_localizer must not start")
    monkeypatch.setattr(train_script, "train_localizer", no_training)
    a_file = tmp_path / "file"
    a_file.write_text("")
    for argv, message in (
            (["--data-dir", str(a_file)], f"--data-dir {a_file}: is a file, not a folder"),
            (["--checkpoint", str(tmp_path)], f"--checkpoint {tmp_path}: is a folder, not a file"),
            (["--checkpoint", str(a_file / "m.pt")],
             f"--checkpoint {a_file / 'm.pt'}: its folder {a_file}: is a file, not a folder"),
            (["--n-val-logs", "1", "--seed", "11"],
             "--n-val-logs 1: no episode of this draw (seed 11) has DOI > 0, the only ones the "
             "OLSTM learns from; draw more"),
            (["--seed", str(2**64)],
             "--seed 18446744073709551616 must be an integer in [0, 18446744073709551615]")):
        with pytest.raises(SystemExit) as exit_:
            train_script.main(["localizer", "--data-dir", str(tmp_path / "logs"),
                               "--checkpoint", str(tmp_path / "m.pt"), *argv])
        assert exit_.value.code == 2
        assert capsys.readouterr().err.strip().splitlines()[-1] == \
            f"train.py localizer: error: {message}"
    assert not (tmp_path / "logs").exists()


def test_a_damaged_cached_log_or_pattern_is_named(doi_sim, tmp_path, train_script, monkeypatch,
                                                  capsys) -> None:
    """The data folder's logs and patterns are reused across runs; a damaged one ended in a
    traceback from np.load, or (a pattern of another shape) in a wrong target."""
    log = tmp_path / "a.npz"
    doi_sim.finish().save(log)
    np.save(pattern_path(log), doi_sim.radio.anchor_pattern)
    (first,), _ = _examples([log])
    assert first.target.shape == (360,)
    for content, message in (
            (b"garbage", "not a readable anchor pattern"),
            (np.zeros(90), "an anchor pattern is 360 finite floats, got float64 of shape (90,)"),
            (np.full(360, np.nan), "an anchor pattern is 360 finite floats")):
        if isinstance(content, bytes):
            pattern_path(log).write_bytes(content)
        else:
            np.save(pattern_path(log), content)
        with pytest.raises(CachedLogError) as info:
            _examples([log])
        assert str(info.value).startswith(f"{pattern_path(log)}: {message}")
        assert str(info.value).endswith("; delete it and its pair to simulate them again")
    log.write_bytes(b"garbage")
    with pytest.raises(CachedLogError, match=rf"^{log}: not an .npz archive"):
        _examples([log])

    def damaged(*args, **kwargs):
        raise CachedLogError("x.npz: damaged")
    monkeypatch.setattr(train_script, "train_localizer", damaged)
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["localizer", "--data-dir", str(tmp_path / "logs"),
                           "--checkpoint", str(tmp_path / "m.pt")])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == \
        "train.py localizer: error: --data-dir: x.npz: damaged"


def test_a_cached_log_of_other_settings_is_simulated_again(tmp_path) -> None:
    """The data folder outlives config changes: a log simulated before a default changed
    (here its recorded radio range) was reused, and the localizer trained on the old radio."""
    spec = EpisodeSpec("train/d0.10_f100_s000", 100, 0.05, 1)
    lines: list[str] = []
    (path,) = generate_logs([spec], tmp_path, lines.append)
    assert len(lines) == 1 and spec.file_name in lines[0]          # simulated
    fresh = path.read_bytes()
    assert generate_logs([spec], tmp_path, lines.append) == [path]
    assert len(lines) == 1 and path.read_bytes() == fresh            # reused as it is

    log = BeaconLog.load(path)
    record = json.loads(log.config_json)
    now = record["config"]["radio_range"]
    record["config"]["radio_range"] = now + 2.0
    dataclasses.replace(log, config_json=json.dumps(record, sort_keys=True)).save(path)
    generate_logs([spec], tmp_path, lines.append)
    assert f"{spec.file_name}: simulated with other settings (radio_range {now + 2.0!r}, now " \
           f"{now!r}); simulating it again" in lines[1]
    again = BeaconLog.load(path)                                      # the same episode again
    assert again.config_json == log.config_json
    assert np.array_equal(again.receptions, log.receptions)

    record["config"] = [1, 2]                        # valid JSON, but not a config
    dataclasses.replace(log, config_json=json.dumps(record, sort_keys=True)).save(path)
    with pytest.raises(CachedLogError, match=rf"^{path}: no readable config_json \(its config "
                                             rf"is a list, not an object\); delete it"):
        generate_logs([spec], tmp_path, lines.append)
    path.write_bytes(b"garbage")
    with pytest.raises(CachedLogError, match=rf"^{path}: no readable config_json .*; delete it"):
        generate_logs([spec], tmp_path, lines.append)


def test_a_diverged_training_is_one_line_and_writes_nothing(doi_sim, tmp_path, train_script,
                                                            monkeypatch, capsys) -> None:
    """No epoch with a finite validation loss (too large a learning rate) used to end in
    torch's TypeError from ``load_state_dict(None)``."""
    from aoass_env.localization import training
    log = tmp_path / "a.npz"
    doi_sim.finish().save(log)
    np.save(pattern_path(log), doi_sim.radio.anchor_pattern)
    monkeypatch.setattr(training, "draw_episodes", lambda cfg: ([], [], [], []))
    monkeypatch.setattr(training, "generate_logs", lambda specs, folder, report: [log])
    monkeypatch.setattr(training, "gaussian_nll",
                        lambda mean, logstd, y: (mean * float("nan")).mean())
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["localizer", "--data-dir", str(tmp_path / "logs"), "--checkpoint",
                           str(tmp_path / "m.pt"), "--epochs", "2", "--learning-rate", "0.5"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "train.py localizer: error: --learning-rate 0.5: training diverged: the validation NLL "
        "was not finite in any of 2 epoch(s) (learning_rate=0.5); nothing was written")
    assert not (tmp_path / "m.pt").exists()


def test_a_cached_log_without_beacons_is_named(tmp_path) -> None:
    """The cached log's own errors (no beacons, a config this version cannot read) named no
    file, yet told the user to delete "it"."""
    log = tmp_path / "a.npz"
    make_log(np.zeros((2, 2)), np.zeros((0, 2)), [], []).save(log)
    with pytest.raises(CachedLogError, match=rf"^{log}: beacon log key 'beacons': the log "
                                             rf"holds no beacons"):
        _examples([log])
