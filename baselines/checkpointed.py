"""A pose-transfer method whose weights are one trained stage: shipped beside it, or a training run.

The base of ``npt``, ``cgt`` and ``sfpt``. A subclass names its ``stage`` (the trainable and the
weights' file name), the environment variable ``env`` that points at a training run, and the
``shipped`` folder; the weights are ``shipped/<stage>.safetensors`` or ``RUN/<stage>/model.safetensors``
(:func:`mimicbench.training.checkpoint.stage_weights`).
"""
from __future__ import annotations

import os
from pathlib import Path

from mimicbench.benchmark.method import PoseTransferMethod


def checkpoint_path(folder: Path, stage: str) -> Path:
    """The weights of ``stage`` (``npt``, ``cgt``, ``sfpt``) in a checkpoint folder (shipped or run layout)."""
    from mimicbench.training.checkpoint import stage_weights

    return stage_weights(folder, stage, stage)


class CheckpointedMethod(PoseTransferMethod):
    """Loads the network of trainable ``stage`` from ``checkpoint`` (or ``$env``, or ``shipped``)."""

    stage: str
    env: str
    shipped: Path

    def __init__(self, checkpoint: str | os.PathLike | None = None):
        self.checkpoint = Path(checkpoint or os.environ.get(self.env) or self.shipped)
        self.device = "cpu"
        self.module = None
        self.config: dict = {}

    def weights_fingerprint(self) -> str:
        from mimicbench.schemas.fingerprint import files_fingerprint

        return files_fingerprint({self.stage: self.weights_path()})

    def weights_path(self) -> Path:
        """The weights file this method loads (:func:`checkpoint_path` of ``stage``)."""
        return checkpoint_path(self.checkpoint, self.stage)

    def setup(self, device: str = "cpu") -> None:
        """Build the stage's network from the checkpoint's config (``self.config``) and load its weights."""
        from mimicbench.training.checkpoint import load_module, read_header
        from mimicbench.training.registry import trainable

        self.device = device
        stage = trainable(self.stage).stage(self.stage)
        path = self.weights_path()
        self.module = load_module(path, lambda cfg: stage.build(cfg, None), device)
        self.config = read_header(path)["config"]
