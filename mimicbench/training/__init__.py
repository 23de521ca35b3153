"""The one trainer: stages of a trainable model, a registry by name, the training loop, checkpoints.

A trainable model (the MimiCAT reference, the MMDMC reference) is a list of
:class:`~mimicbench.training.stage.TrainStage` registered with
:func:`~mimicbench.training.registry.register_trainable`; :func:`~mimicbench.training.loop.train_stage`
trains one stage (AdamW, seeds, DDP under ``torchrun``, progress bar, checkpoints that resume,
loss.csv and loss.png); ``mimicbench train`` is its command line.
"""
from mimicbench.training.stage import StageContext, TrainStage  # noqa: F401
