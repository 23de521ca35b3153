"""Where the cycle error of MimiCAT's initialisation sits (H off), on a fixed set of training cycles.

The transfer stage trains H by the cycle source -> target -> source (L_rec, in units of the
source's size). This script draws a fixed set of the stage's (source, clip, frame, target)
examples from DATA (``transfer_examples`` with ``--seed``, the ``small`` preset's settings and
``data.split=all``), runs the cycle through the structured initialisation alone (the shipped E
and G, M decoded as ``--decode``) and splits every source vertex's returned error by what
happened to the bone that dominates it (largest skin weight):

- ``round trip``: the bone and all its ancestors go to a target bone and come back to themselves;
- ``no forward match``: the bone has no target bone (its pose cannot reach the target);
- ``back to another bone``: it has one, but the return leg's decoding sends that target bone to
  another source bone;
- ``ancestor lost``: the bone round-trips but an ancestor does not.

It shows why H does not learn (docs/notes/mimicat.md):

    python analyses/mimicat_cycle_loss.py data/zoo13_5k --decode hungarian
    python analyses/mimicat_cycle_loss.py data/zoo13_5k --decode hungarian_sym
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import from the repository root


def frozen_context(data: Path, checkpoint: Path, decode: str):
    """The transfer stage's context (frozen E, prior, G from ``checkpoint``) with the ``small``
    preset's config, ``data.split=all`` and ``transfer.m_decode=decode``."""
    from mimicbench.baselines.mimicat.config import preset
    from mimicbench.baselines.mimicat.method import checkpoint_path
    from mimicbench.training.checkpoint import load_module
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    config = preset("small")
    config["data"]["split"] = "all"
    config["transfer"]["m_decode"] = decode
    model = trainable("mimicat")
    ctx = StageContext(data, torch.device("cpu"), config)
    for need in model.stage("transfer").needs:
        m = load_module(checkpoint_path(checkpoint, need), lambda cfg, s=model.stage(need): s.build(cfg, ctx),
                        ctx.device)
        ctx.frozen[need] = m.eval()
    return model, config, ctx


def chain_kinds(m_fwd: np.ndarray, m_back: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Per source bone (Ks,): 0 round trip, 1 no forward match, 2 back to another bone, 3 ancestor
    lost, from one-to-one matrices ``m_fwd`` (Ks, Kt) and ``m_back`` (Kt, Ks)."""
    has = m_fwd.sum(axis=1) > 0
    to = m_fwd.argmax(axis=1)
    back_has = m_back.sum(axis=1) > 0
    back = m_back.argmax(axis=1)
    ok = np.array([has[i] and back_has[to[i]] and back[to[i]] == i for i in range(len(has))])
    kind = np.where(~has, 1, np.where(~ok, 2, 0))
    for i in range(len(parents)):
        a = parents[i]
        while kind[i] == 0 and a >= 0:
            if not ok[a]:
                kind[i] = 3
            a = parents[a]
    return kind


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("data", type=Path, help="a training zoo (resampled, correspondences computed)")
    parser.add_argument("--decode", default="hungarian_sym", help="transfer.m_decode")
    parser.add_argument("--examples", type=int, default=32)
    parser.add_argument("--seed", type=int, default=2002)
    parser.add_argument("--checkpoint", type=Path, default=None, help="default: the bundled checkpoint")
    args = parser.parse_args()
    torch.set_num_threads(1)

    import mimicbench.baselines.mimicat.transfer_training as tt
    from mimicbench.baselines.mimicat.method import BUNDLED
    from mimicbench.baselines.mimicat.transfer import correspondences, decode_correspondence, pose_mesh

    model, config, ctx = frozen_context(args.data, args.checkpoint or BUNDLED, args.decode)
    c = tt.section(config, "transfer")
    records, motions, tensors = tt._characters(args.data, ctx.device, c["points"], c["split"])
    examples = tt.transfer_examples(records, motions, args.examples, c["same_skeleton_share"],
                                    np.random.default_rng(args.seed))
    torch.manual_seed(0)
    h = model.stage("transfer").build(config, ctx)  # zero residual: the initialisation
    names = ("round trip", "no forward match", "back to another bone", "ancestor lost")
    err_sum, count, losses = np.zeros(4), np.zeros(4), []
    enc, g, cache, temp = ctx.frozen["shape"], ctx.frozen["corr"], tt._m_cache(ctx), float(c["m_temperature"])
    for s_id, clip, frame, t_id in examples:
        s, t = tensors[s_id], tensors[t_id]
        with torch.no_grad():
            losses.append(float(tt.cycle_losses(h, {"examples": [(s_id, clip, frame, t_id)]}, ctx, 0.0)["rec"]))
            pose = torch.as_tensor(motions[s_id][clip][frame])
            g_fwd = correspondences(enc, g, [s], [t], cache, temp)[0]
            g_back = correspondences(enc, g, [t], [s], cache, temp)[0]
            m_fwd = decode_correspondence(g_fwd, args.decode, g_back)
            m_back = decode_correspondence(g_back, args.decode, g_fwd)
            q1, t1 = h.initialise(s, pose[:, :4], pose[:, 4:], t, m_fwd)[:2]
            q2, t2 = h.initialise(t, q1, t1, s, m_back)[:2]
            err = ((pose_mesh(s, q2, t2) - pose_mesh(s, pose[:, :4], pose[:, 4:])).norm(dim=-1) / s.size).numpy()
        kind = chain_kinds(m_fwd.numpy(), m_back.numpy(), s.parents)
        dom = s.weight_indices.numpy()[np.arange(len(err)), s.weight_values.numpy().argmax(axis=1)]
        for k in range(4):
            err_sum[k] += err[kind[dom] == k].sum()
            count[k] += (kind[dom] == k).sum()
    print(f"{args.data}, {args.examples} cycles (seed {args.seed}), m_decode={args.decode}: "
          f"L_rec of the initialisation {np.mean(losses):.5f}")
    print(f"{'dominant bone':<22} {'share of vertices':>18} {'mean error':>11} {'share of error':>15}")
    for k, name in enumerate(names):
        print(f"{name:<22} {count[k] / count.sum():>18.3f} {err_sum[k] / max(count[k], 1):>11.5f} "
              f"{err_sum[k] / err_sum.sum():>15.3f}")


if __name__ == "__main__":
    main()
