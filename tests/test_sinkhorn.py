import numpy as np
import pytest
import torch

from mimicbench.geometry.sinkhorn import sinkhorn_log


def naive_sinkhorn(scores, temperature, a, b, iters=2000):
    k = np.exp(scores / temperature)
    u, v = np.ones(len(a)), np.ones(len(b))
    for _ in range(iters):
        u = a / (k @ v)
        v = b / (k.T @ u)
    return u[:, None] * k * v[None, :]


@pytest.mark.parametrize("k1,k2", [(5, 5), (7, 4), (3, 9)])
def test_marginals_met_and_matches_plain_loop(k1, k2):
    rng = np.random.default_rng(k1 * 10 + k2)
    s = rng.uniform(-1, 1, size=(6, k1, k2))
    m = sinkhorn_log(s, temperature=0.2, tol=1e-9, num_iters=5000)
    np.testing.assert_allclose(m.sum(2), 1.0, atol=1e-4)
    np.testing.assert_allclose(m.sum(1), k1 / k2, atol=1e-4)
    for b in range(2):
        ref = naive_sinkhorn(s[b], 0.2, np.ones(k1), np.full(k2, k1 / k2))
        np.testing.assert_allclose(m[b], ref, atol=1e-5)


def test_square_is_doubly_stochastic_and_torch_twin_agrees():
    s = np.random.default_rng(0).normal(size=(4, 8, 8))
    m = sinkhorn_log(s, temperature=0.5, tol=1e-10, num_iters=3000)
    np.testing.assert_allclose(m.sum(1), 1.0, atol=1e-4)
    np.testing.assert_allclose(m.sum(2), 1.0, atol=1e-4)
    mt = sinkhorn_log(torch.tensor(s), temperature=0.5, tol=1e-10, num_iters=3000)
    np.testing.assert_allclose(mt.numpy(), m, atol=1e-8)


def test_stated_marginals_and_low_temperature_stability():
    s = np.random.default_rng(1).uniform(-1, 1, size=(5, 3))
    a = np.array([0.5, 1.0, 1.5, 2.0, 1.0])
    b = np.array([2.0, 2.0, 2.0])
    m = sinkhorn_log(s, temperature=0.01, row_marginals=a, col_marginals=b, tol=1e-9, num_iters=10000)
    assert np.isfinite(m).all()
    np.testing.assert_allclose(m.sum(1), a, atol=1e-4)
    np.testing.assert_allclose(m.sum(0), b, atol=1e-4)
    with pytest.raises(ValueError, match="equal totals"):
        sinkhorn_log(s, row_marginals=np.ones(5), col_marginals=np.ones(3))


@pytest.mark.parametrize("k1,k2,temperature", [(5, 5, 1.0), (7, 4, 0.2), (41, 60, 0.1), (120, 29, 0.1)])
def test_matrix_scaling_twin_matches_the_log_space_iteration(k1, k2, temperature):
    """The scaling iteration against the plain NumPy loop (small sizes) and the log-space one (all)."""
    from mimicbench.geometry.sinkhorn import sinkhorn_scaling_torch

    s = np.random.default_rng(k1 + k2).normal(scale=3.0, size=(k1, k2))
    got = sinkhorn_scaling_torch(torch.tensor(s), temperature, num_iters=600, tol=1e-7).numpy()
    np.testing.assert_allclose(got.sum(1), 1.0, atol=1e-5)
    np.testing.assert_allclose(got.sum(0), k1 / k2, atol=1e-6)
    np.testing.assert_allclose(got, sinkhorn_log(torch.tensor(s), temperature, num_iters=600, tol=1e-7).numpy(),
                               atol=1e-5)
    if k1 < 10:
        np.testing.assert_allclose(got, naive_sinkhorn(s, temperature, np.ones(k1), np.full(k2, k1 / k2)), atol=1e-6)
    assert sinkhorn_scaling_torch(torch.tensor(s, dtype=torch.float32), temperature).dtype == torch.float32


def test_matrix_scaling_falls_back_where_the_kernel_underflows():
    """Scores 1000 apart at T = 0.1: exp underflows in float64 (a column no row reaches); the
    answer is still the balanced matrix of the log-space iteration."""
    from mimicbench.geometry.sinkhorn import sinkhorn_scaling_torch

    s = np.random.default_rng(5).normal(size=(6, 4))
    s[:, 0] += 1000.0
    s[:, 1] -= 1000.0
    got = sinkhorn_scaling_torch(torch.tensor(s), 0.1, num_iters=3000, tol=1e-8)
    assert torch.isfinite(got).all()
    np.testing.assert_allclose(got.numpy(), sinkhorn_log(torch.tensor(s), 0.1, num_iters=3000, tol=1e-8).numpy(),
                               atol=1e-9)
    with pytest.raises(ValueError, match="num_iters"):
        sinkhorn_scaling_torch(torch.tensor(s), 0.1, num_iters=0)
