"""``datagen ingest FOLDER``: a folder stands for the asset files under it (datagen/ingest/asset_paths.py)."""
import shutil

import pytest

from mimicbench.datagen.ingest.runner import ingest_assets
from mimicbench.datagen.ingest.asset_paths import expand_asset_paths
from mimicbench.cli import main
from mimicbench.schemas.shards import read_records


def test_the_shared_assets_folder_lists_every_model_and_no_motion_or_text(assets_dir):
    assets, empty = expand_asset_paths([assets_dir])
    names = sorted(p.name for p in assets)
    # ../shared/assets: 12 .glb, 1 .bvh, 1 .pmx; .vmd (played by its model), .md files left out
    want = sorted([p.name for p in (assets_dir / "glb").glob("*.glb")] + ["CMU_02_01.bvh", "Gene.pmx"])
    assert names == want and len(names) == 14 and empty == []


def test_hidden_folders_the_output_duplicates_and_empty_folders(tmp_path):
    root = tmp_path / "chars"
    for rel in ["a.glb", "sub/deep/b.GLTF", "sub/c.bvh", "m/x.pmx", "m/x.vmd", "notes.txt", ".git/d.glb",
                "sub/.cache/e.fbx", "out/export/f.obj"]:
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(b"")
    (tmp_path / "empty").mkdir()
    missing = tmp_path / "missing.glb"
    assets, empty = expand_asset_paths([root, root / "a.glb", tmp_path / "empty", missing], skip=root / "out")
    got = [str(p.relative_to(tmp_path)) if p.is_relative_to(tmp_path) else str(p) for p in assets]
    assert got == ["chars/a.glb", "chars/m/x.pmx", "chars/sub/c.bvh", "chars/sub/deep/b.GLTF", "missing.glb"]
    assert empty == [str((tmp_path / "empty").resolve())]


@pytest.mark.blender
def test_ingest_a_folder_and_report_an_empty_one(assets_dir, tmp_path):
    root = tmp_path / "mine"
    (root / "sea").mkdir(parents=True)
    shutil.copy(assets_dir / "glb" / "Quaternius_Dolphin.glb", root / "sea" / "Dolphin.glb")
    shutil.copy(assets_dir / "mmd" / "Gene_README.md", root / "README.md")
    (root / ".trash").mkdir()
    shutil.copy(assets_dir / "glb" / "Quaternius_MantaRay.glb", root / ".trash" / "Manta.glb")
    (tmp_path / "nothing").mkdir()
    out = root / "dataset"  # inside the walked folder: its own files are never assets
    assert main(["datagen", "ingest", str(root), str(tmp_path / "nothing"), "--out", str(out), "--quiet",
                 "--export", "obj"]) == 1  # the empty folder is a failure row; the rest goes on
    assert [c.character_id for c in read_records(out, "characters")] == ["assets/Dolphin"]
    rows = {s.asset: s for s in read_records(out, "status")}
    assert "no asset files" in rows[str((tmp_path / "nothing").resolve())].reason
    again = ingest_assets([root], out, progress=False, export=("obj",))  # the exported .obj is not picked up
    assert again["skipped"] == 1 and again["ingested"] == 0 and again["failed"] == 0
