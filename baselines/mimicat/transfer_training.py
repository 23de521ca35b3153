"""Training stages of G (``corr``) and H (``transfer``, ``transfer_no_prior``) for ``mimicbench train mimicat``.

- ``corr`` (needs ``shape``): G against the dataset's ``pairs/`` table (Eq. 6,
  :func:`mimicbench.baselines.mimicat.correspondence.correspondence_loss`).
- ``transfer`` (needs ``shape``, ``prior``, ``corr``): H by cycle consistency (Eq. 7-8) on
  (source, pose, target) triples drawn from the dataset's characters and clips: the source pose
  goes to the target (forward leg) and H's answer back to the source (return leg);
  ``L_rec``: mean vertex distance between the returned and the posed source, in units of the
  source's size; ``L_reg``: negative log-likelihood of the forward leg's rotations under the
  frozen pose prior F (matrix-Fisher per keypoint); ``L_feat``: squared difference between the
  residual features of the two legs (E(posed target) - E(target) should move like
  E(posed source) - E(source)). ``total = rec_weight L_rec + reg_weight L_reg + feat_weight L_feat``.
  G's M of every pair an epoch draws is computed once for all ranks and epochs at the epoch's
  start (:func:`shared_correspondences`), and E reads each rest mesh once (the frozen encoder's
  rest tokens are cached per character); only the posed meshes go through E each step.
  Both legs use G's M at the Sinkhorn temperature ``m_temperature`` (see
  :func:`mimicbench.baselines.mimicat.transfer.correspondences`) decoded as ``m_decode`` says (``soft``: as
  it is; ``hungarian``: one-to-one; ``hungarian_sym``: one one-to-one assignment of the pair from
  G's M of both directions, the presets' default, see
  :func:`mimicbench.baselines.mimicat.transfer.decode_correspondence`), as the method does at test time, and H's
  initialisation ``init`` (``structured`` in the presets; ``paper``, Eq. 3-4 as published, for a
  config without the key, which is what checkpoints trained before it used).
- ``transfer_no_prior`` (needs ``shape``, ``corr``): the same without ``L_reg`` (ablation A2):
  the very training of ``--stage transfer --set transfer.reg_weight=0`` (same seed, initial
  weights, batches and settings), kept as its own stage so that one run folder holds both.

Config sections ``corr`` and ``transfer`` (defaults in :data:`CORR_DEFAULTS`,
:data:`TRANSFER_DEFAULTS`; ``--set transfer.reg_weight=0.05`` overrides one).
"""
from __future__ import annotations

import numpy as np
import torch

from mimicbench.baselines.mimicat.corr_data import read_pairs
from mimicbench.baselines.mimicat.correspondence import CorrespondenceTransformer, correspondence_loss
from mimicbench.baselines.mimicat.transfer import (PoseTransferTransformer, correspondences, decode_correspondence, pose_mesh,
                                        transfer_batch)
from mimicbench.baselines.mimicat.transfer_data import (CharacterTensors, correspondence_inputs, read_transfer_pool,
                                             shape_tokens)

CORR_DEFAULTS = {"width": 64, "layers": 2, "heads": 4, "mlp": 128, "batch_size": 8, "points": 512, "split": "all",
                 "sinkhorn_iters": 50}
TRANSFER_DEFAULTS = {"width": 64, "layers": 2, "heads": 4, "mlp": 128, "batch_size": 4, "points": 512, "split": "all",
                     "examples_per_epoch": 64, "same_skeleton_share": 0.3, "rec_weight": 1.0,
                     "reg_weight": 0.01, "feat_weight": 0.1, "m_temperature": 1.0, "init": "paper",
                     "m_decode": "soft"}
"""Values a config without the key means: what the checkpoints trained before the key existed
used (the presets of :mod:`mimicbench.baselines.mimicat.config` set ``init`` to ``structured``)."""


def section(config: dict, name: str) -> dict:
    """A config section with its defaults filled in; ``points`` (what E reads per mesh) and
    ``split`` (the characters trained on) come from the ``data`` section when it has them."""
    defaults = {"corr": CORR_DEFAULTS, "transfer": TRANSFER_DEFAULTS}[name]
    data = config.get("data") or {}
    shared = {k: data[k] for k in ("points", "split") if k in data}
    return {**defaults, **shared, **(config.get(name) or {})}


def shape_width(config: dict) -> int:
    """Width d of the shape encoder's tokens (config ``shape.width``)."""
    shape = config.get("shape") or {}
    return int(shape.get("width", shape.get("d", 64)))


_CACHE: dict = {}

SHARED_CACHES = True
"""Precompute G's M per epoch for all ranks and cache E's rest tokens (see the module docstring);
``benchmarks/mimicat.py`` switches it off to time the per-step path it replaced (M computed in the
step for pairs not yet in this process's cache, every rest mesh through E every step)."""


def _characters(dataset, device, points: int, split: str = "all") -> tuple[dict, dict, dict]:
    """Records, clips and CharacterTensors of a dataset's ``split`` (cached per dataset, device,
    point count and split)."""
    key = (str(dataset), str(device), points, split)
    if key not in _CACHE:
        records, motions = read_transfer_pool(dataset, split)
        tensors = {cid: CharacterTensors.of_record(r, points, device) for cid, r in records.items()}
        _CACHE[key] = (records, motions, tensors)
    return _CACHE[key]


# ---- corr -------------------------------------------------------------------------------------

def build_corr(config: dict, ctx) -> CorrespondenceTransformer:
    c = section(config, "corr")
    return CorrespondenceTransformer(shape_width(config), c["width"], c["layers"], c["heads"], c["mlp"],
                                     c["sinkhorn_iters"], float(c.get("geometry_weight", 0.0)))


def _pairs(dataset):
    key = ("pairs", str(dataset))
    if key not in _CACHE:
        _CACHE[key] = read_pairs(dataset)
    return _CACHE[key]


def corr_batches(config: dict, ctx, rng: np.random.Generator):
    from mimicbench.training.batching import rank_batches

    c = section(config, "corr")
    _, _, tensors = _characters(ctx.dataset, ctx.device, c["points"], c["split"])
    pairs = [i for i, p in enumerate(_pairs(ctx.dataset)) if p.source_id in tensors and p.target_id in tensors]
    if not pairs:
        raise ValueError(f"{ctx.dataset}: no pairs/ rows between characters with a mesh")
    for idx in rank_batches(len(pairs), c["batch_size"], rng, ctx.rank, ctx.world_size):
        yield {"pair_index": np.asarray([pairs[i] for i in idx], np.int64)}


def corr_loss(module: CorrespondenceTransformer, batch: dict, ctx) -> dict:
    c = section(ctx.config, "corr")
    _, _, tensors = _characters(ctx.dataset, ctx.device, c["points"], c["split"])
    rows = [_pairs(ctx.dataset)[int(i)] for i in batch["pair_index"]]
    src = [tensors[p.source_id] for p in rows]
    tgt = [tensors[p.target_id] for p in rows]
    with torch.no_grad():
        tok = shape_tokens(ctx.frozen["shape"], torch.stack([s.normalised(s.vertices) for s in src + tgt]))
    m = module(shape_s=tok[:len(src)], shape_t=tok[len(src):], **correspondence_inputs(src, tgt))
    dev = tok.device
    return correspondence_loss(m, [torch.as_tensor(p.m_sink, device=dev) for p in rows],
                               [torch.as_tensor(p.hungarian, device=dev) for p in rows])


# ---- transfer ---------------------------------------------------------------------------------

def build_transfer(config: dict, ctx) -> PoseTransferTransformer:
    c = section(config, "transfer")
    return PoseTransferTransformer(shape_width(config), c["width"], c["layers"], c["heads"], c["mlp"],
                                   init=c["init"])


def transfer_examples(records: dict, motions: dict, n: int, same_skeleton_share: float,
                      rng: np.random.Generator) -> list[tuple[str, int, int, str]]:
    """``n`` (source ID, clip index, frame, target ID) draws: a source with clips, a non-rest frame,
    a different target (of the source's skeleton family with probability ``same_skeleton_share``
    when it has one)."""
    sources = sorted(motions)
    ids = sorted(records)
    family: dict = {}
    for cid in ids:
        if records[cid].skeleton_id:
            family.setdefault(records[cid].skeleton_id, []).append(cid)
    out = []
    for _ in range(n):
        s = sources[rng.integers(len(sources))]
        clip = int(rng.integers(len(motions[s])))
        frame = int(rng.integers(1, len(motions[s][clip])))
        kin = [c for c in family.get(records[s].skeleton_id, []) if c != s]
        pool = kin if kin and rng.random() < same_skeleton_share else [c for c in ids if c != s]
        out.append((s, clip, frame, pool[rng.integers(len(pool))]))
    return out


def _m_cache(ctx) -> dict:
    """This process's cache of G's M, keyed (source ID, target ID, temperature)."""
    return _CACHE.setdefault(("m", str(ctx.dataset), str(ctx.device)), {})


def shared_correspondences(ctx, tensors: dict, pairs, temperature: float, chunk: int = 16) -> None:
    """Put G's M (at ``temperature``) of every (source ID, target ID) in ``pairs`` into this
    process's cache, each missing pair computed once for all ranks: rank r takes the sorted
    missing pairs r, r + W, ... (W ranks) through G in batches of ``chunk``, and every rank
    receives what every rank computed (:func:`mimicbench.training.distributed.gather_objects`).
    Every rank must call it with the same ``pairs`` (the epoch's examples are drawn alike on all).

    Args:
        ctx: the stage context (frozen ``shape`` and ``corr``, rank, world size).
        tensors: CharacterTensors by ID.
        pairs: iterable of (source ID, target ID).
    """
    from mimicbench.baselines.mimicat.transfer import correspondences
    from mimicbench.training.distributed import gather_objects

    cache, temp = _m_cache(ctx), float(temperature)
    todo = sorted({(s, t) for s, t in pairs if (s, t, temp) not in cache})
    mine, fresh = todo[ctx.rank::ctx.world_size], {}
    for i in range(0, len(mine), chunk):
        part = mine[i:i + chunk]
        correspondences(ctx.frozen["shape"], ctx.frozen["corr"], [tensors[s] for s, _ in part],
                        [tensors[t] for _, t in part], fresh, temp)
    for got in gather_objects({k: v.cpu() for k, v in fresh.items()}, ctx.world_size):
        cache.update({k: v.to(ctx.device) for k, v in got.items()})


def transfer_batches(config: dict, ctx, rng: np.random.Generator):
    from mimicbench.training.batching import rank_batches

    c = section(config, "transfer")
    records, motions, tensors = _characters(ctx.dataset, ctx.device, c["points"], c["split"])
    examples = transfer_examples(records, motions, c["examples_per_epoch"], c["same_skeleton_share"], rng)
    if SHARED_CACHES:
        shared_correspondences(ctx, tensors, [p for s, _, _, t in examples for p in ((s, t), (t, s))],
                               c["m_temperature"])
    for idx in rank_batches(len(examples), c["batch_size"], rng, ctx.rank, ctx.world_size):
        chosen = [examples[i] for i in idx]
        yield {"examples": chosen}


def prior_nll(prior: torch.nn.Module, tgt: CharacterTensors, f_rest: torch.Tensor, f_posed: torch.Tensor,
              q: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Mean negative log-likelihood of rotations q (K, 4) under the frozen prior F for a posed target."""
    return prior.nll(f_rest=f_rest, f_posed=f_posed, rest=(tgt.keypoints - tgt.centre) / tgt.size,
                     posed=(t - tgt.centre) / tgt.size, parents=tgt.parents, q=q)


def cycle_losses(h: PoseTransferTransformer, batch: dict, ctx, reg_weight: float) -> dict:
    """Eq. 7-8 on one batch (see the module docstring)."""
    c = section(ctx.config, "transfer")
    _, motions, tensors = _characters(ctx.dataset, ctx.device, c["points"], c["split"])
    encoder, g = ctx.frozen["shape"], ctx.frozen["corr"]
    src, tgt, q_s, t_s, posed = [], [], [], [], []
    for s_id, clip, frame, t_id in batch["examples"]:
        pose = torch.as_tensor(motions[s_id][clip][frame], device=ctx.device)
        src.append(tensors[s_id])
        tgt.append(tensors[t_id])
        q_s.append(pose[:, :4])
        t_s.append(pose[:, 4:])
        posed.append(pose_mesh(tensors[s_id], pose[:, :4], pose[:, 4:]))
    cache = _m_cache(ctx)
    temp = float(c["m_temperature"])
    g_fwd, g_back = (correspondences(encoder, g, a, b, cache, temp) for a, b in ((src, tgt), (tgt, src)))
    m_fwd = [decode_correspondence(m, c["m_decode"], r) for m, r in zip(g_fwd, g_back)]
    m_back = [decode_correspondence(m, c["m_decode"], r) for m, r in zip(g_back, g_fwd)]
    rest = _CACHE.setdefault(("rest tokens", str(ctx.dataset), str(ctx.device), c["points"]), {}) \
        if SHARED_CACHES else None
    forward, _, f_fwd = transfer_batch(encoder, g, h, src, q_s, t_s, posed, tgt, m_fwd, rest)
    pred = [pose_mesh(t, q, p) for t, (q, p) in zip(tgt, forward)]
    back, _, f_back = transfer_batch(encoder, g, h, tgt, [q for q, _ in forward], [p for _, p in forward], pred, src,
                                     m_back, rest)
    rec = torch.stack([(pose_mesh(s, q, p) - v).norm(dim=-1).mean() / s.size
                       for s, (q, p), v in zip(src, back, posed)]).mean()
    feat = ((f_back[3] - f_fwd[3]) ** 2).mean()
    losses = {"rec": rec, "feat": feat}
    total = c["rec_weight"] * rec + c["feat_weight"] * feat
    if reg_weight > 0:
        reg = torch.stack([prior_nll(ctx.frozen["prior"], t, f_back[0][b], f_back[1][b], q, p)
                           for b, (t, (q, p)) in enumerate(zip(tgt, forward))]).mean()
        losses["reg"] = reg
        total = total + reg_weight * reg
    losses["total"] = total
    return losses


def transfer_loss(module: PoseTransferTransformer, batch: dict, ctx) -> dict:
    return cycle_losses(module, batch, ctx, section(ctx.config, "transfer")["reg_weight"])


def transfer_no_prior_loss(module: PoseTransferTransformer, batch: dict, ctx) -> dict:
    return cycle_losses(module, batch, ctx, 0.0)


def stages():
    """The TrainStage objects this module contributes, in training order."""
    from mimicbench.training.stage import TrainStage

    return [
        TrainStage("corr", build_corr, corr_batches, corr_loss, needs=("shape",)),
        TrainStage("transfer", build_transfer, transfer_batches, transfer_loss, needs=("shape", "prior", "corr")),
        TrainStage("transfer_no_prior", build_transfer, transfer_batches, transfer_no_prior_loss,
                   needs=("shape", "corr")),
    ]
