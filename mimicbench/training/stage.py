"""What a training stage is: how to build its module, feed it batches and score it.

A stage knows nothing about optimisers, devices, processes or files: the loop
(:mod:`mimicbench.training.loop`) owns those. A stage's functions get the whole model config
(the preset, e.g. ``small`` or ``paper``, with command-line overrides applied) and a
:class:`StageContext`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import torch


@dataclass
class StageContext:
    """Everything a stage may look at besides its config.

    Attributes:
        dataset: the dataset folder given on the command line.
        device: where the module and the batches live (the loop moves batch tensors there).
        config: the whole model config (preset + overrides), the same dict every stage gets.
        frozen: trained modules of the stages in ``TrainStage.needs`` by stage name, in eval()
            mode with ``requires_grad`` False, already on ``device``.
        rank: this process's rank (0 without torchrun).
        world_size: the number of processes (1 without torchrun). ``batches`` must give each rank
            distinct batches (see :func:`mimicbench.training.batching.rank_batches`).
    """

    dataset: Path
    device: torch.device
    config: dict
    frozen: dict[str, torch.nn.Module] = field(default_factory=dict)
    rank: int = 0
    world_size: int = 1


@dataclass(frozen=True)
class TrainStage:
    """One stage of a trainable model.

    Attributes:
        name: e.g. ``"shape"``, ``"prior"``, ``"corr"``, ``"transfer"``.
        build: ``(config, context) -> torch.nn.Module``, the module trained in this stage (built
            after the loop seeded torch, so its initial weights repeat).
        batches: ``(config, context, rng) -> iterator of dict``: one epoch of batches for this
            rank. ``rng`` is a ``numpy.random.Generator`` seeded by (seed, epoch) and identical on
            every rank, so every rank can draw the same global order and take its own share.
            Values may be torch tensors, numpy arrays or anything else; tensors and numeric numpy
            arrays are moved to ``context.device`` as tensors by the loop.
        loss: ``(module, batch, context) -> dict[str, Tensor]``: scalar losses, must hold
            ``"total"`` (the one minimised); every key is logged. ``module`` is the bare module
            (not the DDP wrapper): call any of its methods.
        needs: earlier stages whose trained modules this stage uses (frozen), by name.
    """

    name: str
    build: Callable[[dict, StageContext], torch.nn.Module]
    batches: Callable[[dict, StageContext, np.random.Generator], Iterator[dict]]
    loss: Callable[[torch.nn.Module, dict, StageContext], dict[str, torch.Tensor]]
    needs: tuple[str, ...] = ()
