"""examples/random_and_zero_agent.py: a short run writes both GIFs; bad input is refused in one
line naming the flag, before any episode."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from PIL import Image

SCRIPT = Path(__file__).resolve().parents[2] / "examples" / "random_and_zero_agent.py"


def load():
    spec = importlib.util.spec_from_file_location("aoass_example_agents", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_short_run_writes_both_gifs(tmp_path, capsys):
    load().main(["--field-size", "20", "--max-steps", "6", "--frame-every", "2",
                 "--gif-width", "64", "--out", str(tmp_path)])
    for name in ("random", "zero"):
        with Image.open(tmp_path / f"{name}_agent.gif") as gif:
            assert gif.width == 64 and gif.n_frames == 4      # frames 0, 2, 4, 6 of 6 steps
    assert capsys.readouterr().out.count("steps 6") == 2


@pytest.mark.parametrize(("argv", "message"), [
    (["--frame-every", "0"], "argument --frame-every: must be an integer >= 1, got '0'"),
    (["--gif-width", "-2"], "argument --gif-width: must be an integer >= 1, got '-2'"),
    (["--seed", "-1"], "argument --seed: must be an integer >= 0, got '-1'"),
    (["--max-steps", "-5"], "argument --max-steps: must be an integer >= 0, got '-5'"),
    (["--field-size", "0"], "--field-size: field_size=0.0 must be a number in [10.0, 2000.0] m"),
])
def test_bad_flags_are_refused_in_one_line(capsys, tmp_path, argv, message):
    with pytest.raises(SystemExit):
        load().main([*argv, "--out", str(tmp_path / "out")])
    assert message in capsys.readouterr().err.strip().splitlines()[-1]
    assert not (tmp_path / "out").exists()


def test_an_out_that_is_a_file_is_refused_before_any_episode(capsys, tmp_path):
    out = tmp_path / "file"
    out.write_text("")
    with pytest.raises(SystemExit):
        load().main(["--out", str(out)])
    assert f"--out {out}: is a file, not a folder" in capsys.readouterr().err
