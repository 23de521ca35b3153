"""``probe_apparel_jitter``: a good apparel transfer with frame-to-frame noise on its apparel.

A probe of the ``apparel`` protocol's scores (not a method to rank): it runs ``lbs_kinematic``
(the apparel follows its bones) and adds independent Gaussian noise to every apparel vertex in
every frame, :data:`NOISE_MM` millimetres per axis at 1.70 m height (scaled with the character's
height). The noise leaves each frame's distance to the ground truth almost unchanged (PMD_a), but
its second differences are about ``sqrt(6) * sigma * fps^2`` per axis (3.5 m/s^2 of mean
magnitude at 30 fps for 1 mm), which ``accel_error`` must see. The apparel vertices are the
probe's own reading of the request: vertices whose skin weight on bones outside
``request.body_bones`` is above one half (it is not given the ground truth's mask). The noise is
seeded by the request's transforms, so a re-run gives the same bytes.
"""
from __future__ import annotations

import zlib

import numpy as np

from mimicbench.baselines.lbs_kinematic import LbsKinematic
from mimicbench.benchmark.method import MethodMetadata
from mimicbench.schemas.weights import as_dense

NOISE_MM = 1.0
"""Standard deviation of the noise per axis, millimetres of the character scaled to 1.70 m."""
REFERENCE_HEIGHT_M = 1.70


def apparel_vertices(weights, body_bones: np.ndarray) -> np.ndarray:
    """(N,) bool: vertices whose skin weight on the bones not in ``body_bones`` (K,) is above one half."""
    body = np.asarray(body_bones, bool)
    return as_dense(weights, len(body))[:, ~body].sum(axis=1) > 0.5


def jitter(posed: np.ndarray, mask: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    """``posed`` (F, N, 3) with independent N(0, sigma^2) noise (metres) on each axis of the ``mask`` (N,) vertices."""
    out = np.array(posed, np.float32, copy=True)
    rng = np.random.default_rng(seed)
    out[:, mask] += rng.normal(0.0, sigma, size=(len(out), int(mask.sum()), 3)).astype(np.float32)
    return out


class ProbeApparelJitter(LbsKinematic):
    metadata = MethodMetadata(name="probe_apparel_jitter", version="1", licence="MIT", protocols=("apparel",),
                              tags=("probe", "apparel"),
                              description=f"probe: lbs_kinematic with {NOISE_MM:g} mm (at 1.70 m) of independent "
                                          f"noise per frame on its apparel vertices")
    noise_mm = NOISE_MM

    def transfer_motion(self, requests):
        """(F, N, 3) float32 per request: :class:`LbsKinematic`'s mesh with its apparel jittered."""
        out = []
        for r, posed in zip(requests, super().transfer_motion(requests)):
            v = np.asarray(r.target.vertices, np.float64)
            sigma = self.noise_mm / 1000.0 * float(np.ptp(v[:, 1])) / REFERENCE_HEIGHT_M
            seed = zlib.crc32(np.ascontiguousarray(r.transforms, np.float32).tobytes())
            out.append(jitter(posed, apparel_vertices(r.target.weights, r.body_bones), sigma, seed))
        return out
