"""Same bytes before and after a refactor: a small run of every stage, the sha256 of each output.

Runs the CLI (``python -m mimicbench``, so the code under test is whatever ``PYTHONPATH`` puts
first) on a small zoo (zoo, resample, correspond, cases, bench run, apparel) and on shared real
assets (glTF through Blender, Gene.pmx with its VMD through the MMD reader), then writes
``OUT/digests.json``: the sha256 of every Parquet shard, and of the rows of every status table
and results folder with the timing column dropped (``seconds`` and part names differ run to run).
Compare two runs' folders with ``--compare``:

    PYTHONPATH=/path/to/old/tree python tools/same_bytes.py /tmp/old
    PYTHONPATH=$PWD python tools/same_bytes.py /tmp/new
    python tools/same_bytes.py --compare /tmp/old /tmp/new   # last line: identical files / all files
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


def rows_digest(paths: list[Path]) -> str:
    """sha256 of the rows of Parquet files (sorted, timing columns dropped): for tables whose file
    names or ``seconds`` differ from run to run (results parts, status rows)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.concat_tables([pq.read_table(p) for p in paths])
    table = table.drop([c for c in TIMING_COLUMNS if c in table.column_names])
    rows = sorted(json.dumps(r, sort_keys=True, default=str) for r in table.to_pylist())
    return hashlib.sha256("\n".join(rows).encode()).hexdigest()


def digests(out: Path) -> dict[str, str]:
    """Per dataset shard its sha256; per status table and per results folder the digest of its rows."""
    found: dict[str, str] = {}
    parts: dict[str, list[Path]] = {}
    for p in sorted(out.rglob("*.parquet")):
        rel = p.relative_to(out)
        if rel.parts[0] == "results":
            parts.setdefault(str(rel.parent) + "/*.parquet", []).append(p)
        elif "status" in rel.parts:
            found[str(rel) + " (rows)"] = rows_digest([p])
        else:
            found[str(rel)] = hashlib.sha256(p.read_bytes()).hexdigest()
    found.update({name: rows_digest(ps) for name, ps in parts.items()})
    return found


def compare(a: Path, b: Path) -> int:
    """Print what differs between two runs' outputs; the last line counts the identical ones."""
    da, db = digests(a), digests(b)
    names = sorted(set(da) | set(db))
    differ = [n for n in names if da.get(n) != db.get(n)]
    for n in differ:
        why = f"missing in {a}" if n not in da else f"missing in {b}" if n not in db else "differs"
        print(f"{why}: {n}")
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
