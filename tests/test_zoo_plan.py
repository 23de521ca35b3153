"""Zoo plan: category counts, IDs, the H2H family and the stratified split rule."""
import pytest

from mimicbench.datagen.zoo.plan import assign_splits, category_counts, plan_zoo
from mimicbench.datagen.zoo.templates import ZOO_CATEGORIES


@pytest.mark.parametrize("n", [0, 1, 7, 12, 16, 20, 40, 101])
def test_counts_sum_to_n_and_cover_all_categories_when_possible(n):
    counts = category_counts(n)
    assert sum(counts.values()) == n
    if n >= len(ZOO_CATEGORIES):
        assert all(v >= 1 for v in counts.values())


def test_subset_of_categories_and_unknown_category():
    assert category_counts(5, ["fish", "bird"]) == {"fish": 3, "bird": 2} or sum(category_counts(5, ["fish", "bird"]).values()) == 5
    with pytest.raises(ValueError, match="unknown"):
        category_counts(3, ["dragon"])


def test_ids_are_stable_when_the_zoo_grows():
    small = {s.character_id: s for s in plan_zoo(12, seed=3)}
    big = {s.character_id: s for s in plan_zoo(40, seed=3)}
    for cid, s in small.items():
        assert cid.startswith(f"zoo/{s.category}-")
        if cid in big:
            assert big[cid].entropy == s.entropy


@pytest.mark.parametrize("n", [12, 16, 20, 40])
def test_split_rule_keeps_h2h_family_members_in_test(n):
    specs = plan_zoo(n)
    splits = assign_splits(specs)
    family = [s for s in specs if s.family]
    in_test = sum(splits[s.character_id] == "test" for s in family)
    assert in_test >= min(3, len(family) - 1) >= 2
    assert any(splits[s.character_id] == "train" for s in family)
    assert set(splits.values()) <= {"train", "val", "test"}
    # deterministic and independent of the order of the specs
    assert assign_splits(list(reversed(specs))) == splits


def test_family_size_in_a_40_zoo():
    assert sum(s.family for s in plan_zoo(40)) >= 8
