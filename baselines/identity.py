"""``identity``: the target at rest, whatever the source does (the floor of the leaderboard)."""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod


class Identity(PoseTransferMethod):
    metadata = MethodMetadata(name="identity", version="1", licence="MIT", reads_rig=False,
                              description="returns the target's rest mesh")

    def transfer(self, requests):
        return [np.array(r.target.vertices, dtype=np.float32) for r in requests]
