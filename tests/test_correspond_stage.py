import itertools
import json
import shutil

import numpy as np
import pytest

from datagen.correspond import correspond_dataset, correspondence_for_names
from datagen.correspond.sampling import sample_pairs
from mimicbench.cli import main
from schemas.shards import read_records
from schemas.validate import validate_dataset
from tests.test_correspond_canonical import HUMANOID_STYLES


@pytest.fixture(scope="module")
def corresponded(small_zoo, tmp_path_factory):
    root = tmp_path_factory.mktemp("corr") / "zoo"
    shutil.copytree(small_zoo, root)
    summary = correspond_dataset(root, all_pairs=True, progress=False)
    return root, summary


def test_pairs_written_validated_and_roles_agree_across_humanoid_styles(corresponded):
    root, summary = corresponded
    assert validate_dataset(root) == []
    pairs = read_records(root, "pairs")
    chars = {c.character_id: c for c in read_records(root, "characters")}
    per_split = {}
    for c in chars.values():
        per_split[c.split] = per_split.get(c.split, 0) + 1
    assert len(pairs) == sum(n * (n - 1) for n in per_split.values())
    for p in pairs[:20]:
        assert p.s_cos.shape == p.m_sink.shape == (chars[p.source_id].num_joints, chars[p.target_id].num_joints)
        np.testing.assert_allclose(p.m_sink.sum(1), 1.0, atol=1e-4)
    report = json.loads((root / "correspond_report.json").read_text())
    assert report == json.loads(json.dumps(summary["report"]))
    assert report["by_category"]["humanoid->humanoid"]["agreement"] >= 0.9
    assert report["humanoid_styles"] and report["humanoid_cross_style_agreement"] >= 0.9
    assert set(report["by_category"]) == {f"{chars[p.source_id].category}->{chars[p.target_id].category}"
                                          for p in pairs if chars[p.source_id].bone_roles}


def test_sampling_is_deterministic_and_mixes_categories(small_zoo):
    chars = read_records(small_zoo, "characters")
    a = sample_pairs(chars, 20, False, seed=3)
    b = sample_pairs(chars, 20, False, seed=3)
    assert [(x.character_id, y.character_id) for x, y in a] == [(x.character_id, y.character_id) for x, y in b]
    intra = sum(x.category == y.category for x, y in a)
    assert len(a) == 20 and 0 < intra < 20


def test_hand_written_humanoid_styles_match_bone_for_bone():
    # roles are the list positions; the target's bones are shuffled so the answer is not the identity
    rng = np.random.default_rng(0)
    for (sa, names_a), (sb, names_b) in itertools.permutations(sorted(HUMANOID_STYLES.items()), 2):
        order = rng.permutation(len(names_b))
        s, h, m = correspondence_for_names(names_a, [names_b[i] for i in order])
        roles_b = order[h[:, 1]]
        agreement = np.mean(h[:, 0] == roles_b)
        assert agreement >= 0.9, (sa, sb, agreement)
        np.testing.assert_allclose(m.sum(1), 1.0, atol=1e-4)


def test_on_the_fly_pair_and_cli(small_zoo, tmp_path, capsys):
    s, h, m = correspondence_for_names(["mixamorig:LeftArm", "mixamorig:Tail"], ["upper_arm.L", "tail", "head"])
    assert s.shape == (2, 3) and h.tolist() == [[0, 0], [1, 1]]
    root = tmp_path / "zoo"
    shutil.copytree(small_zoo, root)
    assert main(["datagen", "correspond", str(root), "--pairs", "6", "--quiet"]) == 0
    assert "pairs written" in capsys.readouterr().out
    assert len(read_records(root, "pairs", "train")) == 6
