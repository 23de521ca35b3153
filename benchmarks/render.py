"""Rendering speed: every panel of a sheet in one Blender process (what mimicbench does) against
one Blender process per mesh (the naive peer); the ratio (per mesh / one process) last.

    python benchmarks/render.py [--characters 8] [--px 240]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from mimicbench.datagen.render.contact_sheet import contact_sheet_panels
from mimicbench.datagen.render.render import render_panels
from mimicbench.datagen.zoo.dataset import build_zoo
from mimicbench.schemas.shards import read_records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--characters", type=int, default=8)
    ap.add_argument("--px", type=int, default=240)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        zoo = Path(tmp) / "zoo"
        build_zoo(zoo, args.characters, seed=0, clips_per_character=1, progress=False)
        panels = contact_sheet_panels(read_records(zoo, "characters"))
    start = time.perf_counter()
    render_panels(panels, args.px, args.px)
    one = time.perf_counter() - start
    start = time.perf_counter()
    for p in panels:
        render_panels([p], args.px, args.px)
    each = time.perf_counter() - start
    print(f"{len(panels)} panels of {args.px} px: one Blender process {one:.1f} s ({one / len(panels):.2f} s a panel); "
          f"one process per mesh {each:.1f} s ({each / len(panels):.2f} s a panel)")
    print(f"ratio (one process per mesh / one process for all): {each / one:.2f}")


if __name__ == "__main__":
    main()
