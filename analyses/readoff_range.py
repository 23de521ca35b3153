"""The range-of-motion score (:mod:`mimicbench.benchmark.motion_range`) on a dataset, and a method's cycle
before and after a read-off change.

``range DATA``: (1) each clip of each character against the ranges of its *other* clips, the share
of scored bones beyond 0, 5, 10 and 20 degrees (how far a pose the character really takes can
lie outside what a few clips reach); (2) the character's own clip frames with a random
15-degree rotation added to every bone's local rotation, against the clean frames (the corruption
the score must detect), with standard errors clustered by character; (3) ``out_of_range`` of the
forward predictions of ``nearest_joint``, ``text_soft`` and ``identity`` (the target at rest) on
the dataset's cct cases, with paired differences against ``nearest_joint`` and standard errors
clustered by (source, target) pair.

``cycle BEFORE AFTER``: two result folders of one method and protocol (``RESULTS/<method>/<version>``
of `mimicbench bench run`), the paired difference per metric over their common cases with its
pair-clustered standard error.

``changed DATA --methods a,b``: for each method, the largest vertex change (% of the target's
height) between its outputs with the joint-fit read-off and with per-bone Kabsch in its place, on
a few cct cases: whether a method's version must go up with the read-off.

    python analyses/readoff_range.py range DATA [--cases 150]
    python analyses/readoff_range.py cycle BEFORE AFTER [--metrics pmd_extent,pmd_height,els,els_forward]
    python analyses/readoff_range.py changed DATA --methods name_copy,nearest_joint,text_soft,mimicat
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root


def range_report(data: Path, n_cases: int) -> None:
    from mimicbench.baselines.identity import Identity
    from mimicbench.baselines.nearest_joint import NearestJoint
    from mimicbench.baselines.text_soft import TextSoft
    from mimicbench.benchmark.intervals import pair_clustered_se, pair_of
    from mimicbench.benchmark.motion_range import MARGIN_DEG, out_of_range_bones, ranges_for_clips, ranges_for_dataset
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.geometry.kinematics import forward_kinematics, local_from_global, transforms_to_array
    from mimicbench.geometry.quaternion import quat_from_axis_angle, quat_multiply
    from mimicbench.schemas.dataset import Dataset

    ev = EvalData.load(data)
    start = time.time()
    ranges = ranges_for_dataset(data, ev.characters)
    print(f"ranges of {len(ranges)} characters in {time.time() - start:.1f} s")
    table = Dataset.of(data).read_table("motions", columns=["character_id", "name", "num_frames", "num_joints",
                                                           "transforms"]).to_pylist()
    clips: dict[str, list] = {}
    for m in table:
        if not m["name"].endswith("@sim"):
            clips.setdefault(m["character_id"], []).append(
                np.asarray(m["transforms"], np.float32).reshape(m["num_frames"], m["num_joints"], 7))

    margins = (0, 5, 10, 20)
    held: dict[int, list] = {m: [] for m in margins}
    held_who, clean, noisy, who = [], [], [], []
    rng = np.random.default_rng(0)
    for cid, cl in sorted(clips.items()):
        if cid not in ev.characters:
            continue
        char = ev.characters[cid]
        rig = char.rig
        for i, clip in enumerate(cl):
            others = [o for j, o in enumerate(cl) if j != i]
            if not others:
                continue
            out = ranges_for_clips(cid, rig, others)
            excess = out.excess_degrees(clip[1::5, :, :4].astype(np.float64))[:, out.scored]
            for m in margins:
                held[m].append(float((excess > m).mean()))
            held_who.append(cid)
        for frame in cl[0][1::9]:
            local = local_from_global(frame[:, :4].astype(np.float64), rig.parents)
            local = quat_multiply(local, quat_from_axis_angle(rng.normal(size=(len(local), 3)), np.radians(15.0)))
            g, p = forward_kinematics(local, rig.keypoints, rig.parents, frame[:, 4:].astype(np.float64))
            for verts, into in ((ev.posed(char, frame), clean), (ev.posed(char, transforms_to_array(g, p)), noisy)):
                beyond, scored = out_of_range_bones(verts, rig, ranges[cid])
                into.append(beyond.sum() / scored.sum())
            who.append(cid)
    print("(1) held-out clips against the ranges of the character's other clips: share of scored bones beyond")
    for m in margins:
        v = np.array(held[m])
        print(f"    {m:2d} degrees: {v.mean():.3f} (SE by character {pair_clustered_se(v, held_who):.3f}, {len(v)} clips)")
    d = np.array(noisy) - np.array(clean)
    print(f"(2) own clip frames: clean {np.mean(clean):.3f}, 15-degree rotation noise {np.mean(noisy):.3f}: "
          f"{d.mean():+.3f} (SE by character {pair_clustered_se(d, who):.3f}, {len(d)} frames)")

    cases = [c for c in Dataset.of(data).records("cases") if c.protocol == "cct" and c.target_id in ranges]
    cases = cases[::max(1, len(cases) // n_cases)][:n_cases]
    methods = {"nearest_joint": NearestJoint(), "text_soft": TextSoft(), "identity": Identity()}
    share: dict[str, list] = {m: [] for m in methods}
    start = time.time()
    for c in cases:
        s, t = ev.characters[c.source_id], ev.characters[c.target_id]
        request = ev.request(s, ev.posed(s, c.source_transforms), t, c.case_id)
        for name, method in methods.items():
            beyond, scored = out_of_range_bones(method.transfer([request])[0], t.rig, ranges[c.target_id])
            share[name].append(beyond.sum() / scored.sum())
    pairs = [pair_of(c.case_id) for c in cases]
    print(f"(3) cct forward out_of_range (margin {MARGIN_DEG:g} degrees), {len(cases)} cases, {len(set(pairs))} pairs, "
          f"{time.time() - start:.0f} s")
    for name in methods:
        v = np.array(share[name])
        d = v - np.array(share["nearest_joint"])
        print(f"    {name:14s} {v.mean():.3f} (pair SE {pair_clustered_se(v, pairs):.3f}); minus nearest_joint "
              f"{d.mean():+.3f} (pair SE {pair_clustered_se(d, pairs):.3f})")


def cycle_report(before: Path, after: Path, metrics: list[str]) -> None:
    import pandas as pd

    from mimicbench.benchmark.intervals import pair_clustered_se, pair_of

    def load(folder):
        return pd.concat([pd.read_parquet(f) for f in sorted(Path(folder).glob("*.parquet"))])

    a, b = load(before), load(after)
    m = a.merge(b, on="case_id", suffixes=("_before", "_after"))
    m = m[(m["status_before"] == "ok") & (m["status_after"] == "ok")]
    pairs = [pair_of(c) for c in m["case_id"]]
    print(f"{len(m)} common ok cases, {len(set(pairs))} pairs")
    for col in metrics:
        x, y = m[f"{col}_before"].to_numpy(float), m[f"{col}_after"].to_numpy(float)
        d = y - x
        print(f"  {col:12s} before {x.mean():.3f}  after {y.mean():.3f}  difference {d.mean():+.3f} "
              f"(pair SE {pair_clustered_se(d, pairs):.3f}, {y.mean() / x.mean() - 1:+.1%}; lower on {np.mean(d < 0):.0%} of cases)")


def changed_report(data: Path, methods: list[str], n_cases: int = 4) -> None:
    import mimicbench.geometry.pose_readoff as readoff
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.benchmark.registry import get_method
    from mimicbench.geometry.kabsch import kabsch_transforms
    from mimicbench.schemas.dataset import Dataset

    ev = EvalData.load(data)
    cases = [c for c in Dataset.of(data).records("cases") if c.protocol == "cct"]
    cases = cases[::max(1, len(cases) // n_cases)][:n_cases]
    joint = readoff.estimate_transforms
    kabsch = lambda rest, posed, weights, keypoints, **_: kabsch_transforms(rest, posed, weights, keypoints)  # noqa: E731
    for name in methods:
        method = get_method(name)
        method.setup("cpu")
        largest = 0.0
        for c in cases:
            s, t = ev.characters[c.source_id], ev.characters[c.target_id]
            outputs = []
            for fit in (joint, kabsch):
                readoff.estimate_transforms = fit
                try:
                    outputs.append(method.transfer([ev.request(s, ev.posed(s, c.source_transforms), t, c.case_id)])[0])
                finally:
                    readoff.estimate_transforms = joint
            largest = max(largest, float(np.abs(outputs[0] - outputs[1]).max() / t.rig.height * 100))
        print(f"{name:20s} v{method.metadata.version}: largest vertex change {largest:.3f} % of height "
              f"over {len(cases)} cct cases", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    r = sub.add_parser("range")
    r.add_argument("data", type=Path)
    r.add_argument("--cases", type=int, default=150)
    c = sub.add_parser("cycle")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    c.add_argument("--metrics", default="pmd_extent,pmd_height,els,els_forward")
    k = sub.add_parser("changed")
    k.add_argument("data", type=Path)
    k.add_argument("--methods", required=True)
    args = ap.parse_args()
    if args.what == "range":
        range_report(args.data, args.cases)
    elif args.what == "cycle":
        cycle_report(args.before, args.after, args.metrics.split(","))
    else:
        changed_report(args.data, args.methods.split(","))


if __name__ == "__main__":
    main()
