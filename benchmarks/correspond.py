"""Speed of the correspond stage's pair computation (embedding excluded), per method.

20,000 pairs of 80-joint characters through :func:`mimicbench.datagen.correspond.batched.correspondence_batch`
(batched S_cos, scaling-domain Sinkhorn in torch, scipy Hungarian) with the ``text`` method (the
paper's) and with the ``structure`` method (structure features of 80 zoo-like bones: the feature
product, the no-match Hungarian and the Sinkhorn dustbin), against two peers on a subset: a plain
per-pair loop (scipy's Hungarian plus a NumPy log-domain Sinkhorn) and POT's ``ot.sinkhorn`` with
scipy's Hungarian. Embeddings mimic bone names: each character draws its 80 names from a shared
160-word vocabulary of 384-d unit vectors, with a little noise. Structure features are those of
real zoo skeletons (:func:`mimicbench.datagen.correspond.structure.skeleton_features`), cut or tiled to 80.
The last lines are the structure method's speed over the plain per-pair loop's and over the text
method's, in the same run.

Measured (2-core machine shared with other work, 4,096 pairs, two alternating runs of this script
on the code before and after the chain rules of issue 35): the structure method before 616 and
646 pairs/s (0.77x and 0.75x the text method), after 406 and 410 pairs/s (0.48x and 0.55x): the
chain alignments (a compiled DP a limb pair and the trunk, per pair in Python) cost about 1.55x,
within the 2x the issue allows; still about 11-25x the plain per-pair loop.

    python benchmarks/correspond.py [--pairs 20000] [--peer-pairs 400]

``--stage DATASET`` profiles the whole stage instead (cProfile): ``--stage-pairs`` sampled pairs a
split of a copy of DATASET through :func:`mimicbench.datagen.correspond.stage.correspond_dataset`, printing
the CPU milliseconds a pair (encoder loading included), the bytes a pair takes on disk and the
functions that took the most time. On the 975-character zoo (all-pairs blocks of the first
5,000 train pairs, 2-core machine shared with other work) the Sinkhorn sweeps took about 75% of
the time; in place and without redundant masks they take 1.35x less, bit for bit, and on one
torch thread instead of two about 5x less CPU again (the threads mostly waited for each other).
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from mimicbench.datagen.correspond.batched import DEFAULT_TEMPERATURE, correspondence_batch
from mimicbench.datagen.correspond.methods import get_matcher, match_batch
from mimicbench.geometry.sinkhorn import sinkhorn_log


def make_characters(n: int, k: int = 80, vocab: int = 160, d: int = 384, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    words = rng.normal(size=(vocab, d))
    chars = []
    for _ in range(n):
        e = words[rng.choice(vocab, k, replace=False)] + 0.3 * rng.normal(size=(k, d))
        chars.append((e / np.linalg.norm(e, axis=1, keepdims=True)).astype(np.float32))
    return chars


def zoo_features(n: int, k: int = 80) -> list[np.ndarray]:
    """(k, F) structure features of ``n`` zoo skeletons (every category), rows tiled or cut to k."""
    from mimicbench.datagen.correspond.canonical import canonicalize_names
    from mimicbench.datagen.correspond.structure import skeleton_features
    from mimicbench.datagen.zoo.build import build_skeleton, naming_style
    from mimicbench.datagen.zoo.naming import bone_names
    from mimicbench.datagen.zoo.plan import plan_zoo
    from mimicbench.schemas.character import HUMANOID_LIKE

    out = []
    for spec in plan_zoo(n, seed=0):
        skel, _ = build_skeleton(spec)
        names = bone_names(skel.roles, naming_style(spec), humanoid=spec.category in HUMANOID_LIKE)
        f = skeleton_features(canonicalize_names(names), skel.parents, skel.heads).matrix()
        out.append(np.resize(f, (k, f.shape[1])))
    return out


def profile_stage(dataset: str, pairs: int) -> None:
    """cProfile of the correspond stage on a copy of ``dataset`` (``pairs`` sampled pairs a split)."""
    import cProfile
    import pstats
    import shutil
    import tempfile
    from pathlib import Path

    from mimicbench.datagen.correspond.stage import correspond_dataset

    with tempfile.TemporaryDirectory(prefix="correspond-profile-") as tmp:
        copy = Path(tmp) / "data"
        shutil.copytree(dataset, copy, ignore=shutil.ignore_patterns("pairs"))
        cpu = time.process_time()
        profile = cProfile.Profile()
        summary = profile.runcall(correspond_dataset, copy, pairs=pairs, progress=False)
        cpu = time.process_time() - cpu
        n = sum(summary["pairs"].values())
        size = sum(p.stat().st_size for p in (copy / "pairs").glob("*.parquet"))
    print(f"{n:,} pairs: {cpu / n * 1e3:.2f} ms CPU a pair (encoder loading included), {size / n / 1e3:.1f} kB a pair "
          f"on disk")
    pstats.Stats(profile).sort_stats("tottime").print_stats(15)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=20000)
    ap.add_argument("--peer-pairs", type=int, default=400)
    ap.add_argument("--batch", type=int, default=2048)
    ap.add_argument("--stage", default=None, metavar="DATASET", help="profile the stage on a copy of DATASET")
    ap.add_argument("--stage-pairs", type=int, default=3000, help="with --stage: sampled pairs a split")
    args = ap.parse_args()
    if args.stage:
        profile_stage(args.stage, args.stage_pairs)
        return
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

    feats = zoo_features(len(chars))
    fa = [feats[i] for i in idx[:, 0]]
    fb = [feats[j] for j in idx[:, 1]]
    method = get_matcher("structure")
    start = time.perf_counter()
    for i in range(0, args.pairs, args.batch):
        match_batch(method, a[i:i + args.batch], b[i:i + args.batch], fa[i:i + args.batch], fb[i:i + args.batch])
    structure = args.pairs / (time.perf_counter() - start)

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

    print(f"pairs/s: batched text {ours:,.0f}, batched structure {structure:,.0f} ({args.pairs} pairs); "
          f"plain loop {loop:,.0f}; POT ot.sinkhorn {pot:,.0f} ({n} pairs each)")
    print(f"projected time for 384,000 pairs: batched text {384000 / ours / 60:.1f} min, structure "
          f"{384000 / structure / 60:.1f} min, plain loop {384000 / loop / 60:.1f} min, POT {384000 / pot / 60:.1f} min")
    print(f"ratio batched text / plain loop: {ours / loop:.1f}x; batched text / POT: {ours / pot:.1f}x")
    print(f"ratio batched structure / plain loop (same run): {structure / loop:.1f}x")
    print(f"ratio structure / text (same run): {structure / ours:.2f}x")


if __name__ == "__main__":
    main()
