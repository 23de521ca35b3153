"""What made a set of results: dataset fingerprints, the method's metadata, the toolkit version.

``bench cases`` records in the manifest the fingerprints of the ``characters`` and ``motions``
tables it read (``configs.cases.fingerprint.inputs``, see :func:`mimicbench.schemas.fingerprint.stage_config`;
``validate`` reports cases made from other tables too); ``bench run`` refuses cases whose recorded
fingerprints differ from the tables now in the dataset (the dataset was regenerated after the
cases were made).

``bench run`` writes ``RESULTS/<method>/<version>/meta.json``::

    {"method": {MethodMetadata fields}, "toolkit_version": "0.1.0", "dataset": "data/zoo",
     "fingerprints": {"characters": sha, "motions": sha, "pairs": sha | null,
                      "cases": {"h2h": sha, "cct": sha}},
     "weights": sha | null,
     "created": "2026-11-30T08:00:00+00:00"}

(``weights``: :meth:`mimicbench.benchmark.method.PoseTransferMethod.weights_fingerprint`, null for a method
without weights) and refuses (it never silently redoes) to add rows to a results folder whose
rows were made from other fingerprints, with other weights or by another toolkit version, saying
which differs: use another ``--out``, or delete the old folder. The leaderboard calls :func:`check_results_provenance`, which refuses
a results folder that mixes fingerprints.
"""
from __future__ import annotations

import json
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

from mimicbench import __version__ as TOOLKIT_VERSION
from mimicbench.schemas.errors import UserError
from mimicbench.schemas.fingerprint import digest_of, stage_config, stale_inputs, table_fingerprint
from mimicbench.schemas.dataset import Dataset
from mimicbench.schemas.manifest import atomic_write_bytes, load_manifest

META_FILE = "meta.json"
CASES_INPUTS = ("characters", "motions")


class ProvenanceError(UserError):
    """Results, cases or a dataset do not come from the same inputs."""


def split_fingerprint(manifest: dict, table: str, split: str) -> str | None:
    """Fingerprint of one split of ``table`` (its shards' paths, rows, sha256), None when absent."""
    shards = [s for s in manifest.get("tables", {}).get(table, {}).get("shards", []) if s["split"] == split]
    if not shards:
        return None
    return digest_of(sorted((s["path"], s["rows"], s["sha256"]) for s in shards))


def cases_config(dataset, params: dict) -> dict:
    """The manifest config of the cases table: ``params`` plus the fingerprints of the characters
    and motions tables of ``dataset`` (:func:`mimicbench.schemas.fingerprint.stage_config`)."""
    manifest = load_manifest(dataset)
    return stage_config(params, {t: table_fingerprint(dataset, t, manifest) for t in CASES_INPUTS})


def check_cases_current(dataset, manifest: dict | None = None) -> None:
    """Raise :class:`ProvenanceError` unless the cases were built from the dataset's current
    characters and motions (as recorded by ``bench cases``); a dataset without cases passes."""
    if manifest is None:
        manifest = dataset.manifest if isinstance(dataset, Dataset) else load_manifest(dataset)
    if not manifest.get("tables", {}).get("cases", {}).get("shards"):
        return  # no cases at all: the reader says to run `bench cases`
    recorded = (manifest.get("configs", {}).get("cases") or {}).get("fingerprint", {}).get("inputs", {})
    rebuild = f"run `mimicbench bench cases {dataset}` again"
    if not all(t in recorded for t in CASES_INPUTS):
        raise ProvenanceError(f"{dataset}: the cases do not record which characters and motions they were built "
                              f"from (made by an older toolkit); {rebuild}")
    stale = stale_inputs(dataset, manifest, "cases")
    if stale:
        raise ProvenanceError(f"{stale}: the dataset changed after its cases were made, so they no longer match "
                              f"it; {rebuild}")


def cases_are_current(dataset) -> bool:
    """Whether the dataset has cases built from its current characters and motions."""
    try:
        check_cases_current(dataset)
    except (ProvenanceError, KeyError):
        return False
    return True


def dataset_fingerprints(dataset, protocols: Sequence[str]) -> dict:
    """The fingerprints results record: characters, motions, pairs (None without a pairs table)
    and the cases of each protocol."""
    dataset = Dataset.of(dataset)
    return {"characters": dataset.fingerprint("characters"), "motions": dataset.fingerprint("motions"),
            "pairs": dataset.fingerprint("pairs") if dataset.has_table("pairs") else None,
            "cases": {p: split_fingerprint(dataset.manifest, "cases", p) for p in protocols}}


def method_meta(metadata, dataset, fingerprints: dict, weights: str | None = None) -> dict:
    """The content of ``meta.json`` for a method version run on ``dataset`` with the weights whose
    fingerprint is ``weights`` (None: the method has none)."""
    return {"method": asdict(metadata), "toolkit_version": TOOLKIT_VERSION, "dataset": str(dataset),
            "fingerprints": fingerprints, "weights": weights,
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds")}


def read_meta(folder) -> dict | None:
    """``folder/meta.json``, or None when absent.

    Raises:
        ProvenanceError: it exists but is not readable JSON.
    """
    path = Path(folder) / META_FILE
    if not path.exists():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ProvenanceError(f"{path}: unreadable ({exc}); cannot tell which dataset made these results") from exc


def _has_parts(folder: Path) -> bool:
    return any(folder.glob("part-*.parquet"))


def _cases(fingerprints: dict) -> dict:
    """``{protocol: fingerprint}`` of a fingerprints dict (a lone value, as a hand-written meta.json
    may hold, counts as protocol ``*``)."""
    cases = fingerprints.get("cases")
    if isinstance(cases, dict):
        return cases
    return {} if cases is None else {"*": cases}


def _differences(a: dict, b: dict) -> list[str]:
    """Names of the fingerprints that differ between two ``fingerprints`` dicts (cases per protocol
    compared only where both have the protocol)."""
    diff = [k for k in ("characters", "motions", "pairs") if a.get(k) != b.get(k)]
    ca, cb = _cases(a), _cases(b)
    diff += [f"cases/{p}" for p in sorted(set(ca) & set(cb)) if ca[p] != cb[p]]
    return diff


def check_method_folder(folder, meta: dict) -> None:
    """Raise :class:`ProvenanceError` when ``folder`` holds rows not made from ``meta``'s inputs."""
    folder = Path(folder)
    old = read_meta(folder)
    fresh = f"use another --out, or delete {folder} to start it again"
    if old is None:
        if _has_parts(folder):
            raise ProvenanceError(f"{folder}: result parts without {META_FILE} (made by an older toolkit, or the "
                                  f"file was lost): cannot tell which dataset made them; {fresh}")
        return
    diff = _differences(old.get("fingerprints", {}), meta["fingerprints"])
    if diff:
        raise ProvenanceError(f"{folder}: its rows were made from another dataset state ({', '.join(diff)} differ; "
                              f"dataset was {old.get('dataset')}); {fresh}")
    if old.get("weights") != meta.get("weights"):
        recorded = "no weights recorded" if "weights" not in old else f"weights {_short(old['weights'])}"
        raise ProvenanceError(f"{folder}: its rows were made with other weights ({recorded}; this run loads "
                              f"{_short(meta.get('weights'))}), e.g. a checkpoint given by option or environment "
                              f"variable against the shipped one; {fresh}")
    if old.get("toolkit_version") != meta["toolkit_version"]:
        raise ProvenanceError(f"{folder}: its rows were scored by mimicbench {old.get('toolkit_version')}, this is "
                              f"{meta['toolkit_version']}; {fresh}")


def _short(weights: str | None) -> str:
    return "none" if weights is None else weights[:12]


def write_method_meta(folder, meta: dict) -> None:
    """Write ``folder/meta.json``: the method's metadata as now, the cases fingerprints of earlier
    protocols kept, ``created`` kept from the first run."""
    folder = Path(folder)
    old = read_meta(folder) or {}
    merged = dict(meta, fingerprints=dict(meta["fingerprints"]))
    merged["fingerprints"]["cases"] = {**_cases(old.get("fingerprints", {})), **meta["fingerprints"]["cases"]}
    merged["created"] = old.get("created", meta["created"])
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(folder / META_FILE, (json.dumps(merged, indent=2, sort_keys=True) + "\n").encode())


def method_folders(results) -> list[Path]:
    """Every ``RESULTS/<method>/<version>`` folder holding result parts or a meta.json."""
    root = Path(results)
    if not root.is_dir():
        return []
    return [v for m in sorted(p for p in root.iterdir() if p.is_dir())
            for v in sorted(p for p in m.iterdir() if p.is_dir()) if _has_parts(v) or (v / META_FILE).exists()]


def check_results_provenance(results) -> dict:
    """Check that every method version in ``results`` was run on the same dataset state.

    A method version without ``meta.json`` (results written by hand or by an older toolkit) is
    not checked: the leaderboard shows its provenance as unknown.

    Returns:
        The common fingerprints (cases: the union over protocols), or {} when none is recorded.

    Raises:
        ProvenanceError: two folders' fingerprints differ (the message names both folders and
            what differs), or a meta.json is unreadable.
    """
    common: dict = {}
    first: Path | None = None
    for folder in method_folders(results):
        meta = read_meta(folder)
        if meta is None:
            continue
        fps = meta.get("fingerprints", {})
        if first is None:
            first, common = folder, {**fps, "cases": dict(_cases(fps))}
            continue
        diff = _differences(common, fps)
        if diff:
            raise ProvenanceError(f"{results}: results from different dataset states cannot be compared: "
                                  f"{folder} and {first} differ in {', '.join(diff)}; run every method on one "
                                  "dataset state, into its own results folder")
        common["cases"].update(_cases(fps))
    return common


def check_results_folder(results, fingerprints: dict) -> None:
    """Raise :class:`ProvenanceError` when ``results`` already holds rows of another dataset state."""
    for folder in method_folders(results):
        meta = read_meta(folder)
        if meta is None:
            raise ProvenanceError(f"{folder}: result parts without {META_FILE} (made by an older toolkit, or the "
                                  "file was lost): cannot tell which dataset made them; use another --out")
        diff = _differences(meta.get("fingerprints", {}), fingerprints)
        if diff:
            raise ProvenanceError(f"{results}: holds results made from another dataset state ({folder}: "
                                  f"{', '.join(diff)} differ; dataset was {meta.get('dataset')}); use another "
                                  "--out for this dataset")
