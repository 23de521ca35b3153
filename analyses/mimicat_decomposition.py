"""Where `mimicat`'s cct cycle error comes from: the correspondence M (G's or nearest_joint's) and
the pose-transfer transformer H (trained, or switched off so the Eq. 3-4 initialisation is the
answer), beside `nearest_joint` and `text_soft`; then how soft G's M is at inference and how far
Eq. 4's rotation average is from the plain weighted sum of ablation A1 on the same cases.

Variants (each scored by the real evaluator on the dataset's first ``--cases`` cct cases, ARAP on
as in `mimicat`):

- ``init_G``: the initialisation of Eq. 3-4 alone (H's decoder zeroed), M from G;
- ``init_NJ``: the same with M the one-hot Hungarian match of nearest_joint (unit-height rest
  keypoints, Euclidean cost);
- ``H_G``: `mimicat` itself;
- ``H_NJ``: H with nearest_joint's matches as M;
- ``nj_eq3``, ``nj_identity``, ``nj_eq3_identity``: `nearest_joint` with one of its steps
  replaced by the initialisation's: translations by Eq. 3 (the target's own bones by forward
  kinematics, every root shifted by the mean of what the matched keypoints miss of their
  displacements) instead of the source root's displacement and the carried bone translations;
  unmatched target bones at the identity rotation (Eq. 4's empty column) instead of their
  parent's; both.

Run it on a training zoo's cases (the held-out zoo is for the final table):

    python analyses/mimicat_decomposition.py DATA --out RESULTS [--checkpoint DIR] [--cases 100]

RESULTS is a scratch results folder (re-running resumes it). Prints cct cycle PMD x100 (largest
extent) per variant, then the M statistics.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np
import torch

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root


def nearest_joint_matches(source, target) -> torch.Tensor:
    """One-hot (Ks, Kt) M of nearest_joint's Hungarian match (:func:`mimicbench.baselines.nearest_joint.nearest_joint_pairs`)."""
    from mimicbench.baselines.nearest_joint import nearest_joint_pairs

    pairs = nearest_joint_pairs(source, target)
    m = torch.zeros(len(source.keypoints), len(target.keypoints))
    m[pairs[:, 0], pairs[:, 1]] = 1
    return m


def variant(name: str, use_h: bool, matches: str, checkpoint: Path):
    """A `Mimicat` subclass registered as ``name``: H on or off, M from ``G`` or ``NJ``."""
    from mimicbench.baselines.mimicat.method import CITATION, Mimicat
    from mimicbench.benchmark.method import MethodMetadata

    class Variant(Mimicat):
        metadata = MethodMetadata(name=name, version="1", licence="MIT", needs_training=True, citation=CITATION,
                                  description=f"mimicat decomposition: H {'on' if use_h else 'off'}, M from {matches}")

        def __init__(self):
            super().__init__(checkpoint)

        def setup(self, device: str = "cpu") -> None:
            super().setup(device)
            if not use_h:  # a zero decoder returns the initialisation exactly
                last = self._modules["transfer"].decoder[-1]
                with torch.no_grad():
                    last.weight.zero_()
                    last.bias.zero_()

        def _correspondences(self, requests, src, tgt):
            if matches == "G":
                return super()._correspondences(requests, src, tgt)
            return [nearest_joint_matches(r.source, r.target).to(self.device) for r in requests]

    return Variant


def nearest_joint_variant(name: str, eq3_translation: bool, identity_unmatched: bool):
    """`nearest_joint` with its translation or unmatched-bone step replaced by the initialisation's."""
    from mimicbench.baselines.posing import (carried_translations, inherit_unmatched, pose_target, pose_target_local,
                                  size_ratio, source_pose)
    from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
    from mimicbench.geometry.kinematics import forward_kinematics, local_from_global

    class NearestJointVariant(PoseTransferMethod):
        metadata = MethodMetadata(name=name, version="1", licence="MIT", description=f"nearest_joint variant {name}")

        def transfer(self, requests):
            return [self._one(r) for r in requests]

        @staticmethod
        def _one(r):
            q_src, t_src = source_pose(r)
            m = nearest_joint_matches(r.source, r.target).numpy().astype(np.float64)
            src_of, matched = m.argmax(axis=0), m.sum(axis=0) > 0
            q = np.tile([1.0, 0.0, 0.0, 0.0], (len(r.target.parents), 1))
            q[matched] = q_src[src_of[matched]]
            if not identity_unmatched:
                q = inherit_unmatched(q, matched, r.target.parents)
            if eq3_translation:  # as mimicbench.baselines.mimicat.initialisation.initial_pose
                wanted = t_src[src_of[matched]] - r.source.keypoints[src_of[matched]]
                _, at_rest_root = forward_kinematics(local_from_global(q, r.target.parents), r.target.keypoints,
                                                     r.target.parents)
                shift = (wanted * size_ratio(r) - (at_rest_root - r.target.keypoints)[matched]).mean(axis=0)
                return pose_target(r.target, q, shift)
            moved = carried_translations(r, q_src, t_src, np.where(matched, src_of, -1))
            src_root = int(np.flatnonzero(r.source.parents < 0)[0])
            moved[r.target.parents < 0] = (t_src[src_root] - r.source.keypoints[src_root]) * size_ratio(r)
            return pose_target_local(r.target, q, moved)

    return NearestJointVariant


def m_statistics(data: Path, checkpoint: Path, cases) -> str:
    """Softness of G's M at the checkpoint's temperature and Eq. 4 against the naive average (A1)."""
    from mimicbench.baselines.mimicat.initialisation import quaternion_average
    from mimicbench.baselines.mimicat.method import Mimicat
    from mimicbench.baselines.mimicat.transfer import correspondences
    from mimicbench.baselines.posing import source_pose
    from mimicbench.benchmark.protocols.base import EvalData

    method = Mimicat(checkpoint, arap=False)
    method.setup("cpu")
    ev = EvalData.load(data)
    row_max, col_max, angles = [], [], []
    for c in cases:
        s, t = ev.characters[c.source_id], ev.characters[c.target_id]
        request = ev.request(s, ev.posed(s, c.source_transforms), t, c.case_id)
        cs, ct = method._character(request.source), method._character(request.target)
        m = correspondences(method._modules["shape"], method._modules["corr"], [cs], [ct], method._m_cache,
                            method.m_temperature)[0]
        mn = m.numpy()
        row_max.append(mn.max(axis=1).mean())
        col_max.append((mn / mn.sum(axis=0, keepdims=True)).max(axis=0).mean())
        q = torch.as_tensor(source_pose(request)[0])
        cos = (quaternion_average(q, m, "eq4") * quaternion_average(q, m, "naive")).sum(-1).abs().clamp(max=1)
        angles.append(np.degrees(2 * np.arccos(cos.numpy())))
    a = np.concatenate(angles)
    return (f"G's M at temperature {method.m_temperature}: mean row maximum {np.mean(row_max):.3f}, mean column "
            f"maximum (column normalised) {np.mean(col_max):.3f}\n"
            f"Eq. 4 against the naive average (A1), per target bone: mean {a.mean():.3f} deg, median "
            f"{np.median(a):.4f}, 95th percentile {np.percentile(a, 95):.3f}, max {a.max():.2f}; "
            f"{100 * (a > 1).mean():.1f}% of bones differ by more than 1 deg")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", help="dataset folder with cct cases (`mimicbench bench cases`)")
    ap.add_argument("--out", required=True, help="scratch results folder")
    ap.add_argument("--checkpoint", default=None, help="checkpoint folder (default: the bundled one)")
    ap.add_argument("--cases", type=int, default=100, help="first N cct cases scored")
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from mimicbench.baselines.mimicat.method import BUNDLED
    from mimicbench.benchmark.aggregate import aggregate
    from mimicbench.benchmark.evaluator import load_cases, run_benchmark
    from mimicbench.benchmark.registry import register

    if args.cases < 1:
        raise SystemExit(f"--cases: expected >= 1, got {args.cases}")
    data, checkpoint = Path(args.data), Path(args.checkpoint) if args.checkpoint else BUNDLED
    names = []
    for name, use_h, matches in (("init_G", False, "G"), ("init_NJ", False, "NJ"), ("H_G", True, "G"),
                                 ("H_NJ", True, "NJ")):
        register(f"decomp_{name}", variant(f"decomp_{name}", use_h, matches, checkpoint))
        names.append(f"decomp_{name}")
    for name, eq3, identity in (("nj_eq3", True, False), ("nj_identity", False, True),
                                ("nj_eq3_identity", True, True)):
        register(name, nearest_joint_variant(name, eq3, identity))
        names.append(name)
    import mimicbench.benchmark.evaluator as evaluator

    all_cases = load_cases(data, ("cct",))["cct"]
    cases = all_cases[:args.cases]
    evaluator.load_cases = lambda dataset, protocols: {"cct": cases}  # score the first N only
    run_benchmark(data, names + ["nearest_joint", "text_soft"], ("cct",), out=args.out, in_process=True)
    print(f"cct cycle PMD x100 (largest extent) on {len(cases)} of {len(all_cases)} cases of {data}:")
    for e in sorted(aggregate(args.out)["protocols"]["cct"], key=lambda e: e["pmd_extent"]):
        print(f"  {e['method']:16s} {e['pmd_extent']:.3f}  ({e['ok']} ok)")
    print(m_statistics(data, checkpoint, cases))


if __name__ == "__main__":
    main()
