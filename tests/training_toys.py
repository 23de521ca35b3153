"""A toy trainable for the trainer's tests: an MLP regressing y = sin(3x) + x^2 from a dataset folder.

The dataset folder holds ``toy.npz`` (x (N,2), y (N,1) float32), written by :func:`write_toy_dataset`.
Stage ``fit`` trains the MLP; stage ``head`` trains a linear head on the frozen ``fit`` MLP.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from mimicbench.training.batching import rank_batches
from mimicbench.training.registry import register_trainable
from mimicbench.training.stage import TrainStage

CONFIG = {"lr": 1e-2, "batch_size": 16, "fit": {"width": 16, "epochs": 2}, "head": {"epochs": 1}}


def write_toy_dataset(root: Path, n: int = 96, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
    y = (np.sin(3 * x[:, :1]) + x[:, 1:] ** 2).astype(np.float32)
    root.mkdir(parents=True, exist_ok=True)
    np.savez(root / "toy.npz", x=x, y=y)
    return root


def _data(context):
    d = np.load(Path(context.dataset) / "toy.npz")
    return d["x"], d["y"]


def _batches(config, context, rng):
    x, y = _data(context)
    for idx in rank_batches(len(x), config["batch_size"], rng, context.rank, context.world_size):
        yield {"x": x[idx], "y": y[idx]}


def _build_fit(config, context):
    w = config["fit"]["width"]
    return torch.nn.Sequential(torch.nn.Linear(2, w), torch.nn.Tanh(), torch.nn.Linear(w, w), torch.nn.Tanh(),
                               torch.nn.Linear(w, 1))


def _loss_fit(module, batch, context):
    err = module(batch["x"]) - batch["y"]
    return {"total": (err ** 2).mean(), "mae": err.abs().mean().detach()}


def _build_head(config, context):
    return torch.nn.Linear(1, 1)


def _loss_head(module, batch, context):
    with torch.no_grad():
        feat = context.frozen["fit"](batch["x"])
    return {"total": ((module(feat) - batch["y"]) ** 2).mean()}


STAGES = [TrainStage("fit", _build_fit, _batches, _loss_fit),
          TrainStage("head", _build_head, _batches, _loss_head, needs=("fit",))]
register_trainable("toy", STAGES, {"small": CONFIG})
