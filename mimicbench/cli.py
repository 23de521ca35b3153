"""The ``mimicbench`` command line: one entry point, one sub-command per job.

Each sub-command lives in its own module exposing ``register(subparsers)``, which adds a parser
whose ``func`` default takes the command's options (a dataclass derived from that parser, see
:mod:`mimicbench.runtime.options`) and returns a :class:`~mimicbench.runtime.summary.StageSummary` or an exit code. Modules import their
heavy dependencies inside ``func``, so ``mimicbench --help`` stays fast.

User errors (:class:`~mimicbench.schemas.errors.UserError` and its subclasses such as ``DatasetError``,
any ``OSError`` (a missing file, a full disk, a read-only folder), a ``ValueError`` from an
argument check) print ``mimicbench: error: ...`` and exit
with status 2; ``--debug`` (anywhere on the command line, or ``MIMICBENCH_DEBUG=1``) shows the
traceback instead. ``--no-verify`` (or ``MIMICBENCH_VERIFY=0``) skips the sha256 check of every
shard read, for speed on trusted data.
"""
from __future__ import annotations

import argparse
import os
import sys

from mimicbench import __version__
from mimicbench.runtime.options import from_namespace
from mimicbench.runtime.errors import USER_ERRORS, error_text  # noqa: F401 (USER_ERRORS: part of this module's API)
from mimicbench.runtime.summary import exit_code



def command_modules() -> tuple:
    """(group, module) of every sub-command in ``--help`` order; group None puts it at the top level.
    Imported here, after :func:`main` has fitted the address space: a command module keeps its heavy
    imports inside its ``func``."""
    from mimicbench.benchmark import command as bench
    from mimicbench.commands import demo, pipeline, train, validate
    from mimicbench.datagen.apparel import command as apparel
    from mimicbench.datagen.correspond import command as correspond
    from mimicbench.datagen.ingest import command as ingest
    from mimicbench.datagen.render import command as render
    from mimicbench.datagen.resample import command as resample
    from mimicbench.datagen.retarget import command as retarget
    from mimicbench.datagen.roles import command as roles
    from mimicbench.datagen.zoo import command as zoo

    return ((None, validate), (None, zoo), ("datagen", resample), ("datagen", correspond), ("datagen", ingest),
            ("datagen", retarget), ("datagen", roles), ("datagen", apparel), (None, bench), (None, demo),
            (None, render), (None, train), (None, pipeline))

GROUP_HELP = {
    "datagen": "dataset stages: ingest real assets, attach role labels, resample meshes, compute correspondences, "
               "retarget clips, simulate apparel",
}

DESCRIPTION = """\
mimicbench builds datasets for 3D character pose transfer and scores pose-transfer methods.

Typical flow:
  mimicbench demo                                   build a small zoo and print a leaderboard
  mimicbench zoo --out data/zoo --characters 40     procedural rigged, animated characters
  mimicbench datagen ingest assets/*.glb --out data/mine    real assets through Blender
  mimicbench datagen retarget data/mine data/mmd data/out   humanoid clips onto other humanoids
  mimicbench datagen roles data/mine --labels roles.toml    hidden bone roles and categories from a file
  mimicbench datagen resample data/zoo data/zoo5k   5,000-face meshes, weights re-skinned
  mimicbench datagen correspond data/zoo5k          bone-name correspondences (pairs/)
  mimicbench datagen apparel data/zoo data/zoo_sim   apparel chains simulated with Bullet (<clip>@sim)
  mimicbench bench cases data/zoo5k                 benchmark cases (cases/)
  mimicbench bench run data/zoo5k --methods identity,name_copy --out results
  mimicbench bench leaderboard results              Markdown, CSV, JSON and HTML
  mimicbench validate data/zoo5k                    check shards against manifest.json
  mimicbench render data/zoo zoo/bird-0001 --out bird.png   a character through Blender
  mimicbench train mimicat data/zoo --out runs/m1   train the MimiCAT-style reference (stages, resume)
  mimicbench pipeline examples/pipelines/demo.toml  every step above from one file, resumable

Run `mimicbench COMMAND --help` for each command's options.
"""


class Parser(argparse.ArgumentParser):
    """argparse with the toolkit's error line: ``mimicbench: error: ...`` and exit status 2."""

    def error(self, message: str):
        self.print_usage(sys.stderr)
        self.exit(2, f"mimicbench: error: {message}\n")


GLOBAL_FLAGS = (
    ("--debug", "show the Python traceback of an error instead of the one-line message"),
    ("--no-verify", "skip the sha256 check of each shard read (faster on large trusted data; sizes are "
                    "still checked); same as MIMICBENCH_VERIFY=0"),
)


def _add_global_flags(parser: argparse.ArgumentParser, top: bool) -> None:
    """Add --debug and --no-verify to ``parser``; sub-commands accept them too (after their name)."""
    for flag, text in GLOBAL_FLAGS:
        parser.add_argument(flag, action="store_true", help=text,
                            default=False if top else argparse.SUPPRESS)


def _subparsers_of(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                yield sub
                yield from _subparsers_of(sub)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="mimicbench", description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"mimicbench {__version__}")
    _add_global_flags(parser, top=True)
    top = parser.add_subparsers(dest="command", metavar="COMMAND")
    groups: dict[str, argparse._SubParsersAction] = {}
    for group, module in command_modules():
        if group is None:
            target = top
        else:
            if group not in groups:
                gp = top.add_parser(group, help=GROUP_HELP.get(group, ""), description=GROUP_HELP.get(group, ""))
                groups[group] = gp.add_subparsers(dest=f"{group}_command", metavar="STAGE")
                gp.set_defaults(func=lambda args, gp=gp: (gp.print_help(), 2)[1])
            target = groups[group]
        module.register(target)
    for sub in _subparsers_of(parser):
        _add_global_flags(sub, top=False)
        sub.set_defaults(command_parser=sub)  # the deepest one wins: its options become the dataclass
    return parser


def command_parser(words: tuple[str, ...], parser: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The parser of the command ``words`` (e.g. ``("datagen", "resample")``)."""
    parser = parser or build_parser()
    for word in words:
        parser = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[word]
    return parser


def main(argv: list[str] | None = None) -> int:
    from mimicbench.runtime.address_space import fit_to_address_space_limit, limit_text

    fit_to_address_space_limit()  # under `ulimit -v`: small reservations, one thread a pool (before numpy loads)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.no_verify:
        os.environ["MIMICBENCH_VERIFY"] = "0"  # child processes (workers) inherit it
    debug = args.debug or os.environ.get("MIMICBENCH_DEBUG", "") not in ("", "0")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return exit_code(args.func(from_namespace(args.command_parser, args)))
    except KeyboardInterrupt:
        print("interrupted; work already written is kept, re-run to resume", file=sys.stderr)
        return 130
    except MemoryError:
        if debug:
            raise
        limit = limit_text()
        print(f"mimicbench: error: out of memory{' under ' + limit if limit else ''}; work already written is "
              f"kept: raise the limit{' (ulimit -v)' if limit else ''} or give the command less to hold at once, "
              f"and re-run to resume", file=sys.stderr)
        return 2
    except USER_ERRORS as exc:
        if debug:
            raise
        print(f"mimicbench: error: {error_text(exc)}", file=sys.stderr)
        print("(run with --debug for the traceback)", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
