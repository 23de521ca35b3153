"""Deterministic benchmark cases: ``mimicbench bench cases DATASET``.

Each protocol module builds its own cases (:mod:`mimicbench.benchmark.protocols`): ``h2h`` from pairs of
characters that share a skeleton (any category: "same-skeleton" transfer, ground truth carried
over bone by bone), ``cct`` from cross-category pairs with a humanoid on one side (scored by
cycle consistency). Poses are frames (not the rest frame 0) of the source's own motions, drawn
with a generator seeded by ``seed`` and the protocol's name, so the same dataset and options
give the same cases.

``split`` picks the characters (``all``: every split). ``all_pairs`` takes every candidate pair of
every split, pairs across splits included, instead of a sample.
"""
from __future__ import annotations

from mimicbench.benchmark.protocols import DEFAULT_PROTOCOLS, get_protocol
from mimicbench.benchmark.protocols.base import CasePool
from mimicbench.schemas.case import CaseRecord
from mimicbench.schemas.shards import write_records
from mimicbench.schemas.tables import rows_per_shard


def build_cases(dataset, split: str = "test", h2h_pairs: int | None = 100, h2h_poses: int = 20,
                cct_pairs: int | None = 300, cct_poses: int = 10, seed: int = 0, all_pairs: bool = False,
                protocols=DEFAULT_PROTOCOLS, sizes: dict | None = None) -> dict[str, list[CaseRecord]]:
    """Cases per protocol.

    Args:
        dataset: dataset folder with ``characters`` and ``motions``.
        split: ``train``, ``val``, ``test`` or ``all``; ignored (taken as ``all``) with ``all_pairs``.
        h2h_pairs, h2h_poses, cct_pairs, cct_poses: pairs to sample (None: all) and poses per pair
            (``h2h_xskel`` takes the h2h sizes).
        seed: generator seed.
        all_pairs: every candidate pair, across splits.
        protocols: protocol names to build.
        sizes: ``{protocol: (pairs, poses)}`` for protocols without their own arguments here.
    """
    per = {"h2h": (h2h_pairs, h2h_poses), "h2h_xskel": (h2h_pairs, h2h_poses), "cct": (cct_pairs, cct_poses),
           **(sizes or {})}
    pool = CasePool.load(dataset, "all" if all_pairs else split)
    out = {}
    for name in protocols:
        pairs, poses = per.get(name, (None, 10))
        out[name] = get_protocol(name).build_cases(pool, None if all_pairs else pairs, poses, seed)
    return out


def write_cases(dataset, cases: dict[str, list[CaseRecord]], config: dict) -> dict[str, int]:
    """Write the cases table, one shard group per protocol (split = protocol name).

    The manifest's ``configs.cases`` records ``config`` plus the fingerprints of the characters
    and motions tables the cases were built from (``configs.cases.fingerprint.inputs``):
    ``bench run`` refuses, and ``validate`` reports, cases that no longer match the dataset.

    Raises:
        ValueError: no protocol has any case: nothing is written, existing cases are kept.
    """
    from mimicbench.benchmark.provenance import cases_config

    if not any(cases.values()):
        raise ValueError(f"{dataset}: no cases were made (no two characters of the split share a skeleton_id "
                         "for h2h, no cross-category pair for cct, or no characters); the existing cases are kept. "
                         + ("Add characters that share a skeleton or differ in category"
                            if config.get("split") == "all" or config.get("all_pairs")
                            else "Try another split (--split all)"))
    config = cases_config(dataset, config)
    counts = {}
    for protocol, recs in cases.items():
        write_records(dataset, "cases", recs, split=protocol, rows_per_shard=rows_per_shard("cases"), config=config)
        counts[protocol] = len(recs)
    return counts
