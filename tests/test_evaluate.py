"""The main job's runner end to end on its smallest preset."""

from __future__ import annotations

import csv
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def evaluate():
    spec = importlib.util.spec_from_file_location("evaluate", ROOT / "evaluate.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["evaluate"] = module        # dataclasses look their module up by name
    spec.loader.exec_module(module)
    yield module
    del sys.modules["evaluate"]


def test_smoke_preset_writes_table_csv_figures_and_logs(evaluate, tmp_path, capsys):
    assert evaluate.main(["--preset", "smoke", "--seeds", "1", "--out", str(tmp_path),
                          "--save-logs"]) == 0
    rows = list(csv.DictReader((tmp_path / "episodes.csv").open()))
    assert len(rows) == 1
    row = rows[0]
    assert row["method"] == "spiral" and row["n_nodes"] == "60"
    assert 0.9 <= float(row["coverage"]) <= 1.0
    assert float(row["localized"]) == pytest.approx(float(row["coverage"]))
    assert 0.0 < float(row["rmse_olstm"]) < float(row["rmse_dvhop"])
    for name in ("summary.md", "trajectories.png", "metrics.png"):
        assert (tmp_path / name).stat().st_size > 0
    assert len(list((tmp_path / "logs").glob("*.npz"))) == 1
    assert "RMSE OLSTM-DV-Hop [m]" in capsys.readouterr().out


def test_bad_seed_count_is_a_usage_error(evaluate, tmp_path):
    with pytest.raises(SystemExit):
        evaluate.main(["--seeds", "0", "--out", str(tmp_path)])
