"""Apparel of an MMD model from its physics: which bones the artist simulates, which vertices
they carry, and what kind of apparel each chain is (from its Japanese/English names)."""
from __future__ import annotations

import re

import numpy as np

from mimicbench.datagen.mmd.model import MMDModel

# (kind, name fragments): first match wins, so specific kinds come before general ones
APPAREL_KINDS = (
    ("breast", ("胸", "おっぱい", "乳", "breast", "bust", "oppai")),
    ("sleeve", ("袖", "そで", "sleeve")),
    ("skirt", ("スカート", "skirt", "すそ", "裾", "hem")),
    ("ribbon", ("リボン", "ribbon", "ネクタイ", "タイ", "紐", "ひも", "tie", "string", "sash", "帯")),
    ("hair", ("髪", "毛", "hair", "ツインテ", "ポニテ", "もみあげ", "おさげ", "三つ編み", "bang", "ponytail",
              "twintail", "braid", "ahoge", "アホ毛")),
    ("accessory", ("飾り", "アクセ", "イヤリング", "ピアス", "ペンダント", "ネックレス", "鈴", "帽子", "耳",
                   "尻尾", "しっぽ", "accessory", "earring", "pendant", "necklace", "ornament", "hat", "tail",
                   "ear", "chain", "鎖")),
    # Cloaks, coats and capes have no kind of their own: ``other``, with the word as evidence
    ("other", ("クローク", "マント", "コート", "ケープ", "cloak", "cape", "coat", "mantle")),
)
DYNAMIC_MODES = (1, 2)


def apparel_bones(model: MMDModel) -> np.ndarray:
    """(K,) bool in the file's bone order: bones that a dynamic rigid body (mode 1 physics or 2
    physics + bone) drives, and the bones below them that have no rigid body of their own (chain
    tips such as ``前髪1End`` move rigidly with their simulated parent)."""
    k = len(model.bones)
    driven = np.zeros(k, bool)
    has_body = np.zeros(k, bool)
    for rb in model.rigid_bodies:
        if rb.bone >= 0:
            has_body[rb.bone] = True
            if rb.mode in DYNAMIC_MODES:
                driven[rb.bone] = True
    out = driven.copy()
    changed = True
    while changed:  # parents can come after children in a PMX file: iterate to a fixed point
        changed = False
        for i, b in enumerate(model.bones):
            if not out[i] and not has_body[i] and b.parent >= 0 and out[b.parent]:
                out[i] = changed = True
    return out


def apparel_vertex_mask(weight_indices: np.ndarray, weight_values: np.ndarray, bone_mask: np.ndarray,
                        threshold: float = 0.5) -> np.ndarray:
    """(N,) bool: vertices whose skin weights on apparel bones sum to at least ``threshold``.

    ``weight_indices``/``weight_values`` (N, J) over the bones ``bone_mask`` (K,) indexes."""
    on = np.asarray(bone_mask, bool)[weight_indices] & (weight_values > 0)
    return (np.where(on, weight_values, 0.0).sum(axis=1) >= threshold)


def apparel_chains(model: MMDModel, bone_mask: np.ndarray) -> list[dict]:
    """The apparel chains: each apparel bone whose parent is not apparel roots one chain.

    Returns one dict per chain: ``root`` (bone index in the file), ``bones`` (indices),
    ``kind`` (one of hair, skirt, sleeve, ribbon, accessory, breast, other) and ``evidence``
    (the name and fragment that decided it, or why ``other``)."""
    children: dict[int, list[int]] = {}
    for i, b in enumerate(model.bones):
        children.setdefault(b.parent, []).append(i)
    body_names: dict[int, list[str]] = {}
    for rb in model.rigid_bodies:
        body_names.setdefault(rb.bone, []).extend([rb.name, rb.name_en])
    chains = []
    for i, b in enumerate(model.bones):
        if not bone_mask[i] or (b.parent >= 0 and bone_mask[b.parent]):
            continue
        members, stack = [], [i]
        while stack:
            j = stack.pop()
            members.append(j)
            stack.extend(c for c in children.get(j, []) if bone_mask[c])
        names = []
        for j in sorted(members):
            names += [model.bones[j].name, model.bones[j].name_en] + body_names.get(j, [])
        kind, evidence = apparel_kind([n for n in names if n])
        chains.append({"root": i, "bones": sorted(members), "kind": kind, "evidence": evidence})
    return chains


def apparel_kind(names: list[str]) -> tuple[str, str]:
    """Kind of apparel from bone/body names: the first kind whose fragment occurs in a name."""
    for kind, fragments in APPAREL_KINDS:
        for n in names:
            low = n.lower()
            for f in fragments:
                if f.isascii():
                    hit = re.search(r"(?<![a-z])" + re.escape(f), low) is not None
                else:
                    hit = f in n
                if hit:
                    return kind, f"{n!r} contains {f!r}"
    return "other", "no apparel word in " + ", ".join(repr(n) for n in names[:3])
