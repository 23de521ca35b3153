"""Speed of the MimiCAT reference: training steps per second and inference seconds per case.

Builds (or reuses) a 16-character zoo resampled to 5,000 faces with correspondences and cases
(the demo's data), then:

- training: steps per second of the ``corr`` stage (G) and of the ``transfer`` stage (H, both
  cycle legs, with L_reg when the checkpoint has a prior), each a loss, a backward pass and an
  AdamW step on the stage's configured batch, frozen modules from the checkpoint;
- the transfer stage before and after, on the same batches: before, G's Sinkhorn in log space
  for the pairs each step meets and every rest mesh through E every step (the code up to version
  3); then with the shared caches alone
  (:data:`mimicbench.baselines.mimicat.transfer_training.SHARED_CACHES`: G's M computed once per pair at an
  epoch's start, E's rest tokens once per mesh); after, the caches and G's Sinkhorn by matrix
  scaling (:func:`mimicbench.geometry.sinkhorn.sinkhorn_scaling_torch`); a first epoch from empty caches
  (the epoch's M computation included in its time) and a second epoch in the same process;
- inference: seconds per request of ``mimicat`` (E -> G -> H -> LBS, with and without ARAP) on
  the cases' forward requests, against the named peer ``text_soft`` (the same initialisation
  without the networks); the last line is mimicat's time per case over text_soft's.

    python benchmarks/mimicat.py [--work DIR] [--checkpoint DIR] [--device cpu|cuda] [--steps 20] [--cases 48]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)  # run as a script, benchmarks/baselines.py would hide the `baselines` package


def dataset(work: Path) -> Path:
    from mimicbench.benchmark.cases import build_cases, write_cases
    from mimicbench.datagen.correspond.stage import correspond_dataset
    from mimicbench.datagen.resample.stage import resample_dataset
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import has_table

    zoo, data = work / "zoo", work / "zoo5k"
    if not (zoo / "manifest.json").exists():
        build_zoo(zoo, 16, seed=0, clips_per_character=3, progress=False)
    if not (data / "manifest.json").exists():
        resample_dataset(zoo, data, faces=5000, backend="fast", progress=False)
    if not has_table(data, "pairs"):
        correspond_dataset(data, all_pairs=True, encoder="minilm", progress=False)
    if not has_table(data, "cases"):
        write_cases(data, build_cases(data, "all", h2h_pairs=100, h2h_poses=4, cct_pairs=24, cct_poses=2), {})
    return data


def training_steps_per_second(stage_name: str, data: Path, checkpoint: Path, device: torch.device, steps: int) -> float:
    from mimicbench.baselines.mimicat.method import checkpoint_path
    from mimicbench.training.checkpoint import load_module, read_header
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    model = trainable("mimicat")
    stage = model.stage(stage_name)
    config = read_header(checkpoint_path(checkpoint, stage_name))["config"]
    ctx = StageContext(data, device, config)
    for need in stage.needs:
        m = load_module(checkpoint_path(checkpoint, need), lambda cfg, s=model.stage(need): s.build(cfg, ctx), device)
        for p in m.parameters():
            p.requires_grad_(False)
        ctx.frozen[need] = m.eval()
    return timed_steps(stage, config, ctx, device, steps)


def timed_steps(stage, config: dict, ctx, device: torch.device, steps: int) -> float:
    """Training steps per second of a fresh network of ``stage`` (seed 0, AdamW lr 1e-4) over its own
    batches: ``steps`` timed after two warm-up steps that fill the caches."""
    from mimicbench.training.loop import _to_device

    torch.manual_seed(0)
    module = stage.build(config, ctx).to(device)
    opt = torch.optim.AdamW(module.parameters(), lr=1e-4)
    rng = np.random.default_rng(0)

    def batches():
        while True:
            yield from stage.batches(config, ctx, rng)

    it = batches()
    for i in range(steps + 2):
        if i == 2:
            if device.type == "cuda":
                torch.cuda.synchronize()
            t0 = time.perf_counter()
        loss = stage.loss(module, _to_device(next(it), device), ctx)["total"]
        opt.zero_grad()
        loss.backward()
        opt.step()
    if device.type == "cuda":
        torch.cuda.synchronize()
    return steps / (time.perf_counter() - t0)


def transfer_epochs_steps_per_second(data: Path, checkpoint: Path, device: torch.device, steps: int,
                                     shared: bool, scaling: bool) -> tuple[float, float]:
    """Steps per second of two epochs of ``steps`` steps of the transfer stage, caches emptied
    first, with the shared caches on or off and G's no-gradient Sinkhorn by matrix scaling or in
    log space; each epoch timed from its first batch (the epoch's M precomputation included)."""
    import mimicbench.baselines.mimicat.correspondence as corr
    import mimicbench.baselines.mimicat.transfer_training as tt
    from mimicbench.geometry.sinkhorn import sinkhorn_log, sinkhorn_scaling_torch
    from mimicbench.baselines.mimicat.method import checkpoint_path
    from mimicbench.training.checkpoint import load_module, read_header
    from mimicbench.training.loop import _to_device
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    model = trainable("mimicat")
    stage = model.stage("transfer")
    config = read_header(checkpoint_path(checkpoint, "transfer"))["config"]
    c = config["transfer"]
    config = {**config, "transfer": {**c, "examples_per_epoch": steps * int(c.get("batch_size", 4))}}
    ctx = StageContext(data, device, config)
    for need in stage.needs:
        m = load_module(checkpoint_path(checkpoint, need), lambda cfg, s=model.stage(need): s.build(cfg, ctx), device)
        for p in m.parameters():
            p.requires_grad_(False)
        ctx.frozen[need] = m.eval()
    tt._CACHE.clear()
    tt.SHARED_CACHES = shared
    if not scaling:  # the log-space iteration every G call used before
        corr.sinkhorn_scaling_torch = lambda s, temperature, num_iters, tol: sinkhorn_log(
            s, temperature=temperature, num_iters=num_iters, tol=tol)
    torch.manual_seed(0)
    module = stage.build(config, ctx).to(device)
    opt = torch.optim.AdamW(module.parameters(), lr=1e-4)
    rates = []
    try:
        for epoch in range(2):
            rng = np.random.default_rng(epoch)
            t0 = time.perf_counter()
            n = 0
            for batch in stage.batches(config, ctx, rng):
                loss = stage.loss(module, _to_device(batch, device), ctx)["total"]
                opt.zero_grad()
                loss.backward()
                opt.step()
                n += 1
            if device.type == "cuda":
                torch.cuda.synchronize()
            rates.append(n / (time.perf_counter() - t0))
    finally:
        tt.SHARED_CACHES = True
        corr.sinkhorn_scaling_torch = sinkhorn_scaling_torch
    return rates[0], rates[1]


def seconds_per_case(method, requests) -> float:
    method.transfer(requests[:2])  # warm-up: weights, caches
    t0 = time.perf_counter()
    method.transfer(requests)
    return (time.perf_counter() - t0) / len(requests)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default=None, help="folder for the data (default: a temporary folder)")
    ap.add_argument("--checkpoint", default=None, help="checkpoint folder (default: the bundled one)")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--steps", type=int, default=20, help="timed training steps per stage")
    ap.add_argument("--cases", type=int, default=48, help="forward requests timed")
    args = ap.parse_args()
    from mimicbench.baselines.mimicat.method import BUNDLED, Mimicat
    from mimicbench.baselines.text_soft import TextSoft
    from mimicbench.benchmark.evaluator import load_cases
    from mimicbench.benchmark.protocols.base import EvalData

    device = torch.device(args.device)
    checkpoint = Path(args.checkpoint) if args.checkpoint else BUNDLED
    data = dataset(Path(args.work or tempfile.mkdtemp(prefix="mimicbench-mimicat-")))
    print(f"device {device}, torch threads {torch.get_num_threads()}, checkpoint {checkpoint}")
    for stage in ("corr", "transfer"):
        print(f"training {stage}: {training_steps_per_second(stage, data, checkpoint, device, args.steps):.2f} steps/s")
    before = transfer_epochs_steps_per_second(data, checkpoint, device, args.steps, shared=False, scaling=False)
    caches = transfer_epochs_steps_per_second(data, checkpoint, device, args.steps, shared=True, scaling=False)
    after = transfer_epochs_steps_per_second(data, checkpoint, device, args.steps, shared=True, scaling=True)
    for i, name in enumerate(("first epoch (empty caches)", "second epoch")):
        print(f"transfer {name}: before {before[i]:.3f} steps/s, caches alone {caches[i]:.3f}, after "
              f"{after[i]:.3f} ({after[i] / before[i]:.2f}x)")
    ev = EvalData.load(data)
    by_protocol = load_cases(data, ("h2h", "cct"))
    cases = [c for p in ("h2h", "cct") for c in by_protocol[p][:args.cases // 2]]
    requests = [ev.request(ev.characters[c.source_id], ev.posed(ev.characters[c.source_id], c.source_transforms),
                           ev.characters[c.target_id], c.case_id) for c in cases]
    peer = seconds_per_case(TextSoft(), requests)
    print(f"text_soft: {peer:.4f} s/case")
    no_arap = Mimicat(checkpoint, arap=False)
    no_arap.setup(args.device)
    print(f"mimicat without ARAP: {seconds_per_case(no_arap, requests):.4f} s/case")
    full = Mimicat(checkpoint)
    full.setup(args.device)
    ours = seconds_per_case(full, requests)
    print(f"mimicat: {ours:.4f} s/case ({len(requests)} cases)")
    print(f"mimicat / text_soft time per case: {ours / peer:.2f}")


if __name__ == "__main__":
    main()
