"""``datagen ingest`` routes .pmx/.pmd/.vmd files to mimicbench.datagen.mmd (no Blender): characters, motions,
rigid bodies, joints and status rows."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.ingest.runner import ingest_assets
from mimicbench.schemas.shards import read_records
from tests.mmd_fixtures import pmd_bytes, pmx_bytes, vmd_bytes


def test_ingest_mmd_models_motions_physics_and_bad_files(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    (src / "small.pmx").write_bytes(pmx_bytes(version=2.1, encoding=1, extra_uv=1, qdef=True))
    (src / "old.pmd").write_bytes(pmd_bytes())
    (src / "cut.pmx").write_bytes(pmx_bytes()[:300])
    # beside small.pmx: a clip that lifts the IK goal and names one bone the model lacks
    (src / "small_lift.vmd").write_bytes(vmd_bytes([("左足ＩＫ", 0, (0, 0, 0), (0, 0, 0, 1), {}),
                                                    ("左足ＩＫ", 4, (0, 1, 0), (0, 0, 0, 1), {}),
                                                    ("尻尾", 0, (0, 0, 0), (0, 0, 0, 1), {})], [("あ", 0, 1.0)]))
    (src / "broken.vmd").write_bytes(b"Vocaloid Motion Data 0002")
    out = tmp_path / "ds"
    s = ingest_assets(sorted(src.glob("*.pm*")) + [src / "broken.vmd"], out, progress=False)
    assert s["characters"] == 2 and s["motions"] == 1
    chars = {c.character_id: c for c in read_records(out, "characters")}
    assert set(chars) == {"assets/small", "assets/old"}
    status = {st.asset.rsplit("/", 1)[-1]: st for st in read_records(out, "status")}
    assert status["cut.pmx"].status == "failed" and "cut.pmx" in status["cut.pmx"].reason
    assert "truncated" in status["cut.pmx"].reason
    assert status["broken.vmd"].status == "failed" and "broken.vmd" in status["broken.vmd"].reason
    assert status["small_lift.vmd"].status == "ok" and "1 unmatched (尻尾)" in status["small_lift.vmd"].reason
    (motion,) = read_records(out, "motions")
    assert motion.motion_id == "assets/small/lift" and motion.transforms.shape == (5, 3, 7)
    small = chars["assets/small"]
    assert small.meta["mmd"]["motions"]["lift"]["ignored_morph_keys"] == 1
    ik = small.bone_names.index("左足ＩＫ")
    # the key at VMD frame 4 (4 / 30 s) is frame 4: t0 = 0, the file's own clock
    assert small.meta["mmd"]["motions"]["lift"]["t0"] == 0 and small.meta["mmd"]["motions"]["lift"]["first_frame"] == 0
    np.testing.assert_allclose(motion.transforms[4, ik, 4:], small.keypoints[ik] + [0, 0.08, 0], atol=1e-6)
    assert np.abs(motion.transforms[3, ik, 4:] - small.keypoints[ik] - [0, 0.08, 0]).max() > 1e-3
    bodies = read_records(out, "rigid_bodies")
    joints = read_records(out, "joints")
    assert sorted(b.character_id for b in bodies) == ["assets/old", "assets/old", "assets/small", "assets/small"]
    assert len(joints) == 2 and {j.kind for j in joints} == {"spring_6dof"}


def test_mmd_physics_rows_follow_the_chosen_split(tmp_path):
    """``--split`` / ``--split-file`` move an MMD character's rigid bodies and joints with it (its
    hashed split would be train: ``assets/small``)."""
    import json

    from mimicbench.schemas.shards import shard_entries

    (tmp_path / "small.pmx").write_bytes(pmx_bytes())
    (tmp_path / "splits.json").write_text(json.dumps({"val": ["assets/small"]}))
    for name, options in (("by_split", {"split": "test"}), ("by_file", {"split_file": str(tmp_path / "splits.json")})):
        out = tmp_path / name
        ingest_assets([tmp_path / "small.pmx"], out, progress=False, **options)
        want = options.get("split", "val")
        assert [c.split for c in read_records(out, "characters")] == [want]
        for table in ("rigid_bodies", "joints"):
            assert {e["split"] for e in shard_entries(out, table) if e["rows"]} == {want}, table


@pytest.mark.slow
def test_ingest_gene_with_its_motion(tmp_path, assets_dir):
    out = tmp_path / "ds"
    s = ingest_assets([assets_dir / "mmd" / "Gene.pmx"], out, progress=False)
    assert s["characters"] == 1 and s["motions"] == 1 and s["failed"] == 0
    (gene,) = read_records(out, "characters")
    (stand,) = read_records(out, "motions")
    assert gene.category == "humanoid" and len(gene.vertices) == 28646
    assert stand.name == "stand" and stand.num_frames == 121 and stand.fps == 30
    assert len(read_records(out, "rigid_bodies")) == 87 and len(read_records(out, "joints")) == 92
    report = gene.meta["mmd"]["motions"]["stand"]
    assert report["unmatched"] == [] and report["duplicate_keys"] == 2
    # feet on the ground where the VMD puts them: the ankles stay at their rest height (+-1 cm)
    for name in ("左足首", "右足首"):
        k = gene.bone_names.index(name)
        assert np.abs(stand.transforms[:, k, 5] - gene.keypoints[k, 1]).max() < 0.01


def test_cli_motions_folder_plays_on_every_model(tmp_path):
    from mimicbench.cli import main

    (tmp_path / "models").mkdir()
    (tmp_path / "mocap").mkdir()
    (tmp_path / "models" / "a.pmx").write_bytes(pmx_bytes())
    (tmp_path / "models" / "b.pmx").write_bytes(pmx_bytes(encoding=1))
    (tmp_path / "mocap" / "hop.vmd").write_bytes(vmd_bytes([("センター", 0, (0, 0, 0), (0, 0, 0, 1), {}),
                                                           ("センター", 2, (0, 2, 0), (0, 0, 0, 1), {})]))
    out = tmp_path / "ds"
    assert main(["datagen", "ingest", str(tmp_path / "models" / "*.pmx"), "--out", str(out), "--motions",
                 str(tmp_path / "mocap"), "--quiet"]) == 0
    motions = sorted(m.motion_id for m in read_records(out, "motions"))
    assert motions == ["assets/a/hop", "assets/b/hop"]
    assert main(["datagen", "ingest", str(tmp_path / "models" / "a.pmx"), "--out", str(out), "--motions",
                 str(tmp_path / "nowhere"), "--quiet"]) == 2


def test_second_run_keeps_earlier_physics_and_status(tmp_path):
    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    (tmp_path / "a_hop.vmd").write_bytes(vmd_bytes([("センター", 0, (0, 0, 0), (0, 0, 0, 1), {})]))
    (tmp_path / "b.pmx").write_bytes(pmx_bytes(encoding=1))
    out = tmp_path / "ds"
    ingest_assets([tmp_path / "a.pmx"], out, progress=False)
    ingest_assets([tmp_path / "b.pmx"], out, progress=False)
    ingest_assets([tmp_path / "a.pmx"], out, progress=False)  # again: replaces a's rows, keeps b's
    assert sorted(c.character_id for c in read_records(out, "characters")) == ["assets/a", "assets/b"]
    bodies = sorted(b.character_id for b in read_records(out, "rigid_bodies"))
    assert bodies == ["assets/a", "assets/a", "assets/b", "assets/b"]
    assert len(read_records(out, "joints")) == 2
    assets = sorted(s.asset.rsplit("/", 1)[-1] for s in read_records(out, "status"))
    assert assets == ["a.pmx", "a_hop.vmd", "b.pmx"]


def test_cli_mmd_unit_scales_model_motion_and_physics(tmp_path):
    from mimicbench.cli import main

    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    (tmp_path / "a_lift.vmd").write_bytes(vmd_bytes([("左足ＩＫ", 0, (0, 0, 0), (0, 0, 0, 1), {}),
                                                    ("左足ＩＫ", 4, (0, 1, 0), (0, 0, 0, 1), {})]))
    for unit in ("0.08", "0.1"):
        assert main(["datagen", "ingest", str(tmp_path / "a.pmx"), "--out", str(tmp_path / unit), "--mmd-unit", unit,
                     "--quiet"]) == 0
    default, tenth = (read_records(tmp_path / u, "characters")[0] for u in ("0.08", "0.1"))
    assert default.meta["mmd"]["metres_per_unit"] == pytest.approx(0.08) and tenth.meta["mmd"]["metres_per_unit"] == pytest.approx(0.1)
    # the fixture's bone 左足 sits at (1, 8, 0) MMD units and vertex 1 at (1, 0, -1): times 0.1, z mirrored
    np.testing.assert_allclose(tenth.keypoints[tenth.bone_names.index("左足")], [0.1, 0.8, 0.0], atol=1e-7)
    np.testing.assert_allclose(tenth.vertices[1], [0.1, 0.0, 0.1], atol=1e-7)
    np.testing.assert_allclose(tenth.vertices, default.vertices * 1.25, atol=1e-6)
    (lift,) = read_records(tmp_path / "0.1", "motions")
    ik = tenth.bone_names.index("左足ＩＫ")
    np.testing.assert_allclose(lift.transforms[4, ik, 4:], tenth.keypoints[ik] + [0, 0.1, 0], atol=1e-6)
    b08, b10 = (read_records(tmp_path / u, "rigid_bodies") for u in ("0.08", "0.1"))
    for a, b in zip(b08, b10):
        np.testing.assert_allclose(b.position, a.position * 1.25, atol=1e-6)
        np.testing.assert_allclose(b.size, a.size * 1.25, atol=1e-6)
    for bad in ("0", "-0.08", "nan", "metres"):
        with pytest.raises(SystemExit) as exc:
            main(["datagen", "ingest", str(tmp_path / "a.pmx"), "--out", str(tmp_path / "bad"), "--mmd-unit", bad])
        assert exc.value.code == 2
    assert not (tmp_path / "bad").exists()
    with pytest.raises(ValueError, match="--mmd-unit: expected metres per MMD unit"):
        ingest_assets([tmp_path / "a.pmx"], tmp_path / "bad", progress=False, mmd_unit=float("inf"))
