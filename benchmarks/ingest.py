"""Ingest speed on the shared assets (../shared/assets): assets per second and seconds per asset
with one and with two Blender child processes; the ratio (two jobs / one job) last.

    python benchmarks/ingest.py [--assets ../shared/assets]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from datagen.ingest import ingest_assets

DEFAULT_ASSETS = Path(__file__).resolve().parents[2] / "shared" / "assets"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--assets", default=str(DEFAULT_ASSETS))
    args = ap.parse_args()
    root = Path(args.assets)
    paths = sorted((root / "glb").glob("*.glb")) + sorted((root / "bvh").glob("*.bvh"))
    rates = {}
    for jobs in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            s = ingest_assets(paths, Path(tmp) / "ds", jobs=jobs, progress=False)
            seconds = time.perf_counter() - start
        per = {x.asset.split("/")[-1]: round(x.seconds, 2) for x in s["statuses"]}
        rates[jobs] = len(paths) / seconds
        print(f"jobs={jobs}: {len(paths)} assets in {seconds:.1f} s = {rates[jobs]:.2f} assets/s; seconds per asset {per}")
    print(f"ratio 2 jobs / 1 job: {rates[2] / rates[1]:.2f}x")


if __name__ == "__main__":
    main()
