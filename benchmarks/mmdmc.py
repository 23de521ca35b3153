"""MMDMC reference speed: training steps per second of each stage, inference frames per second on
CPU (and on CUDA where a GPU is present), against the apparel stage's Bullet simulation of the same
clip (what the model stands in for).

The clip: the first simulated clip of the first character of DATASET (a ``mimicbench datagen
apparel`` output). Simulation: :func:`mimicbench.datagen.apparel.setup.simulate_motion` at 240 Hz with the
default parameters, relaxation frames included (as the stage runs it). Inference: the shipped
``mmdmc`` answering the whole clip as one motion request, once cold (geodesics, mask and weights
computed) and once warm (cached per character). Training: ``--steps`` optimiser steps of each
stage on batches of DATASET, the shipped modules as the frozen earlier stages.

    python benchmarks/mmdmc.py DATASET [--steps 5]

Printed last: inference frames per second / simulation frames per second (warm, CPU).
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch


def simulation_fps(record, motion) -> float:
    from mimicbench.datagen.apparel.params import ApparelParams
    from mimicbench.datagen.apparel.setup import character_physics, simulate_motion

    params = ApparelParams()
    start = time.perf_counter()
    physics = character_physics(record, record.apparel_bone_mask, record.apparel_vertex_mask, params)
    simulate_motion(record, physics, motion, params, 240.0, 30)
    return motion.num_frames / (time.perf_counter() - start)


def inference_fps(record, motion, device: str) -> tuple[float, float]:
    from mimicbench.benchmark.registry import get_method
    from mimicbench.benchmark.request import MotionRequest, Rig

    rig = Rig(record.character_id, record.category, record.vertices, record.faces, record.keypoints, record.parents,
              record.weights, record.bone_names)
    k = len(record.parents)
    req = MotionRequest(rig, np.asarray(motion.transforms, np.float32).reshape(-1, k, 7),
                        ~np.asarray(record.apparel_bone_mask, bool), float(motion.fps))
    method = get_method("mmdmc")
    method.setup(device)
    times = []
    for _ in range(2):
        start = time.perf_counter()
        method.transfer_motion([req])
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        times.append(time.perf_counter() - start)
    return motion.num_frames / times[0], motion.num_frames / times[1]


def training_steps_per_second(dataset, steps: int) -> dict:
    from mimicbench.baselines.mmdmc.method import checkpoint_path, load_modules
    from mimicbench.training.checkpoint import read_header
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    model = trainable("mmdmc")
    # the settings the shipped weights were trained with (the last stage's header holds the run's config)
    cfg = {**model.config("small"), **read_header(checkpoint_path("apparel"))["config"]}
    mods = load_modules()
    frozen = {"seg": mods.seg, "body": mods.body, "apparel": mods.apparel}
    out = {}
    for stage in model.stages:
        ctx = StageContext(dataset, torch.device("cpu"), cfg, {n: frozen[n] for n in stage.needs})
        module = stage.build(cfg, ctx)
        opt = torch.optim.AdamW(module.parameters(), lr=cfg["lr"])
        batches = stage.batches(cfg, ctx, np.random.default_rng(0))
        next(iter(batches))  # data loading and per-character caches outside the timing
        start, done = time.perf_counter(), 0
        for batch in batches:
            batch = {k: torch.as_tensor(v) if isinstance(v, np.ndarray) else v for k, v in batch.items()}
            loss = stage.loss(module, batch, ctx)["total"]
            opt.zero_grad()
            loss.backward()
            opt.step()
            done += 1
            if done == steps:
                break
        out[stage.name] = done / (time.perf_counter() - start)
    return out


def main() -> None:
    from mimicbench.schemas.shards import read_records

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset")
    p.add_argument("--steps", type=int, default=5)
    args = p.parse_args()
    torch.set_num_threads(max(1, torch.get_num_threads()))
    chars = {c.character_id: c for c in read_records(args.dataset, "characters") if np.asarray(c.apparel_bone_mask).any()}
    motions = [m for m in read_records(args.dataset, "motions") if m.character_id in chars and not m.name.endswith("@sim")]
    if not motions:
        raise SystemExit(f"{args.dataset}: no apparel character with a clip; run `mimicbench datagen apparel` first")
    motion = sorted(motions, key=lambda m: m.motion_id)[0]
    record = chars[motion.character_id]
    print(f"clip {motion.motion_id}: {motion.num_frames} frames, {len(record.vertices)} vertices, "
          f"{int(np.sum(record.apparel_bone_mask))} apparel bones")
    for stage, rate in training_steps_per_second(args.dataset, args.steps).items():
        print(f"training {stage:8s} {rate:7.2f} steps/s (CPU, small config)")
    sim = simulation_fps(record, motion)
    print(f"simulation (pybullet, 240 Hz)   {sim:8.1f} frames/s")
    cold, warm = inference_fps(record, motion, "cpu")
    print(f"mmdmc inference CPU cold / warm {cold:8.1f} / {warm:.1f} frames/s")
    if torch.cuda.is_available():
        gcold, gwarm = inference_fps(record, motion, "cuda")
        print(f"mmdmc inference CUDA cold / warm {gcold:8.1f} / {gwarm:.1f} frames/s (ratio to simulation {gwarm / sim:.2f})")
    print(f"ratio mmdmc inference (CPU, warm) / simulation: {warm / sim:.2f}")


if __name__ == "__main__":
    main()
