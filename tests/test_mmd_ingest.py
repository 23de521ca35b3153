"""``datagen ingest`` routes .pmx/.pmd files to datagen.mmd (no Blender): records and status rows."""
from __future__ import annotations

import shutil

from datagen.ingest.runner import ingest_assets
from schemas.shards import read_records
from tests.mmd_fixtures import pmd_bytes, pmx_bytes


def test_ingest_mmd_models_and_bad_files(tmp_path, assets_dir):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "small.pmx").write_bytes(pmx_bytes(version=2.1, encoding=1, extra_uv=1, qdef=True))
    (tmp_path / "in" / "old.pmd").write_bytes(pmd_bytes())
    (tmp_path / "in" / "cut.pmx").write_bytes(pmx_bytes()[:300])
    paths = [assets_dir / "mmd" / "Gene.pmx"] + sorted((tmp_path / "in").iterdir())
    out = tmp_path / "ds"
    s = ingest_assets(paths, out, progress=False)
    assert s["characters"] == 3 and s["failed"] == 1
    chars = {c.character_id: c for c in read_records(out, "characters")}
    assert set(chars) == {"assets/Gene", "assets/small", "assets/old"}
    assert chars["assets/Gene"].category == "humanoid" and len(chars["assets/Gene"].vertices) == 28646
    status = {st.asset.rsplit("/", 1)[-1]: st for st in read_records(out, "status")}
    assert status["cut.pmx"].status == "failed" and "cut.pmx" in status["cut.pmx"].reason
    assert "truncated" in status["cut.pmx"].reason
    assert status["Gene.pmx"].status == "ok"
