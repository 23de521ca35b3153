"""Correspondence matrices for many character pairs at once.

For a pair with canonical-name embeddings E1 (K1, d) and E2 (K2, d) (unit rows):
``S_cos = E1 E2^T`` (K1, K2); ``M_hung`` the rectangular Hungarian matching maximising total
similarity (scipy); ``M_sink`` the Sinkhorn balancing of ``exp(S_cos / T)`` with rows summing to
1 and columns to K1/K2 (as :func:`mimicbench.sinkhorn.sinkhorn_log`).

Pairs are processed in batches padded to the largest K1 and K2 in the batch. Sinkhorn runs in
the scaling (exp) domain in float32 torch: each sweep is two batched matrix-vector products,
which is what makes hundreds of thousands of pairs cheap; scores are shifted by their maximum (1)
so ``exp`` cannot overflow, and ``exp(-2 / T)`` stays above float32's smallest normal number
for T >= 0.03 (a smaller T raises a clear error when the marginals are not met).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

DEFAULT_TEMPERATURE = 0.1


def sinkhorn_padded(scores: torch.Tensor, k1: torch.Tensor, k2: torch.Tensor, temperature: float,
                    tol: float = 2e-5, max_iters: int = 3000, omega: float = 1.5) -> torch.Tensor:
    """Batched Sinkhorn on padded scores, in the scaling domain with over-relaxation.

    Each sweep updates ``u <- u^(1-w) (a / K v)^w`` and ``v <- v^(1-w) (b / K^T u)^w``
    (over-relaxed Sinkhorn, Thibault et al. 2017; w = 1 is the classic update), which cuts the
    sweeps several-fold on near-duplicate bone names. Pairs leave the batch once their row and
    column sums are within ``tol``; after ``max_iters // 2`` sweeps the rest continue with w = 1,
    whose convergence is guaranteed.

    Args:
        scores: (B, P1, P2) similarities in [-1, 1]; entries beyond each pair's (k1, k2) are ignored.
        k1, k2: (B,) long valid sizes.
        temperature: T >= 0.01.

    Returns:
        (B, P1, P2) of the dtype of ``scores``: the valid block balanced to rows 1 and columns
        k1/k2; zeros elsewhere.
    """
    if temperature < 0.01:
        raise ValueError(f"temperature: expected >= 0.01 for the scaling-domain solver, got {temperature}")
    bsz, p1, p2 = scores.shape
    rows = torch.arange(p1)[None, :] < k1[:, None]
    cols = torch.arange(p2)[None, :] < k2[:, None]
    zero = torch.zeros((), dtype=scores.dtype)
    kernel = torch.where(rows[:, :, None] & cols[:, None, :], torch.exp((scores - 1.0) / temperature), zero)
    a = rows.to(scores.dtype)
    b = cols.to(scores.dtype) * (k1.to(scores.dtype) / k2.to(scores.dtype))[:, None]
    u, v = a.clone(), b.clone()
    active = torch.arange(bsz)
    k_act, a_act, b_act, u_act, v_act = kernel, a, b, u, v
    for it in range(max_iters):
        w = omega if it < max_iters // 2 else 1.0
        un = torch.where(a_act > 0, a_act / torch.bmm(k_act, v_act[:, :, None])[:, :, 0].clamp_min(1e-30), zero)
        u_act = un if w == 1.0 else torch.where(a_act > 0, u_act.clamp_min(1e-30) ** (1 - w) * un ** w, zero)
        vn = torch.where(b_act > 0, b_act / torch.bmm(k_act.transpose(1, 2), u_act[:, :, None])[:, :, 0].clamp_min(1e-30), zero)
        v_act = vn if w == 1.0 else torch.where(b_act > 0, v_act.clamp_min(1e-30) ** (1 - w) * vn ** w, zero)
        if it % 5 == 4 or it == max_iters - 1:
            row_err = (u_act * torch.bmm(k_act, v_act[:, :, None])[:, :, 0] - a_act).abs().amax(dim=1)
            col_err = (v_act * torch.bmm(k_act.transpose(1, 2), u_act[:, :, None])[:, :, 0] - b_act).abs().amax(dim=1)
            done = torch.maximum(row_err, col_err) < tol
            if done.any():
                u[active[done]], v[active[done]] = u_act[done], v_act[done]
                keep = ~done
                active, k_act, a_act, b_act = active[keep], k_act[keep], a_act[keep], b_act[keep]
                u_act, v_act = u_act[keep], v_act[keep]
                if len(active) == 0:
                    break
    if len(active):
        u[active], v[active] = u_act, v_act
    return u[:, :, None] * kernel * v[:, None, :]


def correspondence_batch(emb_a: Sequence[np.ndarray], emb_b: Sequence[np.ndarray],
                         temperature: float = DEFAULT_TEMPERATURE) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(S_cos (K1, K2) float32, hungarian pairs (min(K1, K2), 2) int32, M_sink (K1, K2) float32) per pair.

    Args:
        emb_a, emb_b: per pair the unit-row embeddings of the source (K1, d) and target (K2, d).
    """
    n = len(emb_a)
    if n == 0:
        return []
    k1 = torch.tensor([len(e) for e in emb_a])
    k2 = torch.tensor([len(e) for e in emb_b])
    d = emb_a[0].shape[1]
    pa = torch.zeros(n, int(k1.max()), d, dtype=torch.float32)
    pb = torch.zeros(n, int(k2.max()), d, dtype=torch.float32)
    for i, (ea, eb) in enumerate(zip(emb_a, emb_b)):
        pa[i, : len(ea)] = torch.from_numpy(np.asarray(ea, dtype=np.float32))
        pb[i, : len(eb)] = torch.from_numpy(np.asarray(eb, dtype=np.float32))
    scores = torch.bmm(pa, pb.transpose(1, 2)).clamp(-1.0, 1.0)
    sink = sinkhorn_padded(scores, k1, k2, temperature)
    row_error = (sink.sum(dim=2) - (torch.arange(sink.shape[1])[None, :] < k1[:, None]).to(sink.dtype)).abs().max().item()
    if row_error > 1e-4:
        raise RuntimeError(f"Sinkhorn did not converge (row marginal error {row_error:.1e}); "
                           f"use a higher temperature than {temperature}")
    sink = sink.numpy()
    scores = scores.numpy()
    out = []
    for i in range(n):
        s = scores[i, : k1[i], : k2[i]]
        r, c = linear_sum_assignment(s, maximize=True)
        out.append((s.astype(np.float32), np.stack([r, c], 1).astype(np.int32),
                    sink[i, : k1[i], : k2[i]].astype(np.float32)))
    return out
