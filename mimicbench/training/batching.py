"""Splitting one epoch into per-rank batches, so runs on any number of processes see the same data.

``batch_size`` is the global batch: under ``torchrun`` with W processes each rank gets a W-th of
every global batch, and DDP's gradient averaging makes a step equal to one process's step on the
whole global batch (for losses that are means over the batch).
"""
from __future__ import annotations

import numpy as np


def rank_batches(n_items: int, batch_size: int, rng: np.random.Generator, rank: int = 0,
                 world_size: int = 1, shuffle: bool = True) -> list[np.ndarray]:
    """Index batches of one epoch for one rank.

    Args:
        n_items: how many items the epoch draws from (indices 0..n_items-1).
        batch_size: the global batch size (summed over ranks), >= world_size.
        rng: the epoch's generator, identical on every rank (same permutation everywhere).
        rank, world_size: this process and the number of processes.
        shuffle: permute the items first (else take them in order).

    Returns:
        A list of int64 arrays, one per step, each this rank's share of a global batch
        (``np.array_split`` of it into ``world_size`` parts). Every rank gets the same number of
        steps. The last incomplete global batch is dropped, unless the whole epoch is smaller than
        one global batch (then that is the one batch).
    """
    if batch_size < 1 or world_size < 1 or not 0 <= rank < world_size:
        raise ValueError(f"expected batch_size >= 1 and 0 <= rank < world_size, got batch_size={batch_size}, "
                         f"rank={rank}, world_size={world_size}")
    if n_items < world_size:
        raise ValueError(f"{n_items} items cannot feed {world_size} processes (at least one each)")
    order = rng.permutation(n_items) if shuffle else np.arange(n_items)
    batch_size = min(batch_size, n_items)
    if batch_size < world_size:
        raise ValueError(f"global batch_size {batch_size} is smaller than the {world_size} processes")
    steps = n_items // batch_size
    return [np.array_split(order[i * batch_size:(i + 1) * batch_size], world_size)[rank].astype(np.int64)
            for i in range(steps)]
