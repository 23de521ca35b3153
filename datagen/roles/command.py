"""``mimicbench datagen roles DATASET --labels FILE [FILE ...]``: attach role-label files."""
from __future__ import annotations

import argparse

from mimicbench.datagen.roles.params import RolesParams
from mimicbench.runtime.options import add_options
from mimicbench.runtime.summary import StageSummary


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "roles", help="attach role-label files (bone -> role, category) to a dataset's characters",
        description="Give the characters of DATASET hidden bone roles (ground truth for scores such as the "
        "semantic agreement of cct; never given to a method) and, where a file says so, a category that wins "
        "over the inferred one. A label file (TOML or JSON) labels characters by character ID or by source "
        "file stem; per character an optional category and a table of bone name (or glob) = role, a role being "
        "a zoo role (left/upper_arm, tail/3) or a class (left/forelimb, spine, tail, head, apparel). Format: "
        "docs/roles.md; labels for the shared assets: examples/roles/shared_assets.toml.\n\n"
        "A key naming no bone of its character is an error (with the closest names) and nothing is written; a "
        "character of the file that the dataset lacks is a warning. The characters table is rewritten through "
        "the shard writer (split by split, the dataset marked incomplete meanwhile; a re-run finishes it). "
        "Tables made from the old characters (pairs, cases) are reported stale.\n\nExamples:\n"
        "  mimicbench datagen ingest assets/ --out data/mine\n"
        "  mimicbench datagen roles data/mine --labels examples/roles/shared_assets.toml",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_options(p, RolesParams)
    p.set_defaults(func=run)


def run(params: RolesParams) -> StageSummary:
    from mimicbench.datagen.roles.attach import run_command

    return run_command(params)
