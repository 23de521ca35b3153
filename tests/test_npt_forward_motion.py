"""analyses/npt_forward_motion.py: how far an npt/cgt forward answer moves the target, checked on
two stand-in models whose answers are known by hand."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import torch

_spec = importlib.util.spec_from_file_location(
    "npt_forward_motion", Path(__file__).resolve().parents[1] / "analyses" / "npt_forward_motion.py")
forward_motion = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(forward_motion)


class RestModel:
    """Answers the identity mesh unchanged (``identity``'s rule), seeing every pose vertex."""

    def pose_rows(self, count: int) -> np.ndarray:
        return np.arange(count)

    def _answer(self, pose: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        return identity.clone()


class ShiftModel(RestModel):
    """Answers the identity mesh with every vertex moved by ``offset`` along x, whatever the pose."""

    offset = 0.01

    def _answer(self, pose, identity):
        out = identity.clone()
        out[..., 0] += self.offset
        return out


def pair():
    """(A rest, A posed, B rest): A a unit box's 8 corners, posed by moving two of them 0.1 along z; B
    a 2 x 1 x 1 box."""
    a_rest = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float32)
    a_posed = a_rest.copy()
    a_posed[:2, 2] += 0.1
    b_rest = a_rest * np.array([2, 1, 1], np.float32)
    return a_rest, a_posed, b_rest


def test_a_model_that_answers_the_rest_mesh_moves_the_target_by_nothing():
    from mimicbench.baselines.npt.placement import centred

    a_rest, a_posed, b_rest = pair()
    r = forward_motion.measure(RestModel(), [(a_rest, a_posed, b_rest)])
    # by hand: the source moves in its centred unit-size frame (box centre and size 1 of the rest mesh)
    source = np.linalg.norm(centred(a_posed, a_rest) - centred(a_rest, a_rest), axis=1).mean()
    assert source > 0.01
    assert r["forward"] == 0.0 and r["ratio"] == 0.0 and r["null"] == 0.0
    # a self-transfer answers the rest mesh, so its error is the source's own motion, x100
    assert np.isclose(r["self"], 100 * source, rtol=1e-6)
    assert np.isclose(r["source"], source, rtol=1e-6)


def test_a_constant_shift_is_measured_as_that_shift():
    a_rest, a_posed, b_rest = pair()
    r = forward_motion.measure(ShiftModel(), [(a_rest, a_posed, b_rest)])
    assert np.isclose(r["forward"], ShiftModel.offset, rtol=1e-5)
    assert np.isclose(r["ratio"], ShiftModel.offset / r["source"], rtol=1e-5)
    # the null cycle: the way back re-centres B' (the shift is gone) and shifts A's rest mesh once
    assert np.isclose(r["null"], 100 * ShiftModel.offset, rtol=1e-5)
