"""``mimicbench train mimicat``: the stages of the MimiCAT reference, registered with the one trainer.

- ``shape``: the shape encoder E as an autoencoder (unsigned distance at query points) on rest
  and posed meshes of the dataset (:mod:`mimicbench.baselines.mimicat.shape_encoder`).
- ``prior`` (needs ``shape``): the pose prior F, negative log-likelihood of the dataset's
  rotations under per-keypoint matrix-Fisher distributions (:mod:`mimicbench.baselines.mimicat.pose_prior`).
- ``corr``, ``transfer``, ...: G and H, from :mod:`mimicbench.baselines.mimicat.transfer_training` when present.

Presets ``small`` and ``paper`` (:mod:`mimicbench.baselines.mimicat.config`).
"""
from __future__ import annotations

import importlib

import numpy as np
import torch

from mimicbench.baselines.mimicat import data
from mimicbench.baselines.mimicat.config import PRESETS
from mimicbench.baselines.mimicat.pose_prior import PosePrior, prior_loss
from mimicbench.baselines.mimicat.shape_encoder import ShapeAutoencoder, shape_loss
from mimicbench.training.batching import rank_batches
from mimicbench.training.registry import make_trainable
from mimicbench.training.stage import StageContext, TrainStage


def _characters(config: dict, context: StageContext) -> list:
    return data.read_characters(context.dataset, config["data"]["split"])


# ---- shape ------------------------------------------------------------------------------------

def build_shape(config: dict, context: StageContext) -> ShapeAutoencoder:
    return ShapeAutoencoder.from_config(config)


def shape_batches(config: dict, context: StageContext, rng: np.random.Generator):
    """Rest meshes and ``frames_per_motion`` posed frames per clip, shuffled, in global batches."""
    chars = _characters(config, context)
    s = config["shape"]
    items = data.draw_poses(chars, config["data"]["frames_per_motion"], rng, include_rest=True)
    key = int(rng.integers(2**62))  # item i draws from default_rng([key, i]): the same on every rank
    for idx in rank_batches(len(items), s["batch_size"], rng, context.rank, context.world_size):
        examples = []
        for i in idx:
            ci, mi, f = items[i]
            # one generator per item: the same item gets the same samples on any rank
            examples.append(data.shape_example(chars[ci], mi, f, np.random.default_rng([key, int(i)]), config["data"]["points"], s["queries"],
                                               s["surface_samples"]))
        yield data.collate(examples)


def shape_stage_loss(module: ShapeAutoencoder, batch: dict, context: StageContext) -> dict:
    return shape_loss(module, batch["points"], batch["queries"], batch["distances"])


# ---- prior ------------------------------------------------------------------------------------

def build_prior(config: dict, context: StageContext) -> PosePrior:
    return PosePrior.from_config(config)


def prior_batches(config: dict, context: StageContext, rng: np.random.Generator):
    """``frames_per_motion`` posed frames per clip (no rest frames), shuffled, in global batches."""
    chars = _characters(config, context)
    p = config["prior"]
    items = data.draw_poses(chars, config["data"]["frames_per_motion"], rng, include_rest=False)
    if not items:
        raise ValueError(f"{context.dataset}: no clip of a character with a mesh in split "
                         f"{config['data']['split']!r}; the prior needs posed frames")
    key = int(rng.integers(2**62))
    for idx in rank_batches(len(items), p["batch_size"], rng, context.rank, context.world_size):
        examples = []
        for i in idx:
            ci, mi, f = items[i]
            examples.append(data.prior_example(chars[ci], mi, f, np.random.default_rng([key, int(i)]),
                                               config["data"]["points"], p.get("max_keypoints")))
        batch = data.collate(examples, pad_values={"parents": -1})
        batch["sample_seed"] = [key, int(idx[0])]  # the sampling term's draws (A3)
        yield batch


def prior_stage_loss(module: PosePrior, batch: dict, context: StageContext) -> dict:
    encoder = context.frozen["shape"]
    with torch.no_grad():
        f_rest = encoder(batch["rest_points"])
        f_posed = encoder(batch["posed_points"])
    p = context.config["prior"]
    return prior_loss(module, f_rest, f_posed, batch, float(p.get("sampling_weight", 0.0)), int(p.get("samples", 4)),
                      np.random.default_rng(batch["sample_seed"]))


STAGES = [
    TrainStage("shape", build_shape, shape_batches, shape_stage_loss),
    TrainStage("prior", build_prior, prior_batches, prior_stage_loss, needs=("shape",)),
]


def _more_stages() -> list[TrainStage]:
    """G and H's stages (``corr``, ``transfer``, ...) from their module, when it is installed."""
    try:
        module = importlib.import_module("mimicbench.baselines.mimicat.transfer_training")
    except ModuleNotFoundError as exc:
        if exc.name == "mimicbench.baselines.mimicat.transfer_training":
            return []
        raise
    return list(module.stages())


TRAINABLE = make_trainable("mimicat", STAGES + _more_stages(), PRESETS)
