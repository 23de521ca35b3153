"""Fit MimiCAT's range model, and compare variants of the method on a dataset's cct cases.

``fit TRAIN --out FILE``: the nearest-neighbour range model
(:mod:`mimicbench.baselines.mimicat.range_model`) of every character of TRAIN that has clips.

``check DATA --range FILE``: for the first ``--cases`` cct cases of DATA, each variant's forward
``out_of_range`` share, forward ELS and cycle PMD x100 (extent), as the cct protocol scores them,
with the paired difference to the first variant and its standard error clustered by (source,
target) pair. ``--loo`` leaves the target's own character out of the range model's neighbours
(for DATA = the zoo the model was fitted on). Variants: ``init`` (``mimicat_init_only`` without
ARAP), ``init_arap`` (with ARAP), ``range`` (the initialisation projected into the predicted
ranges), ``mimicat`` (H and the projection), ``mimicat_arap``, ``no_prior`` (H trained without
L_reg, no projection), ``nearest_joint``; ``--k`` and ``--slack`` override the model's settings.

    python analyses/mimicat_range.py fit data/train_zoo5k --out baselines/mimicat/checkpoints/range.safetensors
    python analyses/mimicat_range.py check data/train_zoo5k --range baselines/mimicat/checkpoints/range.safetensors \\
        --loo --cases 60 --variants init,range,mimicat,init_arap
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def fit(args) -> None:
    from mimicbench.baselines.mimicat.range_model import RangeModel
    from mimicbench.benchmark.motion_range import ranges_for_dataset
    from mimicbench.benchmark.rigs import load_characters
    from mimicbench.schemas.dataset import Dataset

    ds = Dataset.of(args.train)
    chars = load_characters(ds)
    rigs = {cid: c.rig for cid, c in chars.items()}
    ranges = ranges_for_dataset(ds, chars)
    source = {"dataset": Path(args.train).name, "characters": len(ranges),
              "bones": int(sum(r.scored.sum() for r in ranges.values()))}
    model = RangeModel.fit(rigs, ranges, k=args.k, slack_deg=args.slack, parts=args.parts, keep=args.keep,
                           scope=args.scope, max_deg=args.max_deg, source=source)
    model.save(args.out)
    print(f"range model: {len(model.features)} bones of {len(ranges)} characters, k={model.k}, "
          f"slack {model.slack_deg} deg -> {args.out}")


def _variant(name: str, range_file, loo: bool, k, slack, parts=None, keep=None, scope=None,
             max_deg=None):
    from mimicbench.baselines.mimicat.method import Mimicat, MimicatInitOnly, MimicatNoPrior
    from mimicbench.baselines.mimicat.range_model import RangeModel
    from mimicbench.baselines.nearest_joint import NearestJoint

    if name == "nearest_joint":
        return NearestJoint()
    cls, arap, use_range = {"init": (MimicatInitOnly, False, False), "init_arap": (MimicatInitOnly, True, False),
                            "range": (MimicatInitOnly, False, True), "mimicat": (Mimicat, False, True),
                            "mimicat_arap": (Mimicat, True, True), "no_prior": (MimicatNoPrior, False, False)}[name]
    m = cls(arap=arap)
    m.use_range = False
    m.interpolate = use_range or name == "no_prior"
    m.setup("cpu")
    if use_range:
        m._range = RangeModel.load(range_file)
        m._range.k = int(k) if k is not None else m._range.k
        m._range.slack_deg = float(slack) if slack is not None else m._range.slack_deg
        m._range.parts = parts or m._range.parts
        m._range.keep = keep or m._range.keep
        m._range.scope = scope or m._range.scope
        m._range.max_deg = max_deg if max_deg is not None else m._range.max_deg
        m.range_exclude_self = loo
    return m


def _use_clip_ranges(methods, ev) -> None:
    """Hand the methods each character's ranges from its own clips instead of the predicted ones
    (the oracle: the bound a perfect range model reaches)."""
    from mimicbench.baselines.mimicat.range_model import PredictedRanges
    from mimicbench.benchmark.motion_range import _twist_arc, ranges_for_dataset

    ranges = ranges_for_dataset(ev.dataset, ev.characters)
    for m in methods:
        for cid, r in ranges.items():
            rig = ev.characters[cid].rig
            m._predicted[(cid, len(rig.vertices), len(rig.parents))] = PredictedRanges(
                r, r.hulls, np.array([_twist_arc(r.twist[k]) for k in range(len(r.hulls))]))


def check(args) -> None:
    import torch

    from mimicbench.benchmark.evaluator import load_cases
    from mimicbench.benchmark.intervals import pair_clustered_se, pair_of
    from mimicbench.benchmark.metrics import els
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.benchmark.scoring import score_pose

    torch.set_num_threads(1)
    ev = EvalData.load(args.data)
    cases = load_cases(args.data, ("cct",))["cct"][: args.cases]
    names = args.variants.split(",")
    methods = {n: _variant(n, args.range, args.loo, args.k, args.slack, args.parts, args.keep, args.scope,
                            args.max_deg)
               for n in names}
    if args.oracle:
        _use_clip_ranges([m for m in methods.values() if getattr(m, "_range", None) is not None], ev)
    cols = ("cycle", "out_of_range", "els_forward")
    res = {n: {c: [] for c in cols} for n in names}
    t0 = time.time()
    for c in cases:
        src, tgt = ev.characters[c.source_id], ev.characters[c.target_id]
        posed = ev.posed(src, c.source_transforms)
        for n, m in methods.items():
            pred = m.transfer([ev.request(src, posed, tgt, c.case_id)])[0]
            back = m.transfer([ev.request(tgt, pred, src, c.case_id)])[0]
            res[n]["cycle"].append(score_pose(back, posed, ev.frame(src), "extent")["pmd_extent"])
            oor = ev.out_of_range(tgt, pred)
            res[n]["out_of_range"].append(np.nan if oor is None else oor)
            res[n]["els_forward"].append(els(pred, tgt.rig.vertices, ev.frame(tgt).edges))
    pairs = [pair_of(c.case_id) for c in cases]
    print(f"{args.data}: {len(cases)} cct cases, {len(set(pairs))} pairs, loo={args.loo}, k={args.k}, "
          f"slack={args.slack}, parts={args.parts}, keep={args.keep}, scope={args.scope}, max_deg={args.max_deg}, {time.time() - t0:.0f} s")
    base = names[0]
    for col in cols:
        print(f"\n{col} (mean +- pair SE; difference to {base} +- pair SE, relative)")
        b = np.asarray(res[base][col], float)
        for n in names:
            v = np.asarray(res[n][col], float)
            ok = np.isfinite(v) & np.isfinite(b)
            d = v[ok] - b[ok]
            p = [pairs[i] for i in np.flatnonzero(ok)]
            rel = d.mean() / b[ok].mean() if b[ok].mean() else float("nan")
            print(f"  {n:14s} {v[ok].mean():.4f} +- {pair_clustered_se(v[ok], p):.4f}   "
                  f"{d.mean():+.4f} +- {pair_clustered_se(d, p):.4f} ({rel:+.1%})")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    f = sub.add_parser("fit", help="fit the range model on a training zoo")
    f.add_argument("train")
    f.add_argument("--out", required=True)
    f.add_argument("--k", type=int, default=3)
    f.add_argument("--slack", type=float, default=5.0)
    f.add_argument("--parts", choices=("both", "swing", "twist"), default="both")
    f.add_argument("--keep", choices=("local", "world"), default="local")
    f.add_argument("--scope", choices=("all", "free", "both"), default="all")
    f.add_argument("--max-deg", type=float, default=180.0)
    c = sub.add_parser("check", help="compare variants on a dataset's cct cases")
    c.add_argument("data")
    c.add_argument("--range", required=True)
    c.add_argument("--cases", type=int, default=60)
    c.add_argument("--variants", default="init,range,mimicat")
    c.add_argument("--loo", action="store_true")
    c.add_argument("--k", type=int)
    c.add_argument("--slack", type=float)
    c.add_argument("--parts", choices=("both", "swing", "twist"))
    c.add_argument("--keep", choices=("local", "world"))
    c.add_argument("--scope", choices=("all", "free", "both"))
    c.add_argument("--max-deg", type=float)
    c.add_argument("--oracle", action="store_true", help="use each target's own clip ranges (the bound)")
    args = ap.parse_args(argv)
    fit(args) if args.command == "fit" else check(args)


if __name__ == "__main__":
    main()
