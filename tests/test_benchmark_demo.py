"""The main job: `mimicbench demo` runs the whole toolkit and prints a leaderboard."""
import json

import pytest

from mimicbench.cli import main


@pytest.mark.slow
def test_demo_prints_a_leaderboard_with_four_methods_and_two_protocols(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--characters", "14", "--h2h-poses", "4", "--cct-pairs", "8",
                 "--cct-poses", "2"]) == 0
    printed = capsys.readouterr().out
    assert "leaderboard: " in printed and (out / "results" / "leaderboard.html").exists()
    board = json.loads((out / "results" / "leaderboard.json").read_text())
    assert set(board["protocols"]) == {"h2h", "cct"}
    for protocol, entries in board["protocols"].items():
        assert {e["method"] for e in entries} == {"identity", "name_copy", "nearest_joint", "text_soft"}
        assert all(e["complete"] for e in entries)
    h2h = {e["method"]: e["pmd"] for e in board["protocols"]["h2h"]}
    assert h2h["identity"] == max(h2h.values()) and h2h["name_copy"] < 1.0
    # a second run resumes: nothing is recomputed
    assert main(["demo", "--out", str(out), "--characters", "14"]) == 0
