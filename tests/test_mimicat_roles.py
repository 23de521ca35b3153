"""analyses/mimicat_roles.py's role-class accuracy and match decoding, against hand-counted cases."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

_spec = importlib.util.spec_from_file_location("mimicat_roles",
                                               Path(__file__).resolve().parents[1] / "analyses" / "mimicat_roles.py")
roles = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(roles)


def test_role_accuracy_by_hand():
    source = ["root", "left/forelimb", "right/forelimb", "tail", None]
    target = ["root", "right/forelimb", "left/forelimb", "head", None, "left/forelimb"]
    # target 0 -> source 0 (right), 1 -> 2 (right), 2 -> 1 (right), 3: head, not a source class (not
    # scored), 4: unlabelled (not scored), 5 -> none (wrong)
    match = np.array([0, 2, 1, 3, 4, -1])
    scored, right = roles.role_accuracy(match, source, target)
    assert scored.tolist() == [0, 1, 2, 5] and right.tolist() == [True, True, True, False]
    mirrored = np.array([0, 1, 2, 3, 4, 2])  # left and right swapped, the last to the other side too
    assert roles.role_accuracy(mirrored, source, target)[1].tolist() == [True, False, False, False]


def test_matches_from_pairs_and_assignments():
    assert roles.match_from_pairs(np.array([[2, 0], [0, 2]]), 4).tolist() == [2, -1, 0, -1]
    m = np.zeros((3, 4))
    m[1, 0] = m[2, 3] = 1
    assert roles.match_from_m(m).tolist() == [1, -1, -1, 2]
