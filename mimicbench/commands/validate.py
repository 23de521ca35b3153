"""``mimicbench validate DIR``: check a dataset folder and name every bad file."""
from __future__ import annotations

import argparse


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "validate",
        help="check a dataset folder against manifest.json and the schema",
        description="Check every shard listed in DIR/manifest.json: its path inside DIR, present, size and "
        "sha256 as recorded, readable Parquet with the recorded rows, a known schema version and the "
        "contract's column types; the dataset marked complete (not left half-written by a killed stage); "
        "tables derived from other tables of DIR (pairs from characters) still matching their "
        "fingerprints; no unlisted shard on disk; no NaN or infinite mesh or animation value; no character or "
        "motion ID held by two rows. Exits 1 and names each bad file and why.",
    )
    p.add_argument("dataset", help="dataset folder (holds manifest.json)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from mimicbench.schemas.manifest import load_manifest
    from mimicbench.schemas.validate import validate_dataset

    problems = validate_dataset(args.dataset, values=True)
    if problems:
        for p in problems:
            print(f"INVALID {p}")
        print(f"{len(problems)} problem(s) in {args.dataset}")
        return 1
    manifest = load_manifest(args.dataset)
    parts = [f"{t}: {info.get('rows', 0)} rows in {len(info.get('shards', []))} shard(s)"
             for t, info in sorted(manifest.get("tables", {}).items())]
    print(f"OK {args.dataset} (schema {manifest.get('schema_version')}): " + "; ".join(parts))
    return 0
