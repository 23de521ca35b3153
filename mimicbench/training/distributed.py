"""Process-group set-up for ``torchrun``: rank, world size and device, gloo on CPU and nccl on CUDA."""
from __future__ import annotations

import os

import torch
import torch.distributed as dist


def launched_by_torchrun() -> bool:
    """True when the environment says this is one of several torchrun processes."""
    return int(os.environ.get("WORLD_SIZE", "1")) > 1


def init_distributed(device: torch.device) -> tuple[int, int, torch.device, bool]:
    """Join the process group when launched by torchrun.

    Returns:
        ``(rank, world_size, device, created)``: ``device`` is ``cuda:LOCAL_RANK`` for CUDA runs
        under torchrun; ``created`` says whether this call created the group (then the caller
        destroys it when done).
    """
    if not launched_by_torchrun():
        return 0, 1, device, False
    created = False
    if device.type == "cuda":
        device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))
        torch.cuda.set_device(device)
    if not dist.is_initialized():
        dist.init_process_group(backend="nccl" if device.type == "cuda" else "gloo")
        created = True
    return dist.get_rank(), dist.get_world_size(), device, created


def gather_objects(obj, world_size: int) -> list:
    """Every rank's ``obj`` (picklable), in rank order; ``[obj]`` without a process group."""
    if world_size == 1:
        return [obj]
    out: list = [None] * world_size
    dist.all_gather_object(out, obj)
    return out


def barrier(world_size: int) -> None:
    if world_size > 1:
        dist.barrier()
