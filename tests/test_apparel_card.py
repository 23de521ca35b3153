"""The apparel section of a build's CARD.md and its plot (datagen/apparel/card.py)."""
from __future__ import annotations

from mimicbench.datagen.apparel.card import BEGIN, END, PLOT, write_apparel_card


def _q(peak, p99, kin, touch, new_in, worst, resettles=0):
    return {"max_accel": peak, "p99_accel": p99, "max_accel_kinematic": kin, "max_accel_kinematic_touching": touch,
            "new_inside_pct": new_in, "new_inside_max_pct": worst, "resettles": resettles}


def test_card_lists_every_clip_against_its_bound_and_plots_them(tmp_path):
    (tmp_path / "CARD.md").write_text("# Build\n")
    clips = {"assets/Gene/guide": _q(39.3, 9.0, 2.0, 12.6, 18.03, 21.9),  # 39.3 / 12.6 = 3.12: over 3x
             "assets/Gene/walk": _q(36.2, 14.0, 10.2, 56.9, 19.70, 23.1, resettles=2)}  # 36.2 / 56.9 = 0.64
    card = write_apparel_card(tmp_path, clips)
    text = card.read_text()
    assert text.startswith("# Build\n") and BEGIN in text and END in text
    assert "2 simulated clips; 1 over the jitter bound" in text and "1 with re-settled chains" in text
    assert "| assets/Gene/guide | 39.3 | 9.0 | 2.0 / 12.6 | 3.12 (over) | 18.03 | 21.90 | 0 |" in text
    assert "| assets/Gene/walk | 36.2 | 14.0 | 10.2 / 56.9 | 0.64 | 19.70 | 23.10 | 2 |" in text
    assert f"]({PLOT})" in text
    assert (tmp_path / PLOT).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    write_apparel_card(tmp_path, clips)  # a re-run replaces the section
    assert card.read_text().count(BEGIN) == 1
