import itertools
import json
import shutil

import numpy as np
import pytest

from mimicbench.datagen.correspond.pair import correspondence_for_names, correspondence_for_skeletons
from mimicbench.datagen.correspond.stage import correspond_dataset
from mimicbench.datagen.correspond.sampling import sample_pairs
from mimicbench.datagen.zoo.build import build_skeleton
from mimicbench.datagen.zoo.naming import HUMANOID_STYLES, bone_names
from mimicbench.datagen.zoo.plan import CharacterSpec
from mimicbench.cli import main
from mimicbench.schemas.shards import read_records, splits_of
from mimicbench.schemas.validate import validate_dataset


@pytest.fixture(scope="module")
def corresponded(small_zoo, tmp_path_factory):
    root = tmp_path_factory.mktemp("corr") / "zoo"
    shutil.copytree(small_zoo, root)
    summary = correspond_dataset(root, all_pairs=True, progress=False)
    return root, summary


def test_pairs_written_validated_and_roles_agree(corresponded):
    root, summary = corresponded
    assert validate_dataset(root) == []
    pairs = read_records(root, "pairs")
    chars = {c.character_id: c for c in read_records(root, "characters")}
    per_split = {}
    for c in chars.values():
        per_split[c.split] = per_split.get(c.split, 0) + 1
    assert len(pairs) == sum(n * (n - 1) for n in per_split.values())
    for p in pairs:
        k1, k2 = chars[p.source_id].num_joints, chars[p.target_id].num_joints
        assert p.s_cos.shape == p.m_sink.shape == (k1, k2) and len(p.hungarian) <= min(k1, k2)
        assert len(set(p.hungarian[:, 0])) == len(set(p.hungarian[:, 1])) == len(p.hungarian)
        assert p.method == "structure" and p.method_params["no_match"] == pytest.approx(0.45)
        assert np.all(p.m_sink.sum(1) <= 1 + 1e-4) and np.all(p.m_sink >= 0)
    report = json.loads((root / "correspond_report.json").read_text())
    assert report == json.loads(json.dumps(summary["report"]))
    assert report["method"]["name"] == "structure" and summary["method"] == "structure"
    assert report["humanoid_styles"] and report["humanoid_cross_style_agreement"] >= 0.99
    for key, v in report["humanoid_styles"].items():
        assert v["agreement"] >= 0.99 and v["recall"] >= 0.9, (key, v)
    cross = {k: v for k, v in report["by_category"].items() if k.split("->")[0] != k.split("->")[1]}
    assert cross and report["cross_category_agreement"] >= 0.8
    for key, v in cross.items():
        assert v["agreement"] is None or v["agreement"] >= 0.8, (key, v)
        assert 0 < v["matched"] <= 1 and 0 < v["recall"] <= 1
    assert set(report["by_category"]) == {f"{chars[p.source_id].category}->{chars[p.target_id].category}"
                                          for p in pairs if chars[p.source_id].bone_roles}


def test_text_method_reproduces_the_papers_matrices(corresponded, tmp_path):
    root, _ = corresponded
    text_root = tmp_path / "zoo"
    shutil.copytree(root, text_root)
    summary = correspond_dataset(text_root, pairs=8, method="text", progress=False)
    assert summary["method"] == "text"
    chars = {c.character_id: c for c in read_records(text_root, "characters")}
    for p in read_records(text_root, "pairs"):
        k1, k2 = chars[p.source_id].num_joints, chars[p.target_id].num_joints
        assert p.method == "text" and p.method_params["no_match"] is None
        assert len(p.hungarian) == min(k1, k2)
        np.testing.assert_allclose(p.m_sink.sum(1), 1.0, atol=1e-4)
        np.testing.assert_allclose(p.m_sink.sum(0), k1 / k2, atol=1e-4)
        s, h, m = correspondence_for_names(chars[p.source_id].bone_names, chars[p.target_id].bone_names)
        np.testing.assert_allclose(s, p.s_cos, atol=1e-6)
        np.testing.assert_array_equal(h, p.hungarian)


def test_sampling_is_deterministic_and_mixes_categories(small_zoo):
    chars = read_records(small_zoo, "characters")
    a = sample_pairs(chars, 20, False, seed=3)
    b = sample_pairs(chars, 20, False, seed=3)
    assert [(x.character_id, y.character_id) for x, y in a] == [(x.character_id, y.character_id) for x, y in b]
    intra = sum(x.category == y.category for x, y in a)
    assert len(a) == 20 and 0 < intra < 20


@pytest.mark.parametrize("topology", [{"spine": 3, "fingers": 5, "pose": "T"}, {"spine": 2, "fingers": 0, "pose": "A"}])
def test_humanoid_naming_styles_match_role_for_role(topology):
    # one zoo humanoid named in every style; the target's bones are shuffled so the answer is not the identity
    spec = CharacterSpec("zoo/humanoid-0009", "humanoid", 9, 0)
    skel, _ = build_skeleton(spec)
    rng = np.random.default_rng(0)
    for sa, sb in itertools.permutations(HUMANOID_STYLES, 2):
        names_a = bone_names(skel.roles, sa, humanoid=True)
        names_b = bone_names(skel.roles, sb, humanoid=True)
        order = rng.permutation(len(names_b))
        where = np.argsort(order)
        parents_b = np.array([where[skel.parents[i]] if skel.parents[i] >= 0 else -1 for i in order])
        s, h, m = correspondence_for_skeletons(names_a, skel.parents, skel.heads, [names_b[i] for i in order],
                                               parents_b, skel.heads[order])
        right = np.mean(h[:, 0] == order[h[:, 1]])
        assert right >= 0.99 and len(h) >= 0.95 * len(names_a), (sa, sb, right, len(h))
        assert np.all(m.sum(1) <= 1 + 1e-4)


def test_on_the_fly_pair_and_cli(small_zoo, tmp_path, capsys):
    s, h, m = correspondence_for_names(["mixamorig:LeftArm", "mixamorig:Tail"], ["upper_arm.L", "tail", "head"])
    assert s.shape == (2, 3) and h.tolist() == [[0, 0], [1, 1]]
    root = tmp_path / "zoo"
    shutil.copytree(small_zoo, root)
    assert main(["datagen", "correspond", str(root), "--pairs", "6", "--quiet"]) == 0
    assert "method structure" in capsys.readouterr().out
    assert len(read_records(root, "pairs", "train")) == 6
    assert main(["datagen", "correspond", str(root), "--pairs", "4", "--method", "text", "--quiet"]) == 0
    assert {p.method for p in read_records(root, "pairs", "train")} == {"text"}


def test_pairs_across_splits(small_zoo, tmp_path):
    """``--pairs-across-splits``: every ordered pair of characters of different splits, as the pair
    split ``across`` (counted by a naive loop over the characters); a run without it removes them."""
    root = tmp_path / "zoo"
    shutil.copytree(small_zoo, root)
    chars = read_records(root, "characters")
    want = {(a.character_id, b.character_id) for a in chars for b in chars
            if a.split != b.split and a.num_joints and b.num_joints}
    assert want  # the small zoo has several splits
    assert main(["datagen", "correspond", str(root), "--all-pairs", "--pairs-across-splits", "--method", "text",
                 "--quiet"]) == 0
    assert validate_dataset(root) == []
    across = read_records(root, "pairs", "across")
    assert {(p.source_id, p.target_id) for p in across} == want and len(across) == len(want)
    split_of = {c.character_id: c.split for c in chars}
    assert all(p.split == "across" and split_of[p.source_id] != split_of[p.target_id] for p in across)
    within = [p for s in ("train", "val", "test") if s in splits_of(root, "pairs") for p in read_records(root, "pairs", s)]
    assert all(split_of[p.source_id] == split_of[p.target_id] == p.split for p in within)
    summary = correspond_dataset(root, pairs=5, progress=False, method="text", across_splits=True, unordered=True)
    across = read_records(root, "pairs", "across")
    assert summary["pairs"]["across"] == len(across) == 5
    assert all(p.source_id < p.target_id and split_of[p.source_id] != split_of[p.target_id] for p in across)
    correspond_dataset(root, pairs=3, progress=False, method="text")
    assert "across" not in splits_of(root, "pairs") and validate_dataset(root) == []
