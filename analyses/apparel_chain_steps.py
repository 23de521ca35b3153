"""Issue 33: one apparel chain of one clip logged physics step by physics step.

The clip is simulated as the apparel stage does it (:func:`mimicbench.datagen.apparel.setup.character_physics`,
:class:`mimicbench.datagen.apparel.world.ApparelWorld`, :func:`mimicbench.datagen.apparel.simulate.simulate_clip`); after
every step of clip frames ``--frames A B`` (relaxation frames negative), before the world's own
limits and springs act on it, one line for the chain that holds ``--bone`` (the chain from that
bone's link down its first children):

- ``w``: each joint's speed (rad/s); ``b`` / ``tw``: its swing and twist (rad, the rotation vector's
  parts across and along the bone; the world projects them onto the kind's limits after the step);
- ``v``: each link's speed (m/s);
- ``root``: the first link's depth in each body piece it overlaps (mm, negative inside; also pairs
  whose collision is off);
- ``c``: each contact of the chain's links with a body piece: link, piece, depth (mm), normal force (N).

At the start: the chain's anchor bone, its links' contact frequencies and each link's distance from
the body pieces at rest (mm).

    PYTHONPATH=. OMP_NUM_THREADS=1 python analyses/apparel_chain_steps.py ZOO apparel-0000 random_poses \\
        --bone 92 --frames 17 21 --relax 20 [--params JSON]
"""
from __future__ import annotations

import argparse
import json

import numpy as np
from scipy.spatial.transform import Rotation

from mimicbench.datagen.apparel.params import params_from_json
from mimicbench.datagen.apparel.setup import character_physics, physics_step, substeps_for
from mimicbench.datagen.apparel.simulate import simulate_clip
from mimicbench.datagen.apparel.world import ApparelWorld
from mimicbench.schemas.shards import read_records

PHYSICS_FPS = 240.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("zoo")
    ap.add_argument("character", help="character id's last part (apparel-0000)")
    ap.add_argument("clip", help="clip name (random_poses, jump, ...)")
    ap.add_argument("--bone", type=int, required=True, help="a bone of the chain's first logged link")
    ap.add_argument("--frames", type=int, nargs=2, default=[0, 5], help="clip frames to log, [A, B)")
    ap.add_argument("--relax", type=int, default=30, help="relaxation frames (the stage's default 30)")
    ap.add_argument("--params", default="{}", help="the stage's --params JSON, inline")
    args = ap.parse_args()

    params = params_from_json(json.loads(args.params))
    rec = next(r for r in read_records(args.zoo, "characters") if r.character_id.split("/")[-1] == args.character)
    motion = next(m for m in read_records(args.zoo, "motions")
                  if m.character_id == rec.character_id and m.name == args.clip)
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    world = ApparelWorld(rec.keypoints, physics.pieces, physics.chains, params.simulation,
                         physics_step(PHYSICS_FPS, motion.fps))
    pb, cid = world.pb, world.client
    chain = next(c for c in world.chains if args.bone in c.spec.bones)
    links = [chain.spec.bones.index(args.bone)]
    while True:
        children = [k for k, p in enumerate(chain.spec.link_parents) if p == links[-1]]
        if not children:
            break
        links.append(children[0])
    name = {body: rec.bone_names[p.bone].split(":")[-1] for body, p in zip(world.piece_ids, physics.pieces)}
    print(f"anchor {rec.bone_names[chain.spec.anchor_bone]}, links {links}, contact frequency "
          f"{[chain.spec.links[j].contact_frequency for j in links]} rad/s")
    for body in world.piece_ids:
        for point in pb.getClosestPoints(chain.body, body, 0.05, physicsClientId=cid):
            if point[3] in links:
                print(f"  at rest: link {point[3]} to {name[body]} {point[8] * 1000:.1f} mm")
    substeps = substeps_for(PHYSICS_FPS, motion.fps)
    first, last = (args.relax + args.frames[0]) * substeps, (args.relax + args.frames[1]) * substeps
    step, after = [0], world._after_step

    def logged() -> None:
        s = step[0]
        step[0] += 1
        if first <= s < last:
            states = pb.getJointStatesMultiDof(chain.body, links, physicsClientId=cid)
            speed = [np.linalg.norm(x[1]) for x in states]
            r = Rotation.from_quat([x[0] for x in states]).as_rotvec()
            contacts, depth = [], []
            for body in world.piece_ids:
                for p in pb.getContactPoints(chain.body, body, physicsClientId=cid):
                    if p[3] in links:
                        contacts.append(f"L{links.index(p[3])}{name[body][-8:]}:{p[8] * 1000:.1f}/{p[9]:.1f}N")
                inside = [p[8] for p in pb.getClosestPoints(chain.body, body, 0.0, linkIndexA=links[0],
                                                            physicsClientId=cid)]
                if inside:
                    depth.append(f"{name[body]}:{min(inside) * 1000:.1f}")
            v = [np.linalg.norm(x[6]) for x in pb.getLinkStates(chain.body, links, computeLinkVelocity=1,
                                                                 physicsClientId=cid)]
            print(f"f{s // substeps - args.relax:4d}.{s % substeps} w " + " ".join(f"{x:5.1f}" for x in speed)
                  + " |b " + " ".join(f"{x:4.2f}" for x in np.hypot(r[:, 0], r[:, 1]))
                  + " tw " + " ".join(f"{x:+4.2f}" for x in r[:, 2]) + " |v " + " ".join(f"{x:5.2f}" for x in v)
                  + " |root " + " ".join(depth) + " |c " + " ".join(contacts))
        after()

    world._after_step = logged
    with world:
        simulate_clip(world, motion.transforms, substeps, args.relax, params.simulation.max_resettles)


if __name__ == "__main__":
    main()
