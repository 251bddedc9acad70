"""agents.callbacks.read_evaluations: evaluations.npz read without unpickling, and checked."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from agents.callbacks import read_evaluations


def test_reads_what_sb3_writes(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    np.savez(path, timesteps=[100, 200], results=[[-3.5, -2.0], [1.0, 4.0]],
             ep_lengths=[[10, 12], [9, 11]])
    found = read_evaluations(path)
    assert found.timesteps.tolist() == [100, 200]
    assert found.results.tolist() == [[-3.5, -2.0], [1.0, 4.0]]
    assert found.ep_lengths.tolist() == [[10, 12], [9, 11]]


@pytest.mark.parametrize("arrays, message", [
    ({"timesteps": [100], "results": [[1.0]]}, "not an evaluation record (no 'ep_lengths')"),
    ({"timesteps": [100, 200], "results": [[1.0]], "ep_lengths": [[3]]},
     "timesteps int64[2], results float64[1, 1]"),
    ({"timesteps": [100], "results": [[np.nan]], "ep_lengths": [[3]]}, "finite returns"),
    ({"timesteps": [-1], "results": [[1.0]], "ep_lengths": [[3]]}, "not an evaluation record"),
    ({"timesteps": [1.5], "results": [[1.0]], "ep_lengths": [[3]]}, "timesteps float64[1]"),
    ({"timesteps": [100], "results": [[1.0]], "ep_lengths": [[3, 4]]}, "ep_lengths [1, 2]"),
])
def test_a_malformed_record_is_named(tmp_path: Path, arrays: dict, message: str):
    path = tmp_path / "evaluations.npz"
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match="evaluations.npz: ") as err:
        read_evaluations(path)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_pickled_arrays_are_not_loaded(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    ragged = np.empty(2, dtype=object)
    ragged[:] = [[1.0], [1.0, 2.0]]
    np.savez(path, timesteps=[1, 2], results=ragged, ep_lengths=ragged)
    with pytest.raises(ValueError, match="not a readable evaluation record .*allow_pickle"):
        read_evaluations(path)


def test_an_unreadable_file_is_named(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    path.write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ValueError, match=f"{path}: not a readable evaluation record"):
        read_evaluations(path)


def test_a_single_array_is_not_a_record(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    with open(path, "wb") as f:
        np.save(f, np.zeros(3))
    with pytest.raises(ValueError, match="not a readable evaluation record \\(an array, not an"):
        read_evaluations(path)
