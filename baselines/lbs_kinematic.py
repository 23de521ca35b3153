"""``lbs_kinematic``: the apparel follows its bones' kinematic clip (what LBS-only methods do).

For a motion request it poses the rest mesh by linear blend skinning with the window's
transforms as given: body bones exact, apparel bones as the clip keys them, no physics. Its
PMD_b is 0 wherever body vertices are weighted to body bones only; its PMD_a is what ignoring
the apparel's dynamics costs.
"""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.geometry.skinning import linear_blend_skinning


class LbsKinematic(PoseTransferMethod):
    metadata = MethodMetadata(name="lbs_kinematic", version="1", licence="MIT", protocols=("apparel",),
                              description="LBS with the kinematic clip: apparel moves rigidly with its bones")

    def transfer(self, requests):
        raise NotImplementedError("lbs_kinematic answers motion requests only (the apparel protocol)")

    def transfer_motion(self, requests):
        """(F, N, 3) float32 per request: LBS of the rest mesh with ``request.transforms``."""
        return [linear_blend_skinning(r.target.vertices, r.target.keypoints, r.target.weights,
                                      np.asarray(r.transforms, np.float32)) for r in requests]
