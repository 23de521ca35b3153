"""How sure a benchmark mean is: intervals and standard errors clustered by (source, target) pair.

Cases of one (source, target) character pair share one correspondence (and often one motion), so
their scores are not independent: a method that mismatches a pair's legs fails every case of that
pair. Every interval and standard error here treats the pair as the unit that is sampled.

- :func:`pair_of`: the pair a case belongs to, read from its case ID
  (``<protocol>/<source_id>-><target_id>/<motion>#<frame>``).
- :func:`cluster_bootstrap_means`: the mean over the cases of pairs drawn with replacement (all
  cases of a drawn pair together), ``draws`` times, from a seeded generator.
- :func:`bootstrap_interval`: the percentile interval of those means (95% by default).
- :func:`paired_values`: two methods' values on the cases both have a value for, with their pairs.
- :func:`pair_clustered_se`: the cluster-robust standard error of a mean (pass paired
  differences for the standard error of a paired difference).
- :func:`tie_ranks`: rank = 1 + the number of methods surely better (paired interval excludes 0).
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

DRAWS = 2000
"""Bootstrap draws of every interval the leaderboard shows."""
SEED = 0
"""Seed of every bootstrap the leaderboard runs (the same results give the same intervals)."""
LEVEL = 0.95


def pair_of(case_id: str) -> str:
    """The ``source->target`` pair of a case ID ``<protocol>/<source_id>-><target_id>/<motion>#<frame>``.

    Character IDs may hold ``/`` (``zoo/humanoid-0003``): the pair is what lies between the
    protocol's prefix and the last ``/`` before the ``#``. A case ID without ``->`` is its own
    pair (each case then counts as independent).

    >>> pair_of("cct/zoo/humanoid-0001->zoo/bird-0003/walk#12")
    'zoo/humanoid-0001->zoo/bird-0003'
    """
    if "->" not in case_id:
        return case_id
    head = case_id.rsplit("#", 1)[0]
    protocol, _, rest = head.partition("/")
    pair, _, _motion = rest.rpartition("/")
    return pair if "->" in pair else rest


def _clusters(values, pair_ids) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pair (sorted by pair ID): sums of values (G, M), case counts (G,) and each case's pair
    index (N,), for values (N,) or (N, M)."""
    x = np.asarray(values, dtype=np.float64)
    x = x.reshape(len(x), -1) if x.ndim else x.reshape(1, 1)
    ids = np.asarray([str(p) for p in pair_ids])
    if len(ids) != len(x):
        raise ValueError(f"pair_ids: expected one pair ID per value ({len(x)}), got {len(ids)}")
    if len(x) == 0:
        raise ValueError("values: expected at least one value, got none")
    if not np.isfinite(x).all():
        raise ValueError("values: expected finite numbers (leave out cases without a value), got NaN or inf")
    _, inverse = np.unique(ids, return_inverse=True)
    groups = int(inverse.max()) + 1
    sums = np.zeros((groups, x.shape[1]))
    np.add.at(sums, inverse, x)
    return sums, np.bincount(inverse, minlength=groups).astype(np.float64), inverse


def cluster_bootstrap_means(values, pair_ids, draws: int = DRAWS, seed: int = SEED) -> np.ndarray:
    """Means of ``draws`` pair-clustered bootstrap resamples.

    Each draw picks G pairs with replacement among the G distinct pairs (sorted by ID, so the row
    order does not matter) and averages every case of every drawn pair (a pair drawn twice counts
    twice): ``sum_g S[idx_g] / sum_g n[idx_g]``. The indices are one ``(draws, G)`` matrix
    ``np.random.default_rng(seed).integers(0, G, size=(draws, G))``, the same for every column of
    ``values``: the difference of two columns' means is then, draw by draw, the mean of their
    paired differences.

    Args:
        values: (N,) per-case values, or (N, M): M methods on the same N cases.
        pair_ids: (N,) the pair of each case (e.g. :func:`pair_of` of its case ID).

    Returns:
        (draws,) float64 resampled means, or (draws, M) for (N, M) values.
    """
    if draws < 1:
        raise ValueError(f"draws: expected >= 1, got {draws}")
    sums, counts, _ = _clusters(values, pair_ids)
    groups = len(counts)
    idx = np.random.default_rng(seed).integers(0, groups, size=(draws, groups))
    drawn = np.bincount((np.arange(draws)[:, None] * groups + idx).ravel(), minlength=draws * groups)
    drawn = drawn.reshape(draws, groups).astype(np.float64)  # (draws, G): how often each pair was drawn
    means = (drawn @ sums) / (drawn @ counts)[:, None]
    return means[:, 0] if np.asarray(values).ndim == 1 else means


def bootstrap_interval(values, pair_ids, level: float = LEVEL, draws: int = DRAWS,
                       seed: int = SEED) -> tuple[float, float]:
    """The percentile interval (``level``, e.g. 0.95: the 2.5% and 97.5% quantiles, numpy's linear
    interpolation) of :func:`cluster_bootstrap_means`. One pair only: the interval of its one
    possible resample (zero width), which says nothing; callers show the pair count beside it."""
    if not 0 < level < 1:
        raise ValueError(f"level: expected a number in (0, 1), got {level}")
    means = cluster_bootstrap_means(values, pair_ids, draws, seed)
    lo, hi = np.quantile(means, [(1 - level) / 2, 1 - (1 - level) / 2])
    return float(lo), float(hi)


def pair_clustered_se(values, pair_ids) -> float:
    """Standard error of the mean of ``values`` with cases clustered by pair (CR1).

    ``se^2 = G / (G - 1) * sum_g (sum_{i in g} (x_i - mean))^2 / N^2`` over the G pairs and N
    cases: the sandwich variance of a mean with the usual small-sample factor G/(G-1). With one
    case per pair it is the ordinary ``std(ddof=1) / sqrt(N)``. For a paired difference between
    two methods pass the per-case differences (:func:`paired_values`).

    Args:
        values: (N,) per-case values (or differences).
        pair_ids: (N,) pair of each case.

    Returns:
        The standard error (same unit as ``values``); NaN with fewer than two pairs.
    """
    x = np.asarray(values, dtype=np.float64).reshape(-1)
    _, _, inverse = _clusters(x, pair_ids)
    groups = int(inverse.max()) + 1
    if groups < 2:
        return float("nan")
    resid = np.bincount(inverse, weights=x - x.mean())
    return float(np.sqrt(groups / (groups - 1) * (resid ** 2).sum()) / len(x))


def paired_values(a: Mapping[str, float | None], b: Mapping[str, float | None]
                  ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Two methods' values on the cases both have a value for (case IDs sorted).

    Args:
        a, b: case ID -> value (None: no value, e.g. failed or not scored).

    Returns:
        (values of a (M,), values of b (M,), pair IDs (M,) from :func:`pair_of`).
    """
    common = sorted(k for k in a.keys() & b.keys() if a[k] is not None and b[k] is not None)
    return (np.array([a[k] for k in common], np.float64), np.array([b[k] for k in common], np.float64),
            [pair_of(k) for k in common])


def paired_difference(a: Mapping[str, float | None], b: Mapping[str, float | None], level: float = LEVEL,
                      draws: int = DRAWS, seed: int = SEED) -> dict | None:
    """Mean of ``a - b`` over the cases both have, its bootstrap interval and pair-clustered SE.

    Returns:
        ``{"diff", "lo", "hi", "se", "cases", "pairs"}``, or None when no case has both.
    """
    va, vb, pairs = paired_values(a, b)
    if len(va) == 0:
        return None
    d = va - vb
    lo, hi = bootstrap_interval(d, pairs, level, draws, seed)
    return {"diff": float(d.mean()), "lo": lo, "hi": hi, "se": pair_clustered_se(d, pairs), "cases": int(len(d)),
            "pairs": len(set(pairs))}


def tie_ranks(order: Sequence[str], surely_better: Mapping[tuple[str, str], bool]) -> dict[str, int]:
    """Ranks with ties: a method's rank is 1 + the number of methods surely better than it.

    Args:
        order: method keys, best mean first.
        surely_better: ``(a, b) -> True`` when ``a`` is surely better than ``b`` (the interval of
            their paired difference excludes 0 on ``a``'s side); a missing key counts as False.

    Two methods with the same rank are tied. Ties are not chained: with A surely better than C
    and B tied with both, A and B rank 1 and C ranks 2.
    """
    return {m: 1 + sum(bool(surely_better.get((o, m), False)) for o in order if o != m) for m in order}
