import itertools

import numpy as np
import pytest

from mimicbench.geometry.hungarian import hungarian_match


def brute_force_best(s):
    k1, k2 = s.shape
    best = -np.inf
    if k1 <= k2:
        for cols in itertools.permutations(range(k2), k1):
            best = max(best, s[np.arange(k1), list(cols)].sum())
    else:
        for rows in itertools.permutations(range(k1), k2):
            best = max(best, s[list(rows), np.arange(k2)].sum())
    return best


@pytest.mark.parametrize("shape", [(4, 4), (3, 6), (6, 3), (5, 2)])
def test_partial_permutation_with_maximal_total(shape):
    s = np.random.default_rng(sum(shape)).normal(size=shape)
    pairs, onehot = hungarian_match(s)
    assert len(pairs) == min(shape)
    assert onehot.sum(0).max() <= 1 and onehot.sum(1).max() <= 1 and onehot.sum() == min(shape)
    assert np.isclose(s[pairs[:, 0], pairs[:, 1]].sum(), brute_force_best(s))
    assert (np.diff(pairs[:, 0]) > 0).all()


def test_minimize_and_rejects_nan():
    s = np.random.default_rng(0).normal(size=(4, 4))
    pairs, _ = hungarian_match(s, maximize=False)
    assert np.isclose(s[pairs[:, 0], pairs[:, 1]].sum(), -brute_force_best(-s))
    with pytest.raises(ValueError, match="finite"):
        hungarian_match(np.array([[np.nan, 1.0], [0.0, 1.0]]))
