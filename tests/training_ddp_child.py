"""Run by the trainer's torchrun test: ``torchrun --nproc-per-node 2 tests/training_ddp_child.py DATA OUT``."""
import sys

from tests import training_toys  # noqa: F401  (registers "toy")
from mimicbench.training.loop import train_model

if __name__ == "__main__":
    # both stages in one launch: the process group must survive from one stage to the next
    train_model("toy", "all", sys.argv[1], sys.argv[2], dict(training_toys.CONFIG), "cpu", epochs=1, seed=3,
                progress=False)
