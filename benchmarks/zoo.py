"""Speed of the procedural zoo: characters per second, per-stage shares, and a named peer.

Run: ``python benchmarks/zoo.py [--characters 16]``. Prints the whole build's characters per
second (``build_zoo`` into a temporary folder, shards and CARD included), the time of each stage
of one character build summed over the zoo, and last the ratio of the mesh stage against the
peer: the same bones meshed with trimesh's own primitive (``trimesh.creation.capsule`` per bone,
placed with a transform and joined with ``trimesh.util.concatenate``) at the same face budget.
"""
from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np


def trimesh_capsules(skel, faces_per_bone: np.ndarray):
    """The peer: one trimesh capsule per bone (uniform radius), transformed into place, concatenated."""
    import trimesh

    parts = []
    for k in range(skel.num_joints):
        a, b = skel.heads[k], skel.tails[k]
        length = float(np.linalg.norm(b - a))
        r = float(max(skel.radius_head[k], skel.radius_tail[k]))
        n = max(4, int(np.sqrt(faces_per_bone[k] / 2)))
        cap = trimesh.creation.capsule(height=length, radius=r, count=[n, n])
        z = (b - a) / length
        m = trimesh.geometry.align_vectors([0, 0, 1], z)
        m[:3, 3] = (a + b) / 2
        cap.apply_transform(m)
        parts.append(cap)
    return trimesh.util.concatenate(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--characters", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.datagen.zoo.build import TARGET_FACES, build_skeleton, clip_list
    from mimicbench.datagen.zoo.clips import generator
    from mimicbench.datagen.zoo.mesh_builder import build_mesh
    from mimicbench.datagen.zoo.motions import NUM_FRAMES, clip_transforms
    from mimicbench.datagen.zoo.plan import plan_zoo
    from mimicbench.datagen.zoo.skin_weights import skin_weights

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        s = build_zoo(tmp, args.characters, seed=args.seed, progress=False)
        whole = time.perf_counter() - t0
    print(f"build_zoo: {s['characters']} characters, {s['motions']} clips in {whole:.2f} s "
          f"= {s['characters'] / whole:.2f} characters/s")

    stages = {"template": 0.0, "mesh": 0.0, "weights": 0.0, "clips": 0.0, "peer mesh (trimesh)": 0.0}
    for spec in plan_zoo(args.characters, seed=args.seed):
        t = time.perf_counter()
        skel, _ = build_skeleton(spec)
        stages["template"] += time.perf_counter() - t
        t = time.perf_counter()
        verts, faces, owner = build_mesh(skel, TARGET_FACES)
        stages["mesh"] += time.perf_counter() - t
        t = time.perf_counter()
        skin_weights(skel, verts, owner)
        stages["weights"] += time.perf_counter() - t
        t = time.perf_counter()
        for j, name in enumerate(clip_list(spec.category, skel, 3)):
            rv, root = generator(spec.category, name)(skel, np.random.default_rng(j), NUM_FRAMES)
            clip_transforms(skel, rv, root)
        stages["clips"] += time.perf_counter() - t
        per_bone = np.bincount(owner[faces[:, 0]], minlength=skel.num_joints)
        t = time.perf_counter()
        trimesh_capsules(skel, per_bone)
        stages["peer mesh (trimesh)"] += time.perf_counter() - t
    ours = sum(v for k, v in stages.items() if not k.startswith("peer"))
    for k, v in stages.items():
        share = f"{100 * v / ours:5.1f}% of the stages" if not k.startswith("peer") else ""
        print(f"  {k:22s} {v:7.3f} s  {share}")
    print(f"mesh stage: zoo capsule builder vs trimesh.creation.capsule + concatenate: "
          f"{stages['peer mesh (trimesh)'] / stages['mesh']:.2f}x faster")


if __name__ == "__main__":
    main()
