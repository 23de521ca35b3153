"""Canonical bone names: the text a bone's name is embedded as.

Real rigs name the same bone many ways (``mixamorig:LeftArm``, ``upper_arm.L``,
``Bip01 L UpperArm``, ``b_LeftUpperArm_09``). Before embedding, names are rewritten to plain
lower-case words in one vocabulary; the raw name is always kept beside it.

**Identical raw names give identical text.** A name's text depends on that name alone, never on
the other bones of its skeleton (an earlier version renumbered chains per skeleton, so ``Torso``
became ``torso 1`` in a rig that also had ``Torso2`` and ``torso`` elsewhere, and the two embedded
apart). Where a bone sits in its chain is the skeleton's business: the structure-aware matching
(:mod:`.structure`) reads it from the parents, not from the text. The one skeleton-wide rule is
the export index (step 4), which removes a number that is not part of the name at all.

Steps:

1. **MikuMikuDance's Japanese names** are translated by ``mmd-bone-tools`` (its standard MMD
   dictionary for whole standard names such as ``左人指１`` -> ``fore1_L``, else run by run of
   Japanese characters, ASCII parts such as ``IK`` or ``1_2`` kept as written), after NFKC
   normalisation of full-width characters. MMD's English finger words ``fore``/``third``/
   ``little`` become ``index``/``ring``/``pinky``.
2. **Namespaces and export prefixes** are stripped: everything up to the last ``:`` or ``|``;
   ``mixamorig``, ``Bip01``/``Bip001``, ``DEF-``/``ORG-``/``MCH-``, ``CC_Base_``, ``J_Bip_`` (with its
   ``C_``/``L_``/``R_`` side code), ``_`` at the start (``_rootJoint``), and the glTF-export ``b_``
   prefix together with its trailing export index (``b_LeftUpperArm_09`` -> ``LeftUpperArm``).
3. **Split** camel case, snake case, dots, dashes, spaces and letter/digit boundaries. Single
   capitals glued to a word are split off first (``LHipJoint`` -> ``L Hip Joint``,
   ``UpperArmL`` -> ``Upper Arm L``) when they are side letters.
4. **Numbers** lose leading zeros and are otherwise kept as written: in rigs they are nearly
   always segment numbers (``Spine1``, ``Tail01``, ``wing_l_02``), whatever they count from.
   Blender's duplicate suffix ``.00n`` is the (n+1)-th bone of that name (``Tail.001`` -> ``tail 2``,
   ``Leg2.002.L`` -> ``left leg 2 3``); several dotted numbers (``skirt.003.002``) are segment
   numbers as written.
   Export indices are dropped: the ``b_`` style's trailing index, and a trailing ``_<digits>``
   when every name of the skeleton ends in one and those numbers are the bone indices (a
   permutation of 0..K-1 or 1..K) while the names differ in more than the number. 3ds Max biped
   fingers ``Finger<f><s>`` become thumb/index/middle/ring/pinky with a segment number.
5. **Sides** (``L``, ``.L``, ``_l``, ``l_``, ``Left``; and right) become the words ``left`` /
   ``right``, placed first.
6. **Synonyms and abbreviations** map to one vocabulary, each from the name alone, in words the
   text encoder knows well (MiniLM: cos("left lower leg", "left leg") 0.92, but cos("left shin",
   "left leg") 0.63): ``UpLeg``/``UpperLeg``/``Thigh`` -> ``upper leg``;
   ``LowerLeg``/``LowLeg``/``Calf``/``Shin`` -> ``lower leg``; ``ForeArm``/``LowerArm`` -> ``lower arm``;
   ``UpperArm`` -> ``upper arm``; a bone named after the joint at its head is the segment that
   joint moves (MMD's ``ひじ`` elbow, ``ひざ`` knee, ``手首`` wrist, ``足首`` ankle): ``Elbow`` ->
   ``lower arm``, ``Knee`` -> ``lower leg``, ``Wrist`` -> ``hand``, ``Ankle`` -> ``foot``;
   ``Clavicle``/``Clav``/``Collar`` -> ``shoulder``; ``Pelvis`` and an unsided ``Hip`` -> ``hips``
   (a sided ``LHipJoint`` is the leg's ``left hip``, not the pelvis); ``ToeBase``/``Toes`` -> ``toe``;
   ``Jnt``/``Joint``/``Bone``/``Def``/``Skeleton`` and Rigify's finger ``f_`` are dropped. A bare ``Arm`` or ``Leg`` stays ``arm``/``leg``.
"""
from __future__ import annotations

import re
import unicodedata
from functools import lru_cache
from typing import Sequence

_NAMESPACE = re.compile(r"^.*[:|]")
_PREFIXES = (
    (re.compile(r"^mixamorig\d*[_:]?", re.I), False),
    (re.compile(r"^bip0*1[\s_]*", re.I), False),
    (re.compile(r"^(DEF|ORG|MCH)[-_]", re.I), False),
    (re.compile(r"^J_Bip_(?:C_)?", re.I), False),
    (re.compile(r"^CC_Base_", re.I), False),
    (re.compile(r"^b_"), True),  # glTF-export style: drop the trailing export index too
    (re.compile(r"^_+"), False),
)
_BLENDER_NUMBER = re.compile(r"\.(\d{3})(?=$|[._\-\s])")
# a side letter glued before a capitalised word (LHipJoint) or after a word at the end (UpperArmL)
_GLUED_SIDE = re.compile(r"^([LR])(?=[A-Z][a-z])|(?<=[a-z])([LR])$")
_CAMEL = re.compile(r"(?<=[a-z])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])|(?<=[A-Za-z])(?=\d)|(?<=\d)(?=[A-Za-z])")
_SIDES = {"l": "left", "left": "left", "r": "right", "right": "right", "lf": "left", "rt": "right"}
_DROP = {"jnt", "joint", "bone", "def", "bn", "grp", "skeleton", "f"}  # f: Rigify's f_index
_SYNONYMS = {
    ("up", "leg"): ["upper", "leg"], ("upper", "leg"): ["upper", "leg"], ("lower", "leg"): ["lower", "leg"],
    ("low", "leg"): ["lower", "leg"], ("fore", "arm"): ["lower", "arm"], ("lower", "arm"): ["lower", "arm"],
    ("upper", "arm"): ["upper", "arm"], ("toe", "base"): ["toe"], ("up", "arm"): ["upper", "arm"],
}
_WORDS = {"upleg": ["upper", "leg"], "thigh": ["upper", "leg"], "calf": ["lower", "leg"], "shin": ["lower", "leg"],
          "clavicle": ["shoulder"], "clav": ["shoulder"], "collar": ["shoulder"], "pelvis": ["hips"], "toes": ["toe"],
          "toebase": ["toe"], "forearm": ["lower", "arm"], "lowerarm": ["lower", "arm"], "upperarm": ["upper", "arm"],
          "elbow": ["lower", "arm"], "knee": ["lower", "leg"], "wrist": ["hand"], "ankle": ["foot"]}
_MMD_FINGERS = {"fore": "index", "third": "ring", "little": "pinky"}
_BIPED_FINGERS = ("thumb", "index", "middle", "ring", "pinky")
_NON_ASCII = re.compile(r"[^\x00-\x7f]+")
_MMD_FINGER_WORD = re.compile(r"(?<![A-Za-z])(fore|third|little)(?=\d|_|\s|$)", re.I)


@lru_cache(maxsize=65536)
def translate_japanese(name: str) -> str:
    """English for a name with Japanese characters (NFKC first), through ``mmd-bone-tools``.

    A whole standard MMD name goes through the library's standard dictionary (``左人指１`` ->
    ``index1_L`` after the finger words are mapped); otherwise each run of non-ASCII characters is
    translated on its own and ASCII parts are kept, so that numbers such as ``1_2`` stay apart.
    Characters the library cannot translate are kept.
    """
    name = unicodedata.normalize("NFKC", name)
    if not _NON_ASCII.search(name):
        return name
    try:
        from mmd_bone_tools import translate_bone
    except ImportError as exc:  # pragma: no cover - a dependency of the text extra
        raise ImportError("bone names in Japanese need the package mmd-bone-tools "
                          "(pip install 'mimicbench[text]')") from exc
    whole = translate_bone(name, fit=False)
    if whole.method == "standard" and whole.complete:
        text = whole.result
    else:
        text = _NON_ASCII.sub(lambda m: f" {translate_bone(m.group(0), fit=False).result} ", name)
    return _MMD_FINGER_WORD.sub(lambda m: _MMD_FINGERS[m.group(1).lower()], text)


def _strip_prefixes(name: str, drop_b_index: bool = True) -> tuple[str, bool]:
    name = translate_japanese(name.strip())
    name = _NAMESPACE.sub("", name.strip())
    biped = bool(re.match(r"^bip0*1", name, re.I))
    for pattern, drops_index in _PREFIXES:
        if pattern.match(name):
            name = pattern.sub("", name, count=1)
            if drops_index and drop_b_index:
                name = re.sub(r"_\d+$", "", name)
    return name, biped


def _tokens(name: str) -> list[str]:
    """Lower-case word tokens; a single Blender ``.00n`` suffix becomes the number n + 1."""
    dotted = _BLENDER_NUMBER.findall(name)
    shift = 1 if len(dotted) == 1 else 0  # several dotted numbers are segment numbers as written
    name = _BLENDER_NUMBER.sub(lambda m: f" {int(m.group(1)) + shift} ", name)
    name = _GLUED_SIDE.sub(lambda m: f" {m.group(1) or m.group(2)} ", name)
    parts = re.split(r"[\s_.\-]+", _CAMEL.sub(" ", name))
    return [p.lower() for p in parts if p]


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
        tok = [t for t in tokens if t.isdigit()][0]
        finger, seg = int(tok[0]), (int(tok[1:]) if len(tok) > 1 else 0)
        if finger < len(_BIPED_FINGERS):
            words, numbers = [_BIPED_FINGERS[finger]], [seg + 1]
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
    if "hip" in out:  # unsided Hip is the pelvis; LHipJoint is the leg's hip
        out = [("hip" if sides else "hips") if w == "hip" else w for w in out]
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


@lru_cache(maxsize=262144)
def _canonical(raw: str, indexed: bool) -> str:
    stripped, biped = _strip_prefixes(raw, drop_b_index=not indexed)
    sides, words, numbers = _words(_tokens(stripped), biped)
    text = " ".join(list(sides) + list(words) + [str(n) for n in numbers])
    return text or "bone"


def canonicalize_names(names: Sequence[str]) -> list[str]:
    """Canonical text of every bone name of one skeleton.

    Each name's text depends on that name alone, except that a skeleton whose names all end in
    their own bone index (``Hips_000``, ``Spine_001``, ...) has that index removed.
    """
    indexed = _export_indexed(names)
    if indexed:  # the list's export indices go here, so the b_ rule must not drop a second number
        names = [_EXPORT_INDEX.sub("", n.strip()) for n in names]
    return [_canonical(raw, indexed) for raw in names]


def canonicalize_bone_name(name: str) -> str:
    """Canonical text of one bone name (see :func:`canonicalize_names`)."""
    return canonicalize_names([name])[0]
