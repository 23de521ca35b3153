"""A few predictions kept for pictures: ``RESULTS/<method>/<version>/samples/<protocol>/<name>.npz``.

Results store metrics, not meshes; the leaderboard's rendered strips need the meshes of a few
cases. The evaluator hands every batch's outputs to a :class:`SampleSink`, which keeps those of
a deterministic sample of each protocol's cases (:func:`sample_case_ids`: the same cases for every
method, every rank and every resume, so strips compare methods on one case).

Each file (written atomically) holds:

- ``case_id``: 0-d string array, the case.
- ``forward``: (Nt, 3) float32, the method's prediction on the target (dataset frame, metres).
- ``returned``: (Ns, 3) float32, only for cycle protocols (cct): the return leg's prediction on
  the source.

A failed leg leaves its key out. The file name is the case ID made safe for file systems plus a
short digest of it (IDs hold ``/``, ``>`` and ``#``).
"""
from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

SAMPLES_DIR = "samples"
SAMPLES_PER_PROTOCOL = 3


def sample_rank(case_id: str) -> str:
    """Sort key of a case in the sample (the sha256 hex digest of its ID)."""
    return hashlib.sha256(case_id.encode()).hexdigest()


def sample_case_ids(cases: Sequence, k: int = SAMPLES_PER_PROTOCOL) -> list[str]:
    """``k`` case IDs of one protocol's cases, a function of the IDs and categories only.

    Cases are ranked by the sha256 of their ID; the first of each distinct (source category,
    target category) pair is taken in rank order, then the first of each distinct character pair,
    then the rest by rank, so a sample spans category pairs, then characters, where it can.
    """
    ranked = sorted(cases, key=lambda c: sample_rank(c.case_id))
    picked: list[str] = []
    for key in (lambda c: (c.source_category, c.target_category), lambda c: (c.source_id, c.target_id),
                lambda c: c.case_id):
        seen = {key(c) for c in ranked if c.case_id in picked}
        for c in ranked:
            if len(picked) >= k:
                return picked
            if c.case_id not in picked and key(c) not in seen:
                picked.append(c.case_id)
                seen.add(key(c))
    return picked


def sample_path(method_folder, protocol: str, case_id: str) -> Path:
    """Where the sample of ``case_id`` lives under ``RESULTS/<method>/<version>``."""
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", case_id).strip("_")[:80]
    return Path(method_folder) / SAMPLES_DIR / protocol / f"{safe}-{sample_rank(case_id)[:8]}.npz"


def read_sample(method_folder, protocol: str, case_id: str) -> dict[str, np.ndarray]:
    """The arrays kept for ``case_id`` (``forward``, ``returned`` where present); empty if none."""
    path = sample_path(method_folder, protocol, case_id)
    if not path.exists():
        return {}
    with np.load(path) as d:
        return {k: d[k] for k in d.files if k != "case_id"}


def _write(path: Path, arrays: dict) -> None:
    """Write ``arrays`` as a compressed .npz, atomically (built in memory, then renamed into place;
    a full disk is an OSError naming ``path``)."""
    import io

    from mimicbench.schemas.manifest import atomic_write_bytes

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


class SampleSink:
    """Keeps the predictions of the sampled cases of one method version.

    Args:
        method_folder: ``RESULTS/<method>/<version>``.
        cases: ``{protocol: every case of the protocol}`` (all ranks' cases, so the sample is the
            same on every rank).
        k: cases a protocol.
    """

    def __init__(self, method_folder, cases: dict[str, Sequence], k: int = SAMPLES_PER_PROTOCOL):
        self.folder = Path(method_folder)
        self.sampled = {p: set(sample_case_ids(cs, k)) for p, cs in cases.items()}

    def keep(self, cases: Sequence, outputs: Iterable, leg: str = "forward") -> None:
        """Store ``outputs`` of sampled ``cases`` (aligned lists).

        Args:
            cases: CaseRecords of one batch.
            outputs: per case an (N, 3) array, or a tuple whose first item is one (the
                evaluator's ``(prediction, error, seconds)``), or None for a failed leg.
            leg: ``forward`` (on the target) or ``returned`` (the cycle's return, on the source).
        """
        if leg not in ("forward", "returned"):
            raise ValueError(f"leg: expected 'forward' or 'returned', got {leg!r}")
        for case, out in zip(cases, outputs):
            if case.case_id not in self.sampled.get(case.protocol, ()):
                continue
            pred = out[0] if isinstance(out, tuple) else out
            if pred is None:
                continue
            path = sample_path(self.folder, case.protocol, case.case_id)
            arrays = read_sample(self.folder, case.protocol, case.case_id) if leg == "returned" else {}
            arrays.update(case_id=np.array(case.case_id), **{leg: np.asarray(pred, np.float32)})
            _write(path, arrays)
