"""The matrix-Fisher distribution on SO(3): normaliser, negative log-likelihood, mode.

``p(R | F) = exp(tr(F^T R)) / c(F)`` with respect to the uniform (Haar) probability measure on
SO(3), F any real 3x3 matrix (Khatri & Mardia 1977). With the *proper* singular value
decomposition ``F = U diag(s) V^T`` (U, V rotations, ``s1 >= s2 >= |s3|``, s3 carrying the sign
of det F), the normaliser depends on ``s`` only and is one integral (Mohlin, Sullivan & Bianchi,
"Probabilistic orientation estimation with matrix Fisher distributions", NeurIPS 2020):

    c(s) = int_{-1}^{1} 1/2 I0((s1 - s2)(1 - u)/2) I0((s1 + s2)(1 + u)/2) exp(s3 u) du.

Here it is evaluated with the substitution ``u = 1 - z^2`` (which removes the square-root
behaviour of I0 at large arguments near u = 1) and exponentially scaled Bessel functions:

    c(s) = exp(s1 + s2 + s3) * int_0^sqrt(2) z i0e(a z^2 / 2) i0e(b (2 - z^2) / 2) exp(-(s2 + s3) z^2) dz,

a = s1 - s2, b = s1 + s2, so ``log c`` never overflows. The integrand is bounded by z, cut where
``(s2 + s3) z^2 > 50`` (relative error e^-50), and integrated by Gauss-Legendre on panels that shrink
geometrically towards both ends of the range (down to 2^-15 of it), which resolves the scales
1/sqrt(a), 1/sqrt(s2 + s3) and, at u = -1, 1/sqrt(b), for concentrations up to about 1e8. The gradient with respect to F is
``U diag(d log c / ds) V^T`` (a hand-written backward, as Mohlin et al. do), which stays finite
when singular values repeat, where the backward of ``torch.linalg.svd`` does not.
"""
from __future__ import annotations

import numpy as np
import torch

_PANELS = 14          # geometric panels towards each end of the range, down to 2^-_PANELS of its half
_NODES = 8            # Gauss-Legendre nodes per panel
_CUTOFF = 50.0        # stop where exp(-(s2 + s3) z^2) < e^-50


def _quadrature_unit() -> tuple[np.ndarray, np.ndarray]:
    """Nodes in (0, 1) and weights for the range [0, 1] (scaled to [0, z_max] later), float64.

    Panels shrink geometrically towards 0 (the peak of width 1/sqrt(s2 + s3) and the scale
    1/sqrt(s1 - s2) live there) and towards 1 (where, for z_max = sqrt 2, u = -1 and the factor
    I0((s1 + s2)(1 + u)/2) has its square-root behaviour when s3 is close to -s2).
    """
    x, w = np.polynomial.legendre.leggauss(_NODES)
    low = [0.0] + [0.5 * 2.0 ** -j for j in range(_PANELS, -1, -1)]          # 0 ... 0.5
    edges = low + [1.0 - e for e in reversed(low[:-1])]                     # ... 1
    nodes, weights = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        nodes.append((hi - lo) / 2 * x + (hi + lo) / 2)
        weights.append((hi - lo) / 2 * w)
    return np.concatenate(nodes), np.concatenate(weights)


_UNIT_NODES, _UNIT_WEIGHTS = _quadrature_unit()


class _I0eRight(torch.autograd.Function):
    """``exp(-x) I0(x)`` for x >= 0 with the derivative ``i1e(x) - i0e(x)`` (also at x = 0, where
    ``torch.special.i0e``, defined with |x|, returns the subgradient 0 instead of the needed -1)."""

    @staticmethod
    def forward(ctx, x):
        ctx.save_for_backward(x)
        return torch.special.i0e(x)

    @staticmethod
    def backward(ctx, grad):
        (x,) = ctx.saved_tensors
        return grad * (torch.special.i1e(x) - torch.special.i0e(x))


def proper_svd(F: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Proper SVD of F (..., 3, 3): ``U, s, V`` with U, V in SO(3) and ``F = U diag(s) V^T``.

    ``s`` (..., 3) is sorted ``s1 >= s2 >= |s3|``; ``s3 < 0`` when det F < 0.
    """
    if F.shape[-2:] != (3, 3):
        raise ValueError(f"F: expected (..., 3, 3), got {tuple(F.shape)}")
    U, s, Vh = torch.linalg.svd(F)
    V = Vh.transpose(-1, -2)
    du, dv = torch.linalg.det(U), torch.linalg.det(V)
    flip_u = torch.ones_like(s)
    flip_v = torch.ones_like(s)
    flip_u[..., 2] = du
    flip_v[..., 2] = dv
    s = s.clone()
    s[..., 2] = s[..., 2] * du * dv
    return U * flip_u[..., None, :], s, V * flip_v[..., None, :]


def log_normaliser_of_singular_values(s: torch.Tensor) -> torch.Tensor:
    """``log c(s)`` for proper singular values s (..., 3) (``s1 >= s2 >= |s3|``); differentiable.

    Computed in float64 and returned in ``s``'s dtype. ``log c(0) = 0`` (c is relative to the
    uniform probability measure on SO(3)).
    """
    if s.shape[-1] != 3:
        raise ValueError(f"s: expected (..., 3), got {tuple(s.shape)}")
    x = s.to(torch.float64)
    s1, s2, s3 = x[..., 0], x[..., 1], x[..., 2]
    # a, b, s2 + s3 >= 0 for proper singular values (rounding may leave -1e-16: harmless, and no
    # clamp here, whose zero gradient at the boundary would bias d log c / ds at repeated values)
    a = s1 - s2
    b = s1 + s2
    decay = s2 + s3
    z_max = torch.sqrt(torch.clamp(_CUTOFF / decay.detach().clamp_min(1e-300), max=2.0))
    nodes = torch.as_tensor(_UNIT_NODES, dtype=torch.float64, device=s.device)
    weights = torch.as_tensor(_UNIT_WEIGHTS, dtype=torch.float64, device=s.device)
    z = z_max[..., None] * nodes                                    # (..., n)
    z2 = z * z
    i0e = _I0eRight.apply
    integrand = (z * i0e(a[..., None] * z2 / 2) * i0e(b[..., None] * (2 - z2) / 2)
                 * torch.exp(-decay[..., None] * z2))
    integral = (integrand * weights).sum(-1) * z_max
    return (s1 + s2 + s3 + torch.log(integral)).to(s.dtype)


class _LogNormaliser(torch.autograd.Function):
    @staticmethod
    def forward(ctx, F):
        U, s, V = proper_svd(F.detach().to(torch.float64))
        with torch.enable_grad():
            s_ = s.detach().requires_grad_(True)
            logc = log_normaliser_of_singular_values(s_)
            (ds,) = torch.autograd.grad(logc.sum(), s_)
        ctx.save_for_backward(U, ds, V)
        ctx.dtype = F.dtype
        return logc.detach().to(F.dtype)

    @staticmethod
    def backward(ctx, grad):
        U, ds, V = ctx.saved_tensors
        g = (U * ds[..., None, :]) @ V.transpose(-1, -2)
        return (grad.to(torch.float64)[..., None, None] * g).to(ctx.dtype)


def log_normaliser(F: torch.Tensor) -> torch.Tensor:
    """``log c(F)`` for F (..., 3, 3) -> (...); gradient ``U diag(d log c/ds) V^T`` (= E[R] under p)."""
    return _LogNormaliser.apply(F)


def negative_log_likelihood(F: torch.Tensor, R: torch.Tensor) -> torch.Tensor:
    """``-log p(R | F) = -tr(F^T R) + log c(F)`` (the paper's Eq. A2) for F, R (..., 3, 3) -> (...)."""
    if R.shape[-2:] != (3, 3) or F.shape != R.shape:
        raise ValueError(f"F and R: expected equal shapes (..., 3, 3), got {tuple(F.shape)} and {tuple(R.shape)}")
    return -(F * R).sum((-1, -2)) + log_normaliser(F)


def mode(F: torch.Tensor) -> torch.Tensor:
    """The most likely rotation ``U V^T`` (proper SVD) of F (..., 3, 3)."""
    U, _, V = proper_svd(F)
    return U @ V.transpose(-1, -2)


def mean_rotation(F: torch.Tensor) -> torch.Tensor:
    """``E[R]`` under p(R | F), (..., 3, 3): the derivative of log c(F) (not a rotation)."""
    U, s, V = proper_svd(F.detach().to(torch.float64))
    s_ = s.requires_grad_(True)
    (ds,) = torch.autograd.grad(log_normaliser_of_singular_values(s_).sum(), s_)
    return ((U * ds[..., None, :]) @ V.transpose(-1, -2)).to(F.dtype)


def _quat_to_matrix_homogeneous(q: np.ndarray) -> np.ndarray:
    """R(q) (..., 3, 3) as a homogeneous quadratic in q (w, x, y, z) (a rotation when |q| = 1)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1),
    ], -2)


def bingham_matrix(F: np.ndarray) -> np.ndarray:
    """A (..., 4, 4) symmetric with ``q^T A q = tr(F^T R(q))`` for unit quaternions q (polarisation)."""
    F = np.asarray(F, np.float64)
    eye = np.eye(4)
    A = np.empty(F.shape[:-2] + (4, 4))
    for a in range(4):
        for b in range(4):
            plus = np.einsum("...ij,ij->...", F, _quat_to_matrix_homogeneous(eye[a] + eye[b]))
            minus = np.einsum("...ij,ij->...", F, _quat_to_matrix_homogeneous(eye[a] - eye[b]))
            A[..., a, b] = (plus - minus) / 4
    return A


def sample(F: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rotations from p(R | F) for each F (..., 3, 3) -> (n, ..., 3, 3) float64.

    Through the Bingham distribution of the unit quaternion (density exp(q^T A q) on S^3, see
    :func:`bingham_matrix`), by rejection from an angular central Gaussian envelope (Kent, Ganeiber
    & Mardia, "A new method to simulate the Bingham and related distributions", 2013), whose
    acceptance rate stays bounded away from 0 at any concentration. Not differentiable: for
    gradients use :func:`sampling_loss`.
    """
    F = np.asarray(F, np.float64)
    lead = F.shape[:-2]
    A = bingham_matrix(F.reshape(-1, 3, 3))                            # (M, 4, 4)
    m = len(A)
    lam_max = np.linalg.eigvalsh(A)[:, -1]
    psi = lam_max[:, None, None] * np.eye(4) - A                       # PSD, smallest eigenvalue 0
    lam = np.clip(np.linalg.eigvalsh(psi), 0, None)                    # (M, 4)
    lo, hi = np.full(m, 1e-12), np.full(m, 4.0)                        # b solves sum 1 / (b + 2 lam) = 1
    for _ in range(80):
        mid = (lo + hi) / 2
        big = (1.0 / (mid[:, None] + 2 * lam)).sum(1) > 1
        lo, hi = np.where(big, mid, lo), np.where(big, hi, mid)
    b = (lo + hi) / 2
    omega = np.eye(4) + 2 * psi / b[:, None, None]
    log_bound = -(4 - b) / 2 + 2 * np.log(4 / b)                       # log M of the envelope
    chol = np.linalg.cholesky(np.linalg.inv(omega))                    # y ~ N(0, Omega^-1)
    out = np.zeros((m, n, 4))
    have = np.zeros(m, int)
    while (have < n).any():
        need = np.nonzero(have < n)[0]
        y = np.einsum("mij,mkj->mki", chol[need], rng.standard_normal((len(need), 2 * n, 4)))
        x = y / np.linalg.norm(y, axis=-1, keepdims=True)
        log_f = -np.einsum("mki,mij,mkj->mk", x, psi[need], x)
        log_g = -2 * np.log(np.einsum("mki,mij,mkj->mk", x, omega[need], x))
        accept = np.log(rng.random(log_f.shape)) < log_f - log_g - log_bound[need, None]
        for row, i in enumerate(need):
            got = x[row][accept[row]][: n - have[i]]
            out[i, have[i]:have[i] + len(got)] = got
            have[i] += len(got)
    R = _quat_to_matrix_homogeneous(out)                               # (M, n, 3, 3)
    return np.moveaxis(R, 1, 0).reshape((n,) + lead + (3, 3))


def sampling_loss(F: torch.Tensor, R: torch.Tensor, n: int, rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """The expected distance of samples from p(. | F) to the true R, and a surrogate for its gradient.

    ``d(R', R) = ||R' - R||_F^2 / 8`` (0 equal, 1 opposite). With ``n >= 2`` samples R'_s per F
    (:func:`sample`), the surrogate ``mean_s (d_s - b_s) log p(R'_s | F)`` (``b_s`` the mean of the
    other samples' distances, a baseline that keeps it unbiased) has the gradient of
    ``E_{R' ~ p(. | F)}[d(R', R)]`` (score-function estimator), so minimising it sharpens F
    around R as drawing samples would.

    Args:
        F, R: (..., 3, 3). rng: the generator of the samples.

    Returns:
        ``(surrogate, mean_distance)``: scalars; ``mean_distance`` (no gradient) is the sample
        estimate of the expected distance, to log.
    """
    if n < 2:
        raise ValueError(f"sampling_loss needs n >= 2 samples for its baseline, got {n}")
    samples = torch.as_tensor(sample(F.detach().cpu().numpy(), n, rng), dtype=F.dtype, device=F.device)
    d = ((samples - R[None].to(F.dtype)) ** 2).sum((-1, -2)) / 8          # (n, ...)
    baseline = (d.sum(0, keepdim=True) - d) / (n - 1)
    log_p = -negative_log_likelihood(F[None].expand_as(samples), samples)
    surrogate = ((d - baseline).detach() * log_p).mean()
    return surrogate, d.mean().detach()
