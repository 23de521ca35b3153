"""The main job: `mimicbench demo` runs the whole toolkit and prints a leaderboard."""
import json

import pytest

from mimicbench.cli import main


@pytest.mark.slow
def test_demo_prints_a_leaderboard_with_nine_methods_and_its_protocols(tmp_path, capsys):
    out = tmp_path / "demo"
    options = ["demo", "--out", str(out), "--characters", "14", "--h2h-poses", "4", "--cct-pairs", "8", "--cct-poses", "2"]
    assert main(options) == 0
    printed = capsys.readouterr().out
    assert "leaderboard: " in printed and (out / "results-leaderboard" / "leaderboard.html").exists()
    board = json.loads((out / "results-leaderboard" / "leaderboard.json").read_text())
    # h2h_xskel when the test split holds humanoids of two skeleton families
    assert {"h2h", "cct"} <= set(board["protocols"]) <= {"h2h", "h2h_xskel", "cct"}
    for protocol, entries in board["protocols"].items():
        assert {e["method"] for e in entries} == {"identity", "name_copy", "nearest_joint", "text_soft", "mimicat",
                                                   "mimicat_init_only", "npt", "cgt", "sfpt"}
        assert all(e["complete"] for e in entries)
    h2h = {e["method"]: e["pmd"] for e in board["protocols"]["h2h"]}
    assert h2h["identity"] == max(h2h.values()) and h2h["name_copy"] < 1.0
    # the apparel table: the bundled apparel methods on every case of the zoo's 2 apparel characters;
    # lbs_kinematic moves body vertices exactly as the ground truth does (PMD_b = 0) but not apparel
    from mimicbench.benchmark.aggregate import aggregate
    from mimicbench.commands.demo import BUNDLED_APPAREL

    from mimicbench.benchmark.registry import get_method

    for name in BUNDLED_APPAREL:  # each row names the method's version (the shipped weights' for mmdmc)
        assert f"| {name} v{get_method(name).metadata.version} |" in printed, name
    apparel = {e["method"]: e for e in aggregate(out / "results-apparel")["protocols"]["apparel"]}
    assert set(apparel) == set(BUNDLED_APPAREL) == {"lbs_kinematic", "body_only", "mmdmc", "sfpt"}
    assert all(e["complete"] and e["ok"] > 0 and e["failed"] == 0 for e in apparel.values())
    assert apparel["lbs_kinematic"]["pmd_body"] == pytest.approx(0.0, abs=1e-9) and apparel["lbs_kinematic"]["pmd_apparel"] > 0.0
    assert "apparel leaderboard: " in printed and (out / "results-apparel-leaderboard" / "leaderboard.html").exists()
    # the demo is its bundled pipeline file: a second run resumes and recomputes nothing
    parts = {p: p.stat().st_mtime_ns for p in out.rglob("*.parquet")}
    assert main(options) == 0
    summary = capsys.readouterr().out.split("pipeline demo in ")[1].splitlines()
    assert any(line.startswith("  10 skipped;") for line in summary), summary
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.parquet")} == parts
