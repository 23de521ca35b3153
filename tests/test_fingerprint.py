"""Fingerprints of configs and tables, checked against sha256 computed by hand."""
import hashlib
import json

import pytest

from mimicbench.schemas.fingerprint import digest_of, table_fingerprint, tables_fingerprint
from mimicbench.schemas.manifest import save_manifest


def test_digest_is_sha256_of_canonical_json_and_ignores_key_order():
    expected = hashlib.sha256(b'{"a":[1,2],"b":"x"}').hexdigest()
    assert digest_of({"b": "x", "a": [1, 2]}) == expected
    assert digest_of({"a": (1, 2), "b": "x"}) == expected
    assert digest_of({"a": [1, 2], "b": "y"}) != expected
    with pytest.raises(ValueError):
        digest_of({"a": float("nan")})


def test_table_fingerprint_follows_the_shards_checksums(tmp_path):
    shards = [{"path": "motions/train-00000-of-00001.parquet", "split": "train", "rows": 3, "sha256": "ab"},
              {"path": "characters/test-00000-of-00001.parquet", "split": "test", "rows": 2, "sha256": "cd"}]
    manifest = {"format": "mimicbench-dataset", "schema_version": "1.0", "configs": {},
                "tables": {"characters": {"shards": shards[1:]}, "motions": {"shards": shards[:1]}}}
    save_manifest(tmp_path, manifest)
    by_hand = hashlib.sha256(json.dumps([["characters/test-00000-of-00001.parquet", 2, "cd"]],
                                        separators=(",", ":")).encode()).hexdigest()
    assert table_fingerprint(tmp_path, "characters") == by_hand
    before = tables_fingerprint(tmp_path, ["characters", "motions"])
    shards[0]["sha256"] = "ef"  # one byte of one motions shard changed
    save_manifest(tmp_path, manifest)
    after = tables_fingerprint(tmp_path, ["characters", "motions"])
    assert after["characters"] == before["characters"] and after["motions"] != before["motions"]
    with pytest.raises(KeyError, match="pairs"):
        table_fingerprint(tmp_path, "pairs")


def test_stage_config_mismatch_names_the_changed_parameters_and_inputs():
    from mimicbench.schemas.fingerprint import fingerprint_mismatch, stage_config

    a = stage_config({"stage": "resample", "faces": 2000}, {"characters": "c1"}, info={"source": "/a"})
    assert a["fingerprint"]["config"] == digest_of({"stage": "resample", "faces": 2000}) and a["source"] == "/a"
    assert fingerprint_mismatch(a, stage_config({"stage": "resample", "faces": 2000}, {"characters": "c1"},
                                                info={"source": "/moved"})) is None
    b = stage_config({"stage": "resample", "faces": 5000}, {"characters": "c2"})
    why = fingerprint_mismatch(a, b)
    assert "faces 2000 -> 5000" in why and "input table(s) characters changed" in why
    assert "no fingerprint" in fingerprint_mismatch({"stage": "resample", "faces": 5000}, b)
