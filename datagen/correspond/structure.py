"""What a skeleton says about each bone, beside its name: features for structure-aware matching.

For one skeleton with K bones (canonical names, ``parents``, rest ``keypoints``), every bone gets:

- ``side`` (K,) in {-1, 0, +1}: right, centre, left. From the names' ``left``/``right``; only
  when no name of the skeleton has a side, from the rest position (|x| above
  :data:`SIDE_THRESHOLD` of the skeleton's size in the normalised frame below). An asymmetric
  model's neck a little off the middle stays a centre bone.
- ``position`` (K, 3): the rest position in a **normalised body frame**: origin at the keypoints'
  mean, divided by their median distance from it; x to the character's left (the mean of the
  left-named bones minus the right-named ones, made horizontal; +X when no bone has a side),
  z along the **body axis** (towards the head, made perpendicular to x), y = z cross x.
  A humanoid's head is up (+Y) and a quadruped's is forward (+Z): both end up along +z, with
  the back towards +y and the belly towards -y, so an upright and a horizontal body compare.
- ``axial`` (K,): where along the body axis the bone *attaches*: the head is 1, the keypoints'
  mean 0, tails are negative. A centre bone's own z divided by the head's z; a limb bone (sided)
  carries its limb's base, so an arm's hand has its shoulder's value: arms, front legs, wings and
  pectoral fins attach high, legs, hind legs and pelvic fins low.
- ``along`` (K,): position along its limb, 0 at the limb's base (the first sided bone below a
  centre bone) to 1 at its farthest bone, measured in bone length (hops without keypoints), so
  twist bones and short connectors do not shift it; 0 for centre bones.
- ``chain_hop`` (K,): a centre bone's hops from the first bone of its body part (the root for
  the trunk, the first neck bone, the tail's base), divided by :data:`HOP_SCALE`, so the n-th
  spine bone meets the n-th spine bone whatever the chain lengths (0 for limb bones);
  ``limb_hop`` (K,): a limb bone's hops from its limb's base, divided likewise (0 for centre
  bones); a bone hanging from a twist or roll bone (:data:`HELPER_WORDS`) counts in that bone's
  segment, so MMD's elbow below the arm's twist bone is still the second segment.
- ``pelvis`` (K,): 1 for the first bone on the way from the root to the head that a limb hangs
  from (a humanoid's hips, Rigify's ``spine``, a horse's ``Back``, an insect's thorax), else 0:
  the bone a ground-level root or a ``Spine`` above the hips must not be mistaken for.
- ``part`` (K, 4): one-hot trunk / neck / head / tail of the centre bones (see :func:`_body_parts`).
- ``depth`` (K,): hops from the skeleton's root divided by the deepest bone's hops.
- ``seq_id``, ``seq_pos`` (K,): the sequences matched in order (:mod:`.methods`): the trunk (id
  0, pelvis to below the neck, position its arc length from the pelvis over the pelvis-to-head
  length) and each limb's main path (id base + 1, base to farthest bone, position its rank); -1
  for other bones.
- ``chain`` (K,): the chain kind and side (:func:`chain_kinds`); ``name_key`` (K,): a code of the
  canonical name after :data:`NAME_SYNONYMS` (:func:`name_keys`).

Trees apart from the largest (IK targets, an IK foot kept as its own root) are first hung from the
main-tree bone nearest their root's head (:func:`_attach_detached`).

The head is the shallowest centre bone whose name has the word ``head``; without one, the centre
bone farthest along y + z from the mean (a head is up or forward in the dataset frame).
Without keypoints, positions and axial values are zero and only names and parents speak.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SIDE_THRESHOLD = 0.08  # |x| / size beyond which an unnamed bone counts as sided
HOP_SCALE = 4.0
HELPER_WORDS = {"twist", "roll"}
HEAD_LIMB_WORDS = {"ear", "antenna", "horn", "antler"}  # limbs of the head wherever they hang
IK_WORDS = {"ik", "pole", "target"}  # IK helpers: no limb of the body  # helper bones inside a limb segment (MMD's 腕捩 is "arm twist")


@dataclass
class SkeletonFeatures:
    """Per-bone structure features of one skeleton (all float32; see the module docstring)."""

    side: np.ndarray      # (K,)
    axial: np.ndarray     # (K,)
    along: np.ndarray     # (K,)
    chain_hop: np.ndarray  # (K,)
    pelvis: np.ndarray    # (K,)
    limb_hop: np.ndarray  # (K,)
    part: np.ndarray      # (K, 4)
    depth: np.ndarray     # (K,)
    position: np.ndarray  # (K, 3)
    seq_id: np.ndarray    # (K,) sequence: 0 the trunk, b + 1 the main path of the limb based at b, -1 none
    seq_pos: np.ndarray   # (K,) position in it: trunk arc length pelvis (0) to head (1); limb path rank
    chain: np.ndarray     # (K,) chain kind code (:func:`chain_kinds`)
    name_key: np.ndarray  # (K,) name class code (:func:`name_keys`)

    def matrix(self) -> np.ndarray:
        """(K, 19) columns side, limb_axial, centre_axial, along, chain_hop, limb_hop, pelvis, trunk, neck,
        head, tail, depth, x, y, z (``axial`` split into limb and centre bones, weighted apart), then
        ``seq_id``, ``seq_pos`` and the two codes ``chain`` and ``name_key`` (compared for equality,
        never subtracted): these four are read by :func:`mimicbench.datagen.correspond.batched.chain_scores` and
        :func:`mimicbench.datagen.correspond.batched.chain_hungarian_pairs`."""
        limb = self.side != 0
        return np.column_stack([self.side, np.where(limb, self.axial, 0), np.where(limb, 0, self.axial), self.along,
                                self.chain_hop, self.limb_hop, self.pelvis, self.part, self.depth,
                                self.position, self.seq_id, self.seq_pos, self.chain,
                                self.name_key]).astype(np.float32)


# Canonical names that name the same bone (deliver: the no-match rule never drops these): the body
# root, the upper spine. ``foot``/``ankle`` and ``hips``/``pelvis`` are one word already (canonical).
NAME_SYNONYMS = {"pelvis": "hips", "body": "hips", "upper spine": "chest", "upper chest": "chest"}
# Chain kinds: the trunk (root to head, neck included), the head's bones, the tail (every other centre
# bone), limbs attached fore (arms, front legs, wings), in the middle (an insect's middle legs), hind
# (legs, hind legs), on the head (ears, antennae). A limb's kind is read from where its base attaches
# along the body axis (``axial`` of its base: >= 1.25 on the head, >= 0.75 fore, <= 0.25 hind).
CHAIN_KINDS = ("trunk", "head", "tail", "fore", "mid", "hind", "head limb")


def name_keys(canonical: list[str]) -> np.ndarray:
    """(K,) float32 code of each canonical name after :data:`NAME_SYNONYMS` (equal codes: equal names).

    A CRC-32 of the name's text cut to 20 bits, so that float32 holds it exactly.
    """
    import zlib

    def key(t: str) -> int:
        sided = t.split(" ", 1)
        if sided[0] in ("left", "right") and len(sided) > 1:
            return zlib.crc32(f"{sided[0]} {NAME_SYNONYMS.get(sided[1], sided[1])}".encode()) & 0xFFFFF
        return zlib.crc32(NAME_SYNONYMS.get(t, t).encode()) & 0xFFFFF

    return np.array([key(t) for t in canonical], np.float32)


def chain_kinds(side: np.ndarray, part: np.ndarray, limb_axial: np.ndarray | None) -> np.ndarray:
    """(K,) float32 code ``3 * kind + side + 1`` of every bone (kinds in :data:`CHAIN_KINDS`).

    Centre bones take their body part (trunk and neck are one chain); sided bones their limb's kind
    from ``limb_axial`` (K,) (the limb base's attachment), or ``fore`` for every limb without it.
    """
    kind = np.where(part[:, 2] > 0, 1, np.where(part[:, 3] > 0, 2, 0))
    if limb_axial is None:
        limb = np.full(len(side), 3)
    else:
        limb = np.select([limb_axial >= 1.25, limb_axial >= 0.75, limb_axial <= 0.25], [6, 3, 5], 4)
    kind = np.where(side != 0, limb, kind)
    return (3 * kind + side + 1).astype(np.float32)


def _attach_detached(parents: np.ndarray, main: np.ndarray, kp: np.ndarray | None) -> np.ndarray:
    """Parents (K,) with each root outside the main tree hung from the main-tree bone nearest its head.

    IK targets and an IK foot kept as a root of its own (a Quaternius mech's ``Foot.L``, a horse's
    ``IKBackLeg.L``) then continue the limb they sit at; a root at the very head of that bone becomes
    its sibling (the mech's ``Foot.L``, which skins the foot, beside its ``FootBack.L``, a claw);
    without keypoints they hang from the main root.
    """
    out = parents.copy()
    pool = np.flatnonzero(main)
    if len(pool) == 0 or main.all():
        return out
    main_root = int(pool[parents[pool] < 0][0])
    for r in np.flatnonzero((parents < 0) & ~main):
        if kp is None:
            out[r] = main_root
            continue
        gap = np.linalg.norm(kp[pool] - kp[r], axis=1)
        near = int(pool[np.argmin(gap)])
        # at the very head of that bone (an IK foot where the leg's last bone starts): its sibling
        out[r] = parents[near] if gap.min() < 1e-6 * max(float(np.ptp(kp[pool], axis=0).max()), 1e-9) \
            and parents[near] >= 0 else near
    return out


def _name_sides(canonical: list[str]) -> np.ndarray:
    first = [t.split(" ", 1)[0] for t in canonical]
    return np.array([1.0 if w == "left" else -1.0 if w == "right" else 0.0 for w in first])


def _hop_depths(parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K,) hops from each bone's root and (K,) that root's index; any bone order, cycles rejected."""
    k = len(parents)
    depth = np.full(k, -1, np.int64)
    root = np.full(k, -1, np.int64)
    for start in range(k):
        path, j = [], start
        while j >= 0 and depth[j] < 0:
            path.append(j)
            if len(path) > k:
                raise ValueError("parents: expected a forest, found a cycle")
            j = int(parents[j])
        d, r = (depth[j], root[j]) if j >= 0 else (-1, path[-1])
        for n in reversed(path):
            d += 1
            depth[n], root[n] = d, r
    return depth, root


def _named_head(canonical: list[str], side: np.ndarray, main: np.ndarray) -> int | None:
    """The first centre bone of the main tree whose name has the word ``head``, or None."""
    heads = [i for i, t in enumerate(canonical) if side[i] == 0 and "head" in t.split() and main[i]]
    return heads[0] if heads else None


def _root_path(parents, head) -> list[int]:
    """Bones from the root down to the head (empty without a head)."""
    path, j = [], head if head is not None else -1
    while j >= 0:
        path.append(j)
        j = int(parents[j])
    return path[::-1]


def _body_parts(canonical, parents, side, main, head) -> np.ndarray:
    """(K, 4) one-hot trunk / neck / head / tail of the centre bones of the main tree; limbs 0.

    Trunk: the path from the root to the head (``neck`` when the name says so); head: the head
    and the centre bones below it (jaw, beak); tail: every other centre bone (tails, an insect's
    abdomen, a snake's body behind its head, fins on the back). Without a head all centre bones
    are trunk.
    """
    k = len(parents)
    out = np.zeros((k, 4), np.float32)
    path = set()
    j = head if head is not None else -1
    while j >= 0:
        path.add(j)
        j = int(parents[j])
    for i in range(k):
        if side[i] != 0 or not main[i]:
            continue
        j, below_head = i, False
        while j >= 0 and not below_head:
            below_head = j == head
            j = int(parents[j])
        if head is None or (i in path and i != head):
            out[i, 1 if "neck" in canonical[i].split() else 0] = 1.0
        elif below_head:
            out[i, 2] = 1.0
        else:
            out[i, 3] = 1.0
    return out


def _frame(kp: np.ndarray, side: np.ndarray, head: int | None, main: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Rotation rows (3, 3) x, y, z of the body frame, the origin (3,) and the head's index."""
    centre = kp[main].mean(0)
    left, right = kp[side > 0], kp[side < 0]
    lateral = np.array([1.0, 0.0, 0.0])
    if len(left) and len(right):
        guess = left.mean(0) - right.mean(0)
        guess[1] = 0.0
        if np.linalg.norm(guess) > 1e-6:
            lateral = guess / np.linalg.norm(guess)
    if head is None:
        pool = np.flatnonzero((side == 0) & main)
        pool = pool if len(pool) else np.flatnonzero(main)
        head = int(pool[np.argmax((kp[pool] - centre) @ np.array([0.0, 1.0, 1.0]))])
    axis = kp[head] - centre
    axis = axis - (axis @ lateral) * lateral
    if np.linalg.norm(axis) < 1e-9:
        axis = np.array([0.0, 0.0, 1.0]) - lateral[2] * lateral
    z = axis / np.linalg.norm(axis)
    y = np.cross(z, lateral)
    return np.stack([lateral, y, z]), centre, head


def _connector_limbs(base, parents, side, position) -> np.ndarray:
    """(K,) 1 for a limb base that is a connector, so that its limb counts segments from the next bone.

    A connector runs from near the midline out to the limb's socket (a clavicle, a hip bone, the
    short ``BackShoulder`` of a Quaternius horse, BVH's ``LHipJoint``): its head's |x| is under
    0.7 of the next bone's and it runs at least half as much sideways as up, down or forward. A
    limb base much shorter than the next bone (under a quarter) counts as one too. Then a
    clavicle-arm-forearm chain meets a upper-leg-lower-leg chain at the upper arm.
    """
    k = len(base)
    out = np.zeros(k)
    for b in np.flatnonzero((base == np.arange(k)) & (side != 0)):
        kids = [c for c in np.flatnonzero(parents == b) if base[c] == b]
        if not kids:
            continue
        c = max(kids, key=lambda j: abs(position[j, 0]))
        step = position[c] - position[b]
        grandkids = [g for g in np.flatnonzero(parents == c) if base[g] == b]
        next_len = max((np.linalg.norm(position[g] - position[c]) for g in grandkids), default=0.0)
        lateral = abs(step[0]) >= 0.5 * np.linalg.norm(step[1:])
        inner = abs(position[b, 0]) < 0.7 * abs(position[c, 0])
        tiny = np.linalg.norm(step) < 0.25 * next_len
        out[b] = float((lateral and inner) or tiny)
    return out


def _arc_fraction(base, parents, order, kp) -> np.ndarray:
    """(K,) length along the limb from its base's head to the bone's head over the limb's reach.

    Bone lengths are the distances between a joint and its parent's; the reach is the longest
    such path in the limb. Extra short bones (twist bones, a hip connector) barely move a bone's
    fraction, where counting hops would shift it a whole step.
    """
    k = len(base)
    dist = np.zeros(k)
    for i in order:  # parents before children
        p = parents[i]
        if p >= 0 and base[i] == base[p] and i != base[i]:
            dist[i] = dist[p] + float(np.linalg.norm(kp[i] - kp[p]))
    reach = np.zeros(k)
    np.maximum.at(reach, base, dist)
    return np.where(reach[base] > 1e-9, dist / np.maximum(reach[base], 1e-9), 0.0)


def _limb_paths(base, parents, side, along, hops, canonical) -> tuple[np.ndarray, np.ndarray]:
    """(K,) sequence ids (base + 1 on a limb's main path, else -1) and (K,) ranks on that path / its length.

    A limb's main path runs from its base to its farthest bone (largest ``along``, then deepest,
    then the plainest name, fewest words: ``foot`` before ``foot back`` at the same place): an
    arm's shoulder to hand to middle finger tip; the other fingers are branches, left out.
    """
    k = len(base)
    seq_id, seq_pos = np.full(k, -1.0), np.zeros(k)
    plain = -np.array([len(t.split()) for t in canonical], float)
    for b in np.flatnonzero((base == np.arange(k)) & (side != 0)):
        members = np.flatnonzero((base == b) & (side != 0))
        leaf = int(members[np.lexsort((plain[members], hops[members], along[members]))[-1]])
        path, j = [], leaf
        while j >= 0 and base[j] == b:
            path.append(j)
            if j == b:
                break
            j = int(parents[j])
        path = path[::-1]
        seq_id[path] = b + 1
        seq_pos[path] = np.arange(len(path)) / max(len(path), 1)
    return seq_id, seq_pos


def _limb_attachment(base, side, parents, main, head, position, reach, canonical=None) -> np.ndarray:
    """(K,) per limb base: 0 at the rearmost limb's attachment, 1 at the foremost, 1.5 on the head.

    Extremes come from the limbs of two or more bones in the main tree that do not hang from the
    head (or from all such limbs when those do not spread); ears and antennae get 1.5, also when
    they hang from a neck bone beside the head (a Quaternius wolf's) as their names say
    (:data:`HEAD_LIMB_WORDS`). Limbs of IK helpers (:data:`IK_WORDS`: an MMD leg's IK parent at
    the ground, pole targets) do not set the extremes.
    """
    k = len(base)
    words = [set(t.split()) for t in canonical] if canonical is not None else [set()] * k
    named_head = np.array([bool(HEAD_LIMB_WORDS & w) for w in words])  # by the limb base's own name
    helper = np.array([bool(IK_WORDS & w) for w in words])
    on_head = np.zeros(k, bool)
    for i in range(k):  # walk up to the root: does the limb hang below the head?
        j = int(parents[i])
        while j >= 0 and not on_head[i]:
            on_head[i] = j == head
            j = int(parents[j])
    on_head |= named_head
    starts = np.flatnonzero((base == np.arange(k)) & (side != 0) & main & ~on_head)
    z = position[:, 2]
    pool = starts[(reach[starts] >= 1) & ~helper[starts]]
    if len(pool) == 0 or np.ptp(z[pool]) < 0.05:
        pool = starts
    out = np.full(k, 1.5)
    if len(pool) and np.ptp(z[pool]) >= 0.05:
        out[starts] = np.clip((z[starts] - z[pool].min()) / np.ptp(z[pool]), -0.5, 1.5)
    elif len(pool):  # one pair of limbs: fore when in front of the middle
        out[starts] = (z[starts] > 0).astype(float)
    out[~main & (base == np.arange(k))] = 0.5
    return out


def skeleton_features(canonical: list[str], parents, keypoints=None) -> SkeletonFeatures:
    """Structure features of one skeleton.

    Args:
        canonical: K canonical names (:func:`mimicbench.datagen.correspond.canonical.canonicalize_names`).
        parents: (K,) int parent indices, -1 for roots, in any order.
        keypoints: (K, 3) rest joint positions (any unit), or None.
    """
    parents = np.asarray(parents, np.int64)
    k = len(parents)
    if len(canonical) != k:
        raise ValueError(f"canonical, parents: expected equal lengths, got {len(canonical)} and {k}")
    if k and (parents.max() >= k or parents.min() < -1):
        raise ValueError(f"parents: expected indices in [-1, {k - 1}], got {parents.min()}..{parents.max()}")
    hops, root = _hop_depths(parents)
    sizes = np.bincount(root, minlength=k)
    main = root == int(np.argmax(sizes)) if k else np.zeros(0, bool)
    if k and not main.all():  # detached trees (IK targets) join the bone they sit at
        kp0 = None if keypoints is None else np.asarray(keypoints, np.float64).reshape(k, 3)
        parents = _attach_detached(parents, main, kp0 if kp0 is not None and np.isfinite(kp0).all() else None)
        hops, root = _hop_depths(parents)
        main = np.ones(k, bool)
    side = _name_sides(canonical)
    position = np.zeros((k, 3))
    axial = np.zeros(k)
    head = _named_head(canonical, side, main)
    if keypoints is not None and k:
        kp = np.asarray(keypoints, np.float64).reshape(k, 3)
        if not np.isfinite(kp).all():
            raise ValueError("keypoints: expected finite positions")
        rot, centre, head = _frame(kp, side, head, main)
        rel = (kp - centre) @ rot.T
        scale = float(np.median(np.linalg.norm(rel[main], axis=1)))
        if scale > 1e-9:
            position = rel / scale
            if not side.any():  # no name says a side: read them from the rest pose
                side = np.where(np.abs(position[:, 0]) > SIDE_THRESHOLD, np.sign(position[:, 0]), 0.0)
                side[head] = 0.0
            head_z = position[head, 2]
            axial = position[:, 2] / head_z if head_z > 1e-6 else position[:, 2]
    # limbs: a sided bone under a bone of another side starts a limb
    base = np.arange(k)
    order = np.argsort(hops, kind="stable")
    for i in order:
        p = parents[i]
        if p >= 0 and side[i] != 0 and side[p] == side[i]:
            base[i] = base[p]
    helper = np.array([bool(HELPER_WORDS & set(t.split())) for t in canonical])
    limb_hops = np.zeros(k)
    for i in order:  # a bone below a twist bone counts as the twist bone's own segment
        p = parents[i]
        if p >= 0 and base[i] == base[p] and i != base[i]:
            limb_hops[i] = limb_hops[p] + (0 if helper[p] else 1)
    reach = np.zeros(k)
    np.maximum.at(reach, base, limb_hops)
    along = np.where(side != 0, limb_hops / np.maximum(reach[base], 1), 0.0)
    if keypoints is not None and k:
        along = np.where(side != 0, 0.5 * (along + _arc_fraction(base, parents, order, kp)), along)
    limb_axial = None
    if keypoints is not None and k:
        limb_axial = _limb_attachment(base, side, parents, main, head, position, reach, canonical)[base]
        axial = np.where(side != 0, limb_axial, axial)
    if keypoints is not None and k:
        connector = _connector_limbs(base, parents, side, position)
        mirror = {t: i for i, t in enumerate(canonical) if base[i] == i and side[i] != 0}
        for b, t in enumerate(canonical):  # a limb is a connector when its mirror image is (asymmetric rests)
            other = mirror.get(t.replace("left", "\0").replace("right", "left").replace("\0", "right"))
            if base[b] == b and other is not None and connector[other]:
                connector[b] = 1.0
        limb_hops = limb_hops - connector[base]
    limb_hop = np.where(side != 0, limb_hops, 0) / HOP_SCALE
    part = _body_parts(canonical, parents, side, main, head)
    chain_hop = np.zeros(k)
    for i in order:  # hops from the first bone of the same body part (the root for the trunk)
        p = parents[i]
        if p >= 0 and side[i] == 0 and side[p] == 0 and part[i].any() and (part[p] == part[i]).all():
            chain_hop[i] = chain_hop[p] + 1
    chain_hop /= HOP_SCALE
    pelvis = np.zeros(k)
    path = _root_path(parents, head)
    limb_parents = {int(parents[i]) for i in range(k) if side[i] != 0 and base[i] == i and parents[i] >= 0}
    body_limbs = {int(parents[i]) for i in range(k) if side[i] != 0 and base[i] == i and parents[i] >= 0
                  and reach[i] >= 1 and not IK_WORDS & set(canonical[i].split())}
    first = next((j for j in path if j in (body_limbs or limb_parents)), None)
    if first is not None and first == path[0] and len(path) > 1 and keypoints is not None:
        # a ground-level root that the legs hang from (a Quaternius soldier's Root): the pelvis is the
        # next bone up when the legs' heads are three times nearer that bone's head than the root's
        kids = [i for i in range(k) if parents[i] == first and side[i] != 0]
        legs = position[kids].mean(0)
        if 3 * np.linalg.norm(legs - position[path[1]]) < np.linalg.norm(legs - position[first]):
            first = path[1]
    if first is not None:
        pelvis[first] = 1.0
    seq_id, seq_pos = _limb_paths(base, parents, side, along, hops, canonical)
    trunk_arc = np.full(k, -1.0)
    if first is not None and keypoints is not None and first != head:
        run = path[path.index(first):]  # pelvis .. head
        steps = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(kp[run], axis=0), axis=1))]
        if steps[-1] > 1e-9:
            trunk_arc[run] = steps / steps[-1]
        trunk_arc[(part[:, 0] == 0)] = -1.0  # the neck and the head keep their own chains
    seq_id = np.where(trunk_arc >= 0, 0.0, seq_id)
    seq_pos = np.where(trunk_arc >= 0, trunk_arc, seq_pos)
    depth = hops / max(int(hops[main].max()) if k else 1, 1)
    return SkeletonFeatures(side.astype(np.float32), np.clip(axial, -3, 3).astype(np.float32),
                            along.astype(np.float32), chain_hop.astype(np.float32), pelvis.astype(np.float32),
                            limb_hop.astype(np.float32), part, np.clip(depth, 0, 2).astype(np.float32),
                            np.clip(position, -5, 5).astype(np.float32), seq_id.astype(np.float32),
                            seq_pos.astype(np.float32),
                            chain_kinds(side, part, limb_axial), name_keys(canonical))
