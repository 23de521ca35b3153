"""Train one stage of a registered model: AdamW, seeds, DDP under torchrun, checkpoints, loss log.

Files under ``OUT`` (rank 0 writes):

- ``OUT/<stage>/resume.json`` naming ``OUT/<stage>/resume-<epoch>-<id>/`` with ``last.safetensors``
  and ``state.pt``: after every epoch, written as one unit (:func:`~.checkpoint.save_resume`; a kill
  leaves the previous pair): weights with header; optimizer state, epoch count, seed, config and the
  dataset's table fingerprints, read back with ``weights_only=True``. A re-run with the same config,
  seed and dataset resumes from them and ends with the weights an uninterrupted run has; a resume
  point of another config, seed or dataset is refused with one line.
- ``OUT/<stage>/loss.csv`` (one row a step: epoch, step, every loss key, averaged over ranks) and
  ``OUT/<stage>/loss.png``.
- ``OUT/<stage>/model.safetensors``: the final weights; ``OUT/config.json``: the config.
- ``<file>.sha256`` beside each checkpoint and resume state; both are verified before a resume
  (a changed byte is refused with a one-line error, never trained on), and so is every trained
  stage a stage needs before it is loaded (a missing digest file is refused too).

Repeatability: torch, numpy and ``random`` are seeded from ``seed`` before the module is built,
and again from (seed, epoch, rank) at the start of every epoch; each epoch's batch order comes
from ``numpy.random.default_rng([seed, epoch])``, identical on every rank. So a run repeats
exactly on CPU, and a resumed run continues where the uninterrupted one would be.
"""
from __future__ import annotations

import json
import math
import random
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from mimicbench.training import checkpoint, loss_log
from mimicbench.training.distributed import barrier, gather_objects, init_distributed
from mimicbench.training.registry import trainable
from mimicbench.training.stage import StageContext, TrainStage
from mimicbench.schemas.errors import UserError

DEFAULT_LR = 1e-4
DEFAULT_WEIGHT_DECAY = 0.01


@dataclass
class StageResult:
    """What :func:`train_stage_result` did: for the CLI's summary."""

    stage: str
    model_path: Path
    epochs: int
    epochs_run: int
    seconds: float
    final: dict = field(default_factory=dict)  # last epoch's mean of every loss key


def stage_setting(config: dict, stage: str, key: str, default):
    """``config[stage][key]``, else ``config[key]``, else ``default``."""
    sub = config.get(stage)
    if isinstance(sub, dict) and key in sub:
        return sub[key]
    return config.get(key, default)


def seed_everything(seed: int) -> None:
    """Seed torch, numpy's global generator and ``random``."""
    torch.manual_seed(seed)
    np.random.seed(seed % 2**32)
    random.seed(seed)


def _epoch_seed(seed: int, epoch: int, rank: int) -> int:
    return int(np.random.SeedSequence([seed, epoch, rank]).generate_state(1)[0])


def _to_device(value, device: torch.device):
    if isinstance(value, torch.Tensor):
        return value.to(device)
    if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
        return torch.from_numpy(np.ascontiguousarray(value)).to(device)
    if isinstance(value, dict):
        return {k: _to_device(v, device) for k, v in value.items()}
    return value


class _LossModule(torch.nn.Module):
    """Wraps the trained module so DDP sees the whole loss computation as one forward."""

    def __init__(self, module: torch.nn.Module, stage: TrainStage, context: StageContext):
        super().__init__()
        self.module = module
        self._loss = stage.loss
        self._context = context

    def forward(self, batch: dict) -> dict:
        return self._loss(self.module, batch, self._context)


def load_frozen(model_name: str, stage: TrainStage, out: Path, context: StageContext) -> dict[str, torch.nn.Module]:
    """The trained modules of ``stage.needs`` from ``OUT/<need>/model.safetensors``, frozen on the device."""
    model = trainable(model_name)
    frozen: dict[str, torch.nn.Module] = {}
    for need in stage.needs:
        path = out / need / "model.safetensors"
        if not path.is_file():
            raise UserError(f"stage {stage.name!r} needs the trained stage {need!r}, but {path} is missing; "
                            f"train it first: mimicbench train {model_name} DATASET --out {out} --stage {need}")
        need_stage = model.stage(need)
        ctx = StageContext(context.dataset, context.device, context.config, dict(frozen), context.rank,
                           context.world_size)
        checkpoint.verify_digest(path, f"train stage {need!r} again (--stage {need} --no-resume), or write "
                                 f"its digest with `sha256sum model.safetensors > model.safetensors.sha256` in "
                                 f"{path.parent} if you trust the file")
        module = checkpoint.load_module(path, lambda cfg, s=need_stage, c=ctx: s.build(cfg, c), context.device,
                                        expect=(model_name, need))
        for p in module.parameters():
            p.requires_grad_(False)
        frozen[need] = module.eval()
    return frozen


def check_same_run(stage_dir: Path, stage: str, state: dict, header: dict, config_json: str, seed: int,
                   tables: dict | None, weights_path: Path) -> None:
    """Refuse, in one line, a resume point that is not this run's: another config or seed (in the
    state or in the weights' header), another dataset (table fingerprints), weights and state of
    two different epochs or runs.

    Raises:
        UserError: naming what differs and how to go on (a new --out, the same options, --no-resume).
    """
    how = "pick a new --out, the same --config/--set/--seed and dataset, or --no-resume to start this stage over"
    head_config = json.dumps(header.get("config"), sort_keys=True)
    for what, mine, theirs in (("seed", seed, state.get("seed")), ("seed", seed, header.get("seed")),
                               ("config", config_json, state.get("config_json")), ("config", config_json, head_config)):
        if theirs != mine:
            shown = f" (seed {theirs}, this run's {mine})" if what == "seed" else ""
            raise UserError(f"{stage_dir} holds a run of stage {stage!r} with another {what}{shown}; {how}")
    theirs = state.get("dataset_tables", (header.get("dataset") or {}).get("tables"))
    if tables is not None and theirs is not None and theirs != tables:
        differ = sorted(t for t in set(tables) | set(theirs) if tables.get(t) != theirs.get(t))
        name = (header.get("dataset") or {}).get("name", "?")
        raise UserError(f"{stage_dir} holds a run of stage {stage!r} on another dataset ({name!r}; tables "
                        f"{', '.join(differ)} differ from this one's); {how}")
    if header.get("epoch") != state.get("epoch"):
        raise UserError(f"{weights_path} (epoch {header.get('epoch')}) and its state (epoch {state.get('epoch')}) "
                        f"disagree; use --no-resume to start this stage over")
    if "weights_sha256" in state:
        from mimicbench.schemas.manifest import sha256_of

        if sha256_of(weights_path) != state["weights_sha256"]:
            raise UserError(f"{weights_path}: not the weights its state was saved with; use --no-resume to start "
                            f"this stage over")


def train_stage(model_name: str, stage_name: str, dataset, out, config: dict, device="cpu",
                epochs: int | None = None, seed: int = 0, resume: bool = True, progress: bool = True) -> Path:
    """Train one stage and return the path of its ``model.safetensors``.

    Args:
        model_name: a registered trainable (``mimicat``, ``mmdmc``).
        stage_name: one of its stages.
        dataset: the dataset folder.
        out: the run folder (``OUT``).
        config: the whole model config (preset with overrides). The loop reads ``lr`` (default
            1e-4), ``weight_decay`` (0.01), ``grad_clip`` (none) and ``epochs`` from
            ``config[stage]`` or else the top level.
        device: ``"cpu"``, ``"cuda"`` (under torchrun: ``cuda:LOCAL_RANK``) or a torch.device.
        epochs: total epochs to reach (None: from the config, else 1). A resumed run trains only
            the missing ones; a finished one just re-writes model.safetensors.
        seed: the run's seed.
        resume: continue from ``OUT/<stage>/state.pt`` when present (else start over).
        progress: show tqdm bars (rank 0 only).
    """
    return train_stage_result(model_name, stage_name, dataset, out, config, device, epochs, seed, resume,
                              progress).model_path


def train_stage_result(model_name: str, stage_name: str, dataset, out, config: dict, device="cpu",
                       epochs: int | None = None, seed: int = 0, resume: bool = True,
                       progress: bool = True) -> StageResult:
    """:func:`train_stage`, returning a :class:`StageResult` (path, epochs, seconds, final losses)."""
    from tqdm import tqdm

    started = time.perf_counter()
    model = trainable(model_name)
    stage = model.stage(stage_name)
    dataset, out = Path(dataset), Path(out)
    device = torch.device(device)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise UserError("--device cuda asked for, but torch sees no CUDA device here; use --device cpu")
    rank, world, device, created_group = init_distributed(device)
    try:
        epochs = int(epochs if epochs is not None else stage_setting(config, stage.name, "epochs", 1))
        if epochs < 0:
            raise UserError(f"epochs must be >= 0, got {epochs}")
        lr = float(stage_setting(config, stage.name, "lr", DEFAULT_LR))
        weight_decay = float(stage_setting(config, stage.name, "weight_decay", DEFAULT_WEIGHT_DECAY))
        grad_clip = stage_setting(config, stage.name, "grad_clip", None)
        stage_dir = out / stage.name
        csv_path, png_path, final_path = stage_dir / "loss.csv", stage_dir / "loss.png", stage_dir / "model.safetensors"
        config_json = json.dumps(config, sort_keys=True)

        context = StageContext(dataset, device, config, {}, rank, world)
        seed_everything(seed)
        context.frozen = load_frozen(model_name, stage, out, context)
        seed_everything(seed)
        module = stage.build(config, context).to(device)
        params = [p for p in module.parameters() if p.requires_grad]
        if not params:
            raise ValueError(f"stage {stage.name!r}: build() returned a module without trainable parameters")
        optimizer = torch.optim.AdamW(params, lr=lr, weight_decay=weight_decay)

        start_epoch = 0
        data_tables = checkpoint.dataset_provenance(dataset).get("tables")
        found = checkpoint.find_resume(stage_dir) if resume else None  # verified: a flipped byte is refused
        if found is not None:
            last_path, state_path = found
            state = checkpoint.load_state(state_path)
            weights, header = checkpoint.load_checkpoint(last_path, device)
            check_same_run(stage_dir, stage.name, state, header, config_json, seed, data_tables, last_path)
            module.load_state_dict(weights)
            optimizer.load_state_dict(state["optimizer"])
            start_epoch = int(state["epoch"])
        rows = [r for r in loss_log.read_rows(csv_path) if r["epoch"] < start_epoch] if start_epoch else []

        wrapper: torch.nn.Module = _LossModule(module, stage, context)
        if world > 1:
            from torch.nn.parallel import DistributedDataParallel

            wrapper = DistributedDataParallel(
                wrapper, device_ids=[device.index] if device.type == "cuda" else None,
                find_unused_parameters=bool(stage_setting(config, stage.name, "find_unused_parameters", True)))

        header = {"model": model_name, "stage": stage.name, "config": config, "seed": seed,
                  "dataset": checkpoint.dataset_provenance(dataset) if rank == 0 else {}}
        run_state = {"seed": seed, "config_json": config_json, "dataset_tables": data_tables}
        final: dict = {}
        for epoch in range(start_epoch, epochs):
            seed_everything(_epoch_seed(seed, epoch, rank))
            rng = np.random.default_rng([seed, epoch])
            module.train()
            steps = _run_epoch(wrapper, stage, config, context, rng, optimizer, params, grad_clip, device,
                               tqdm, progress and rank == 0, f"{model_name}/{stage.name} {epoch + 1}/{epochs}")
            epoch_rows = _merge_ranks(gather_objects(steps, world), epoch)
            if not epoch_rows:
                raise UserError(f"stage {stage.name!r}: the dataset gave no batch in epoch {epoch + 1} "
                                f"({dataset}); is it empty or smaller than the batch size?")
            rows.extend(epoch_rows)
            final = {k: float(np.mean([r[k] for r in epoch_rows if k in r])) for k in epoch_rows[0]
                     if k not in ("epoch", "step")}
            if rank == 0:
                stage_dir.mkdir(parents=True, exist_ok=True)
                loss_log.write_rows(csv_path, rows)
                loss_log.plot(rows, png_path, f"{model_name} / {stage.name}")
                checkpoint.save_resume(stage_dir, module.state_dict(),
                                       {**header, "epoch": epoch + 1, **checkpoint.provenance()},
                                       {**run_state, "epoch": epoch + 1, "optimizer": optimizer.state_dict()})
            barrier(world)
        if not final and rows:
            last_epoch = max(r["epoch"] for r in rows)
            tail = [r for r in rows if r["epoch"] == last_epoch]
            final = {k: float(np.mean([r[k] for r in tail if k in r])) for k in tail[0] if k not in ("epoch", "step")}
        if rank == 0:
            stage_dir.mkdir(parents=True, exist_ok=True)
            checkpoint.save_checkpoint(final_path, module.state_dict(),
                                       {**header, "epoch": max(epochs, start_epoch), **checkpoint.provenance()})
            (out / "config.json").write_text(json.dumps(config, indent=2, sort_keys=True) + "\n")
            if rows and not png_path.is_file():
                loss_log.plot(rows, png_path, f"{model_name} / {stage.name}")
        barrier(world)
        return StageResult(stage.name, final_path, max(epochs, start_epoch), max(0, epochs - start_epoch),
                           time.perf_counter() - started, final)
    finally:
        if created_group:
            import torch.distributed as dist

            dist.destroy_process_group()


def _run_epoch(wrapper, stage, config, context, rng, optimizer, params, grad_clip, device, tqdm, show, desc):
    """One epoch of optimiser steps; returns this rank's per-step loss dicts (floats)."""
    steps: list[dict] = []
    batches = stage.batches(config, context, rng)
    total = len(batches) if hasattr(batches, "__len__") else None
    bar = tqdm(batches, total=total, desc=desc, disable=not show, leave=False, unit="step")
    join = _join_context(wrapper)
    with join:
        for batch in bar:
            losses = wrapper(_to_device(batch, device))
            if "total" not in losses:
                raise ValueError(f"stage {stage.name!r}: loss() must return a dict with 'total', got {sorted(losses)}")
            total_loss = losses["total"]
            if not torch.isfinite(total_loss):
                raise FloatingPointError(f"stage {stage.name!r}: the loss became {float(total_loss)} at step "
                                         f"{len(steps)} ({ {k: float(v) for k, v in losses.items()} }); lower "
                                         f"the learning rate (--set lr=...) or set grad_clip")
            optimizer.zero_grad(set_to_none=True)
            total_loss.backward()
            if grad_clip:
                torch.nn.utils.clip_grad_norm_(params, float(grad_clip))
            optimizer.step()
            record = {k: float(v.detach()) for k, v in losses.items()}
            steps.append(record)
            if show:
                bar.set_postfix(loss=f"{record['total']:.4g}")
    bar.close()
    return steps


def _join_context(wrapper):
    """DDP's Join (ranks with fewer batches shadow the others' collectives), or a no-op."""
    from contextlib import nullcontext

    from torch.nn.parallel import DistributedDataParallel

    if isinstance(wrapper, DistributedDataParallel):
        from torch.distributed.algorithms.join import Join

        return Join([wrapper])
    return nullcontext()


def _merge_ranks(per_rank: list[list[dict]], epoch: int) -> list[dict]:
    """One row a step: each loss key averaged over the ranks that ran that step."""
    n = max((len(s) for s in per_rank), default=0)
    rows = []
    for i in range(n):
        present = [s[i] for s in per_rank if i < len(s)]
        keys = list(dict.fromkeys(k for d in present for k in d))
        row = {"epoch": epoch, "step": i}
        for k in keys:
            vals = [d[k] for d in present if k in d]
            row[k] = float(sum(vals) / len(vals)) if vals else math.nan
        rows.append(row)
    return rows


def train_model(model_name: str, stages, dataset, out, config: dict, device="cpu", epochs: int | None = None,
                seed: int = 0, resume: bool = True, progress: bool = True) -> list[StageResult]:
    """Train ``stages`` (a stage name, a list of names, or ``"all"``: every stage in order).

    Each stage loads its ``needs`` from ``OUT``; with ``"all"`` they are the ones just trained.
    """
    model = trainable(model_name)
    names = [s.name for s in model.stages] if stages == "all" else [stages] if isinstance(stages, str) else list(stages)
    for name in names:
        model.stage(name)  # unknown names fail before any training
    # one process group for all stages (under torchrun): joining again after a destroy can hang
    _, _, _, created = init_distributed(torch.device(device))
    try:
        return [train_stage_result(model_name, name, dataset, out, config, device, epochs, seed, resume, progress)
                for name in names]
    finally:
        if created:
            import torch.distributed as dist

            dist.destroy_process_group()
