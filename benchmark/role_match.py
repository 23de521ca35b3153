"""Match two skeletons' bones through their hidden roles (ground truth, never a method input).

Used by the cross-skeleton ``h2h_xskel`` protocol to carry a pose over as its ground truth, and by the
validity probes (:mod:`mimicbench.baselines.probes`), which read the roles to corrupt a right transfer in a
known way.

A target bone's match is the source bone with the same role (``left/upper_arm``; a role that may
label many bones, such as a role-label file's ``left/forelimb``, is not matched this way); failing that, a
source bone of the same role class (``left/forelimb``, :func:`mimicbench.benchmark.semantic.character_role_classes`)
at the nearest position along the class by skin-weight mass (:func:`class_mass_position`), the bone
with the most skin weight winning a tie; failing that, none (-1).
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.roles.vocabulary import is_class_role


def bone_mass(rig) -> np.ndarray:
    """(K,) each bone's total skin weight over the rest mesh (``rig``: anything with ``weights``, a
    :class:`mimicbench.schemas.weights.SparseWeights`, and ``parents``)."""
    w = rig.weights
    out = np.zeros(len(rig.parents))
    np.add.at(out, np.asarray(w.indices).ravel(), np.asarray(w.values, np.float64).ravel())
    return out


def class_depths(classes: list, parents) -> np.ndarray:
    """(K,) each labelled bone's depth along its class (how many of its ancestors share its class);
    NaN when unlabelled."""
    parents = np.asarray(parents)
    depth = np.full(len(parents), np.nan)
    for k, cls in enumerate(classes):
        if cls is None:
            continue
        d, p = 0, parents[k]
        while p >= 0:
            d += classes[p] == cls
            p = parents[p]
        depth[k] = d
    return depth


def class_mass_position(classes: list, parents, mass) -> np.ndarray:
    """(K,) where each labelled bone lies along its class, in [0, 1], by skin-weight mass: the mass of
    the class's shallower depths plus half the mass of the bone's own depth, over the class's mass
    (depth by depth when the class has no mass). A humanoid's small clavicle sits near 0 and its
    upper arm near 0.3, as a dog's upper foreleg does; NaN when unlabelled."""
    depth = class_depths(classes, parents)
    mass = np.asarray(mass, np.float64)
    out = np.full(len(depth), np.nan)
    for cls in {c for c in classes if c is not None}:
        members = np.array([c == cls for c in classes])
        levels = np.arange(int(np.nanmax(depth[members])) + 1)
        level_mass = np.array([mass[members & (depth == d)].sum() for d in levels])
        if level_mass.sum() <= 0:
            level_mass = np.ones(len(levels))
        before = np.concatenate([[0.0], np.cumsum(level_mass)[:-1]])
        position = (before + 0.5 * level_mass) / level_mass.sum()
        out[members] = position[depth[members].astype(int)]
    return out


def match_by_role(source_roles: list, source_classes: list, source_parents, source_mass,
                  target_roles: list, target_classes: list, target_parents, target_mass,
                  class_map=None) -> np.ndarray:
    """(Kt,) int: each target bone's source bone, or -1 (see the module docstring).

    Args:
        source_roles, target_roles: K role strings (None or "" for an unlabelled bone); exact role
            matches are only used when ``class_map`` is None.
        source_classes, target_classes: K role classes (None for an unlabelled bone).
        source_parents, target_parents: (K,) parents, -1 for roots.
        source_mass, target_mass: (K,) each bone's total skin weight (:func:`bone_mass`): where a
            bone lies along its class (:func:`class_mass_position`), and the source's breaks ties.
        class_map: optional function target class -> the source class that drives it (a
            corruption such as left <-> right); None keeps classes.
    """
    by_role = {}
    if class_map is None:
        for i, r in enumerate(source_roles):
            if r and not is_class_role(r) and r not in by_role:
                by_role[r] = i
    mass = np.asarray(source_mass, np.float64)
    s_frac = class_mass_position(source_classes, source_parents, mass)
    t_frac = class_mass_position(target_classes, target_parents, target_mass)
    out = np.full(len(target_classes), -1)
    for j, cls in enumerate(target_classes):
        if cls is None:
            continue
        if class_map is None and target_roles[j] and target_roles[j] in by_role:
            out[j] = by_role[target_roles[j]]
            continue
        want = cls if class_map is None else class_map(cls)
        cands = np.array([i for i, c in enumerate(source_classes) if c == want])
        if len(cands) == 0:
            continue
        gap = np.abs(s_frac[cands] - t_frac[j])
        best = cands[gap <= gap.min() + 1e-9]
        out[j] = int(best[np.argmax(mass[best])])
    return out
