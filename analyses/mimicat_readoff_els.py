"""Whether the pose read-off of bones that own no vertices is what lowers `mimicat`'s ELS on real rigs.

Every method reads the source's pose off its posed vertices (:func:`mimicbench.baselines.posing.source_pose`,
weighted Kabsch per bone); a bone that owns no vertices (total skin weight 0: a rig's ``root`` or
``Body`` on some artist rigs, pole targets, MMD's helper bones) cannot be read off the mesh (until
version 6 it took its parent's rotation; since, the rotation its children agree on, where they
do). This script scores ``mimicat_init_only`` and ``text_soft`` on the h2h and cct
cases of DATA twice: as they are, and with the forward leg's read-off of those bones replaced by
the case's ground-truth source pose (the return leg, whose source is the forward prediction, has
no ground truth and stays as it is). A case whose source owns every bone counts the same in both.
Prints per case and per protocol mean ELS, lowest ELS and mean PMD (headline normalisation).

    python analyses/mimicat_readoff_els.py DATA

DATA: an ingested, resampled dataset with correspondences and cases (e.g. the shared assets
through ``mimicbench pipeline``).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path, help="dataset with h2h and cct cases")
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    import mimicbench.baselines.posing as posing
    import mimicbench.baselines.text_soft as text_soft
    from mimicbench.baselines.mimicat.method import MimicatInitOnly
    from mimicbench.benchmark.evaluator import load_cases
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.benchmark.scoring import score_pose
    from mimicbench.geometry.transform_estimation import estimate_transforms

    ev = EvalData.load(args.data)
    cases = load_cases(args.data, ("h2h", "cct"))
    read_off, truth = posing.source_pose, {}

    def with_truth(request):
        """The read-off, its bones that own no vertices from ``truth['pose']`` (K, 7) when set."""
        q, t = read_off(request)
        gt = truth.get("pose")
        if gt is not None and len(gt) == len(q):
            s = request.source
            _, owned = estimate_transforms(s.vertices, request.source_posed, s.weights, s.keypoints)
            q, t = q.copy(), t.copy()
            q[~owned], t[~owned] = gt[~owned, :4], gt[~owned, 4:]
        return q, t

    posing.source_pose = with_truth  # mimicat imports it at call time
    text_soft.source_pose = with_truth
    init_only = MimicatInitOnly()
    init_only.setup("cpu")
    methods = {"mimicat_init_only": init_only, "text_soft": text_soft.TextSoft()}
    for proto in ("h2h", "cct"):
        res: dict = {}
        for c in cases[proto]:
            s, t = ev.characters[c.source_id], ev.characters[c.target_id]
            posed = ev.posed(s, c.source_transforms)
            _, owned = estimate_transforms(s.rig.vertices, posed, s.rig.weights, s.rig.keypoints)
            row = []
            for name, m in methods.items():
                for use_truth in (False, True):
                    key = (name, use_truth)
                    if use_truth and owned.all():  # nothing to replace: the same answer
                        res.setdefault(key, []).append(res[(name, False)][-1])
                        continue
                    truth["pose"] = np.asarray(c.source_transforms, np.float64) if use_truth else None
                    pred = m.transfer([ev.request(s, posed, t, c.case_id)])[0]
                    truth["pose"] = None
                    if proto == "h2h":
                        sc = score_pose(pred, ev.posed(t, c.target_transforms), ev.frame(t), "height")
                    else:
                        ret = m.transfer([ev.request(t, pred, s, c.case_id)])[0]
                        sc = score_pose(ret, posed, ev.frame(s), "extent")
                    res.setdefault(key, []).append((sc["els"], sc["pmd"]))
                    row.append(f"{name}{' (truth)' if use_truth else ''} {sc['els']:.3f}/{sc['pmd']:.2f}")
            print(f"{c.case_id}: {int((~owned).sum())} source bones own no vertices; ELS/PMD " + ", ".join(row),
                  flush=True)
        for (name, use_truth), v in res.items():
            a = np.asarray(v)
            print(f"{proto} {name:<18} read-off {'with truth' if use_truth else 'as is   '}: mean ELS {a[:, 0].mean():.4f},"
                  f" lowest {a[:, 0].min():.3f}, PMD {a[:, 1].mean():.3f} ({len(a)} cases)")


if __name__ == "__main__":
    main()
