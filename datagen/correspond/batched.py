"""Correspondence matrices for many character pairs at once.

For a pair with canonical-name embeddings E1 (K1, d) and E2 (K2, d) (unit rows):
``S_cos = E1 E2^T`` (K1, K2); ``M_hung`` the rectangular Hungarian matching maximising total
similarity (scipy); ``M_sink`` the Sinkhorn balancing of ``exp(S_cos / T)`` with rows summing to
1 and columns to K1/K2 (as :func:`mimicbench.geometry.sinkhorn.sinkhorn_log`).

Pairs are processed in batches padded to the largest K1 and K2 in the batch. Sinkhorn runs in
the scaling (exp) domain in float32 torch: each sweep is two batched matrix-vector products,
which is what makes hundreds of thousands of pairs cheap. Before ``exp``, each row's maximum and
then each column's maximum is subtracted from S / T: a diagonal rescaling that the scalings absorb
(the result is unchanged) and that puts an entry equal to 1 in every row and every column, so
``exp`` neither overflows nor leaves a row or column all zero. At small T (below about 0.05 on
real bone names) the balancing may need more sweeps than allowed; the marginals are then checked
and a clear error asks for a higher temperature.

The batches run on one torch thread: with torch's default (one thread a core) the large chunks'
element-wise sweeps and products split over threads, which changed the last bits of a few M_sink
entries with the machine's core count and, on a busy 2-core machine, spent about 5x more CPU time
in threads waiting for each other. Parallelism comes from running blocks in several processes
(``--jobs``) or Ray tasks instead.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from numba import njit
from scipy.optimize import linear_sum_assignment

DEFAULT_TEMPERATURE = 0.1
# Over-relaxation for problems with a dustbin: structure scores make nearly decoupled blocks (left,
# right, centre bones) that balance slowly; on 256 zoo-feature pairs of 80 bones the chunk needed
# 353 sweeps at w = 1.5 and 112 at w = 1.7 (w = 1.9 stalled).
DUSTBIN_OMEGA = 1.7
CHUNK = 256
MIN_TRUNK = 3  # trunk bones (pelvis to below the neck) each skeleton needs for the trunk rules


def sinkhorn_padded(scores: torch.Tensor, k1: torch.Tensor, k2: torch.Tensor, temperature: float,
                    tol: float = 2e-5, max_iters: int = 20000, omega: float = 1.5, chunk: int = 256,
                    dustbin: float | None = None, classic: bool = False) -> torch.Tensor:
    """Batched Sinkhorn on padded scores, in the scaling domain with over-relaxation.

    Each sweep updates ``u <- u^(1-w) (a / K v)^w`` and ``v <- v^(1-w) (b / K^T u)^w``
    (over-relaxed Sinkhorn, Thibault et al. 2017; w = 1 is the classic update), which cuts the
    sweeps several-fold on near-duplicate bone names. Pairs leave the batch once their row and
    column sums are within ``tol`` (relative to the marginal where that exceeds 1); after ``max_iters // 2`` sweeps the rest continue with w = 1,
    whose convergence is guaranteed. Pairs are solved ``chunk`` at a time so that a chunk's
    kernel and its transpose stay in the CPU cache (the sweeps are memory bound: 256 pairs of
    80 x 80 ran about 2.5x faster per pair than 2048 at once).

    With ``dustbin`` (a score), each pair gets a "no match" row and column of that score
    (SuperGlue's dustbin): every source bone keeps row mass 1, every target bone takes at most
    ``max(1, k1/k2)`` (so several source bones may share one target, a 3-bone neck onto a 1-bone
    neck), and what a bone cannot place above the dustbin's score goes to the dustbin. The
    dustbin row holds ``max(k1, k2)``, the column ``k1``, so the problem stays balanced; the
    returned block then has rows summing to at most 1.

    Args:
        scores: (B, P1, P2) scores (cosines, or combined scores of a few units); entries beyond
            each pair's (k1, k2) are ignored.
        k1, k2: (B,) long valid sizes.
        temperature: T >= 0.01.
        dustbin: score of the no-match row and column, or None for the plain balanced problem.
        classic: every sweep with w = 1 (no over-relaxation): slower, but its scalings cannot
            overflow; :func:`correspondence_batch` redoes with it the few pairs whose over-relaxed
            sweeps overflowed.

    Returns:
        (B, P1, P2) of the dtype of ``scores``: the valid block balanced to rows 1 and columns
        k1/k2 (with a dustbin: rows at most 1, columns at most max(1, k1/k2)); zeros elsewhere.
    """
    if temperature < 0.01:
        raise ValueError(f"temperature: expected >= 0.01 for the scaling-domain solver, got {temperature}")
    if not 1.0 <= omega < 2.0:
        raise ValueError(f"omega: expected 1 <= omega < 2, got {omega}")
    return torch.cat([_sinkhorn_chunk(scores[i:i + chunk], k1[i:i + chunk], k2[i:i + chunk], temperature, tol,
                                      max_iters, omega, dustbin, classic) for i in range(0, scores.shape[0], chunk)])


def _matvec(kernel_t: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """(B, P) ``K x`` given the contiguous transpose ``K^T`` (B, Q, P) and x (B, Q).

    Written as the row-vector product ``x^T K^T``, which torch runs several times faster than
    ``bmm(K, x[..., None])`` on CPU.
    """
    return torch.bmm(x[:, None, :], kernel_t)[:, 0]


def _sinkhorn_chunk(scores, k1, k2, temperature, tol, max_iters, omega, dustbin=None, classic=False):
    bsz, p1, p2 = scores.shape
    rows = torch.arange(p1)[None, :] < k1[:, None]
    cols = torch.arange(p2)[None, :] < k2[:, None]
    if dustbin is not None:  # the last row and column of the padded block are the dustbins
        full = torch.full((bsz, p1 + 1, p2 + 1), float(dustbin), dtype=scores.dtype)
        full[:, :p1, :p2] = scores
        yes = torch.ones((bsz, 1), dtype=torch.bool)
        rows, cols = torch.cat([rows, yes], 1), torch.cat([cols, yes], 1)
        f1, f2 = k1.to(scores.dtype), k2.to(scores.dtype)
        a = torch.cat([rows[:, :p1].to(scores.dtype), torch.maximum(f1, f2)[:, None]], 1)
        b = torch.cat([cols[:, :p2].to(scores.dtype) * torch.clamp(f1 / f2, min=1.0)[:, None], f1[:, None]], 1)
        out = _balance(full, rows, cols, a, b, temperature, tol, max_iters, 1.0 if classic else max(omega, DUSTBIN_OMEGA))
        return out[:, :p1, :p2]
    a = rows.to(scores.dtype)
    b = cols.to(scores.dtype) * (k1.to(scores.dtype) / k2.to(scores.dtype))[:, None]
    return _balance(scores, rows, cols, a, b, temperature, tol, max_iters, 1.0 if classic else omega)


def _balance(scores, rows, cols, a, b, temperature, tol, max_iters, omega):
    """Scaling-domain Sinkhorn of exp(scores / T) on the valid block to row sums a, column sums b."""
    bsz = scores.shape[0]
    zero = torch.zeros((), dtype=scores.dtype)
    valid = rows[:, :, None] & cols[:, None, :]
    low = torch.tensor(-torch.inf, dtype=scores.dtype)
    logits = torch.where(valid, scores / temperature, low)
    logits = logits - logits.amax(dim=2, keepdim=True).clamp_min(-1e30)  # rows (padded rows stay -inf)
    logits = logits - logits.amax(dim=1, keepdim=True).clamp_min(-1e30)  # then columns
    kernel = torch.where(valid, torch.exp(logits), zero)
    u, v = a.clone(), b.clone()
    active = torch.arange(bsz)
    k_act, kt_act = kernel, kernel.transpose(1, 2).contiguous()
    a_act, b_act, u_act, v_act = a, b, u.clone(), v.clone()
    for it in range(max_iters):
        w = omega if it < max_iters // 2 else 1.0
        kv = _matvec(kt_act, v_act)  # K v
        if it % 5 == 0 and it > 0:  # (u, v) from the last sweep: rows for free, columns only if rows are met
            # relative to the marginal where it exceeds 1 (a dustbin's mass of max(k1, k2) meets
            # float32's precision only relatively)
            done = ((u_act * kv - a_act).abs() / a_act.clamp_min(1.0)).amax(dim=1) < tol
            if done.any():
                col_err = ((v_act * _matvec(k_act, u_act) - b_act).abs() / b_act.clamp_min(1.0)).amax(dim=1)
                done &= col_err < tol
            if done.any():
                u[active[done]], v[active[done]] = u_act[done], v_act[done]
                keep = ~done
                if not keep.any():
                    active = active[keep]
                    break
                active, k_act, kt_act, a_act, b_act = active[keep], k_act[keep], kt_act[keep], a_act[keep], b_act[keep]
                u_act, v_act, kv = u_act[keep], v_act[keep], kv[keep]
        u_act = _scaling_update(u_act, a_act, kv, w)
        v_act = _scaling_update(v_act, b_act, _matvec(k_act, u_act), w)  # K^T u
    if len(active):
        u[active], v[active] = u_act, v_act
    return u[:, :, None] * kernel * v[:, None, :]


def _scaling_update(x: torch.Tensor, marginal: torch.Tensor, product: torch.Tensor, w: float) -> torch.Tensor:
    """One over-relaxed Sinkhorn half-sweep: ``x^(1-w) (marginal / product)^w`` (B, P), in place.

    ``x`` is the scaling (u or v) of the last sweep, ``product`` the kernel applied to the other
    scaling (both are overwritten). Where the marginal is 0 (padding) the result is exactly +0 with
    no mask: ``0 / p`` is +0 for the clamped p, ``0^w`` is +0, and ``x^(1-w)`` of the clamped x
    is finite, so the mask of the textbook form (``where(marginal > 0, ..., 0)``) changes no bit.
    The operations and their order are otherwise the textbook form's, so the bits are too.
    """
    fresh = torch.div(marginal, product.clamp_min_(1e-30), out=product)  # marginal / product
    if w == 1.0:
        return fresh
    return x.clamp_min_(1e-30).pow_(1 - w).mul_(fresh.pow_(w))


def correspondence_batch(emb_a: Sequence[np.ndarray], emb_b: Sequence[np.ndarray],
                         temperature: float = DEFAULT_TEMPERATURE, chunk: int = CHUNK,
                         feat_a: Sequence[np.ndarray] | None = None, feat_b: Sequence[np.ndarray] | None = None,
                         feature_weights: Sequence[float] | None = None, text_weight: float = 1.0,
                         no_match: float | None = None, chain_penalty: float = 0.0,
                         anchor: float | None = None, trunk_floor: float | None = None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(S_cos (K1, K2) float32, hungarian pairs (P, 2) int32, M_sink (K1, K2) float32) per pair.

    The matching score is ``S = text_weight * S_cos - sum_f w_f (f_a - f_b)^2`` over per-bone
    features f (structure features, :mod:`.structure`; none for the text-only method, S = S_cos).
    Without ``no_match`` the Hungarian matching fills min(K1, K2) slots and Sinkhorn balances
    exp(S / T) to rows 1 and columns K1/K2 (the paper's method). With ``no_match`` = tau, only
    pairs with S > tau are matched (the Hungarian maximises the sum of S - tau over matched
    pairs, so P <= min(K1, K2)), and Sinkhorn gets a dustbin of score tau (see
    :func:`sinkhorn_padded`): bones without a counterpart keep their mass there.

    Args:
        emb_a, emb_b: per pair the unit-row embeddings of the source (K1, d) and target (K2, d).
        temperature: Sinkhorn temperature T.
        chunk: pairs computed together; small enough that a chunk's padded arrays stay in cache
            and are reused by the allocator (large fresh tensors cost page faults).
        feat_a, feat_b: per pair (K1, F) and (K2, F) float32 features, or None.
        feature_weights: (F,) weights w_f >= 0.
        text_weight: weight of S_cos in S.
        no_match: threshold tau on S below which a bone stays unmatched, or None.
        chain_penalty: with features, subtracted from S where the two bones' chain codes (the
            second-last feature column, :func:`.structure.chain_kinds`) differ: a bone of the trunk
            never meets a hand, an arm never a hind leg, unless their names say so (``anchor``).
        anchor: with features, S of two bones whose name codes (the last column,
            :func:`.structure.name_keys`) are equal is raised to at least this score (set it above
            ``no_match``): a bone with a same-named or synonym counterpart is never left unmatched
            for want of a score, whatever the chains say.
        trunk_floor: with features, two trunk bones (sequence id 0 in the fourth-last column, their
            arc-length position from the pelvis, 0, to the head, 1, in the third-last) score at least
            ``trunk_floor - |arc_a - arc_b|``: the spines are aligned as sequences by position,
            whatever their names (``LowerBack``, ``Abdomen``, ``Spine1``, ``Chest``); the Hungarian
            pairs are then :func:`chain_hungarian_pairs` (trunk and limbs aligned in order).
    """
    if len(emb_a) != len(emb_b):
        raise ValueError(f"emb_a, emb_b: expected equal lengths, got {len(emb_a)} and {len(emb_b)}")
    if (feat_a is None) != (feat_b is None) or (feat_a is not None and feature_weights is None):
        raise ValueError("feat_a, feat_b, feature_weights: expected all three or none")
    out = []
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # the same bits on every machine (see the module docstring)
    try:
        for i in range(0, len(emb_a), chunk):
            fa = None if feat_a is None else feat_a[i:i + chunk]
            fb = None if feat_b is None else feat_b[i:i + chunk]
            out.extend(_correspondence_chunk(emb_a[i:i + chunk], emb_b[i:i + chunk], temperature, fa, fb,
                                             feature_weights, text_weight, no_match, chain_penalty, anchor,
                                             trunk_floor))
    finally:
        torch.set_num_threads(threads)
    return out


def _padded(embeddings: Sequence[np.ndarray]) -> np.ndarray:
    """(n, P, d) float32 zero-padded stack of (K_i, d) arrays, P = max K_i."""
    sizes = {len(e) for e in embeddings}
    if len(sizes) == 1:
        return np.stack(embeddings).astype(np.float32, copy=False)
    out = np.zeros((len(embeddings), max(sizes), embeddings[0].shape[1]), np.float32)
    for i, e in enumerate(embeddings):
        out[i, : len(e)] = e
    return out


def feature_penalty(fa: torch.Tensor, fb: torch.Tensor, weights: Sequence[float]) -> torch.Tensor:
    """(B, P1, P2) ``sum_f w_f (fa_f - fb_f)^2`` for fa (B, P1, F) and fb (B, P2, F), as one bmm.

    Expanded as ``w a^2 + w b^2 - 2 w a b``: one product of (F + 2)-wide rows, so the structure
    terms cost a small fraction of the cosine product.
    """
    w = torch.as_tensor(np.asarray(weights, np.float32))
    if w.shape != (fa.shape[-1],):
        raise ValueError(f"feature_weights: expected {fa.shape[-1]} weights, got {tuple(w.shape)}")
    one_a, one_b = torch.ones_like(fa[..., :1]), torch.ones_like(fb[..., :1])
    left = torch.cat([-2 * w * fa, (w * fa * fa).sum(-1, keepdim=True), one_a], -1)
    right = torch.cat([fb, one_b, (w * fb * fb).sum(-1, keepdim=True)], -1)
    return torch.bmm(left, right.transpose(1, 2)).clamp_(min=0.0)


def chain_scores(scores: torch.Tensor, fa: torch.Tensor, fb: torch.Tensor, chain_penalty: float = 0.0,
                 anchor: float | None = None, trunk_floor: float | None = None, k1: torch.Tensor | None = None,
                 k2: torch.Tensor | None = None) -> torch.Tensor:
    """(B, P1, P2) scores of :func:`correspondence_batch`'s chain rules, from the last four columns
    of fa (B, P1, F) and fb (B, P2, F): sequence id and position, chain code, name code
    (:class:`.structure.SkeletonFeatures`); k1, k2 (B,) the valid sizes (padding rows do not count
    as trunk bones)."""
    if trunk_floor is not None:
        on_a, on_b = fa[:, :, -4] == 0, fb[:, :, -4] == 0  # trunk bones
        rows = torch.arange(fa.shape[1])[None, :] < (k1[:, None] if k1 is not None else fa.shape[1])
        cols = torch.arange(fb.shape[1])[None, :] < (k2[:, None] if k2 is not None else fb.shape[1])
        spines = (((on_a & rows).sum(1) >= MIN_TRUNK) & ((on_b & cols).sum(1) >= MIN_TRUNK))[:, None, None]
        gap = (fa[:, :, None, -3] - fb[:, None, :, -3]).abs()
        floor = torch.where(on_a[:, :, None] & on_b[:, None, :] & spines, trunk_floor - gap, torch.tensor(-torch.inf))
        scores = torch.maximum(scores, floor.to(scores.dtype))
    if chain_penalty:
        scores = scores - chain_penalty * (fa[:, :, None, -2] != fb[:, None, :, -2]).to(scores.dtype)
    if anchor is not None:
        same = fa[:, :, None, -1] == fb[:, None, :, -1]
        scores = torch.where(same, scores.clamp(min=float(anchor)), scores)
    return scores


def _correspondence_chunk(emb_a, emb_b, temperature, feat_a=None, feat_b=None, weights=None, text_weight=1.0,
                          no_match=None, chain_penalty=0.0, anchor=None, trunk_floor=None):
    n = len(emb_a)
    if n == 0:
        return []
    k1 = torch.tensor([len(e) for e in emb_a])
    k2 = torch.tensor([len(e) for e in emb_b])
    pa, pb = torch.from_numpy(_padded(emb_a)), torch.from_numpy(_padded(emb_b))
    cosines = torch.bmm(pa, pb.transpose(1, 2)).clamp_(-1.0, 1.0)
    if not torch.isfinite(cosines).all():
        raise ValueError("emb_a, emb_b: expected finite embeddings, got NaN or inf")
    scores = cosines
    if feat_a is not None:
        fa, fb = torch.from_numpy(_padded(feat_a)), torch.from_numpy(_padded(feat_b))
        if not (torch.isfinite(fa).all() and torch.isfinite(fb).all()):
            raise ValueError("feat_a, feat_b: expected finite features, got NaN or inf")
        scores = text_weight * cosines - feature_penalty(fa, fb, weights)
        scores = chain_scores(scores, fa, fb, chain_penalty, anchor, trunk_floor, k1, k2)
    sink = sinkhorn_padded(scores, k1, k2, temperature, chunk=n, dustbin=no_match)
    bad = ~(_row_errors(sink, k1, no_match) <= 1e-4)  # also catches NaN
    if bad.any():  # over-relaxed sweeps that overflowed (seen with a dustbin on 81 x 241 bones): classic sweeps
        sink[bad] = sinkhorn_padded(scores[bad], k1[bad], k2[bad], temperature, chunk=n, dustbin=no_match,
                                    classic=True)
        row_error = _row_errors(sink, k1, no_match).max().item()
        if not row_error <= 1e-4:
            raise RuntimeError(f"Sinkhorn did not converge (row marginal error {row_error:.1e}); "
                               f"use a higher temperature than {temperature}")
    sink, cosines, scores = sink.numpy(), cosines.numpy(), scores.numpy()
    out, seqs = [], {}  # each skeleton's sequences once (its feature array recurs across pairs)

    def sequences_of(f):
        if id(f) not in seqs:
            seqs[id(f)] = (f, _sequences(f[:, -4:-1]))
        return seqs[id(f)][1]

    for i in range(n):
        c = cosines[i, : k1[i], : k2[i]]
        si = scores[i, : k1[i], : k2[i]]
        if trunk_floor is not None:
            pairs = chain_hungarian_pairs(si, feat_a[i][:, -4:-1], feat_b[i][:, -4:-1], no_match,
                                          (sequences_of(feat_a[i]), sequences_of(feat_b[i])))
        if anchor is not None:
            pairs = same_name_pairs(si, pairs, feat_a[i][:, -1], feat_b[i][:, -1])
        else:
            pairs = hungarian_pairs(si, no_match)
        out.append((c.copy(), pairs, sink[i, : k1[i], : k2[i]].copy()))
    return out


def _row_errors(sink: torch.Tensor, k1: torch.Tensor, no_match: float | None) -> torch.Tensor:
    """(B,) largest row-sum error of each pair's M_sink: rows should sum to 1 (to at most 1 with a dustbin)."""
    want_rows = (torch.arange(sink.shape[1])[None, :] < k1[:, None]).to(sink.dtype)
    excess = sink.sum(dim=2) - want_rows
    return (excess if no_match is None else excess.clamp(min=0)).abs().amax(dim=1)


def monotone_pairs(gain: np.ndarray) -> list[tuple[int, int]]:
    """The order-preserving matching of two sequences with the largest total gain (DP alignment).

    ``gain`` (n, m): the gain of matching link i of the first sequence with link j of the second
    (links in order along their chains); pairs (i, j) with i and j both increasing, gains > 0 only.
    The dynamic programme is compiled (numba, :func:`_monotone_kernel`).
    """
    out = _monotone_kernel(np.ascontiguousarray(gain, dtype=np.float64))
    return [(int(i), int(j)) for i, j in out]


@njit(cache=True)
def _monotone_kernel(gain):
    """(P, 2) int64 pairs of :func:`monotone_pairs`: best[i+1, j+1] = max(best[i, j+1], best[i+1, j],
    best[i, j] + max(gain[i, j], 0)), then the path back from best[n, m]."""
    n, m = gain.shape
    best = np.zeros((n + 1, m + 1))
    for i in range(n):
        for j in range(m):
            g = gain[i, j] if gain[i, j] > 0.0 else 0.0
            best[i + 1, j + 1] = max(best[i, j + 1], best[i + 1, j], best[i, j] + g)
    out = np.empty((min(n, m), 2), np.int64)
    k, i, j = 0, n, m
    while i > 0 and j > 0:
        if best[i, j] == best[i - 1, j]:
            i -= 1
        elif best[i, j] == best[i, j - 1]:
            j -= 1
        else:
            out[k, 0], out[k, 1] = i - 1, j - 1
            k += 1
            i -= 1
            j -= 1
    return out[:k][::-1]


def _sequences(seq: np.ndarray) -> dict[int, np.ndarray]:
    """Per sequence id (0 trunk, > 0 a limb's main path) its bone indices in order of position."""
    order = np.lexsort((seq[:, 1], seq[:, 0]))
    order = order[seq[order, 0] >= 0]
    ids = seq[order, 0]
    cuts = np.flatnonzero(np.diff(ids)) + 1
    return {int(ids[c]): part for c, part in zip(np.r_[0, cuts], np.split(order, cuts))} if len(order) else {}


def chain_hungarian_pairs(scores: np.ndarray, seq_a: np.ndarray, seq_b: np.ndarray, no_match: float,
                          sequences: tuple[dict, dict] | None = None) -> np.ndarray:
    """(P, 2) int32 pairs: trunks and limbs aligned as sequences, every other bone by the Hungarian.

    ``seq_a`` (K1, 3), ``seq_b`` (K2, 3): per bone its sequence id (0 the trunk, b + 1 the main path
    of the limb based at b, -1 none), its position in it and its chain code (the feature columns
    of :class:`.structure.SkeletonFeatures`). The trunks (pelvis to below the neck, when both have
    :data:`MIN_TRUNK` bones or more) are matched by :func:`monotone_pairs` on ``S - no_match``, so a
    spine bone never skips past another. Limbs are paired by the Hungarian on the totals of their
    alignments, only limbs of one chain code (kind and side) with each other, and each pair of
    limbs is aligned link by link in order, so a link never jumps to another limb nor crosses its
    neighbour. Every bone left unmatched (fingers off a limb's main path, heads, tails, limbs
    without a partner, links an alignment skipped) goes to :func:`hungarian_pairs` on what is left.
    """
    sa, sb = _sequences(seq_a), _sequences(seq_b)
    pairs = []
    used_a, used_b = np.zeros(len(seq_a), bool), np.zeros(len(seq_b), bool)
    if 0 in sa and 0 in sb and len(sa[0]) >= MIN_TRUNK and len(sb[0]) >= MIN_TRUNK:
        ta, tb = sa[0], sb[0]
        pairs += [(ta[i], tb[j]) for i, j in monotone_pairs(scores[np.ix_(ta, tb)] - no_match)]
    limbs_a = [s for s in sa if s > 0]
    limbs_b = [s for s in sb if s > 0]
    if limbs_a and limbs_b:
        total = np.zeros((len(limbs_a), len(limbs_b)))
        aligned = {}
        code_b = {}
        for y, lb in enumerate(limbs_b):
            code_b.setdefault(seq_b[sb[lb][0], 2], []).append(y)
        for x, la in enumerate(limbs_a):
            for y in code_b.get(seq_a[sa[la][0], 2], ()):
                ia, ib = sa[la], sb[limbs_b[y]]
                gain = scores[np.ix_(ia, ib)] - no_match
                got = monotone_pairs(gain)
                aligned[x, y] = [(ia[i], ib[j]) for i, j in got]
                total[x, y] = sum(gain[i, j] for i, j in got)
        rows, cols = linear_sum_assignment(total, maximize=True)
        for x, y in zip(rows, cols):
            if total[x, y] > 0:
                pairs += aligned[x, y]
    for i, j in pairs:
        used_a[i], used_b[j] = True, True
    rest_a, rest_b = np.flatnonzero(~used_a), np.flatnonzero(~used_b)
    if len(rest_a) and len(rest_b):
        pairs += [(rest_a[i], rest_b[j]) for i, j in hungarian_pairs(scores[np.ix_(rest_a, rest_b)], no_match)]
    return np.array(sorted(pairs), np.int32).reshape(-1, 2)


def same_name_pairs(scores: np.ndarray, pairs: np.ndarray, name_a: np.ndarray, name_b: np.ndarray) -> np.ndarray:
    """``pairs`` (P, 2) plus, among the rows and columns they leave free, the bones of equal name
    codes ``name_a`` (K1,) / ``name_b`` (K2,), the best scored first: the no-match rule never leaves
    a bone out while a same-named or synonym counterpart is free too."""
    free_a, free_b = np.ones(len(name_a), bool), np.ones(len(name_b), bool)
    free_a[pairs[:, 0]], free_b[pairs[:, 1]] = False, False
    rows, cols = np.nonzero((name_a[:, None] == name_b[None, :]) & free_a[:, None] & free_b[None, :])
    if not len(rows):
        return pairs
    extra = []
    for k in np.argsort(-scores[rows, cols], kind="stable"):
        r, c = rows[k], cols[k]
        if free_a[r] and free_b[c]:
            extra.append([int(r), int(c)])
            free_a[r], free_b[c] = False, False
    return np.array(sorted(pairs.tolist() + extra), np.int32).reshape(-1, 2)


def hungarian_pairs(scores: np.ndarray, no_match: float | None = None) -> np.ndarray:
    """(P, 2) int32 (row, column) pairs of the best one-to-one matching of a (K1, K2) score matrix.

    Without ``no_match`` every row or column is matched (P = min(K1, K2)). With it, the matching
    maximises the sum of ``S - no_match`` over matched pairs and keeps only pairs above it: the
    Hungarian on ``max(S - tau, 0)`` then dropping the zero-gain pairs gives exactly that (a
    partial matching extends to a full one with zero-gain pairs, and back).
    """
    if no_match is None:
        r, c = linear_sum_assignment(scores, maximize=True)
    else:
        gain = np.maximum(scores - no_match, 0.0)
        r, c = linear_sum_assignment(gain, maximize=True)
        keep = gain[r, c] > 0
        r, c = r[keep], c[keep]
    return np.stack([r, c], 1).astype(np.int32)
