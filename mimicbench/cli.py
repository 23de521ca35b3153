"""The ``mimicbench`` command line: one entry point, one sub-command per job.

Each sub-command lives in its own module exposing ``register(subparsers)``, which adds a parser
whose ``func`` default takes the parsed arguments and returns an exit code. Modules import their
heavy dependencies inside ``func``, so ``mimicbench --help`` stays fast.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from mimicbench import __version__

# (group, module): group None puts the command at the top level.
COMMAND_MODULES = (
    (None, "mimicbench.commands.validate"),
    (None, "datagen.zoo.command"),
    ("datagen", "datagen.resample.command"),
    ("datagen", "datagen.correspond.command"),
    ("datagen", "datagen.ingest.command"),
    (None, "benchmark.command"),
    (None, "benchmark.demo"),
)

GROUP_HELP = {
    "datagen": "dataset stages: ingest real assets, resample meshes, compute correspondences",
}

DESCRIPTION = """\
mimicbench builds datasets for 3D character pose transfer and scores pose-transfer methods.

Typical flow:
  mimicbench demo                                   build a small zoo and print a leaderboard
  mimicbench zoo --out data/zoo --characters 40     procedural rigged, animated characters
  mimicbench datagen ingest assets/*.glb --out data/mine    real assets through Blender
  mimicbench datagen resample data/zoo data/zoo5k   5,000-face meshes, weights re-skinned
  mimicbench datagen correspond data/zoo5k          bone-name correspondences (pairs/)
  mimicbench bench cases data/zoo5k                 benchmark cases (cases/)
  mimicbench bench run data/zoo5k --methods identity,name_copy --out results
  mimicbench bench leaderboard results              Markdown, CSV, JSON and HTML
  mimicbench validate data/zoo5k                    check shards against manifest.json

Run `mimicbench COMMAND --help` for each command's options.
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mimicbench", description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"mimicbench {__version__}")
    top = parser.add_subparsers(dest="command", metavar="COMMAND")
    groups: dict[str, argparse._SubParsersAction] = {}
    for group, module_name in COMMAND_MODULES:
        module = importlib.import_module(module_name)
        if group is None:
            target = top
        else:
            if group not in groups:
                gp = top.add_parser(group, help=GROUP_HELP.get(group, ""), description=GROUP_HELP.get(group, ""))
                groups[group] = gp.add_subparsers(dest=f"{group}_command", metavar="STAGE")
                gp.set_defaults(func=lambda args, gp=gp: (gp.print_help(), 2)[1])
            target = groups[group]
        module.register(target)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted; work already written is kept, re-run to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
