import itertools

import numpy as np
import pytest

from mimicbench.datagen.correspond.batched import correspondence_batch
from mimicbench.geometry.sinkhorn import sinkhorn_log


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


@pytest.mark.parametrize("temperature", [0.02, 0.05, 0.1, 0.5])
def test_padded_batch_matches_core_log_domain_sinkhorn(temperature):
    rng = np.random.default_rng(1)
    a = [unit_rows(rng, k) for k in (9, 30, 12)]
    b = [unit_rows(rng, k) for k in (20, 8, 12)]
    for (s, _, m) in correspondence_batch(a, b, temperature):
        ref = sinkhorn_log(s.astype(np.float64), temperature, tol=1e-10, num_iters=20000)
        np.testing.assert_allclose(m, ref, atol=5e-5)  # both meet the marginals to 2e-5


def test_a_row_dissimilar_to_every_column_still_balances_at_low_temperature():
    # S = a b^T with b the unit axes. Row 0 is far from every target name: shifting by the global
    # maximum (1) alone gives exp((-0.1 - 1) / 0.01), which underflows to 0 in float32, leaving
    # that row all zero (NaN after balancing). Row-then-column shifting keeps it finite.
    s_want = np.array([[-0.1, -0.105, -0.11], [0.3, 0.305, 0.29], [0.3, 0.29, 0.305]])
    a = np.concatenate([s_want, np.sqrt(1 - (s_want ** 2).sum(1, keepdims=True))], 1).astype(np.float32)
    b = np.eye(4, dtype=np.float32)[:3]
    (s, h, m), = correspondence_batch([a], [b], temperature=0.01)
    np.testing.assert_allclose(s, s_want, atol=1e-6)
    assert np.isfinite(m).all()
    np.testing.assert_allclose(m.sum(1), 1.0, atol=1e-4)
    np.testing.assert_allclose(m.sum(0), 1.0, atol=1e-4)
    np.testing.assert_allclose(m, sinkhorn_log(s.astype(np.float64), 0.01, tol=1e-10, num_iters=20000), atol=5e-5)
    assert h.tolist() == [[0, 0], [1, 1], [2, 2]]


def test_non_finite_embeddings_are_rejected():
    e = np.eye(3, dtype=np.float32)
    bad = e.copy()
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        correspondence_batch([e], [bad])
