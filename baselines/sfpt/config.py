"""Config presets of SFPT: ``cpu`` (cut widths; trains on 2 CPU cores in minutes; the shipped checkpoint)
and ``paper`` (the published size and recipe: EdgeConv base width 64, per-handle codes of 128, 40 handles,
AdamW lr 1e-4, batches of 4, about 125k steps; for a GPU).

Keys: ``handles`` H; ``hidden`` EdgeConv base width h (widths h, 2h, 4h); ``code`` per-handle code width;
``cross_share`` the share of examples whose source and target are a same-skeleton pair (the others are
self examples of any character); ``aug_scale`` the largest relative per-axis scaling of the augmented
target the augmentation term compares with the plain one; ``w_*`` the loss weights, the published ones:
``rec`` (source pose onto the target against its ground truth), ``cycle`` (back from the unpaired third
character), ``trans`` (transform supervision by the target's Kabsch fit), ``cross`` (the unpaired third
character against its Kabsch-posed self, 0.3), ``skin`` (contrastive skinning, 0.03), ``aug`` (KL of the
augmented target's weights), ``fps`` (Chamfer of handle centres to farthest-point samples), ``arap``
(100, each of three deformed meshes); ``fps_per_handle`` samples per handle (4); ``residual`` (ours, ``cpu``
only) the pose decoder answers corrections to the Kabsch fit (:class:`mimicbench.baselines.sfpt.model.PoseDecoder`).

``decoder``: the settings of the second stage, the pose decoder alone on the centred reconstruction with the
Kabsch translations (:mod:`mimicbench.baselines.sfpt.decoder_stage`; ``epochs`` 0 in ``paper``, which trains it
jointly).
"""
from __future__ import annotations

COMMON = {"handles": 40, "cross_share": 0.5, "aug_scale": 0.2, "fps_per_handle": 4, "split": "all",
          "w_rec": 1.0, "w_cycle": 1.0, "w_trans": 1.0, "w_cross": 0.3, "w_skin": 0.03, "w_aug": 1.0,
          "w_fps": 1.0, "w_arap": 100.0}

DECODER = {"examples": 1500, "pair_share": 0.5, "pool_seed": 11, "batch_size": 4, "batches_per_epoch": 300,
           "w_rec": 1.0, "w_arap": 100.0, "w_trans": 0.0}

CPU = {**COMMON, "hidden": 16, "code": 64, "residual": True, "batch_size": 1, "batches_per_epoch": 40, "epochs": 4,
       "lr": 1e-3, "weight_decay": 1e-4, "grad_clip": 1.0,
       "decoder": {**DECODER, "epochs": 6, "lr": 1e-3, "weight_decay": 1e-4, "grad_clip": None}}

PAPER = {**COMMON, "hidden": 64, "code": 128, "residual": False, "batch_size": 4, "batches_per_epoch": 250, "epochs": 500,
         "lr": 1e-4, "weight_decay": 1e-2, "decoder": {**DECODER, "epochs": 0}}

CONFIGS = {"cpu": CPU, "paper": PAPER}
