import json
from collections import Counter

import pytest

from mimicbench.datagen.splits import load_split_file, split_of


def test_split_is_a_function_of_the_id_with_stated_fractions():
    ids = [f"zoo/humanoid-{i:04d}" for i in range(5000)]
    first = [split_of(i) for i in ids]
    assert first == [split_of(i) for i in reversed(ids)][::-1]
    counts = Counter(first)
    assert abs(counts["train"] / 5000 - 0.8) < 0.03 and abs(counts["test"] / 5000 - 0.1) < 0.02
    assert split_of("assets/Fox", salt="a") in ("train", "val", "test")
    with pytest.raises(ValueError, match="summing to 1"):
        split_of("x", {"train": 0.5})


def test_split_file(tmp_path):
    p = tmp_path / "splits.json"
    p.write_text(json.dumps({"train": ["a", "b"], "test": ["c"]}))
    assert load_split_file(p) == {"a": "train", "b": "train", "c": "test"}
    p.write_text(json.dumps({"train": ["a"], "test": ["a"]}))
    with pytest.raises(ValueError, match="both"):
        load_split_file(p)


def test_split_rule_changes_with_the_fractions_the_salt_and_the_split_file_content(tmp_path):
    import hashlib

    from mimicbench.datagen.splits import split_rule

    assert split_rule() == {"rule": "sha256-bucket", "fractions": {"train": 0.8, "val": 0.1, "test": 0.1}, "salt": ""}
    assert split_rule(salt="b") != split_rule() and split_rule({"train": 0.5, "test": 0.5}) != split_rule()
    p = tmp_path / "splits.json"
    p.write_text('{"train": ["a"]}')
    first = split_rule(split_file=p)
    assert first["split_file_sha256"] == hashlib.sha256(b'{"train": ["a"]}').hexdigest()
    p.write_text('{"test": ["a"]}')
    assert split_rule(split_file=p) != first
