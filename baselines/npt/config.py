"""Config presets of NPT: ``small`` (trains on 2 CPU cores in minutes; the shipped checkpoint),
``small_cycle`` (``small`` plus the cross-category cycle term, tried for a version 4 and not shipped:
README) and ``large`` and ``large_cycle`` (``small``'s options, a decoder 384 wide, batches of 8 and 2,500 steps: one GPU
in minutes; a checkpoint below 20 MB), ``paper`` (the paper's widths 64-128-1024 and Adam lr 5e-5, for GPUs; AdamW with weight decay 0 is Adam).

Keys: ``widths`` the pose encoder's (c1, c2, c3); ``points`` vertices drawn from each mesh per
example (the max-pool encoder and the per-point decoder accept any count; 0: every vertex);
``pose_mix`` and ``residual`` the decoder's options (:mod:`baselines.npt.model`; absent in version 1's
config, whose decoder had neither); ``knn`` neighbours standing in for mesh edges in the edge term on that subsample;
``w_edge`` the edge term's weight (the paper's 0.0005); ``self_share`` the share of examples that are
self-transfers of any character (ours, see training.py); ``cycle_batch`` cross-category cycle examples
added to each step (ours, :mod:`baselines.npt.cycle`; absent or 0: off, as in the paper, in ``small`` and
in ``paper``), ``w_cycle`` and ``w_cycle_edge`` the weights of its cycle MSE and of its forward leg's edge
term, ``cycle_detach`` whether the return leg reads the forward answer without a gradient into it
(``small_cycle`` only; off there); ``batches_per_epoch`` steps an
epoch; ``split`` the characters trained on.
"""
from __future__ import annotations

COMMON = {"knn": 6, "w_edge": 0.0005, "self_share": 0.5, "split": "all"}

CYCLE = {"cycle_batch": 2, "w_cycle": 1.0, "w_cycle_edge": 0.01, "cycle_detach": False}
"""The cross-category cycle term's keys as the ``small_cycle`` presets of npt and cgt set them."""

SMALL = {**COMMON, "widths": [32, 64, 256], "pose_mix": True, "pose_cond": True, "residual": True, "points": 512,
         "batch_size": 4, "batches_per_epoch": 60, "epochs": 20, "lr": 1e-3, "weight_decay": 0.0, "grad_clip": 1.0}

PAPER = {**COMMON, "widths": [64, 128, 1024], "pose_mix": True, "residual": False, "points": 0, "batch_size": 8, "batches_per_epoch": 500,
         "epochs": 200, "lr": 5e-5, "weight_decay": 0.0}

SMALL_CYCLE = {**SMALL, **CYCLE}

LARGE = {**SMALL, "widths": [64, 128, 384], "batch_size": 8, "batches_per_epoch": 250, "epochs": 10, "lr": 5e-4}

LARGE_CYCLE = {**LARGE, **CYCLE, "cycle_batch": 4}

CONFIGS = {"small": SMALL, "small_cycle": SMALL_CYCLE, "large": LARGE, "large_cycle": LARGE_CYCLE, "paper": PAPER}
