"""scripts/zero_action_returns.py: the zero action's reference episodes of docs/env.md."""

from __future__ import annotations

import math

from tests.scripts.test_script_input import load, refused


def test_the_table_row_is_the_seeds_episode_again_and_covers_the_quick_field(capsys):
    """A fresh env from the same seed gives the table's row again (every digit)."""
    script = load("zero_action_returns")
    assert script.main(["--seeds", "102"]) == 0
    lines = capsys.readouterr().out.splitlines()
    decisions, total, coverage = script.zero_action_episode("AOASS-Quick-v0", 102)
    assert decisions > 10 and math.isfinite(total) and 0.9 <= coverage <= 1.0
    assert lines[0] == "zero action on AOASS-Quick-v0"
    assert lines[-1] == f"| 102 | {decisions} | {total:.1f} | {coverage:.3f} |"


def test_an_unknown_id_or_a_negative_seed_is_refused(capsys, monkeypatch):
    assert refused(capsys, monkeypatch, "zero_action_returns", "--env", "AOASS-v9").startswith(
        "--env 'AOASS-v9': not a registered id; valid: AOASS-v0, ")
    assert refused(capsys, monkeypatch, "zero_action_returns", "--seeds", "3", "-1") == \
        "--seeds -1: seeds are integers >= 0"
