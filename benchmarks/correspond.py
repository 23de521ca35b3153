"""Speed of the correspond stage's pair computation (embedding excluded).

20,000 pairs of 80-joint characters through :func:`datagen.correspond.batched.correspondence_batch`
(batched S_cos, scaling-domain Sinkhorn in torch, scipy Hungarian), against two peers on a subset:
a plain per-pair loop (scipy's Hungarian plus a NumPy log-domain Sinkhorn) and POT's
``ot.sinkhorn`` with scipy's Hungarian. Embeddings mimic bone names: each character draws its 80
names from a shared 160-word vocabulary of 384-d unit vectors, with a little noise.

    python benchmarks/correspond.py [--pairs 20000] [--peer-pairs 400]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from datagen.correspond.batched import DEFAULT_TEMPERATURE, correspondence_batch
from mimicbench.sinkhorn import sinkhorn_log


def make_characters(n: int, k: int = 80, vocab: int = 160, d: int = 384, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    words = rng.normal(size=(vocab, d))
    chars = []
    for _ in range(n):
        e = words[rng.choice(vocab, k, replace=False)] + 0.3 * rng.normal(size=(k, d))
        chars.append((e / np.linalg.norm(e, axis=1, keepdims=True)).astype(np.float32))
    return chars


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=20000)
    ap.add_argument("--peer-pairs", type=int, default=400)
    ap.add_argument("--batch", type=int, default=2048)
    args = ap.parse_args()
    chars = make_characters(200)
    rng = np.random.default_rng(1)
    idx = rng.integers(0, len(chars), size=(args.pairs, 2))
    a = [chars[i] for i in idx[:, 0]]
    b = [chars[j] for j in idx[:, 1]]
    t = DEFAULT_TEMPERATURE

    start = time.perf_counter()
    for i in range(0, args.pairs, args.batch):
        correspondence_batch(a[i:i + args.batch], b[i:i + args.batch], t)
    ours = args.pairs / (time.perf_counter() - start)

    n = args.peer_pairs
    start = time.perf_counter()
    for ea, eb in zip(a[:n], b[:n]):
        s = ea.astype(np.float64) @ eb.T.astype(np.float64)
        linear_sum_assignment(s, maximize=True)
        sinkhorn_log(s, t, tol=1e-6, num_iters=2000)
    loop = n / (time.perf_counter() - start)

    import ot

    start = time.perf_counter()
    for ea, eb in zip(a[:n], b[:n]):
        s = ea.astype(np.float64) @ eb.T.astype(np.float64)
        linear_sum_assignment(s, maximize=True)
        k1, k2 = s.shape
        ot.sinkhorn(np.ones(k1), np.full(k2, k1 / k2), -s, reg=t, numItermax=2000, stopThr=1e-6)
    pot = n / (time.perf_counter() - start)

    print(f"pairs/s: batched {ours:,.0f} ({args.pairs} pairs); plain loop {loop:,.0f}; POT ot.sinkhorn {pot:,.0f}"
          f" ({n} pairs each)")
    print(f"projected time for 384,000 pairs: batched {384000 / ours / 60:.1f} min, plain loop "
          f"{384000 / loop / 60:.1f} min, POT {384000 / pot / 60:.1f} min")
    print(f"ratio batched / plain loop: {ours / loop:.1f}x; batched / POT: {ours / pot:.1f}x")


if __name__ == "__main__":
    main()
