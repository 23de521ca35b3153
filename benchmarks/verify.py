"""What verifying shards on read costs: ``read_records`` with and without the sha256 check.

Builds a zoo (default 40 characters, seed 0), then reads its characters and motions tables
(``read_records``) three ways, each against the named peer, a plain ``pyarrow.parquet.read_table``
of the same shard files (no checks, no records):

- first read with verification (every file hashed once in this process),
- a later read with verification (digests cached by path, size, inode and times: no re-hash),
- a read with ``verify=False`` (``MIMICBENCH_VERIFY=0``, ``--no-verify``; sizes still checked).

    python benchmarks/verify.py [--characters 40] [--repeats 7]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def timed(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)  # best of: the machine is shared, noise only adds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--characters", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    import pyarrow.parquet as pq

    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas import integrity
    from mimicbench.schemas.manifest import load_manifest
    from mimicbench.schemas.shards import read_records

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "zoo"
        build_zoo(root, args.characters, seed=0, progress=False)
        time.sleep(integrity.RACY_SECONDS + 0.5)  # digests of files changed within this window are not cached
        files = [root / s["path"] for t in ("characters", "motions") for s in load_manifest(root)["tables"][t]["shards"]]
        mb = sum(f.stat().st_size for f in files) / 1e6

        def plain():
            for f in files:
                pq.read_table(f)

        def ours(verify):
            for t in ("characters", "motions"):
                read_records(root, t, verify=verify)

        def first():
            integrity.forget_digests()
            ours(True)

        peer = timed(plain, args.repeats)
        ours(True)
        rows = {"first read, verified": timed(first, args.repeats),
                "later read, verified (cached digest)": timed(lambda: ours(True), args.repeats),
                "read with verify=False": timed(lambda: ours(False), args.repeats)}
        print(f"{len(files)} shards, {mb:.1f} MB; peer: plain pyarrow read_table {peer * 1e3:.1f} ms")
        for name, sec in rows.items():
            print(f"  {name}: {sec * 1e3:.1f} ms")
        base = rows["read with verify=False"]
        print(f"verified first read / unverified read: {rows['first read, verified'] / base:.2f}; "
              f"verified later read / unverified read: {rows['later read, verified (cached digest)'] / base:.2f}; "
              f"unverified read / plain pyarrow: {base / peer:.2f}")


if __name__ == "__main__":
    main()
