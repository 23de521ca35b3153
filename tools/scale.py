"""Scale: a PokeAnimDB-size build on one machine, step by step: wall time, peak memory, disk.

Run: ``python tools/scale.py --size reduced`` (a few minutes; what CI runs) or ``--size full``
(the paper's Table 1 shape: 975 characters, 28,809 clips of 155 frames = 4,465,395 frames, 11-241
joints, resampled to 5,000 faces, every ordered pair within each split, 5,000 cases; hours on 2
cores, run it under ``nice``). Each step is one ``mimicbench`` command in a child process; the
script records its wall time, the peak resident memory of that process and of the processes it
waited for (``resource.getrusage`` of itself and of its children: the local engine's worker
pool; Ray's workers are not its children, so measure with ``--engine local``), and the disk the
workdir takes after it. Figures go to ``WORKDIR/scale.json`` and ``scale.md`` after every step, so
an interrupted run keeps what finished; a re-run skips steps whose output is complete (each
command resumes or skips by fingerprint). At the end the dataset card gets Table 1 beside the
paper's, with distribution plots.

The named peer: memory against data. The streamed stages hold a few shards, not the table, so
the last line prints the ratio of the largest step's peak memory to the size of the motions
table on disk (well below 1 when memory is bounded; a build that held the table would exceed 1).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SIZES = {
    "reduced": {"characters": 40, "motions": 400, "frames": 60, "faces": 2000,
                "cases": {"h2h_pairs": 20, "h2h_poses": 5, "cct_pairs": 20, "cct_poses": 5}},
    "full": {"characters": 975, "motions": 28_809, "frames": 155, "faces": 5000,
             "cases": {"h2h_pairs": 250, "h2h_poses": 10, "cct_pairs": 500, "cct_poses": 5}},
}


def steps(size: dict, work: Path, engine: list[str], jobs: list[str]) -> list[tuple[str, list[str], Path]]:
    """(name, mimicbench argv, folder whose manifest says the step is done)."""
    zoo, data = work / "zoo", work / "zoo5k"
    c = size["cases"]
    return [
        ("zoo", ["zoo", "--out", str(zoo), "--characters", str(size["characters"]), "--motions", str(size["motions"]),
                 "--frames-per-clip", str(size["frames"]), "--no-contact-sheet", "--quiet"] + engine + jobs, zoo),
        ("resample", ["datagen", "resample", str(zoo), str(data), "--faces", str(size["faces"]), "--quiet"]
         + engine + jobs, data),
        ("correspond", ["datagen", "correspond", str(data), "--all-pairs", "--quiet"] + engine + jobs, data),
        ("cases", ["bench", "cases", str(data), "--split", "all", "--h2h-pairs", str(c["h2h_pairs"]),
                   "--h2h-poses", str(c["h2h_poses"]), "--cct-pairs", str(c["cct_pairs"]),
                   "--cct-poses", str(c["cct_poses"])], data),
    ]


def disk_bytes(folder: Path) -> int:
    """Bytes the files under ``folder`` occupy on disk (st_blocks)."""
    return sum(p.stat().st_blocks * 512 for p in folder.rglob("*") if p.is_file()) if folder.exists() else 0


def child(argv: list[str], report: str) -> int:
    """Run one mimicbench command in this process and write its rusage figures to ``report``."""
    from mimicbench.cli import main

    rc = main(argv)
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    Path(report).write_text(json.dumps({"rc": rc, "peak_rss_mb": me.ru_maxrss / 1024,
                                        "children_peak_rss_mb": kids.ru_maxrss / 1024,
                                        "cpu_s": me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime}))
    return rc


def table_done(folder: Path, table: str) -> bool:
    from mimicbench.schemas.manifest import MANIFEST, load_manifest

    if not (folder / MANIFEST).is_file():
        return False
    m = load_manifest(folder)
    return m.get("complete", True) and table in m.get("tables", {})


DONE_TABLE = {"zoo": "motions", "resample": "characters", "correspond": "pairs", "cases": "cases"}


def write_report(work: Path, rows: list[dict], size: str) -> None:
    (work / "scale.json").write_text(json.dumps({"size": size, "steps": rows}, indent=2) + "\n")
    lines = ["| step | wall s | CPU s | peak memory MB (process / its children) | disk after, GB | rc |",
             "|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['step']} | {r['wall_s']:.0f} | {r.get('cpu_s', 0):.0f} | {r.get('peak_rss_mb', 0):.0f} / "
                     f"{r.get('children_peak_rss_mb', 0):.0f} | {r['disk_gb']:.2f} | {r.get('rc')} |")
    (work / "scale.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines), flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", choices=sorted(SIZES), default="reduced")
    ap.add_argument("--workdir", default=None, help="default: data/scale-<size>")
    ap.add_argument("--engine", choices=("local", "ray"), default="local")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes for zoo and resample (default 2)")
    ap.add_argument("--steps", default=None, help="comma-separated subset of zoo,resample,correspond,cases")
    ap.add_argument("--child", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    ap.add_argument("--report", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        return child(args.child, args.report)
    work = Path(args.workdir or f"data/scale-{args.size}").resolve()
    work.mkdir(parents=True, exist_ok=True)
    size = SIZES[args.size]
    wanted = set(args.steps.split(",")) if args.steps else None
    rows = json.loads((work / "scale.json").read_text())["steps"] if (work / "scale.json").exists() else []
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for name, argv, folder in steps(size, work, ["--engine", args.engine], ["--jobs", str(args.jobs)]):
        if wanted is not None and name not in wanted:
            continue
        if table_done(folder, DONE_TABLE[name]) and any(r["step"] == name and r.get("rc") == 0 for r in rows):
            print(f"== {name}: done earlier, kept", flush=True)
            continue
        print(f"== {name}: mimicbench {' '.join(argv)}", flush=True)
        report = work / f".scale-{name}.json"
        start = time.perf_counter()
        with open(work / f"scale-{name}.log", "w") as log:
            rc = subprocess.call([sys.executable, __file__, "--report", str(report), "--child", *argv], env=env,
                                 stdout=log, stderr=subprocess.STDOUT)
        wall = time.perf_counter() - start
        figures = json.loads(report.read_text()) if report.exists() else {"rc": rc}
        rows = [r for r in rows if r["step"] != name] + [
            {"step": name, "wall_s": wall, "disk_gb": disk_bytes(work) / 1e9, **figures, "rc": rc}]
        write_report(work, rows, args.size)
        if rc not in (0, 1):
            print(f"{name} failed (exit {rc}); see {work}/scale-{name}.log")
            return rc
    data = work / "zoo5k"
    if table_done(data, "characters"):
        sys.path.insert(0, str(REPO))
        from mimicbench.datagen.zoo.table1 import add_table1

        t = add_table1(data)
        a = t["all"]
        print(f"Table 1: {a['characters']} characters, {a['motions']:,} motions, {a['frames']:,} frames, joints "
              f"{a['joints_min']}-{a['joints_max']}, {t['pairs']:,} pairs, {t['cases']:,} cases (card: {data}/CARD.md)")
    motions_bytes = disk_bytes(work / "zoo" / "motions")
    peak = max((max(r.get("peak_rss_mb", 0), r.get("children_peak_rss_mb", 0)) for r in rows), default=0)
    if motions_bytes:
        print(f"peak memory of any step / motions table on disk: {peak:.0f} MB / {motions_bytes / 1e6:.0f} MB = "
              f"{peak * 1e6 / motions_bytes:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
