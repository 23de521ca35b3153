"""Apparel simulation speed: this stage's pybullet chains against Blender's rigid-body bake of the
same chains (the route MMDMC took), for 10, 50 and 200 apparel links.

The scene: a 0.3 x 0.4 x 0.2 m torso turning back and forth about the vertical (0.8 rad at
0.75 Hz) and swaying sideways, with chains of 5 links (capsules 8 cm long, 1.5 cm radius,
50 g) hanging in a ring around its waist like a skirt; 2 s at 30 fps, 8 physics substeps a
frame (240 Hz), 30 solver iterations, swing limit 0.7 rad, twist 0.2 rad. This stage: the
world of :mod:`datagen.apparel.world` (a kinematic convex torso, multibody chains with motors
and limits, anchors on moved constraints) stepped by :func:`datagen.apparel.simulate.simulate_clip`,
world set-up included. Blender: one active rigid body per link, Generic Spring constraints with
the same limits, the torso a keyed kinematic passive body, ``ptcache.bake`` over the clip (build
time not counted), in a child process (``benchmarks/apparel_blender_child.py``).

Printed per link count: CPU seconds per clip (``time.process_time`` of the process doing the
work, so other jobs on a shared machine do not count) and the real-time factor (clip seconds /
CPU seconds) of each route; the ratio Blender / this stage is printed last.

    python benchmarks/apparel.py [--links 10 50 200] [--seconds 2]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

FPS, SUBSTEPS, ITERATIONS = 30.0, 8, 30
LINK, RADIUS, MASS, PER_CHAIN = 0.08, 0.015, 0.05, 5
SWING, TWIST = 0.7, 0.2
TORSO_HEAD = np.array([0.0, 1.0, 0.0])
TORSO_BOX = np.array([[-0.15, 1.0, -0.1], [0.15, 1.4, 0.1]])


def scene(links: int, seconds: float):
    """Rest keypoints (K, 3) (torso first), link parents (L,), torso yaw (F,), torso shift (F, 3)."""
    chains = max(1, links // PER_CHAIN)
    heads, parents = [], []
    for c in range(chains):
        a = 2 * np.pi * c / chains
        root = TORSO_HEAD + np.array([0.2 * np.cos(a), -0.05, 0.14 * np.sin(a)])
        for i in range(PER_CHAIN):
            heads.append(root + np.array([0.0, -LINK * i, 0.0]))
            parents.append(-1 if i == 0 else len(heads) - 2)
    t = np.arange(int(round(seconds * FPS))) / FPS
    yaw = 0.8 * np.sin(2 * np.pi * 0.75 * t)
    shift = np.stack([0.1 * np.sin(2 * np.pi * 0.5 * t), np.zeros_like(t), np.zeros_like(t)], 1)
    return np.concatenate([TORSO_HEAD[None], heads]), np.array(parents), yaw, shift


def clip_transforms(keypoints, yaw, shift) -> np.ndarray:
    """(F, K, 7): every bone turned by ``yaw`` about Y through the torso head, then shifted."""
    out = []
    for a, s in zip(yaw, shift):
        q = np.array([np.cos(a / 2), 0.0, np.sin(a / 2), 0.0])
        c, si = np.cos(a), np.sin(a)
        rot = np.array([[c, 0, si], [0, 1, 0], [-si, 0, c]])
        t = (keypoints - TORSO_HEAD) @ rot.T + TORSO_HEAD + s
        out.append(np.concatenate([np.tile(q, (len(keypoints), 1)), t], 1))
    return np.array(out, np.float32)


def run_ours(keypoints, parents, yaw, shift) -> float:
    """CPU seconds to simulate the clip with this stage's world (set-up included)."""
    from datagen.apparel.body_shapes import body_pieces
    from datagen.apparel.chain_spec import ChainSpec, JointSpec, LinkSpec
    from datagen.apparel.params import ApparelParams
    from datagen.apparel.simulate import simulate_clip
    from datagen.apparel.world import ApparelWorld

    sim = ApparelParams().simulation
    box = np.array([[x, y, z] for x in TORSO_BOX[:, 0] for y in TORSO_BOX[:, 1] for z in TORSO_BOX[:, 2]])
    pieces = body_pieces(box, keypoints[:1], np.zeros(8, int), np.array([True]))
    chains, k = [], 1
    roots = [i for i, p in enumerate(parents) if p < 0]
    for r in roots:
        links = tuple(LinkSpec(k + r + i, keypoints[1 + r + i], np.array([0.0, -1.0, 0.0]), LINK, RADIUS, MASS,
                               0.1, 0.3) for i in range(PER_CHAIN))
        torque = [1.5 * sim.gravity * MASS * sum((j - i + 0.5) * LINK for j in range(i, PER_CHAIN)) for i in range(PER_CHAIN)]
        joints = tuple(JointSpec(SWING, TWIST, 0.03, 0.4, f) for f in torque)
        chains.append(ChainSpec(f"chain{r}", "skirt", 0, links, tuple(range(-1, PER_CHAIN - 1)), joints))
    clip = clip_transforms(keypoints, yaw, shift)
    start = time.process_time()
    with ApparelWorld(keypoints, pieces, chains, sim, 1.0 / (FPS * SUBSTEPS)) as world:
        simulate_clip(world, clip, SUBSTEPS, 0)
    return time.process_time() - start


def run_blender(keypoints, parents, yaw, shift, tmp: Path) -> float:
    """CPU seconds of Blender's rigid-body bake of the same chains, in a child process."""
    np.savez(tmp / "in.npz", torso_box=TORSO_BOX, torso_head=TORSO_HEAD, torso_yaw=yaw, torso_shift=shift,
             heads=keypoints[1:], parents=parents, length=LINK, radius=RADIUS, mass=MASS, swing=SWING, twist=TWIST,
             stiffness=20.0, damping=0.5, fps=FPS, substeps=SUBSTEPS, iterations=ITERATIONS)
    child = Path(__file__).with_name("apparel_blender_child.py")
    done = subprocess.run([sys.executable, str(child), str(tmp / "in.npz"), str(tmp / "out.npz")],
                          capture_output=True, text=True, timeout=3600)
    if done.returncode != 0:
        raise RuntimeError(f"Blender child failed:\n{done.stderr[-2000:]}")
    return float(np.load(tmp / "out.npz")["bake_seconds"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--links", type=int, nargs="+", default=[10, 50, 200])
    ap.add_argument("--seconds", type=float, default=2.0, help="clip length in seconds (default 2)")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="mimicbench-apparel-"))
    print(f"{'links':>6s} {'route':34s} {'cpu s/clip':>10s} {'x real time':>12s}")
    ratios = []
    for n in args.links:
        keypoints, parents, yaw, shift = scene(n, args.seconds)
        ours = run_ours(keypoints, parents, yaw, shift)
        blender = run_blender(keypoints, parents, yaw, shift, tmp)
        clip = len(yaw) / FPS
        for name, sec in (("mimicbench pybullet", ours), ("blender rigid-body bake", blender)):
            print(f"{len(parents):6d} {name:34s} {sec:10.3f} {clip / sec:12.1f}")
        ratios.append(f"{len(parents)} links {blender / ours:.1f}x")
    print("ratio blender / mimicbench (seconds per clip): " + "; ".join(ratios))


if __name__ == "__main__":
    main()
