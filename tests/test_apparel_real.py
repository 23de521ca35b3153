"""The apparel stage on a real MMD model (../shared/assets/mmd/Gene.pmx, ingested by datagen ingest):
its 100 hair and accessory bones from dynamic rigid bodies, driven by a quarter turn of the body."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.apparel.stage import simulate_dataset
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.shards import read_records, write_records


@pytest.mark.slow
def test_gene_pmx_hair_swings_and_the_body_is_untouched(assets_dir, tmp_path):
    from mimicbench.cli import main

    assert main(["datagen", "ingest", str(assets_dir / "mmd" / "Gene.pmx"), "--out", str(tmp_path / "gene"),
                 "--quiet"]) == 0
    c = read_records(tmp_path / "gene", "characters")[0]
    assert c.apparel_bone_mask.sum() > 50
    angles = np.minimum(np.arange(30) / 6, 1.0) * (np.pi / 2)  # a quarter turn in 0.2 s, then held
    root = np.asarray(c.keypoints[0], np.float64)
    frames = []
    for a in angles:
        rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        t = (c.keypoints - root) @ rot.T + root
        frames.append(np.concatenate([np.tile([np.cos(a / 2), 0, np.sin(a / 2), 0], (len(t), 1)), t], 1))
    clip = MotionRecord(f"{c.character_id}/turn", c.character_id, "turn", c.split, 30.0, len(angles), c.num_joints,
                        np.array(frames, np.float32), "test")
    src = tmp_path / "in"
    write_records(src, "characters", [c], split=c.split)
    write_records(src, "motions", [clip], split=c.split)
    s = simulate_dataset(src, tmp_path / "out", relax=10, progress=False)
    assert s["failed"] == 0 and s["simulated"] == 1
    sim = {m.name: m for m in read_records(tmp_path / "out", "motions")}["turn@sim"]
    body = ~c.apparel_bone_mask
    np.testing.assert_array_equal(sim.transforms[:, body], clip.transforms[:, body])
    # apparel bones lag behind the rigid turn: their heads leave the kinematic positions, then come back
    lag = np.linalg.norm(sim.transforms[:, ~body, 4:] - clip.transforms[:, ~body, 4:], axis=-1).max(axis=1)
    assert lag.max() > 0.02 * c.height and lag[-1] < lag.max()
    q = read_records(tmp_path / "out", "characters")[0].meta["apparel"]["clips"]["turn"]
    assert q["links"] == int(c.apparel_bone_mask.sum()) and q["secondary_motion_max_pct"] > 0.5
