"""How much of the cct cycle error an H could give back by predicting the bones the cycle loses.

With ``transfer.m_decode=hungarian_sym`` a source bone that round-trips comes back exactly with H
off; what is left of the cycle error (``analyses/mimicat_cycle_loss.py``) is the source bones
with no counterpart in the target (their column of the return leg's M is empty, so the
initialisation gives them their parent's rotation: a local identity) and the bones below them.
The only thing an H could learn about those bones that carries over to other characters is how
their motion follows the rest of the pose (a tail with the gait). This script runs every cct case
of DATA (``bench cases``; the first ``--cases`` of those whose source is held out from the
predictors' fit, see below) through ``mimicat_init_only`` (G's M decoded
``hungarian_sym``, structured initialisation, H off, LBS, ARAP as the method's default, exactly the method's answer) and
rescores the return leg with the lost bones (``no forward match``) changed:

- ``init``: unchanged (the method's cycle; checks that this script reproduces the evaluator);
- ``oracle_rot``: each lost bone's local rotation (relative to its parent) set to the ground
  truth of the case's source pose: an upper bound on what any H can gain from their rotations;
- ``oracle``: the same with the lost bones' local translations too;
- ``ridge``: each lost bone's local rotation (6D) predicted by a ridge regression from the
  local rotations (6D) of the same frame's round-trip bones, fitted on every frame of every clip
  of the characters of the source's category of ``--fit FIT`` (another zoo, every split), or
  without it of DATA's ``train`` split, whose characters are then left out as sources. Bones are aligned across
  characters by the zoo's hidden ``bone_roles`` (ground truth, never a method input: this makes
  the regression easier than anything an H must do, so it is an upper bound on a generalising
  rule of this kind too). A lost bone whose role no training character has keeps the identity.
- ``knn k=K`` (``--alpha -K``): the mean (6D, then Gram-Schmidt) of the same bone in the K
  training frames nearest in those features, a nonlinear check of the same information.

Descendants of a changed bone follow it (forward kinematics with the returned local
translations). Prints cct cycle PMD x100 (largest extent, as the benchmark) per variant with the
paired difference to ``init`` and its standard error clustered by (source, target) pair, per clip
kind, each method of ``--results RES --methods M1,M2`` (its ``bench run`` rows on the same cases)
with its difference to ``init`` and the share of the oracle's gain it reaches, the predictors' angular error
on the lost bones against the identity's, and what the best predictor and the oracle would give
if told which clips are random poses (a bound on gating them; no method is told).

    python analyses/mimicat_ceiling.py DATA [--fit FIT] [--cases N] [--alpha 1,10,100,10000,-1,-8,-32] \
        [--results RES --methods mimicat]

DATA: a zoo with cct cases (``bench cases``), resampled, correspondences computed.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root

VARIANTS = ("init", "oracle_rot", "oracle")


def rot6d(q: np.ndarray) -> np.ndarray:
    """(..., 6): the first two columns of R(q) for unit quaternions q (..., 4) (Zhou et al. 2019)."""
    from mimicbench.geometry.quaternion import quat_to_matrix

    m = quat_to_matrix(q)
    return np.concatenate([m[..., :, 0], m[..., :, 1]], axis=-1)


def quat_from_6d(x: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) from 6D vectors (..., 6) by Gram-Schmidt."""
    from mimicbench.geometry.quaternion import matrix_to_quat

    a, b = x[..., :3], x[..., 3:]
    e1 = a / np.linalg.norm(a, axis=-1, keepdims=True).clip(1e-9)
    b = b - (e1 * b).sum(-1, keepdims=True) * e1
    e2 = b / np.linalg.norm(b, axis=-1, keepdims=True).clip(1e-9)
    e3 = np.cross(e1, e2)
    return matrix_to_quat(np.stack([e1, e2, e3], axis=-1))


def recompose(q: np.ndarray, t: np.ndarray, rest: np.ndarray, parents: np.ndarray, change: np.ndarray,
              local_new: np.ndarray, moved_new: np.ndarray | None = None) -> np.ndarray:
    """Transforms (K, 7) of a returned pose (global q (K, 4), positions t (K, 3)) where the bones
    flagged ``change`` (K,) take local rotations ``local_new`` (K, 4) (and local translations
    ``moved_new`` (K, 3) when given); every other bone keeps its global rotation and its local
    translation, so descendants of a changed bone follow it."""
    from mimicbench.benchmark.protocols.h2h import local_translations, transforms_from_local
    from mimicbench.geometry.kinematics import local_from_global, transforms_to_array
    from mimicbench.geometry.quaternion import quat_multiply

    moved = local_translations(transforms_to_array(q, t), rest, parents)
    if moved_new is not None:
        moved[change] = moved_new[change]
    g = np.array(q, np.float64)
    for k, p in enumerate(parents):  # parents come before children
        if change[k]:
            g[k] = local_new[k] if p < 0 else quat_multiply(g[p], local_new[k])
    return transforms_from_local(local_from_global(g, parents), moved, rest, parents)


class RoleRidge:
    """Ridge regressions of one bone's local rotation (6D) from other bones' (6D), across the
    ``train`` characters of one category, bones aligned by ``bone_roles``."""

    def __init__(self, data: Path, split: str | None = "train"):
        import pyarrow.parquet as pq

        from mimicbench.geometry.kinematics import local_from_global

        chars = pq.read_table(data / "characters", columns=["character_id", "category", "split", "bone_roles",
                                                            "parents"]).to_pylist()
        self.roles = {c["character_id"]: list(c["bone_roles"]) for c in chars}
        self.category = {c["character_id"]: c["category"] for c in chars}
        train = {c["character_id"]: c for c in chars if split is None or c["split"] == split}
        motions = pq.read_table(data / "motions", columns=["character_id", "num_frames", "num_joints", "transforms"],
                                filters=None if split is None else [("split", "=", split)]).to_pylist()
        frames: dict[str, list] = {}
        for m in motions:
            c = train.get(m["character_id"])
            if c is None:
                continue
            tr = np.asarray(m["transforms"], np.float64).reshape(m["num_frames"], m["num_joints"], 7)
            frames.setdefault(c["character_id"], []).append(rot6d(local_from_global(tr[..., :4],
                                                                                   np.asarray(c["parents"]))))
        self.train = {cid: (self.category[cid], {r: i for i, r in enumerate(self.roles[cid])}, np.concatenate(f))
                      for cid, f in frames.items()}
        self._fits: dict = {}

    @staticmethod
    def _frames(chars, role, feature_roles, use):
        """Training features (n, 6 len(use)) and targets (n, 6) of ``role`` over ``chars``."""
        xs = np.concatenate([x[:, [idx[feature_roles[i]] for i in use]].reshape(len(x), -1) for idx, x in chars])
        return xs, np.concatenate([x[:, idx[role]] for idx, x in chars])

    def predict(self, category: str, role: str, feature_roles: list[str], features: np.ndarray, alpha: float):
        """Local rotation (4,) of ``role`` from the 6D local rotations (len(feature_roles), 6) of
        ``feature_roles`` of one frame (ridge penalty ``alpha``), or None when no training
        character of ``category`` has it."""
        chars = [(idx, x) for cat, idx, x in self.train.values() if cat == category and role in idx]
        if not chars:
            return None
        use = [i for i, r in enumerate(feature_roles) if all(r in idx for idx, _ in chars)]
        key = (category, role, tuple(feature_roles[i] for i in use))
        if key not in self._fits:
            xs, ys = self._frames(chars, role, feature_roles, use)
            mx, my = xs.mean(axis=0), ys.mean(axis=0)
            self._fits[key] = (mx, my, (xs - mx).T @ (xs - mx), (xs - mx).T @ (ys - my), {})
        mx, my, xx, xy, w = self._fits[key]
        if alpha < 0:  # k nearest training frames (k = -alpha), a nonlinear check of the same features
            xs, ys = self._frames(chars, role, feature_roles, use)
            near = np.argsort(((xs - features[use].reshape(-1)) ** 2).sum(axis=1))[:int(-alpha)]
            return quat_from_6d(ys[near].mean(axis=0))
        if alpha not in w:
            w[alpha] = np.linalg.solve(xx + alpha * np.eye(len(xx)), xy)
        return quat_from_6d(my + (features[use].reshape(-1) - mx) @ w[alpha])


def _label(alpha: float) -> str:
    return f"knn k={-alpha:g}" if alpha < 0 else f"ridge a={alpha:g}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path, help="zoo with cct cases")
    ap.add_argument("--fit", type=Path, default=None,
                    help="zoo whose characters (every split) the predictors fit on (default: DATA's train split, "
                         "whose characters are then left out as sources)")
    ap.add_argument("--cases", type=int, default=None, help="first N held-out cct cases (default: all)")
    ap.add_argument("--results", type=Path, default=None, help="results folder of `bench run` on DATA")
    ap.add_argument("--methods", default="mimicat", help="methods of --results to place beside the bound")
    ap.add_argument("--alpha", default="1,10,100,10000,-1,-8,-32", help="ridge penalties on the 6D features (comma list; -k: the mean of the k nearest training frames)")
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    from mimicbench.baselines.mimicat.method import MimicatInitOnly
    from mimicbench.baselines.posing import source_pose
    from mimicbench.benchmark.evaluator import load_cases
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.benchmark.scoring import score_pose
    from mimicbench.geometry.kinematics import local_from_global
    from mimicbench.geometry.quaternion import quat_angle
    from mimicbench.geometry.skinning import linear_blend_skinning
    from mimicbench.benchmark.protocols.h2h import local_translations

    from analyses.mimicat_cycle_loss import chain_kinds

    method = MimicatInitOnly()
    method.setup("cpu")
    h = method._modules["transfer"]
    ev = EvalData.load(args.data)
    ridge = RoleRidge(args.fit or args.data, None if args.fit else "train")
    cases = load_cases(args.data, ("cct",))["cct"]
    fitted = set() if args.fit else set(ridge.train)
    held = [c for c in cases if c.source_id not in fitted][:args.cases]
    print(f"{len(held)} held-out cct cases ({len(cases)} in DATA; predictors fitted on "
          f"{'every character of ' + str(args.fit) if args.fit else 'the train split, whose sources are left out'})")
    cases = held
    alphas = [float(x) for x in args.alpha.split(",")]
    variants = VARIANTS + tuple(_label(a) for a in alphas)
    pmd = {v: [] for v in variants}
    clip_of, ang_ridge, ang_ident, n_lost, n_no_model = [], {a: [] for a in alphas}, [], 0, 0
    for n, c in enumerate(cases):
        src, tgt = ev.characters[c.source_id], ev.characters[c.target_id]
        posed = ev.posed(src, c.source_transforms)
        fwd = ev.request(src, posed, tgt, c.case_id)
        pred = method.transfer([fwd])[0]
        back = ev.request(tgt, pred, src, c.case_id)
        ca, cb = method._character(src.rig), method._character(tgt.rig)
        m_fwd = method._correspondences([fwd], [ca], [cb])[0]
        m_back = method._correspondences([back], [cb], [ca])[0]
        q_b, t_b = (torch.as_tensor(x, dtype=torch.float32) for x in source_pose(back))
        with torch.no_grad():
            q2, t2 = (x.double().numpy() for x in h.initialise(cb, q_b, t_b, ca, m_back)[:2])
        rig = src.rig
        lost = chain_kinds(m_fwd.numpy(), m_back.numpy(), rig.parents) == 1
        gt = np.asarray(c.source_transforms, np.float64)
        local_gt = local_from_global(gt[:, :4], rig.parents)
        ident = np.tile([1.0, 0, 0, 0], (len(rig.parents), 1))
        local_ridge = {a: ident.copy() for a in alphas}
        roles = ridge.roles[c.source_id]
        keep = np.flatnonzero(chain_kinds(m_fwd.numpy(), m_back.numpy(), rig.parents) == 0)
        local_ret = rot6d(local_from_global(q2, rig.parents))
        for k in np.flatnonzero(lost):
            n_lost += 1
            for a in alphas:
                p = ridge.predict(ridge.category[c.source_id], roles[k], [roles[i] for i in keep], local_ret[keep], a)
                if p is None:
                    n_no_model += a == alphas[0]
                    continue
                local_ridge[a][k] = p
        if lost.any():
            for a in alphas:
                ang_ridge[a].extend(np.degrees(quat_angle(local_ridge[a][lost], local_gt[lost])))
            ang_ident.extend(np.degrees(quat_angle(ident[lost], local_gt[lost])))
        moved_gt = local_translations(gt, rig.keypoints, rig.parents)
        poses = {"init": recompose(q2, t2, rig.keypoints, rig.parents, np.zeros_like(lost), ident),
                 "oracle_rot": recompose(q2, t2, rig.keypoints, rig.parents, lost, local_gt),
                 "oracle": recompose(q2, t2, rig.keypoints, rig.parents, lost, local_gt, moved_gt)}
        for a in alphas:
            poses[_label(a)] = recompose(q2, t2, rig.keypoints, rig.parents, lost, local_ridge[a])
        for v, tr in poses.items():
            verts = linear_blend_skinning(rig.vertices, rig.keypoints, rig.weights, tr).astype(np.float32)
            if method._refiner is not None:
                verts = method._refiner.refine(rig.character_id, rig.vertices, rig.faces, rig.weights.values, verts)
            pmd[v].append(score_pose(verts, posed, ev.frame(src), "extent")["pmd_extent"])
        clip_of.append(c.motion_id.rsplit("/", 1)[-1])
        if (n + 1) % 50 == 0:
            print(f"{n + 1} cases: " + ", ".join(f"{v} {np.mean(pmd[v]):.4f}" for v in variants), flush=True)
    from mimicbench.benchmark.intervals import pair_clustered_se, pair_of

    res = {v: np.asarray(x) for v, x in pmd.items()}
    pairs = [pair_of(c.case_id) for c in cases]
    print(f"{args.data}: {len(cases)} cct cases, {len(set(pairs))} pairs, mimicat_init_only (hungarian_sym, H off, "
          f"ARAP {'on' if method.arap else 'off'}); cycle PMD x100 (largest extent); paired difference to init +- pair-clustered SE")
    for v in variants:
        d = res[v] - res["init"]
        print(f"  {v:<11} {res[v].mean():.4f}  {d.mean():+.4f} +- {pair_clustered_se(d, pairs):.4f}  "
              f"({100 * d.mean() / res['init'].mean():+.1f}%)")
    if args.results is not None:
        from analyses.mimicat_paired import per_case

        gain = res["init"].mean() - res["oracle"].mean()
        for name in [m for m in args.methods.split(",") if m]:
            got = per_case(args.results, name, "cct", "pmd_extent")
            have = np.array([c.case_id in got for c in cases])
            x = np.array([got.get(c.case_id, np.nan) for c in cases])[have]
            d = x - res["init"][have]
            sub = [p for p, h in zip(pairs, have) if h]
            print(f"  {name} (bench rows, {have.sum()} of the cases): {x.mean():.4f}  {d.mean():+.4f} +- "
                  f"{pair_clustered_se(d, sub):.4f}  ({100 * d.mean() / res['init'][have].mean():+.1f}%); "
                  f"share of the oracle's gain: {100 * -d.mean() / gain:.1f}%")
    kinds = np.array(["random" if k.startswith("random_poses") else k for k in clip_of])
    for k in sorted(set(kinds)):
        sel = kinds == k
        print(f"  clip {k:<8} {sel.sum():>4} cases: " + ", ".join(f"{v} {res[v][sel].mean():.4f}" for v in variants))
    print(f"lost bones: {n_lost} over the cases, {n_no_model} without a training role; their local rotation "
          f"error (deg) against the ground truth: identity (init) {np.mean(ang_ident):.2f} (median "
          f"{np.median(ang_ident):.2f}), " + ", ".join(f"{_label(a)} {np.mean(ang_ridge[a]):.2f} (median "
                                                      f"{np.median(ang_ridge[a]):.2f})" for a in alphas))
    best = min(variants[3:], key=lambda v: res[v].mean())
    share = {v: 100 * (res["init"].mean() - res[v].mean()) / res["init"].mean() for v in ("oracle", best)}
    print(f"the best predictor ({best}) gives back {share[best]:.1f}% of init's cycle PMD, the oracle {share['oracle']:.1f}%")
    rand = kinds == "random"  # told which clips are random poses (no method is): a bound on gating the prediction
    for v in ("oracle", best):
        gated = np.where(rand, res["init"], res[v])
        print(f"  {v} on the clips that are not random poses only, the init on those: {gated.mean():.4f} "
              f"({100 * (gated.mean() - res['init'].mean()) / res['init'].mean():+.1f}%)")


if __name__ == "__main__":
    main()
