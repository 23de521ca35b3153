"""Config presets of SFPT: ``small`` (trains on 2 CPU cores in minutes; the shipped checkpoint) and
``paper`` (40 handles, wider EdgeConv, AdamW lr 1e-4 as in the paper, for GPUs).

Keys: ``handles`` H; ``hidden`` EdgeConv width; ``knn`` EdgeConv neighbours (rest positions);
``points`` vertices drawn per mesh and example (0: every vertex); ``skin_points`` vertices of that
draw the skinning term compares pairwise; ``cross_share`` the share of examples that are
same-skeleton pairs (the cross-transfer term), the others self examples of any character;
``w_rec``, ``w_cross``, ``w_skin``, ``w_edge`` the loss weights (ours: the paper does not give them).
"""
from __future__ import annotations

COMMON = {"handles": 40, "knn": 8, "skin_points": 256, "cross_share": 0.5, "w_rec": 1.0, "w_cross": 1.0,
          "w_skin": 1.0, "w_edge": 1.0, "split": "all"}

SMALL = {**COMMON, "hidden": 32, "points": 512, "batch_size": 4, "batches_per_epoch": 40, "epochs": 5,
         "lr": 1e-3, "weight_decay": 1e-4, "grad_clip": 1.0}

PAPER = {**COMMON, "hidden": 128, "points": 2048, "batch_size": 8, "batches_per_epoch": 500, "epochs": 100,
         "lr": 1e-4, "weight_decay": 1e-4}

CONFIGS = {"small": SMALL, "paper": PAPER}
