"""Apparel simulation speed: this stage's pybullet chains against Blender's rigid-body bake of the
same chains (the route MMDMC took), for 10, 50 and 200 apparel links.

The scene: a 0.3 x 0.85 x 0.2 m torso-and-hips box turning back and forth about the vertical
(0.8 rad at 0.75 Hz) and swaying sideways, with chains of 5 links (capsules of 8 cm between
their caps, 1.5 cm radius, 50 g) hanging from the waist in a ring round the hips like a skirt,
close enough that the turning box strikes them; 2 s at 30 fps.

Both sides simulate the same thing: 8 physics steps a frame (240 Hz; Blender's
``substeps_per_frame`` x fps), 30 solver iterations, gravity 9.8 m/s^2, the same capsules,
masses and linear/angular damping, swing limit 0.7 rad and twist 0.2 rad, springs toward rest
with the stage's per-joint stiffness and damping (Blender: Generic Spring constraints, SPRING2,
given the diagonal of :class:`mimicbench.datagen.apparel.springs.Springs`), links colliding with the body
and not with other chains (Blender: the torso in every collision collection, each chain in one,
neighbours in different ones). Differences that stay: Blender's limits are a box on three Euler
angles where the stage's are a swing cone and a twist bound; Blender joins the root links to
the torso itself where the stage carries them on an anchor moved by a constraint (the issue's
design); the stage also projects joints back onto their limits after each step.

What is timed (CPU seconds, ``time.process_time`` of the process doing the work, so other jobs
on a shared machine do not count): Blender, the bake alone (``ptcache.bake``; building the scene
and starting Blender not counted, shown as its set-up); this stage, as a stage run does it: a
character's world is built once (set-up) and reset before each of its clips (the zoo gives a
character 3), so a clip costs its simulation (driving the body, stepping, the springs and limits,
reading the apparel bones each frame) plus a third of the set-up. Neither side's relaxation
frames are counted (the stage adds ``--relax-frames``, 30 by default, to each clip; MMDMC holds a
clip's first pose about 100 frames).

Printed per link count: set-up seconds, CPU seconds per clip and the real-time factor (clip
seconds / CPU seconds) of each route, and wall seconds per clip; the ratios Blender / this stage
last (above 1: this stage is faster), in CPU and in wall seconds. Blender's bake keeps a second
thread busy (its CPU seconds are about twice its wall seconds at 10 links), this stage one: on an
idle machine the wall ratio is the fairer one; on a loaded machine only the CPU one means anything.

    python benchmarks/apparel.py [--links 10 50 200] [--seconds 2] [--clips 3] [--no-blender]

The compiled joint kernels (numba, :mod:`mimicbench.datagen.apparel.joint_kernel`) are imported and called
once before any figure is timed; that first call (compiling them, or loading numba's cache of
them) is printed on its own line and is in no per-clip figure.

Measurements behind these choices: docs/notes/measurements.md.
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
CLIPS_PER_CHARACTER = 3  # the zoo's default: a character's set-up is shared by this many clips
LINK, RADIUS, MASS, PER_CHAIN = 0.08, 0.015, 0.05, 5
SWING, TWIST, STIFFNESS, DAMPING = 0.7, 0.2, 0.03, 0.6  # the stage's skirt defaults (damping 0.4 up to simulation version 11)
LINEAR_DAMPING, ANGULAR_DAMPING = 0.1, 0.3
TORSO_HEAD = np.array([0.0, 1.0, 0.0])
TORSO_BOX = np.array([[-0.15, 0.55, -0.1], [0.15, 1.4, 0.1]])  # torso and hips; the chains hang round the hips


def scene(links: int, seconds: float):
    """Rest keypoints (K, 3) (torso first), link parents (L,), torso yaw (F,), torso shift (F, 3)."""
    chains = max(1, links // PER_CHAIN)
    heads, parents = [], []
    for c in range(chains):
        a = 2 * np.pi * c / chains
        root = TORSO_HEAD + np.array([0.2 * np.cos(a), 0.0, 0.14 * np.sin(a)])
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


def stage_chains(keypoints, parents):
    """Body pieces and chains of the scene as the stage describes them (skirt defaults)."""
    from mimicbench.datagen.apparel.body_shapes import body_pieces
    from mimicbench.datagen.apparel.chain_spec import ChainSpec, JointSpec, LinkSpec
    from mimicbench.datagen.apparel.params import ApparelParams

    sim = ApparelParams().simulation
    box = np.array([[x, y, z] for x in TORSO_BOX[:, 0] for y in TORSO_BOX[:, 1] for z in TORSO_BOX[:, 2]])
    pieces = body_pieces(box, keypoints[:1], np.zeros(8, int), np.array([True]))
    chains = []
    for r in [i for i, p in enumerate(parents) if p < 0]:
        links = tuple(LinkSpec(1 + r + i, keypoints[1 + r + i], np.array([0.0, -1.0, 0.0]), LINK, RADIUS, MASS,
                               LINEAR_DAMPING, ANGULAR_DAMPING) for i in range(PER_CHAIN))
        torque = [2.0 * sim.gravity * MASS * sum((j - i + 0.5) * LINK for j in range(i, PER_CHAIN))
                  for i in range(PER_CHAIN)]  # the stage's skirt strength 2
        joints = tuple(JointSpec(SWING, TWIST, STIFFNESS, DAMPING, f) for f in torque)
        chains.append(ChainSpec(f"chain{r}", "skirt", 0, links, tuple(range(-1, PER_CHAIN - 1)), joints))
    return sim, pieces, chains


def run_ours(keypoints, parents, yaw, shift, clips: int = CLIPS_PER_CHARACTER) -> tuple[float, float, float]:
    """Seconds of this stage: (CPU set-up of the character's world, CPU and wall mean simulation
    of one clip).

    As the stage does it: one world per character (:mod:`mimicbench.datagen.apparel.world_cache`), reset
    before each of its ``clips`` clips (here the same clip each time).
    """
    from mimicbench.datagen.apparel.simulate import simulate_clip
    from mimicbench.datagen.apparel.world import ApparelWorld

    sim, pieces, chains = stage_chains(keypoints, parents)
    clip = clip_transforms(keypoints, yaw, shift)
    start = time.process_time()
    with ApparelWorld(keypoints, pieces, chains, sim, 1.0 / (FPS * SUBSTEPS)) as world:
        world.reset()
        built, built_wall = time.process_time(), time.perf_counter()
        for i in range(clips):
            if i:
                world.reset()
            simulate_clip(world, clip, SUBSTEPS, 0, sim.max_resettles)
        done, done_wall = time.process_time(), time.perf_counter()
    return built - start, (done - built) / clips, (done_wall - built_wall) / clips


def first_kernel_call() -> tuple[float, float]:
    """Wall seconds of importing the compiled joint kernels (numba) and of their first call in this
    process (compiling them, or loading numba's cache of them beside the module), on the 10-link
    scene's first frame; once a process, so kept out of every per-clip figure (a stage worker
    pays it once)."""
    start = time.perf_counter()
    from mimicbench.datagen.apparel.simulate import simulate_clip
    from mimicbench.datagen.apparel.world import ApparelWorld

    imported = time.perf_counter()
    keypoints, parents, yaw, shift = scene(10, 1.0 / FPS)
    sim, pieces, chains = stage_chains(keypoints, parents)
    with ApparelWorld(keypoints, pieces, chains, sim, 1.0 / (FPS * SUBSTEPS)) as world:
        world.reset()
        first = time.perf_counter()
        simulate_clip(world, clip_transforms(keypoints, yaw, shift), SUBSTEPS, 0, sim.max_resettles)
        return imported - start, time.perf_counter() - first


def blender_springs(keypoints, parents) -> tuple[np.ndarray, np.ndarray]:
    """(L, 3) spring stiffness (N m/rad) and damping (N m s/rad) per link and axis (swing x, y,
    twist z): the diagonal K and C of this stage's springs (:mod:`mimicbench.datagen.apparel.springs`)."""
    from mimicbench.datagen.apparel.springs import Springs

    _, _, chains = stage_chains(keypoints, parents)
    dt = 1.0 / (FPS * SUBSTEPS)
    springs = Springs(chains, dt)
    stiffness = springs.stiffness.reshape(-1, 3)
    return stiffness, (springs.damping.reshape(-1, 3) - stiffness * dt)


def run_blender(keypoints, parents, yaw, shift, tmp: Path) -> tuple[float, float, float]:
    """Seconds of Blender's rigid-body route in a child process: (CPU build, CPU bake, wall bake)."""
    stiffness, damping = blender_springs(keypoints, parents)
    chain_of = np.cumsum(np.asarray(parents) < 0) - 1
    np.savez(tmp / "in.npz", torso_box=TORSO_BOX, torso_head=TORSO_HEAD, torso_yaw=yaw, torso_shift=shift,
             heads=keypoints[1:], parents=parents, chain_of=chain_of, length=LINK, radius=RADIUS, mass=MASS,
             swing=SWING, twist=TWIST, stiffness=stiffness, damping=damping, linear_damping=LINEAR_DAMPING,
             angular_damping=ANGULAR_DAMPING, gravity=9.8, fps=FPS, substeps=SUBSTEPS, iterations=ITERATIONS)
    child = Path(__file__).with_name("apparel_blender_child.py")
    done = subprocess.run([sys.executable, str(child), str(tmp / "in.npz"), str(tmp / "out.npz")],
                          capture_output=True, text=True, timeout=3600)
    if done.returncode != 0:
        raise RuntimeError(f"Blender child failed:\n{done.stderr[-2000:]}")
    out = np.load(tmp / "out.npz")
    return float(out["build_seconds"]), float(out["bake_seconds"]), float(out["bake_wall_seconds"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--links", type=int, nargs="+", default=[10, 50, 200])
    ap.add_argument("--seconds", type=float, default=2.0, help="clip length in seconds (default 2)")
    ap.add_argument("--clips", type=int, default=CLIPS_PER_CHARACTER,
                    help=f"clips per character sharing one set-up (default {CLIPS_PER_CHARACTER}, the zoo's)")
    ap.add_argument("--no-blender", action="store_true", help="time this stage only")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="mimicbench-apparel-"))
    imported, first = first_kernel_call()
    print(f"once a process, not in the figures below: importing the stage {imported:.2f} s, the compiled joint "
          f"kernels' first call {first:.2f} s (numba compiles them, or loads its cache)")
    print(f"{'links':>6s} {'route':26s} {'set-up s':>9s} {'cpu s/clip':>11s} {'x real time':>12s} {'wall s/clip':>12s}")
    ratios, wall_ratios = [], []
    for n in args.links:
        keypoints, parents, yaw, shift = scene(n, args.seconds)
        clip = len(yaw) / FPS
        setup, per_clip, per_clip_wall = run_ours(keypoints, parents, yaw, shift, args.clips)
        ours, ours_wall = per_clip + setup / args.clips, per_clip_wall + setup / args.clips
        rows = [("mimicbench pybullet", setup, ours, ours_wall)]
        if not args.no_blender:
            build, bake, bake_wall = run_blender(keypoints, parents, yaw, shift, tmp)
            rows.append(("blender rigid-body bake", build, bake, bake_wall))
            ratios.append(f"{len(parents)} links {bake / ours:.2f}x")
            wall_ratios.append(f"{len(parents)} links {bake_wall / ours_wall:.2f}x")
        for name, first, sec, wall in rows:
            print(f"{len(parents):6d} {name:26s} {first:9.3f} {sec:11.3f} {clip / sec:12.1f} {wall:12.3f}")
    if ratios:
        print("ratio blender / mimicbench (CPU seconds per clip; above 1: mimicbench is faster): " + "; ".join(ratios))
        print("the same in wall seconds (fair only on an idle machine; Blender's bake may use threads): "
              + "; ".join(wall_ratios))


if __name__ == "__main__":
    main()
