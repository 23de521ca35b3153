"""``mimicbench train MODEL DATASET --out RUN``: train the stages of a bundled learned reference."""
from __future__ import annotations

import argparse

EPILOG = """\
examples:
  mimicbench train mimicat data/zoo --out runs/m1 --stage shape            the shape encoder only
  mimicbench train mimicat data/zoo --out runs/m1 --stage prior --epochs 20   resumes if stopped
  mimicbench train mimicat data/zoo --out runs/m1 --config paper --device cuda --set lr=3e-4
  torchrun --nproc-per-node 4 -m mimicbench train mimicat data/zoo --out runs/m1 --device cuda
  mimicbench train mmdmc data/app --out runs/d1 --threads 1                  one CPU thread (a busy machine)

Each stage writes RUN/<stage>/: model.safetensors (final weights with a JSON header), resume.json naming
resume-<epoch>-<id>/ with last.safetensors and state.pt (after every epoch, written as one unit, for
resume), loss.csv and loss.png; RUN/config.json holds the config. Re-running the same command resumes
a stage where it stopped (same config, seed and dataset required, else refused);
--epochs higher than before trains on. `batch_size` is the global batch: under torchrun each of the
W processes takes a W-th of every batch, and the weights match a one-process run's.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "train",
        help="train a learned reference (mimicat, mmdmc) or published baseline (npt, cgt, sfpt) on a dataset",
        description="Train the stages of a bundled learned reference with AdamW, repeatable seeds, a progress "
        "bar, per-epoch checkpoints that resume, a loss plot per stage, and DistributedDataParallel when "
        "launched by torchrun (gloo on CPU, nccl on CUDA).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("model", help="trainable model: mimicat, mmdmc, npt, cgt or sfpt")
    p.add_argument("dataset", help="dataset folder (e.g. the output of `mimicbench zoo`)")
    p.add_argument("--out", required=True, help="run folder for checkpoints, loss logs and config.json")
    p.add_argument("--stage", default="all",
                   help="stage to train (mimicat: shape, prior, corr, transfer, transfer_no_prior; mmdmc: seg, body, "
                   "apparel; npt, cgt, sfpt: one stage of their own name), or 'all' in order (default)")
    p.add_argument("--config", default="small",
                   help="config preset: small (2 CPU cores, minutes) or paper (the paper's sizes, for GPUs); npt and cgt "
                        "also small_cycle, large (one GPU, minutes; npt's shipped weights) and large_cycle")
    p.add_argument("--device", default="cpu", choices=("cpu", "cuda"), help="where to train (default cpu)")
    p.add_argument("--epochs", type=int, default=None,
                   help="total epochs per stage (default: the preset's per-stage value)")
    p.add_argument("--seed", type=int, default=0, help="seed for weights and batch order (default 0)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config value, dotted for a stage's section (e.g. --set shape.width=64 "
                        "--set lr=3e-4); repeatable")
    p.add_argument("--no-resume", action="store_true", help="start each stage over instead of resuming")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--threads", type=int, default=None, metavar="N",
                   help="CPU threads torch may use for training (torch.set_num_threads; default: torch's own "
                        "default, one per core). On a machine shared with other jobs, --threads 1 avoids "
                        "threads waiting on each other (it made training ten times faster on 2 busy cores)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from mimicbench.training.config_overrides import apply_overrides
    from mimicbench.training.loop import train_model
    from mimicbench.training.registry import trainable

    if args.threads is not None:
        if args.threads < 1:
            raise ValueError(f"--threads: expected a whole number of threads >= 1, got {args.threads}")
        import torch

        torch.set_num_threads(args.threads)
    model = trainable(args.model)
    config = apply_overrides(model.config(args.config), args.overrides)
    results = train_model(args.model, args.stage, args.dataset, args.out, config, args.device, args.epochs,
                          args.seed, not args.no_resume, not args.no_progress)
    import os

    if int(os.environ.get("RANK", "0")) != 0:
        return 0
    print(f"trained {args.model} ({args.config}) on {args.dataset} -> {args.out}")
    for r in results:
        losses = ", ".join(f"{k} {v:.4g}" for k, v in r.final.items())
        print(f"  {r.stage:<10} {r.epochs} epochs ({r.epochs_run} run) in {r.seconds:.1f} s; final {losses or '-'}; "
              f"{r.model_path}")
    return 0
