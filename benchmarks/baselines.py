"""Speed of the re-implemented published baselines (``npt``, ``cgt``, ``sfpt``): training steps per
second and inference seconds per case, against the named peer ``nearest_joint``.

Builds (or reuses) the data of ``benchmarks/mimicat.py`` (a 16-character zoo, seed 0, resampled to
5,000 faces, with pairs and h2h and cct cases), then for each method:

- training: steps per second of its stage with the shipped checkpoint's config (``small``), each a
  loss, a backward pass and an AdamW step on one batch (two warm-up steps first);
- inference: seconds per request on the cases' forward requests (every vertex of both meshes).

The peer ``nearest_joint`` (bone matching and rotation copying, no network) answers the same requests;
the last lines are each method's time per case over the peer's.

    python benchmarks/baselines.py [--work DIR] [--device cpu|cuda] [--steps 10] [--cases 24]
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
from pathlib import Path

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)  # run as a script, this file's own name would hide the `baselines` package

import torch

METHODS = ("npt", "cgt", "sfpt")

_spec = importlib.util.spec_from_file_location("mimicat_benchmark", Path(__file__).with_name("mimicat.py"))
_mimicat_benchmark = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_mimicat_benchmark)
dataset = _mimicat_benchmark.dataset  # the same zoo, resampled, with pairs and cases, as benchmarks/mimicat.py
seconds_per_case = _mimicat_benchmark.seconds_per_case
timed_steps = _mimicat_benchmark.timed_steps


def training_steps_per_second(name: str, data: Path, device: torch.device, steps: int) -> float:
    from mimicbench.baselines.checkpointed import checkpoint_path
    from mimicbench.benchmark.registry import get_method
    from mimicbench.training.checkpoint import read_header
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    config = read_header(checkpoint_path(get_method(name).shipped, name))["config"]
    return timed_steps(trainable(name).stage(name), config, StageContext(data, device, config), device, steps)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default=None, help="folder for the data (default: a temporary folder)")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--steps", type=int, default=10, help="timed training steps per method")
    ap.add_argument("--cases", type=int, default=24, help="forward requests timed")
    args = ap.parse_args()
    from mimicbench.benchmark.evaluator import load_cases
    from mimicbench.benchmark.protocols.base import EvalData
    from mimicbench.benchmark.registry import get_method

    device = torch.device(args.device)
    data = dataset(Path(args.work or tempfile.mkdtemp(prefix="mimicbench-baselines-")))
    print(f"device {device}, torch threads {torch.get_num_threads()}, data {data}")
    for name in METHODS:
        print(f"training {name}: {training_steps_per_second(name, data, device, args.steps):.2f} steps/s")
    ev = EvalData.load(data)
    by_protocol = load_cases(data, ("h2h", "cct"))
    cases = [c for p in ("h2h", "cct") for c in by_protocol[p][:args.cases // 2]]
    requests = [ev.request(ev.characters[c.source_id], ev.posed(ev.characters[c.source_id], c.source_transforms),
                           ev.characters[c.target_id], c.case_id) for c in cases]
    peer = get_method("nearest_joint")
    peer.setup(args.device)
    peer_s = seconds_per_case(peer, requests)
    print(f"nearest_joint: {peer_s:.4f} s/case ({len(requests)} cases)")
    times = {}
    for name in METHODS:
        method = get_method(name)
        method.setup(args.device)
        times[name] = seconds_per_case(method, requests)
        print(f"{name}: {times[name]:.4f} s/case")
    for name in METHODS:
        print(f"{name} / nearest_joint time per case: {times[name] / peer_s:.2f}")


if __name__ == "__main__":
    main()
