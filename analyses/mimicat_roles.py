"""G's role-class accuracy against the zoo's hidden roles, and ablation A3 (G trained on heuristic
correspondences).

``accuracy``: for every (source, target) pair of DATA's cct cases (``bench cases``), each matcher
gives each target bone one source bone or none; a target bone counts where its hidden role class
(:func:`mimicbench.benchmark.semantic.character_role_classes`: arm ~ front leg ~ wing ~ pectoral fin, sides
kept) is also a class of the source, and it is right when its source bone has that class (no
match is wrong). Matchers: each G given as ``--checkpoints NAME=FOLDER``, twice: ``NAME``, G's M
at the transfer checkpoint's temperature decoded as the method reads it (``hungarian_sym`` in the
presets: exactly the matches of ``mimicat``'s initialisation, one to one), and ``NAME argmax``,
each target bone's most likely source bone in G's soft M (what G itself says; several target
bones may share a source bone); and ``nearest_joint`` (Hungarian on unit-height rest keypoints). Prints each matcher's accuracy over the bones with its standard error clustered by
(source, target) pair, and each matcher's paired difference to the first.

``train-a3``: ablation A3, G trained as the shipped one (``small`` preset, the shipped stage's
overrides, same seed) but against heuristic correspondences instead of the dataset's text-guided
``pairs/`` table: for every pair of that table, the ``nearest_joint`` match (Hungarian on
unit-height rest keypoints) as both M_sink (one-hot rows; an unmatched source bone has an empty
row) and M_hung. The run folder must hold ``shape/model.safetensors`` (the frozen E, e.g. the
shipped one with its ``.sha256``); G lands in ``OUT/corr/model.safetensors``. Copy the shipped
``transfer.safetensors`` beside it for ``accuracy`` (its config gives the temperature and decoding).

    python analyses/mimicat_roles.py train-a3 TRAIN_DATA --out RUN [--epochs 10]
    python analyses/mimicat_roles.py accuracy DATA --checkpoints shipped=baselines/mimicat/checkpoints,a3=RUN
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root


def role_accuracy(match: np.ndarray, source_classes: list, target_classes: list) -> tuple[np.ndarray, np.ndarray]:
    """Per scored target bone, whether its match has its class.

    Args:
        match: (Kt,) int, each target bone's source bone or -1.
        source_classes, target_classes: role classes (None for an unlabelled bone).

    Returns:
        (indices of the scored target bones (B,), right (B,) bool): a bone is scored when its class
        is not None and is a class of some source bone.
    """
    present = {c for c in source_classes if c is not None}
    scored = np.array([j for j, c in enumerate(target_classes) if c is not None and c in present], int)
    right = np.array([match[j] >= 0 and source_classes[match[j]] == target_classes[j] for j in scored], bool)
    return scored, right


def match_from_pairs(pairs: np.ndarray, kt: int) -> np.ndarray:
    """(Kt,) each target bone's source bone (-1 for none) from (P, 2) (source, target) pairs."""
    out = np.full(kt, -1)
    out[np.asarray(pairs, int)[:, 1]] = np.asarray(pairs, int)[:, 0]
    return out


def match_from_m(m: np.ndarray) -> np.ndarray:
    """(Kt,) each target bone's source bone from a 0/1 (Ks, Kt) assignment (-1 for an empty column)."""
    m = np.asarray(m)
    return np.where(m.sum(axis=0) > 0, m.argmax(axis=0), -1)


def heuristic_targets(dataset) -> list:
    """The dataset's ``pairs/`` rows with the ``nearest_joint`` match as target (see the module docstring)."""
    from mimicbench.baselines.mimicat.corr_data import PairTarget, read_pairs
    from mimicbench.baselines.nearest_joint import nearest_joint_pairs
    from mimicbench.benchmark.rigs import load_characters

    chars = load_characters(dataset)
    out = []
    for p in read_pairs(dataset):
        s, t = chars[p.source_id].rig, chars[p.target_id].rig
        pairs = np.asarray(nearest_joint_pairs(s, t), np.int64)
        m = np.zeros((len(s.parents), len(t.parents)), np.float32)
        m[pairs[:, 0], pairs[:, 1]] = 1.0
        out.append(PairTarget(p.source_id, p.target_id, m, pairs))
    return out


def train_a3(args) -> None:
    from mimicbench.baselines.mimicat import transfer_training
    from mimicbench.baselines.mimicat.config import shipped_config
    from mimicbench.training.loop import train_stage_result

    dataset = Path(args.data)
    transfer_training._CACHE[("pairs", str(dataset))] = heuristic_targets(dataset)
    config = shipped_config("corr")
    result = train_stage_result("mimicat", "corr", dataset, args.out, config, "cpu", args.epochs, seed=0,
                                progress=False)
    print(result)


def accuracy(args) -> None:
    from mimicbench.baselines.mimicat.method import Mimicat
    from mimicbench.baselines.nearest_joint import nearest_joint_pairs
    from mimicbench.benchmark.evaluator import load_cases
    from mimicbench.benchmark.intervals import pair_clustered_se
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.benchmark.semantic import character_role_classes

    ev = EvalData.load(args.data)
    pairs = sorted({(c.source_id, c.target_id) for c in load_cases(args.data, ("cct",))["cct"]})
    methods = {}
    for spec in args.checkpoints.split(","):
        name, folder = spec.split("=", 1)
        methods[name] = Mimicat(checkpoint=folder, arap=False)
        methods[name].setup("cpu")
    from mimicbench.baselines.mimicat.transfer import correspondences

    names = [x for n in methods for x in (n, f"{n} argmax")] + ["nearest_joint"]
    right = {n: [] for n in names}
    pair_ids, skipped = [], 0
    for s_id, t_id in pairs:
        src, tgt = ev.characters[s_id], ev.characters[t_id]
        sc, tc = character_role_classes(src.record), character_role_classes(tgt.record)
        if sc is None or tc is None:
            skipped += 1
            continue
        matches = {}
        for name, method in methods.items():
            a, b = method._character(src.rig), method._character(tgt.rig)
            m = method._correspondences([None], [a], [b])[0]
            matches[name] = match_from_m(m.cpu().numpy())
            soft = correspondences(method._modules["shape"], method._modules["corr"], [a], [b], method._m_cache,
                                   method.m_temperature)[0].cpu().numpy()
            matches[f"{name} argmax"] = soft.argmax(axis=0)
        matches["nearest_joint"] = match_from_pairs(nearest_joint_pairs(src.rig, tgt.rig), len(tgt.rig.parents))
        for name in names:
            scored, ok = role_accuracy(matches[name], sc, tc)
            right[name].extend(ok.astype(float))
        pair_ids.extend([f"{s_id}->{t_id}"] * len(scored))
    arr = {n: np.asarray(v) for n, v in right.items()}
    ref = names[0]
    print(f"{args.data}: {len(pairs) - skipped} cct pairs ({skipped} without role labels), {len(pair_ids)} target "
          f"bones whose role class the source has; role-class accuracy +- pair-clustered SE, difference to {ref}:")
    for n in names:
        line = f"  {n:22s} {arr[n].mean():.3f} +- {pair_clustered_se(arr[n], pair_ids):.3f}"
        if n != ref:
            d = arr[n] - arr[ref]
            se = pair_clustered_se(d, pair_ids)
            line += f"   {n} - {ref}: {d.mean():+.3f} +- {se:.3f} (z {d.mean() / se:+.1f})"
        print(line)
    first = list(methods)[0]
    for n in list(methods)[1:]:
        for suffix in ("", " argmax"):
            d = arr[n + suffix] - arr[first + suffix]
            se = pair_clustered_se(d, pair_ids)
            print(f"  {n + suffix} - {first + suffix}: {d.mean():+.3f} +- {se:.3f} (z {d.mean() / se:+.1f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    a = sub.add_parser("train-a3", help="train G against nearest_joint's matches (ablation A3)")
    a.add_argument("data", type=Path)
    a.add_argument("--out", type=Path, required=True)
    a.add_argument("--epochs", type=int, default=None, help="default: the shipped corr stage's")
    b = sub.add_parser("accuracy", help="role-class accuracy of G(s) and nearest_joint on DATA's cct pairs")
    b.add_argument("data", type=Path)
    b.add_argument("--checkpoints", default="shipped=baselines/mimicat/checkpoints",
                   help="comma-separated NAME=FOLDER (each with shape, corr and transfer weights)")
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    {"train-a3": train_a3, "accuracy": accuracy}[args.command](args)


if __name__ == "__main__":
    main()
