"""G's one-to-one decoding restricted to pairs of bones the mesh determines on both sides or on
neither (baselines/mimicat/transfer.py: determined_pairs, decode_correspondence(allowed=...)),
against hand-solved assignments."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.mimicat.transfer import decode_correspondence, determined_pairs

# source bones: A (owns vertices), B (an IK target without skin weight), C (owns vertices)
# target bones: X, Y (own vertices), Z (a control bone without skin weight)
DET_SRC = np.array([True, False, True])
DET_TGT = np.array([True, True, False])
SCORES = torch.tensor([[0.9, 0.1, 0.0],
                       [0.1, 0.8, 0.0],
                       [0.3, 0.4, 0.0]], dtype=torch.float64)


def test_allowed_pairs_are_determined_with_determined_and_undetermined_with_undetermined():
    expected = np.array([[1, 1, 0],
                         [0, 0, 1],
                         [1, 1, 0]], bool)
    assert np.array_equal(determined_pairs(DET_SRC, DET_TGT), expected)


def test_the_assignment_routes_around_a_bone_without_skin_weight():
    # unrestricted, the best assignment (by hand: A-X 0.9 + B-Y 0.8 + C-Z 0.0 = 1.7) hands Y the
    # IK target's rotation
    free = decode_correspondence(SCORES, "hungarian").numpy()
    assert np.array_equal(free, [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    # restricted: A-X 0.9 + C-Y 0.4 + B-Z 0.0 = 1.3 is the best over the allowed pairs
    restricted = decode_correspondence(SCORES, "hungarian", allowed=determined_pairs(DET_SRC, DET_TGT)).numpy()
    assert np.array_equal(restricted, [[1, 0, 0], [0, 0, 1], [0, 1, 0]])


def test_a_bone_with_no_allowed_partner_left_stays_unmatched():
    # only B is undetermined on the source side, and the target has no undetermined bone
    allowed = determined_pairs(DET_SRC, np.array([True, True, True]))
    out = decode_correspondence(SCORES, "hungarian", allowed=allowed).numpy()
    assert np.array_equal(out, [[1, 0, 0], [0, 0, 0], [0, 1, 0]])


def test_the_symmetric_decoding_stays_one_assignment_of_the_pair():
    rng = np.random.default_rng(3)
    m, m_rev = torch.tensor(rng.random((5, 4))), torch.tensor(rng.random((4, 5)))
    det_s, det_t = np.array([1, 0, 1, 1, 0], bool), np.array([1, 1, 0, 1], bool)
    forward = decode_correspondence(m, "hungarian_sym", m_rev, determined_pairs(det_s, det_t)).numpy()
    backward = decode_correspondence(m_rev, "hungarian_sym", m, determined_pairs(det_t, det_s)).numpy()
    assert np.array_equal(forward, backward.T)
    assert forward[~determined_pairs(det_s, det_t)].sum() == 0


def test_a_mask_of_the_wrong_shape_is_refused():
    with pytest.raises(ValueError, match="allowed: expected shape"):
        decode_correspondence(SCORES, "hungarian", allowed=np.ones((2, 3), bool))
