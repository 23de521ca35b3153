"""Config presets of NPT: ``cpu`` (cut widths and points; trains on 2 CPU cores in minutes; the shipped
checkpoint) and ``paper`` (the published size and recipe: encoder 64-128-1024, decoder 1027 wide,
every vertex, Adam lr 5e-5, batches of 8, about 500k steps; for a GPU).

Keys: ``widths`` the pose encoder's (c1, c2, c3) (the decoder is c3 + 3 wide); ``points`` vertices drawn
from each mesh per example (the max-pool encoder and the per-point decoder accept any count; 0: every
vertex); ``residual`` (ours, ``cpu`` only) the decoder answers offsets from the rest points
(:mod:`mimicbench.baselines.npt.model`); ``knn`` neighbours standing in for mesh edges in the edge term on a
subsample; ``w_edge`` the edge term's weight (the paper's 0.0005); ``self_share`` the share of examples
that are self-transfers of any character (ours, see training.py); ``cycle_batch`` cross-category cycle
examples added to each step (ours, :mod:`mimicbench.baselines.npt.cycle`; 0 or absent: off, as in the paper and in
both presets; :data:`CYCLE` holds its keys), ``w_cycle``, ``w_cycle_edge``, ``cycle_detach``;
``batches_per_epoch`` steps an epoch; ``split`` the characters trained on.
"""
from __future__ import annotations

COMMON = {"knn": 6, "w_edge": 0.0005, "self_share": 0.5, "split": "all"}

CYCLE = {"cycle_batch": 2, "w_cycle": 1.0, "w_cycle_edge": 0.01, "cycle_detach": False}
"""The cross-category cycle term's keys (ours, off in every preset)."""

CPU = {**COMMON, "widths": [32, 64, 256], "residual": True, "points": 512, "batch_size": 4,
       "batches_per_epoch": 60, "epochs": 20, "lr": 1e-3, "weight_decay": 0.0, "grad_clip": 1.0}

PAPER = {**COMMON, "widths": [64, 128, 1024], "residual": False, "points": 0, "batch_size": 8,
         "batches_per_epoch": 500, "epochs": 1000, "lr": 5e-5, "weight_decay": 0.0}

CONFIGS = {"cpu": CPU, "paper": PAPER}
