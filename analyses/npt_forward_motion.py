"""Does an ``npt``/``cgt`` checkpoint carry the pose across categories, or hide it for the way back?

The ``cct`` protocol scores the cycle A -> B -> A. A model can lower that score without posing B:
its forward answer B' stays near B's rest mesh and the return leg reads A's pose back from small
offsets. This script measures, on random cross-category pairs of a dataset (a humanoid-like
character on exactly one side, :func:`mimicbench.baselines.npt.cycle.cross_category_pairs`), in the centred
unit-size frames of :mod:`mimicbench.baselines.npt.placement` (distances are fractions of the mesh's size):

- ``forward motion``: mean distance of B' from B's rest mesh, against ``source motion``, the mean
  distance of A posed from A's rest mesh; their per-pair ratio (median) is near 0 for a model that
  leaves B at rest (``identity``: 0) and of the order of 1 for one that moves B as much as A moved;
- ``self``: the error x100 of a self-transfer (A posed onto A's own rest mesh), one leg's accuracy
  on characters the model never saw;
- ``null cycle``: the cycle error x100 when A is at rest (what the two legs add with no pose to carry).

    python analyses/npt_forward_motion.py DATA [--pairs 40] [--seed 5] \
        [--model npt=RUN] [--model cgt=RUN] ...   (RUN: a training run folder; no --model: the shipped npt and cgt)
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root

import numpy as np
import torch


def measure(method, items) -> dict:
    """``{"forward", "source", "ratio", "self", "null"}`` of ``method`` (an Npt or Cgt, set up) over
    ``items``: (A rest, A posed, B rest) float32 arrays."""
    from mimicbench.baselines.npt.cycle import box_centred
    from mimicbench.baselines.npt.placement import centred

    def answer(posed, rest, identity):
        pose = torch.as_tensor(centred(posed, rest)[method.pose_rows(len(posed))])[None]
        with torch.no_grad():
            return method._answer(pose, torch.as_tensor(centred(identity, identity))[None])

    rows = []
    for a_rest, a_posed, b_rest in items:
        forward = answer(a_posed, a_rest, b_rest)[0].numpy()
        moved = np.linalg.norm(forward - centred(b_rest, b_rest), axis=1).mean()
        source = np.linalg.norm(centred(a_posed, a_rest) - centred(a_rest, a_rest), axis=1).mean()
        own = answer(a_posed, a_rest, a_rest)[0].numpy()
        at_rest = answer(a_rest, a_rest, b_rest)
        pose = box_centred(at_rest)[:, method.pose_rows(at_rest.shape[1])]
        with torch.no_grad():
            back = method._answer(pose, torch.as_tensor(centred(a_rest, a_rest))[None])[0].numpy()
        rows.append((moved, source, moved / source, 100 * np.linalg.norm(own - centred(a_posed, a_rest), axis=1).mean(),
                     100 * np.linalg.norm(back - centred(a_rest, a_rest), axis=1).mean()))
    r = np.array(rows)
    return {"forward": r[:, 0].mean(), "source": r[:, 1].mean(), "ratio": float(np.median(r[:, 2])),
            "self": r[:, 3].mean(), "self_median": float(np.median(r[:, 3])), "null": r[:, 4].mean()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path)
    ap.add_argument("--pairs", type=int, default=40)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--model", action="append", default=[], metavar="NAME=RUN",
                    help="npt=RUN or cgt=RUN, or npt or cgt alone for the shipped weights (repeatable; default: both shipped)")
    args = ap.parse_args()
    from mimicbench.baselines.cgt.method import Cgt
    from mimicbench.baselines.npt.cycle import cross_category_pairs
    from mimicbench.baselines.npt.method import Npt
    from mimicbench.baselines.pose_pairs import PosePool

    torch.set_num_threads(1)
    pool = PosePool.load(args.data, "all")
    pairs = cross_category_pairs(pool)
    rng = np.random.default_rng(args.seed)
    items = []
    for i in rng.integers(0, len(pairs), args.pairs):
        a, b = pairs[int(i)]
        a_rest = np.asarray(pool.records[a].vertices, np.float32)
        items.append((a_rest, pool.posed(a, pool.draw_pose(a, rng)), np.asarray(pool.records[b].vertices, np.float32)))
    models = [(m.split("=", 1) + [None])[:2] for m in args.model] or [["npt", None], ["cgt", None]]
    classes = {"npt": Npt, "cgt": Cgt}
    print(f"{len(items)} cross-category pairs of {args.data}; distances are fractions of the mesh's size")
    print(f"{'model':40s} forward  source  ratio  self x100 (median)  null cycle x100")
    for name, run in models:
        method = classes[name](checkpoint=run)
        method.setup("cpu")
        r = measure(method, items)
        label = f"{name} {run or 'shipped v' + method.metadata.version}"
        print(f"{label:40s} {r['forward']:.4f}  {r['source']:.4f}  {r['ratio']:.3f}  {r['self']:.2f} ({r['self_median']:.2f})"
              f"         {r['null']:.2f}")


if __name__ == "__main__":
    main()
