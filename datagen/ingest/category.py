"""Infer a character's category from its skeleton when ``--category-map`` or a role-label file
(:mod:`mimicbench.datagen.roles`) does not give it.

Evidence comes first from the **canonical bone names** (:mod:`mimicbench.datagen.correspond.canonical`,
which undoes the naming styles: ``mixamorig:LeftUpLeg``, ``thigh.L``, ``Bip01 L Thigh`` all read
``left thigh``), grouped into limbs by side and by a front/back (or numbered) qualifier, and then
from the **rest-pose geometry** of the hierarchy (which way the body runs, whether legs go down
or out to the side, feet on the ground):

==========================================================  ===========
evidence                                                    category
==========================================================  ===========
one wing chain and one leg chain on each side, no arms      bird
six or more legs                                            insect
fins or flippers, no legs and no arms                       fish
four legs splayed out to the sides (a sprawling gait)       reptile
four legs under the body, every one reaching the ground     quadruped
two arms and two legs, body upright                         humanoid
  ... and apparel chains (hair, skirt, cape, ...)           apparel
two arms and two legs, body horizontal, the arms reaching   quadruped
the ground (Fox: forelegs named as arms)
no limb names: feet found on the ground (2 upright,         as above
4, 6+), or a flat body along one long chain or a path
through three quarters of the joints (a snake: reptile)
anything else                                               unknown
==========================================================  ===========

The rules decide only where the body plan is unambiguous; anything else is ``unknown``, since a
wrong category is worse than none (it decides which pairs become ``cct`` cases), and a
role-label file (:mod:`mimicbench.datagen.roles`) can say what a character is. So wings with anything but a
bird's legs (a wasp's or a bee's, named ``Leg1.L``, ``Leg2.L``: one limb by name, three chains),
four "legs" that do not all reach the ground (a T-rex whose arms are named ``FrontLeg``), two
legs with two arms off the ground under a horizontal body (a T-rex, a velociraptor, a kangaroo)
and two legs with a tail and no arms are all ``unknown``. "Upright" comes from the head above
the hips, else from the arms hanging from well above the legs' tops.

Categories are body plans, not taxonomy: four-legged dinosaurs standing on straight legs
(Stegosaurus, Triceratops) are ``quadruped``; a lizard's splayed legs make it ``reptile``.
Bones named as IK targets or pole targets (``IK``, ``Pole``, ``Target``) are not limbs.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from mimicbench.datagen.correspond.canonical import canonicalize_names

LEG_WORDS = {"thigh", "shin", "leg", "foot", "toe", "knee", "calf", "ankle", "paw", "hoof", "heel"}
ARM_WORDS = {"arm", "forearm", "hand", "elbow", "wrist", "palm", "thumb", "index", "pinky", "finger"}
QUALIFIERS = {"front": "front", "fore": "front", "hind": "back", "back": "back", "rear": "back",
              "middle": "middle", "mid": "middle"}
HELPER_WORDS = {"ik", "pole", "target", "ctrl", "control", "helper", "twist", "roll"}
APPAREL_WORDS = {"hair", "skirt", "cape", "coat", "cloak", "ribbon", "sleeve", "cloth", "scarf", "tie"}
LONG_CHAIN = 8  # joints in a single chain that make a legless body a snake
LONG_PATH = 12  # joints on the longest path (a body branching at the root into head and tail) that do too


def _limbs(words_per_bone: list[list[str]]) -> dict:
    """Group bones into limbs by kind and (side, qualifier, index). IK and other helper bones
    (:data:`HELPER_WORDS`) make no limb; they are kept apart by limb (``helpers``), since an IK
    foot may be the only bone that reaches the ground."""
    limbs: dict[str, set] = {"leg": set(), "arm": set(), "wing": set(), "fin": set()}
    members: dict[tuple, list[int]] = {}
    helpers: dict[tuple, list[int]] = {}
    tail = False
    apparel = 0
    for i, words in enumerate(words_per_bone):
        tokens = set(words)
        helper = bool(tokens & HELPER_WORDS)
        side = words[0] if words and words[0] in ("left", "right") else None
        numbers = [w for w in words if w.isdigit()]
        tail |= "tail" in tokens and not helper
        apparel += bool(tokens & APPAREL_WORDS) and not helper
        if "wing" in tokens:
            kind = "wing"
        elif tokens & {"fin", "flipper", "fins", "flippers"}:
            kind = "fin"
        elif tokens & LEG_WORDS:
            kind = "leg"
        elif tokens & ARM_WORDS and not tokens & {"front", "fore"}:
            kind = "arm"
        else:
            continue
        if kind == "arm" and tokens & {"front", "fore"}:
            kind = "leg"
        qual = next((QUALIFIERS[w] for w in words if w in QUALIFIERS), "") if kind == "leg" else ""
        index = numbers[0] if kind == "leg" and len(numbers) >= 2 else ""  # "leg 2 3": leg 2, segment 3
        if side is None and kind in ("leg", "arm", "wing"):
            continue  # a limb has a side; an unsided "leg" is a body part name
        key = (side, qual, index) if kind == "leg" else (side, "", "")
        if kind == "fin":
            key = (side, " ".join(words), "")
        if helper:
            helpers.setdefault((kind,) + key, []).append(i)
            continue
        limbs[kind].add(key)
        members.setdefault((kind,) + key, []).append(i)
    return {"limbs": limbs, "members": members, "helpers": helpers, "tail": tail, "apparel_bones": apparel}


def _children(parents: np.ndarray) -> list[list[int]]:
    kids: list[list[int]] = [[] for _ in parents]
    for j, p in enumerate(parents):
        if p >= 0:
            kids[int(p)].append(j)
    return kids


def longest_single_chain(parents: Sequence[int]) -> int:
    """Joints in the longest run where each joint has exactly one child."""
    parents = np.asarray(parents)
    kids = _children(parents)
    best = 0
    for j in range(len(parents)):
        p = parents[j]
        if p >= 0 and len(kids[int(p)]) == 1:
            continue  # not the start of a run
        n, k = 1, j
        while len(kids[k]) == 1:
            k = kids[k][0]
            n += 1
        best = max(best, n)
    return best


def longest_path(parents: Sequence[int]) -> int:
    """Joints on the longest path between two joints of the hierarchy (its diameter): a snake
    whose root starts both the body towards the head and the tail spans nearly all its joints."""
    parents = np.asarray(parents)
    kids = _children(parents)
    order = [j for j in range(len(parents)) if parents[j] < 0]
    for j in order:  # parents before children, whatever the joint order
        order.extend(kids[j])
    depth = np.zeros(len(parents), np.int64)  # joints on the longest downward path from each joint
    best = 0
    for j in reversed(order):
        tops = sorted((int(depth[c]) for c in kids[j]), reverse=True)[:2]
        depth[j] = 1 + (tops[0] if tops else 0)
        best = max(best, 1 + sum(tops))
    return best


def _upright(keypoints: np.ndarray, words_per_bone: list[list[str]]) -> bool | None:
    """True when the body runs up (head above hips), False when it runs horizontally."""
    def find(*names):
        for name in names:  # in order of preference
            for i, w in enumerate(words_per_bone):
                if w and w[0] == name and len(w) <= 2:
                    return i
        return None

    head = find("head")
    base = find("hips", "pelvis", "spine", "body", "torso", "root")
    if head is None or base is None or head == base:
        return None
    d = keypoints[head] - keypoints[base]
    return bool(abs(d[1]) > np.hypot(d[0], d[2]))


def _splayed(keypoints: np.ndarray, groups: list[list[int]]) -> bool | None:
    """True when most legs reach out sideways more than down (from a leg's highest joint to its
    lowest: lateral distance above vertical drop), as a lizard's do."""
    votes = []
    for members in groups:
        pts = keypoints[members]
        top, bottom = pts[np.argmax(pts[:, 1])], pts[np.argmin(pts[:, 1])]
        if np.allclose(top, bottom):
            continue
        votes.append(abs(bottom[0] - top[0]) > abs(bottom[1] - top[1]))
    return None if not votes else bool(np.mean(votes) > 0.5)


def _arms_reach_ground(keypoints: np.ndarray, arm_groups: list[list[int]], leg_groups: list[list[int]]) -> bool | None:
    """True when the arms come down to the feet as forelegs do: their lowest joint is within a
    quarter of the legs' drop (hip to foot) above the legs' lowest joint. A bipedal dinosaur's
    small arms hang well above the ground."""
    if not arm_groups or not leg_groups:
        return None
    legs = np.concatenate([keypoints[m] for m in leg_groups])
    drop = float(np.mean([np.ptp(keypoints[m][:, 1]) for m in leg_groups]))
    if drop <= 0:
        return None
    lowest_arm = min(float(keypoints[m][:, 1].min()) for m in arm_groups)
    return bool(lowest_arm - float(legs[:, 1].min()) < 0.25 * drop)


def _chains(members: dict, kind: str, parents: np.ndarray) -> dict:
    """Per side, how many separate chains the bones of limb ``kind`` form (a chain starts at a bone
    whose parent is not a ``kind`` bone of the same side): ``Leg1.L``, ``Leg2.L``, ``Leg3.L`` on
    the thorax are one leg by name and three chains."""
    sides: dict[str, set] = {}
    for key, bones in members.items():
        if key[0] == kind and key[1] is not None:
            sides.setdefault(key[1], set()).update(bones)
    return {side: sum(int(parents[b]) not in bones for b in bones) for side, bones in sorted(sides.items())}


def _all_reach_ground(keypoints: np.ndarray, groups: list[list[int]]) -> bool | None:
    """True when every limb's lowest joint is within a quarter of the limbs' mean drop (highest to
    lowest joint) of the lowest of them all, as a quadruped's four feet are."""
    if not groups:
        return None
    drop = float(np.mean([np.ptp(keypoints[m][:, 1]) for m in groups]))
    if drop <= 0:
        return None
    lows = [float(keypoints[m][:, 1].min()) for m in groups]
    return bool(max(lows) - min(lows) < 0.25 * drop)


def _upright_from_limbs(keypoints: np.ndarray, arm_groups: list[list[int]], leg_groups: list[list[int]]) -> bool | None:
    """Upright from the limbs alone (no head or hips bone found by name): True when the arms hang
    from more than half the legs' drop above the legs' tops (shoulders above hips), False when
    from less than a quarter of it (forelegs beside hind legs), else None."""
    if not arm_groups or not leg_groups:
        return None
    drop = float(np.mean([np.ptp(keypoints[m][:, 1]) for m in leg_groups]))
    if drop <= 0:
        return None
    rise = float(np.mean([keypoints[m][:, 1].max() for m in arm_groups])
                 - np.mean([keypoints[m][:, 1].max() for m in leg_groups]))
    return True if rise > 0.5 * drop else False if rise < 0.25 * drop else None


def _ancestors(parents: np.ndarray, j: int) -> list[int]:
    out = [j]
    while parents[j] >= 0:
        j = int(parents[j])
        out.append(j)
    return out


def feet_on_ground(keypoints: np.ndarray, parents: np.ndarray) -> int:
    """Feet found from geometry alone: leaf joints within 12% of the height of the lowest joint;
    two such leaves are one foot when both are at most 2 joints below their common ancestor
    (toe and heel of one foot). 0 for a flat skeleton (height under a quarter of its size)."""
    kp = np.asarray(keypoints, np.float64)
    parents = np.asarray(parents, np.int64)
    height = float(np.ptp(kp[:, 1]))
    size = float(np.ptp(kp, axis=0).max())
    if size <= 0 or height < 0.25 * size:
        return 0
    kids = _children(parents)
    leaves = [j for j in range(len(kp)) if not kids[j] and kp[j, 1] - kp[:, 1].min() < 0.12 * height]
    foot = {j: j for j in leaves}

    def find(j):
        while foot[j] != j:
            j = foot[j]
        return j

    for a_i, a in enumerate(leaves):
        up_a = _ancestors(parents, a)
        for b in leaves[a_i + 1:]:
            up_b = _ancestors(parents, b)
            common = next((x for x in up_a if x in up_b), None)
            if common is not None and up_a.index(common) <= 2 and up_b.index(common) <= 2:
                foot[find(b)] = find(a)
    return len({find(j) for j in leaves})


def infer_category(bone_names: Sequence[str], parents: Sequence[int], keypoints: np.ndarray) -> tuple[str, dict]:
    """Category and evidence of one skeleton.

    Args:
        bone_names: K names as authored.
        parents: (K,) parent indices, -1 for roots.
        keypoints: (K, 3) rest joint positions (dataset frame: Y up, +Z forward).

    Returns:
        (category, evidence): one of ``mimicbench.schemas.character.CATEGORIES`` and a JSON-ready dict
        with the rule that decided and the counts it used.
    """
    parents = np.asarray(parents, np.int64)
    kp = np.asarray(keypoints, np.float64)
    words = [c.split() for c in canonicalize_names(list(bone_names))]
    found = _limbs(words)
    limbs, members = found["limbs"], found["members"]
    legs, arms = len(limbs["leg"]), len({k[0] for k in limbs["arm"]})
    wings, fins = len({k[0] for k in limbs["wing"]}), len(limbs["fin"])
    chain = longest_single_chain(parents)
    leg_groups = [m for key, m in members.items() if key[0] == "leg"]
    arm_groups = [m for key, m in members.items() if key[0] == "arm"]
    evidence = {"legs": legs, "arms": arms, "wings": wings, "fins": fins, "tail": found["tail"],
                "apparel_bones": found["apparel_bones"], "longest_chain": chain, "from": "names"}

    def decide(category: str, rule: str) -> tuple[str, dict]:
        evidence["rule"] = rule
        return category, evidence

    if wings:
        wing_chains, leg_chains = _chains(members, "wing", parents), _chains(members, "leg", parents)
        evidence.update(wing_chains=wing_chains, leg_chains=leg_chains)
        if legs >= 6 and not arms:
            return decide("insect", f"{legs} legs and wings")
        if wing_chains == {"left": 1, "right": 1} and leg_chains == {"left": 1, "right": 1} and legs == 2 \
                and not arms and not fins:
            return decide("bird", "one wing and one leg on each side")
        return decide("unknown", "wings without a bird's two legs (an insect's, a dragon's, ...): ambiguous")
    if legs >= 6 and not arms:
        return decide("insect", f"{legs} legs")
    if fins and not legs and not arms:
        return decide("fish", "fins and no legs")
    if legs == 4 and not arms:
        evidence["splayed"] = _splayed(kp, leg_groups)
        if evidence["splayed"]:
            return decide("reptile", "four legs splayed to the sides")
        with_ik = [m + found["helpers"].get(key, []) for key, m in members.items() if key[0] == "leg"]
        evidence["legs_reach_ground"] = _all_reach_ground(kp, with_ik)
        if evidence["legs_reach_ground"]:
            return decide("quadruped", "four legs under the body")
        return decide("unknown", "four legs that do not all reach the ground: ambiguous")
    if legs == 2 and arms == 2:
        evidence["upright"] = _upright(kp, words)
        if evidence["upright"] is None:
            evidence["upright"] = _upright_from_limbs(kp, arm_groups, leg_groups)
        if evidence["upright"]:
            if found["apparel_bones"] >= 3:
                return decide("apparel", "arms, legs, upright, and apparel chains")
            return decide("humanoid", "two arms and two legs, upright")
        if evidence["upright"] is False:
            evidence["arms_reach_ground"] = _arms_reach_ground(kp, arm_groups, leg_groups)
            if evidence["arms_reach_ground"]:
                return decide("quadruped", "forelegs named as arms, body horizontal")
        return decide("unknown", "two arms and two legs, not upright, arms off the ground: ambiguous")
    if legs == 0 and arms == 0 and not fins:
        evidence["from"] = "geometry"
        feet = feet_on_ground(kp, parents)
        evidence["feet_on_ground"] = feet
        if feet >= 6:
            return decide("insect", f"{feet} feet on the ground")
        if feet == 4:
            return decide("quadruped", "four feet on the ground")
        if feet == 2:
            evidence["upright"] = bool(np.ptp(kp[:, 1]) > np.ptp(kp[:, 2]))
            if evidence["upright"]:
                return decide("humanoid", "two feet on the ground, upright")
        if feet == 0 and chain >= LONG_CHAIN and chain >= 0.5 * len(parents):
            return decide("reptile", f"no legs; a chain of {chain} of the {len(parents)} joints")
        span = longest_path(parents)
        evidence["longest_path"] = span
        if feet == 0 and span >= LONG_PATH and span >= 0.75 * len(parents):
            return decide("reptile", f"no legs; a path of {span} of the {len(parents)} joints (head to tail)")
    return decide("unknown", "no rule fits")
