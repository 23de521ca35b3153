"""Build one zoo character: template -> skeleton -> mesh -> skin weights -> names -> clips -> records."""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from mimicbench.datagen.zoo.clips import clip_names, generator
from mimicbench.datagen.zoo.mesh_builder import build_mesh
from mimicbench.datagen.zoo.motions import FPS, NUM_FRAMES, clip_transforms
from mimicbench.datagen.zoo.naming import ANIMAL_STYLES, HUMANOID_STYLES, bone_names
from mimicbench.datagen.zoo.plan import CharacterSpec
from mimicbench.datagen.zoo.skeleton import Skeleton, SkeletonBuilder
from mimicbench.datagen.zoo.templates import TEMPLATES, ZOO_CATEGORIES
from mimicbench.datagen.zoo.templates.humanoid import H2H_SKELETON_ID, H2H_TOPOLOGY, build_humanoid, humanoid_params
from mimicbench.schemas.character import HUMANOID_LIKE, CharacterRecord
from mimicbench.schemas.motion import MotionRecord

ZOO_VERSION = "2"  # recorded in the zoo config; CHANGELOG.md says what each version changed
TARGET_FACES = 8000


@dataclass
class BuiltCharacter:
    """A built character: its record, its clips, and the skeleton (bone tails, for BVH end sites)."""

    record: CharacterRecord
    motions: list[MotionRecord]
    skeleton: Skeleton


def naming_style(spec: CharacterSpec) -> str:
    """The bone-naming style of a character (fixed by category and index, so every zoo mixes styles)."""
    if spec.family:
        return H2H_TOPOLOGY["style"]
    if spec.category == "humanoid":
        return HUMANOID_STYLES[1 + spec.index % 3]
    if spec.category == "apparel":
        return HUMANOID_STYLES[spec.index % 4]
    return ANIMAL_STYLES[(spec.index + ZOO_CATEGORIES.index(spec.category)) % len(ANIMAL_STYLES)]


def skeleton_hash(names: list[str], parents: np.ndarray) -> str:
    h = hashlib.sha256(("\n".join(names) + "|" + ",".join(map(str, parents.tolist()))).encode())
    return "zoo/skeleton-" + h.hexdigest()[:16]


def _jsonable(p: dict) -> dict:
    out = {}
    for k, v in p.items():
        if isinstance(v, (np.floating, float)):
            out[k] = round(float(v), 6)
        elif isinstance(v, (np.integer, np.bool_)):
            out[k] = v.item()
        elif isinstance(v, tuple):
            out[k] = list(v)
        else:
            out[k] = v
    return out


def build_skeleton(spec: CharacterSpec) -> tuple[Skeleton, dict]:
    """The character's skeleton and its template parameters (from its own random stream)."""
    rng = np.random.default_rng(list(spec.entropy))
    b = SkeletonBuilder()
    if spec.family:
        params = humanoid_params(rng, H2H_TOPOLOGY)
        build_humanoid(b, params)
    else:
        make_params, build = TEMPLATES[spec.category]
        params = make_params(rng, spec.index)
        build(b, params)
    return b.build(), params


def build_character(spec: CharacterSpec, split: str, clips_per_character: int = 3,
                    num_frames: int = NUM_FRAMES, clip_set: str = "default") -> BuiltCharacter:
    """Build the character ``spec`` with ``clips_per_character`` clips of ``num_frames`` frames at 30 fps.

    ``clip_set`` chooses the clips (:data:`mimicbench.datagen.zoo.clips.CLIP_SETS`; ``dynamic`` gives humanoids
    spins, stops, jumps and turns first).
    """
    skel, params = build_skeleton(spec)
    verts, faces, owner = build_mesh(skel, TARGET_FACES)
    from mimicbench.datagen.zoo.skin_weights import skin_weights

    weights = skin_weights(skel, verts, owner)
    style = naming_style(spec)
    names = bone_names(skel.roles, style, humanoid=spec.category in HUMANOID_LIKE)
    apparel_vertices = skel.apparel[owner]
    verts32 = verts.astype(np.float32)
    meta = {"generator": "mimicbench.zoo", "zoo_version": ZOO_VERSION, "seed": spec.seed,
            "template": "h2h_humanoid" if spec.family else spec.category, "h2h_family": spec.family,
            "naming_style": style, "params": _jsonable(params), "mesh": "capsule per bone",
            "mesh_components": int(skel.num_joints)}
    record = CharacterRecord(
        character_id=spec.character_id, category=spec.category, source=f"zoo:{meta['template']}@{ZOO_VERSION}",
        split=split, vertices=verts32, faces=faces.astype(np.int32), keypoints=skel.heads.astype(np.float32),
        parents=skel.parents.astype(np.int32), bone_names=names, weight_indices=weights.indices,
        weight_values=weights.values, apparel_vertex_mask=apparel_vertices, apparel_bone_mask=skel.apparel.copy(),
        bone_roles=list(skel.roles), skeleton_id=H2H_SKELETON_ID if spec.family else skeleton_hash(names, skel.parents),
        height=float(np.ptp(verts32[:, 1])), meta=meta)
    motions = []
    for j, name in enumerate(clip_list(spec.category, skel, clips_per_character, clip_set)):
        rng = np.random.default_rng(list(spec.entropy) + [1000 + j])
        rotvec, root = generator(spec.category, name)(skel, rng, num_frames)
        transforms = clip_transforms(skel, rotvec, root)
        motions.append(MotionRecord(
            motion_id=f"{spec.character_id}/{name}", character_id=spec.character_id, name=name, split=split,
            fps=FPS, num_frames=num_frames, num_joints=skel.num_joints, transforms=transforms,
            source=f"zoo:{name}@{ZOO_VERSION}"))
    return BuiltCharacter(record, motions, skel)


def clip_list(category: str, skel: Skeleton, count: int, clip_set: str = "default") -> list[str]:
    """``count`` clip names: the kind's own clips (of ``clip_set``) first, then more random-pose clips."""
    names = clip_names(category, skel, clip_set)[:count]
    i = 2
    while len(names) < count:
        names.append(f"random_poses_{i}")
        i += 1
    return names
