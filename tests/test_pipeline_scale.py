"""tools/scale.py at its reduced size: every step measured, Table 1 in the card, numbers as planned."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mimicbench.schemas.shards import read_table

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_reduced_scale_build_is_measured_and_carded(tmp_path):
    work = tmp_path / "scale"
    proc = subprocess.run([sys.executable, str(REPO / "tools" / "scale.py"), "--size", "reduced", "--workdir",
                           str(work), "--jobs", "1"], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    report = json.loads((work / "scale.json").read_text())
    assert [r["step"] for r in report["steps"]] == ["zoo", "resample", "correspond", "cases"]
    for r in report["steps"]:
        assert r["rc"] == 0 and r["wall_s"] > 0 and r["peak_rss_mb"] > 50 and r["disk_gb"] > 0
    data = work / "zoo5k"
    # the plan: 40 characters, 400 clips spread 10 each, 60 frames a clip (hand-computed 24,000 frames)
    mot = read_table(data, "motions", columns=["character_id", "num_frames"])
    per_char = {}
    for cid in mot.column("character_id").to_pylist():
        per_char[cid] = per_char.get(cid, 0) + 1
    assert mot.num_rows == 400 and set(per_char.values()) == {10} and len(per_char) == 40
    assert set(mot.column("num_frames").to_pylist()) == {60}
    card = (data / "CARD.md").read_text()
    assert "| this dataset | 40 | 400 | 0.02M (24,000) | 11 | 240 |" in card
    assert "| PokeAnimDB (paper) | 975 | 28,809 | 4.47M | 11 | 241 | ~384k |" in card
    for png in ("joints.png", "clips.png", "frames.png"):
        assert (data / "card" / png).stat().st_size > 5000
    assert proc.stdout.strip().splitlines()[-1].startswith("peak memory of any step / motions table on disk")
