import itertools

import numpy as np
import pytest

from datagen.correspond.batched import correspondence_batch
from mimicbench.sinkhorn import sinkhorn_log


def unit_rows(rng, k, d=32):
    e = rng.normal(size=(k, d))
    return e / np.linalg.norm(e, axis=1, keepdims=True)


def brute_force_total(s):
    k1, k2 = s.shape
    if k1 <= k2:
        return max(s[np.arange(k1), list(c)].sum() for c in itertools.permutations(range(k2), k1))
    return max(s[list(r), np.arange(k2)].sum() for r in itertools.permutations(range(k1), k2))


def test_hungarian_is_an_optimal_partial_permutation_and_sinkhorn_meets_marginals():
    rng = np.random.default_rng(0)
    sizes = [(4, 6), (6, 4), (5, 5), (3, 7), (7, 2)]
    a = [unit_rows(rng, k1) for k1, _ in sizes]
    b = [unit_rows(rng, k2) for _, k2 in sizes]
    for (k1, k2), (s, h, m) in zip(sizes, correspondence_batch(a, b, temperature=0.1)):
        assert s.shape == m.shape == (k1, k2) and h.shape == (min(k1, k2), 2)
        assert len(set(h[:, 0])) == len(h) and len(set(h[:, 1])) == len(h)
        assert np.isclose(s[h[:, 0], h[:, 1]].sum(), brute_force_total(s), atol=1e-5)
        np.testing.assert_allclose(m.sum(1), 1.0, atol=1e-4)
        np.testing.assert_allclose(m.sum(0), k1 / k2, atol=1e-4)


@pytest.mark.parametrize("temperature", [0.05, 0.1, 0.5])
def test_padded_batch_matches_core_log_domain_sinkhorn(temperature):
    rng = np.random.default_rng(1)
    a = [unit_rows(rng, k) for k in (9, 30, 12)]
    b = [unit_rows(rng, k) for k in (20, 8, 12)]
    for (s, _, m) in correspondence_batch(a, b, temperature):
        ref = sinkhorn_log(s.astype(np.float64), temperature, tol=1e-10, num_iters=20000)
        np.testing.assert_allclose(m, ref, atol=1e-5)
