"""Config presets of CGT: ``cpu`` (cut widths, 512 points, attention over 256 farthest source points;
trains on 2 CPU cores in minutes; the shipped checkpoint) and ``paper`` (the published size and recipe:
encoder 64-128-1024, decoder stages 1024/512/512/256, dense attention over every point, Adam lr 5e-5,
batches of 8, about 10k steps; for a GPU).

Keys as NPT's (:mod:`mimicbench.baselines.npt.config`: the same batches and losses) plus ``cap``: the most points of
the posed source each target point attends over (farthest-point subsample: :mod:`mimicbench.baselines.cgt.sampling`),
in training and at inference; 0 is the paper's dense attention over every point.
"""
from __future__ import annotations

COMMON = {"knn": 6, "w_edge": 0.0005, "self_share": 0.5, "split": "all"}

CPU = {**COMMON, "widths": [32, 64, 128], "cap": 256, "residual": True, "points": 512, "batch_size": 4,
       "batches_per_epoch": 60, "epochs": 10, "lr": 1e-3, "weight_decay": 0.0, "grad_clip": 1.0}

PAPER = {**COMMON, "widths": [64, 128, 1024], "cap": 0, "residual": False, "points": 0, "batch_size": 8,
         "batches_per_epoch": 500, "epochs": 20, "lr": 5e-5, "weight_decay": 0.0}

CONFIGS = {"cpu": CPU, "paper": PAPER}
