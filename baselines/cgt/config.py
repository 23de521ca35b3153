"""Config presets of CGT: ``small`` (trains on 2 CPU cores in minutes; the shipped checkpoint),
``small_cycle`` (plus NPT's cycle term, tried, not shipped), ``large`` and
``large_cycle`` (256 wide, dense attention over the 512 drawn pose points, 2,500 steps: one GPU in minutes) and ``paper`` (wider features, dense attention over every point, for GPUs).

Keys as NPT's (:mod:`baselines.npt.config`, the same batches and cycle term) plus ``blocks`` and ``heads`` of the
cross-attention, ``residual`` (NPT's), and ``cap``: the most points of the posed source each target point
attends over (farthest-point subsample: :mod:`baselines.cgt.sampling`), in training and at inference;
0 is the paper's dense attention over every point.
"""
from __future__ import annotations

from baselines.npt.config import CYCLE

COMMON = {"knn": 6, "w_edge": 0.0005, "self_share": 0.5, "split": "all", "blocks": 4}

SMALL = {**COMMON, "widths": [32, 64, 128], "heads": 4, "cap": 256, "residual": True, "pose_cond": True, "points": 512,
         "batch_size": 4, "batches_per_epoch": 60, "epochs": 12, "lr": 1e-3, "weight_decay": 0.0, "grad_clip": 1.0}

PAPER = {**COMMON, "widths": [64, 128, 512], "heads": 8, "cap": 0, "residual": False, "points": 0, "batch_size": 8,
         "batches_per_epoch": 500, "epochs": 200, "lr": 5e-5, "weight_decay": 0.0}

SMALL_CYCLE = {**SMALL, **CYCLE}

LARGE = {**SMALL, "widths": [64, 128, 256], "heads": 8, "cap": 0, "batch_size": 8, "batches_per_epoch": 250,
         "epochs": 10, "lr": 5e-4}

LARGE_CYCLE = {**LARGE, **CYCLE, "cycle_batch": 4}

CONFIGS = {"small": SMALL, "small_cycle": SMALL_CYCLE, "large": LARGE, "large_cycle": LARGE_CYCLE, "paper": PAPER}
