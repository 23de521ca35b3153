"""Matrix-Fisher normaliser against Monte Carlo over uniform SO(3), a Laplace limit and finite differences."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation
from scipy.special import logsumexp

from mimicbench.baselines.mimicat.matrix_fisher import (log_normaliser, log_normaliser_of_singular_values, mean_rotation, mode,
                                             negative_log_likelihood, proper_svd)


@pytest.fixture(scope="module")
def uniform_rotations():
    return Rotation.random(600_000, random_state=0).as_matrix()  # (n, 3, 3), Haar-uniform


def rotated(s, seed):
    a, b = Rotation.random(2, random_state=seed).as_matrix()
    return a @ np.diag(s) @ b.T


# small, isotropic, anisotropic, negative determinant, large and very anisotropic
CASES = [(0.3, 0.2, 0.1), (2.0, 1.0, -0.5), (6.0, 6.0, 6.0), (15.0, 4.0, 1.0), (25.0, 12.0, -8.0),
         (40.0, 40.0, 40.0), (120.0, 3.0, -1.0), (30.0, 30.0, -30.0)]


@pytest.mark.parametrize("s", CASES)
def test_log_normaliser_matches_monte_carlo(s, uniform_rotations):
    F = rotated(s, seed=int(sum(s) * 7) % 1000)
    e = np.einsum("ij,nij->n", F, uniform_rotations)         # tr(F^T R) per sample
    mc = logsumexp(e) - np.log(len(e))                      # log E_uniform[exp(tr(F^T R))]
    w = np.exp(e - e.max())
    se = w.std() / w.mean() / np.sqrt(len(e))               # standard error of log of the mean
    got = float(log_normaliser(torch.tensor(F)))
    assert abs(got - mc) < 4 * se + 2e-3, (got, mc, se)


@pytest.mark.parametrize("s", [(3e3, 2e3, 1e3), (1e5, 1e5, 1e5), (1e6, 5e5, -2e5)])
def test_log_normaliser_large_concentration_matches_laplace_limit(s):
    """Near the mode tr(F^T R) ~ sum s - w^T diag(s2+s3, s1+s3, s1+s2) w / 2 and the Haar measure is
    dw / (8 pi^2), so log c -> sum s + 1.5 log(2 pi) - log(8 pi^2) - log((s2+s3)(s1+s3)(s1+s2)) / 2."""
    s1, s2, s3 = s
    laplace = sum(s) + 1.5 * np.log(2 * np.pi) - np.log(8 * np.pi ** 2) - 0.5 * np.log((s2 + s3) * (s1 + s3) * (s1 + s2))
    got = float(log_normaliser_of_singular_values(torch.tensor(s, dtype=torch.float64)))
    assert abs(got - laplace) < 20 / min(s2 + s3, s1 + s3), (got, laplace)  # corrections are O(1/s)
    assert np.isfinite(got)


def test_proper_svd_reconstructs_and_is_proper():
    F = torch.tensor(np.stack([rotated(s, i) for i, s in enumerate(CASES)]) * np.array([1, -1, 1])[None, :, None])
    U, s, V = proper_svd(F)
    torch.testing.assert_close(U @ torch.diag_embed(s) @ V.transpose(-1, -2), F)
    torch.testing.assert_close(torch.linalg.det(U), torch.ones(len(F), dtype=F.dtype))
    torch.testing.assert_close(torch.linalg.det(V), torch.ones(len(F), dtype=F.dtype))
    assert (s[:, 0] >= s[:, 1]).all() and (s[:, 1] >= s[:, 2].abs() - 1e-12).all()
    assert (torch.sign(s[:, 2]) == torch.sign(torch.linalg.det(F))).all()


def test_gradient_is_the_mean_rotation_and_matches_finite_differences(uniform_rotations):
    F = torch.tensor(rotated((4.0, 2.0, -1.0), 3), requires_grad=True)
    (g,) = torch.autograd.grad(log_normaliser(F), F)
    eps = 1e-6
    fd = torch.zeros(3, 3, dtype=torch.float64)
    for i in range(3):
        for j in range(3):
            d = torch.zeros(3, 3, dtype=torch.float64)
            d[i, j] = eps
            fd[i, j] = (log_normaliser(F.detach() + d) - log_normaliser(F.detach() - d)) / (2 * eps)
    torch.testing.assert_close(g, fd, atol=1e-6, rtol=1e-5)
    # d log c / dF = E[R]: importance-weighted Monte Carlo over uniform rotations
    e = np.einsum("ij,nij->n", F.detach().numpy(), uniform_rotations)
    w = np.exp(e - e.max())
    mc_mean = np.einsum("n,nij->ij", w, uniform_rotations) / w.sum()
    np.testing.assert_allclose(g.numpy(), mc_mean, atol=0.01)
    torch.testing.assert_close(mean_rotation(F.detach()), g)


def test_gradient_finite_where_singular_values_repeat():
    for F in (torch.zeros(3, 3, dtype=torch.float64), 5 * torch.eye(3, dtype=torch.float64),
              torch.diag(torch.tensor([3.0, 3.0, -3.0], dtype=torch.float64))):
        F = F.clone().requires_grad_(True)
        (g,) = torch.autograd.grad(log_normaliser(F), F)
        assert torch.isfinite(g).all()
    # at F = 0 the distribution is uniform: E[R] = 0
    torch.testing.assert_close(mean_rotation(torch.zeros(3, 3, dtype=torch.float64)),
                               torch.zeros(3, 3, dtype=torch.float64))


def test_nll_is_minimised_at_the_mode_and_is_normalised(uniform_rotations):
    F = torch.tensor(rotated((8.0, 5.0, 2.0), 11))
    m = mode(F)
    R = torch.tensor(uniform_rotations[:2000])
    nll_mode = negative_log_likelihood(F, m)
    nll_random = negative_log_likelihood(F.expand(len(R), 3, 3), R)
    assert (nll_random >= nll_mode - 1e-9).all()
    torch.testing.assert_close(torch.linalg.det(m), torch.tensor(1.0, dtype=F.dtype))
    # exp(-nll) is a density w.r.t. the uniform probability measure: its mean over uniform samples is 1
    n = 5_000
    dens = np.exp(-negative_log_likelihood(F.expand(n, 3, 3), torch.tensor(uniform_rotations[:n])).numpy())
    assert abs(dens.mean() - 1.0) < 4 * dens.std() / np.sqrt(len(dens)) + 1e-3


def test_float32_batch_and_bad_shapes():
    F = torch.tensor(np.stack([rotated(s, i) for i, s in enumerate(CASES)]), dtype=torch.float32, requires_grad=True)
    R = torch.tensor(Rotation.random(len(CASES), random_state=2).as_matrix(), dtype=torch.float32)
    nll = negative_log_likelihood(F, R)
    assert nll.shape == (len(CASES),) and nll.dtype == torch.float32
    nll.sum().backward()
    assert torch.isfinite(F.grad).all()
    with pytest.raises(ValueError, match="3, 3"):
        negative_log_likelihood(F[:, :2], R[:, :2])


def test_bingham_matrix_is_the_quadratic_form_of_the_trace():
    from mimicbench.baselines.mimicat.matrix_fisher import bingham_matrix
    from mimicbench.geometry.quaternion import quat_to_matrix

    F = rotated((5.0, 2.0, -1.0), 4) + np.random.default_rng(0).normal(size=(3, 3))
    q = Rotation.random(50, random_state=3).as_quat()[:, [3, 0, 1, 2]]  # (w, x, y, z)
    np.testing.assert_allclose(np.einsum("ni,ij,nj->n", q, bingham_matrix(F), q),
                               np.einsum("ij,nij->n", F, quat_to_matrix(q)), atol=1e-12)


@pytest.mark.parametrize("s", [(0.0, 0.0, 0.0), (3.0, 1.0, -0.5), (40.0, 20.0, 5.0), (300.0, 1.0, 0.0),
                               (2e3, 2e3, 2e3), (30.0, 30.0, -30.0)])
def test_samples_are_rotations_with_the_mean_of_the_normaliser_gradient(s):
    """Rejection sampling (Bingham, Kent et al.) and d log c / dF = E[R] are independent routes to E[R]."""
    from mimicbench.baselines.mimicat.matrix_fisher import sample

    F = rotated(s, 9)
    R = sample(F[None], 20_000, np.random.default_rng(1))[:, 0]
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
    expected = mean_rotation(torch.tensor(F)).numpy()
    se = R.std(0) / np.sqrt(len(R))
    assert (np.abs(R.mean(0) - expected) < 5 * se + 1e-3).all(), (R.mean(0), expected)
    again = sample(F[None], 10, np.random.default_rng(1))
    np.testing.assert_array_equal(again, sample(F[None], 10, np.random.default_rng(1)))


def test_sampling_loss_gradient_matches_the_expected_distance():
    """The surrogate's gradient estimates d E[||R' - R||^2 / 8] / dF, here by finite differences of
    the exact expectation (6 - 2 tr(E[R']^T R)) / 8 with E[R'] = d log c / dF."""
    from mimicbench.baselines.mimicat.matrix_fisher import sampling_loss

    F0 = torch.tensor(rotated((3.0, 2.0, 1.0), 5))
    R = torch.tensor(Rotation.random(1, random_state=6).as_matrix()[0])

    def expected(F):
        return (6 - 2 * (mean_rotation(F) * R).sum()) / 8

    F = F0.clone().requires_grad_(True)
    surrogate, dist = sampling_loss(F, R, 40_000, np.random.default_rng(2))
    (g,) = torch.autograd.grad(surrogate, F)
    fd = torch.zeros(3, 3, dtype=torch.float64)
    eps = 1e-5
    for i in range(3):
        for j in range(3):
            d = torch.zeros(3, 3, dtype=torch.float64)
            d[i, j] = eps
            fd[i, j] = (expected(F0 + d) - expected(F0 - d)) / (2 * eps)
    assert abs(float(dist) - float(expected(F0))) < 0.01
    assert float((g - fd).norm() / fd.norm()) < 0.15, (g, fd)
    with pytest.raises(ValueError, match="n >= 2"):
        sampling_loss(F, R, 1, np.random.default_rng(0))
