"""Same bytes before and after a refactor: a small run of every stage, the sha256 of each output.

Runs the CLI (``python -m mimicbench``, so the code under test is whatever ``PYTHONPATH`` puts
first) on a small zoo (zoo, resample, correspond, cases, bench run, apparel) and on shared real
assets (glTF through Blender, Gene.pmx with its VMD through the MMD reader), then writes
``OUT/digests.json``: the sha256 of every Parquet shard, and of every results table with its
timing column dropped (``seconds`` differs run to run). Compare two runs with ``--compare``:

    PYTHONPATH=/path/to/old/tree python benchmarks/same_bytes.py /tmp/old
    PYTHONPATH=$PWD python benchmarks/same_bytes.py /tmp/new
    python benchmarks/same_bytes.py --compare /tmp/old /tmp/new   # last line: identical files / all files
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

ASSETS = Path(__file__).resolve().parents[1].parent / "shared" / "assets"
TIMING_COLUMNS = ("seconds",)


def mimicbench(*args: str) -> None:
    """Run one CLI command with this process's environment; stop on failure."""
    cmd = [sys.executable, "-m", "mimicbench", *args]
    print("+ mimicbench " + " ".join(args), flush=True)
    subprocess.run(cmd, check=True, env=dict(os.environ, MIMICBENCH_VERIFY="1"))


def build(out: Path, assets: Path, blender: bool) -> None:
    zoo, zoo2k, sim = out / "zoo", out / "zoo2k", out / "zoo_sim"
    mimicbench("zoo", "--out", str(zoo), "--characters", "8", "--seed", "5", "--clips-per-character", "2",
               "--quiet", "--no-contact-sheet")
    mimicbench("datagen", "resample", str(zoo), str(zoo2k), "--faces", "2000", "--quiet")
    mimicbench("datagen", "correspond", str(zoo2k), "--quiet")
    mimicbench("bench", "cases", str(zoo2k), "--h2h-poses", "2", "--cct-pairs", "4", "--cct-poses", "1")
    mimicbench("bench", "run", str(zoo2k), "--methods", "identity,name_copy,nearest_joint,text_soft", "--out",
               str(out / "results"), "--in-process", "--quiet")
    mimicbench("datagen", "apparel", str(zoo), str(sim), "--quiet")
    mimicbench("datagen", "ingest", str(assets / "mmd" / "Gene.pmx"), "--out",
               str(out / "mmd"), "--quiet")
    if blender:
        mimicbench("datagen", "ingest", str(assets / "glb" / "CesiumMan.glb"), str(assets / "glb" / "Fox.glb"),
                   "--out", str(out / "assets"), "--quiet")


def table_digest(path: Path) -> str:
    """sha256 of a Parquet file, or of its rows without timing columns for a results table."""
    if "results" not in path.parts:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    table = table.drop([c for c in TIMING_COLUMNS if c in table.column_names])
    return hashlib.sha256(json.dumps(table.to_pylist(), sort_keys=True, default=str).encode()).hexdigest()


def digests(out: Path) -> dict[str, str]:
    return {str(p.relative_to(out)): table_digest(p) for p in sorted(out.rglob("*.parquet"))}


def compare(a: Path, b: Path) -> int:
    da, db = (json.loads((p / "digests.json").read_text()) for p in (a, b))
    names = sorted(set(da) | set(db))
    differ = [n for n in names if da.get(n) != db.get(n)]
    for n in differ:
        print(f"differs: {n} ({'missing in ' + str(a) if n not in da else 'missing in ' + str(b) if n not in db else 'bytes'})")
    print(f"identical: {len(names) - len(differ)} / {len(names)}")
    return 1 if differ else 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path, nargs="?")
    p.add_argument("--compare", type=Path, nargs=2, metavar=("OLD", "NEW"))
    p.add_argument("--assets", type=Path, default=ASSETS)
    p.add_argument("--no-blender", action="store_true", help="skip the glTF ingest (needs bpy)")
    args = p.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    if args.out is None:
        p.error("OUT or --compare OLD NEW")
    args.out.mkdir(parents=True, exist_ok=True)
    build(args.out, args.assets, not args.no_blender)
    d = digests(args.out)
    (args.out / "digests.json").write_text(json.dumps(d, indent=1, sort_keys=True))
    print(f"{len(d)} tables digested into {args.out / 'digests.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
