"""The benchmark harness's own overhead: cases per second with the ``identity`` method.

Builds a 40-character zoo, resamples it to 5,000 faces, makes about 5,000 cases (all splits:
h2h 30 poses per family pair, cct 300 pairs x 10 poses), then times ``run_benchmark`` with
``identity`` (whose own cost is nil) against a bare loop that does only the unavoidable work per
case (pose the source and the ground truth by LBS, compute PMD and ELS, no storage, no checks).
On a machine with CUDA it also reports the torch metric twins on the GPU.

    python benchmarks/harness.py [--work DIR]
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default=None, help="folder for the data (default: a temporary folder)")
    args = ap.parse_args()
    from mimicbench.benchmark.cases import build_cases, write_cases
    from mimicbench.benchmark.evaluator import load_cases, run_benchmark
    from mimicbench.benchmark.metrics import els, pmd
    from mimicbench.benchmark.rigs import load_characters
    from mimicbench.datagen.resample.stage import resample_dataset
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.geometry.skinning import linear_blend_skinning

    work = Path(args.work or tempfile.mkdtemp(prefix="mimicbench-harness-"))
    zoo, data = work / "zoo", work / "zoo5k"
    if not (data / "manifest.json").exists():
        build_zoo(zoo, 40, seed=0, progress=False)
        resample_dataset(zoo, data, backend="fast", progress=False)
        write_cases(data, build_cases(data, "all", h2h_pairs=100, h2h_poses=30, cct_pairs=300, cct_poses=10), {})
    cases = load_cases(data, ("h2h", "cct"))
    n = sum(len(c) for c in cases.values())
    results = work / "results"
    shutil.rmtree(results, ignore_errors=True)
    start = time.perf_counter()
    run_benchmark(data, ["identity"], ("h2h", "cct"), results, batch_size=64, progress=False)
    harness = n / (time.perf_counter() - start)

    chars = load_characters(data)
    start = time.perf_counter()
    for protocol, plist in cases.items():
        for c in plist:
            s, t = chars[c.source_id], chars[c.target_id]
            posed = linear_blend_skinning(s.rig.vertices, s.rig.keypoints, s.rig.weights, c.source_transforms)
            if protocol == "h2h":
                gt = linear_blend_skinning(t.rig.vertices, t.rig.keypoints, t.rig.weights, c.target_transforms)
                pmd(t.rig.vertices, gt, t.rig.vertices), els(t.rig.vertices, gt, t.edges)
            else:
                pmd(s.rig.vertices, posed, s.rig.vertices), els(s.rig.vertices, posed, s.edges)
    bare = n / (time.perf_counter() - start)
    print(f"{n} cases: harness with identity {harness:,.0f} cases/s ({n / harness:.1f} s); bare loop {bare:,.0f} cases/s")

    import torch

    if torch.cuda.is_available():
        from mimicbench.benchmark.metrics_torch import pmd_torch

        v = torch.randn(256, 2500, 3, device="cuda")
        torch.cuda.synchronize()
        start = time.perf_counter()
        for _ in range(20):
            pmd_torch(v, v + 0.01, v)
        torch.cuda.synchronize()
        print(f"GPU PMD twin: {20 * 256 / (time.perf_counter() - start):,.0f} cases/s")
    else:
        print("no CUDA device: GPU timing skipped")
    print(f"ratio harness / bare loop: {harness / bare:.2f}")


if __name__ == "__main__":
    main()
