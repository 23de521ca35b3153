"""Canonical bone names: the text a bone's name is embedded as.

Real rigs name the same bone many ways (``mixamorig:LeftArm``, ``upper_arm.L``,
``Bip01 L UpperArm``, ``b_LeftUpperArm_09``). Before embedding, names are rewritten to plain
lower-case words in one vocabulary; the raw name is always kept beside it. Steps:

1. **Namespaces and export prefixes** are stripped: everything up to the last ``:`` or ``|``;
   ``mixamorig``, ``Bip01``/``Bip001``, ``DEF-``/``ORG-``/``MCH-``, ``CC_Base_``, ``J_Bip_`` (with its
   ``C_``/``L_``/``R_`` side code), and the glTF-export ``b_`` prefix together with its
   trailing export index (``b_LeftUpperArm_09`` -> ``LeftUpperArm``).
2. **Split** camel case, snake case, dots, dashes, spaces and letter/digit boundaries.
3. **Sides** (``L``, ``.L``, ``_l``, ``l_``, ``Left``, ``左``; and right) become the words
   ``left`` / ``right``, placed first. MikuMikuDance's Japanese bone words (``腕`` arm, ``ひじ``
   elbow, ``足首`` ankle, ...) are translated and full-width characters normalised (NFKC).
4. **Numbers** lose leading zeros and are otherwise kept: in rigs they are nearly always segment
   numbers (``Spine1``/``Spine2``, ``Tail01``, ``wing_l_02``, ``leg_l_01_03``), which the
   matching needs. Export indices are dropped: the ``b_`` style's trailing index, and any
   trailing ``_<digits>`` (``_013``) when every name of the skeleton ends in one, those numbers
   are the bone indices (a permutation of 0..K-1 or 1..K) and the names differ in more than the
   number. Blender's ``.001`` duplicate suffix becomes a chain position (below). Chain
   numbering is made uniform within one skeleton: where a chain has an unnumbered first bone
   followed by numbered ones (Mixamo ``Spine``, ``Spine1``; Blender ``Tail``, ``Tail.001``), the
   first becomes 1 and the rest n+1 (n as is when the numbering starts at 2, as in MMD's
   ``上半身``, ``上半身2``). Rigify's convention that a root chain called ``spine`` starts at the
   hips (when no hips/pelvis bone exists) is honoured. 3ds Max biped fingers ``Finger<f><s>``
   become thumb/index/middle/ring/pinky with a segment number.
5. **Synonyms and abbreviations** map to one vocabulary: ``UpLeg``/``UpperLeg``/``Thigh`` ->
   ``thigh``; ``LowerLeg``/``Calf``/``Shin`` (and Mixamo's ``Leg`` beside ``UpLeg``) -> ``shin``;
   ``ForeArm``/``LowerArm`` -> ``forearm``; ``Arm`` beside a forearm -> ``upper arm``;
   ``Clavicle``/``Clav``/``Collar`` -> ``shoulder``; ``Pelvis`` -> ``hips``; ``ToeBase``/``Toes``
   -> ``toe``; ``Jnt``/``Joint``/``Bone``/``Def`` are dropped.
"""
from __future__ import annotations

import re
import unicodedata
from typing import Sequence

# MikuMikuDance (PMX) bone words, longest first so that compounds win (足首 ankle before 足 leg)
_MMD_WORDS = dict(sorted({
    "左": "Left", "右": "Right", "上半身": "UpperBody", "下半身": "LowerBody", "センター": "Center",
    "グルーブ": "Groove", "首": "Neck", "頭": "Head", "目": "Eye", "肩": "Shoulder", "腕": "Arm",
    "ひじ": "Elbow", "手首": "Wrist", "手": "Hand", "捩": "Twist", "親指": "Thumb", "人指": "Index",
    "人差指": "Index", "中指": "Middle", "薬指": "Ring", "小指": "Pinky", "足首": "Ankle", "足": "Leg",
    "ひざ": "Knee", "つま先": "Toe", "髪": "Hair", "スカート": "Skirt", "胸": "Chest",
}.items(), key=lambda kv: -len(kv[0])))
_NAMESPACE = re.compile(r"^.*[:|]")
_PREFIXES = (
    (re.compile(r"^mixamorig\d*[_:]?", re.I), False),
    (re.compile(r"^bip0*1[\s_]*", re.I), False),
    (re.compile(r"^(DEF|ORG|MCH)[-_]", re.I), False),
    (re.compile(r"^J_Bip_(?:C_)?", re.I), False),
    (re.compile(r"^CC_Base_", re.I), False),
    (re.compile(r"^b_"), True),  # glTF-export style: drop the trailing export index too
)
_BLENDER_NUMBER = re.compile(r"\.(\d{3})")
_CAMEL = re.compile(r"(?<=[a-z])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])|(?<=[A-Za-z])(?=\d)|(?<=\d)(?=[A-Za-z])")
_SIDES = {"l": "left", "left": "left", "r": "right", "right": "right", "lf": "left", "rt": "right"}
_DROP = {"jnt", "joint", "bone", "def", "bn", "grp"}
_SYNONYMS = {
    ("up", "leg"): ["thigh"], ("upper", "leg"): ["thigh"], ("lower", "leg"): ["shin"],
    ("fore", "arm"): ["forearm"], ("lower", "arm"): ["forearm"], ("upper", "arm"): ["upper", "arm"],
    ("toe", "base"): ["toe"], ("up", "arm"): ["upper", "arm"],
}
_WORDS = {"upleg": ["thigh"], "calf": ["shin"], "clavicle": ["shoulder"], "clav": ["shoulder"],
          "collar": ["shoulder"], "pelvis": ["hips"], "hip": ["hips"], "toes": ["toe"], "toebase": ["toe"],
          "forearm": ["forearm"], "lowerarm": ["forearm"], "upperarm": ["upper", "arm"], "thumb": ["thumb"]}
_BIPED_FINGERS = ("thumb", "index", "middle", "ring", "pinky")


def _strip_prefixes(name: str, drop_b_index: bool = True) -> tuple[str, bool]:
    name = unicodedata.normalize("NFKC", name)  # full-width digits and letters (MMD) to ASCII
    for word in _MMD_WORDS:
        name = name.replace(word, f" {_MMD_WORDS[word]} ")
    name = _NAMESPACE.sub("", name.strip())
    biped = bool(re.match(r"^bip0*1", name, re.I))
    for pattern, drops_index in _PREFIXES:
        if pattern.match(name):
            name = pattern.sub("", name, count=1)
            if drops_index and drop_b_index:
                name = re.sub(r"_\d+$", "", name)
    return name, biped


def _tokens(name: str) -> tuple[list[str], int | None]:
    """Lower-case word tokens and the Blender ``.00n`` chain index (or None)."""
    blender = _BLENDER_NUMBER.search(name)
    index = int(blender.group(1)) if blender else None
    name = _BLENDER_NUMBER.sub(" ", name)
    parts = re.split(r"[\s_.\-]+", _CAMEL.sub(" ", name))
    return [p.lower() for p in parts if p], index


def _words(tokens: list[str], biped: bool) -> tuple[list[str], list[str], list[int]]:
    sides, words, numbers = [], [], []
    for tok in tokens:
        if tok in _SIDES:
            sides.append(_SIDES[tok])
        elif tok.isdigit():
            numbers.append(int(tok))
        elif tok in _DROP:
            continue
        else:
            words.extend(_WORDS.get(tok, [tok]))
    if biped and words == ["finger"] and numbers:
        digits = str(numbers[0]) if numbers[0] > 9 else None
        tok = [t for t in tokens if t.isdigit()][0]
        finger, seg = int(tok[0]), (int(tok[1:]) if len(tok) > 1 else 0)
        if finger < len(_BIPED_FINGERS):
            words, numbers = [_BIPED_FINGERS[finger]], [seg + 1]
        del digits
    elif biped and numbers == [0]:  # biped's single Toe0: the toe
        numbers = []
    out = []
    i = 0
    while i < len(words):
        pair = tuple(words[i:i + 2])
        if pair in _SYNONYMS:
            out.extend(_SYNONYMS[pair])
            i += 2
        else:
            out.append(words[i])
            i += 1
    if len(out) > 1 and out[0] == "hand" and out[1] in _BIPED_FINGERS:
        out = out[1:]
    return sorted(set(sides)), out, numbers


_EXPORT_INDEX = re.compile(r"_(\d+)$")


def _export_indexed(names: Sequence[str]) -> bool:
    """True when every name ends in ``_<n>`` and the n are the bone indices 0..K-1 or 1..K."""
    found = [_EXPORT_INDEX.search(n.strip()) for n in names]
    if len(names) < 3 or not all(found):
        return False
    numbers = sorted(int(m.group(1)) for m in found)
    stems = {_EXPORT_INDEX.sub("", n.strip()).lower() for n in names}
    return numbers in (list(range(len(names))), list(range(1, len(names) + 1))) and len(stems) > 1


def canonicalize_names(names: Sequence[str]) -> list[str]:
    """Canonical text of every bone name of one skeleton (context: the whole name list)."""
    indexed = _export_indexed(names)
    if indexed:  # the list's export indices go here, so the b_ rule must not drop a second number
        names = [_EXPORT_INDEX.sub("", n.strip()) for n in names]
    parsed = []
    for raw in names:
        stripped, biped = _strip_prefixes(raw, drop_b_index=not indexed)
        tokens, blender_index = _tokens(stripped)
        sides, words, numbers = _words(tokens, biped)
        parsed.append([sides, words, numbers, blender_index])
    all_words = {w for _, words, _, _ in parsed for w in words}
    has_hips = "hips" in all_words or "root" in all_words
    # context synonyms: Mixamo's Leg beside UpLeg is the shin; Arm beside ForeArm the upper arm
    for p in parsed:
        unnumbered = not p[2] and p[3] is None
        if p[1] == ["leg"] and "thigh" in all_words and unnumbered:
            p[1] = ["shin"]
        if p[1] == ["arm"] and "forearm" in all_words and unnumbered:
            p[1] = ["upper", "arm"]
    # chain numbering: an unnumbered first bone followed by numbered ones
    chains: dict[tuple, list] = {}
    for p in parsed:
        chains.setdefault((tuple(p[0]), tuple(p[1])), []).append(p)
    for (sides, words), members in chains.items():
        numbered = [p for p in members if p[2] or p[3] is not None]
        bare = [p for p in members if not p[2] and p[3] is None]
        if not (numbered and bare):
            continue
        rigify_hips = words == ("spine",) and not sides and not has_hips
        # Spine, Spine1, Spine2 (Mixamo) shift by one; 上半身, 上半身2 (MMD) already count the bare bone
        shift = 1 if min((p[2][0] for p in numbered if p[2] and p[3] is None), default=1) <= 1 else 0
        for p in bare:
            if rigify_hips:
                p[1] = ["hips"]
            else:
                p[2] = [1]
        for p in numbered:
            if p[3] is not None:  # Blender .00n: n-th after the bare first bone
                p[2] = [p[3] + (0 if rigify_hips else 1)] + p[2]
                p[3] = None
            elif not rigify_hips:
                p[2] = [p[2][0] + shift] + p[2][1:]
    out = []
    for sides, words, numbers, blender_index in parsed:
        if blender_index is not None:
            numbers = [blender_index] + numbers
        text = " ".join(list(sides) + list(words) + [str(n) for n in numbers])
        out.append(text or "bone")
    return out


def canonicalize_bone_name(name: str) -> str:
    """Canonical text of one bone name without skeleton context (see :func:`canonicalize_names`)."""
    return canonicalize_names([name])[0]
