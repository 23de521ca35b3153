"""Test-only methods and a small benchmark dataset built from the zoo."""
from __future__ import annotations

import os
import shutil

import numpy as np

from mimicbench.baselines.name_copy import NameCopy
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod


class FlakyMethod(PoseTransferMethod):
    """Raises on every third request it sees (counting from the first), else returns the rest mesh
    shifted by 1 cm; requests whose case ID is listed in ``nan_cases`` get NaN, in ``bad_shape``
    one vertex too few."""

    metadata = MethodMetadata(name="flaky", version="1", licence="MIT")

    def __init__(self):
        self.seen = 0
        self.nan_cases: set[str] = set()
        self.bad_shape: set[str] = set()

    def transfer(self, requests):
        outs = []
        for r in requests:
            self.seen += 1
            if self.seen % 3 == 0:
                raise RuntimeError(f"flaky failure on request {self.seen}")
            v = r.target.vertices + np.float32(0.01)
            if r.case_id in self.nan_cases:
                v = v * np.nan
            if r.case_id in self.bad_shape:
                v = v[:-1]
            outs.append(v)
        return outs


class KillerCopy(NameCopy):
    """``name_copy`` that kills its own process after ``KILL_AFTER_BATCHES`` batches (env var)."""

    metadata = MethodMetadata(name="killer", version="1", licence="MIT")

    def __init__(self):
        self.batches = 0

    def transfer(self, requests):
        limit = int(os.environ.get("KILL_AFTER_BATCHES", "0"))
        if limit and self.batches >= limit:
            os._exit(17)
        self.batches += 1
        return super().transfer(requests)


def make_bench_dataset(zoo_dir, dest, h2h_poses=3, cct_pairs=6, cct_poses=2):
    """Copy a zoo to ``dest`` and add cases (all splits, small counts)."""
    from mimicbench.benchmark.cases import build_cases, write_cases

    shutil.copytree(zoo_dir, dest)
    cases = build_cases(dest, "test", h2h_pairs=4, h2h_poses=h2h_poses, cct_pairs=cct_pairs, cct_poses=cct_poses)
    write_cases(dest, cases, {"stage": "tests"})
    return dest
