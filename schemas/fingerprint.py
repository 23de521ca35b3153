"""Fingerprints: short sha256 digests that say which inputs and which parameters made something.

A derived thing (a resampled dataset, correspondences, benchmark cases, benchmark results) records
the fingerprints of the tables it read and of its own configuration; resume reuses earlier work
only when both still match. A table's fingerprint is derived from the sha256 of each of its shards
that ``manifest.json`` lists, so computing it reads only the manifest.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Iterable, Mapping

from mimicbench.schemas.manifest import load_manifest, sha256_of


def digest_of(value) -> str:
    """Hex sha256 of ``value`` as canonical JSON (sorted keys, no spaces); tuples hash like lists.

    Raises:
        TypeError: ``value`` holds something JSON cannot represent (e.g. a numpy array).
    """
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def files_fingerprint(files: Mapping[str, str | os.PathLike]) -> str:
    """Fingerprint of named files by content: ``{name: path}`` (e.g. a checkpoint's stage names
    and weight files) to the digest of ``{name: sha256 of the file}``; where the files lie does not
    count, so a copied checkpoint folder keeps its fingerprint.

    Raises:
        ValueError: no file given.
        FileNotFoundError: a path does not exist.
    """
    if not files:
        raise ValueError("files_fingerprint: expected at least one file")
    return digest_of({str(name): sha256_of(path) for name, path in files.items()})


def table_fingerprint(root: str | os.PathLike, table: str, manifest: dict | None = None) -> str:
    """Fingerprint of one table of the dataset at ``root``: its shards' paths, row counts and sha256.

    Raises:
        KeyError: the manifest lists no shard of ``table``.
    """
    manifest = load_manifest(root) if manifest is None else manifest
    shards = manifest.get("tables", {}).get(table, {}).get("shards", [])
    if not shards:
        raise KeyError(f"{root}: manifest.json lists no shard of table {table!r}")
    return digest_of(sorted((s["path"], s["rows"], s["sha256"]) for s in shards))


def tables_fingerprint(root: str | os.PathLike, tables: Iterable[str]) -> dict[str, str]:
    """``{table: fingerprint}`` for each of ``tables`` (see :func:`table_fingerprint`)."""
    manifest = load_manifest(root)
    return {t: table_fingerprint(root, t, manifest) for t in tables}


def stage_config(params: dict, inputs: dict[str, str], inputs_from: str = ".", info: dict | None = None) -> dict:
    """The config a stage stores in the manifest: ``params``, ``info`` and a ``fingerprint``.

    Args:
        params: every parameter that changes the stage's output (face count, backend, seed...).
        inputs: ``{table: table_fingerprint}`` of the tables the stage read.
        inputs_from: where those tables live: ``"."`` for the same dataset (then ``validate``
            checks that they have not changed since), else the input dataset's folder.
        info: fields kept for the reader but not fingerprinted (e.g. the input folder's path,
            which may move without changing anything).

    Returns:
        ``{**params, **info, "fingerprint": {"config": digest_of(params), "params": sorted(params),
        "inputs": inputs, "inputs_from": inputs_from}}``.
    """
    fp = {"config": digest_of(params), "params": sorted(params), "inputs": dict(inputs), "inputs_from": inputs_from}
    return {**params, **(info or {}), "fingerprint": fp}


def fingerprint_mismatch(old: dict | None, new: dict) -> str | None:
    """Why rows made under config ``old`` must not be reused under ``new`` (both from :func:`stage_config`).

    Returns:
        None when the config digests and the input fingerprints are equal, else a reason naming
        the parameters or input tables that differ.
    """
    if not old or "fingerprint" not in old:
        return "the existing rows carry no fingerprint of their inputs and parameters"
    a, b = old["fingerprint"], new["fingerprint"]
    reasons = []
    if a.get("config") != b["config"]:
        changed = [f"{k} {old.get(k)!r} -> {new.get(k)!r}" for k in b.get("params", [])
                   if old.get(k) != new.get(k)]
        reasons.append("parameters changed" + (f" ({', '.join(changed)})" if changed else ""))
    ain, bin_ = a.get("inputs", {}), b["inputs"]
    diff = sorted(t for t in set(ain) | set(bin_) if ain.get(t) != bin_.get(t))
    if diff:
        reasons.append(f"input table(s) {', '.join(diff)} changed")
    return "; ".join(reasons) or None


def stale_inputs(root: str | os.PathLike, manifest: dict, table: str) -> str | None:
    """For a table derived from tables of the same dataset (``inputs_from == "."``): why it is stale.

    Returns:
        None when every input table still has the fingerprint recorded when ``table`` was made
        (or nothing was recorded), else a reason naming the changed tables.
    """
    fp = (manifest.get("configs", {}).get(table) or {}).get("fingerprint") or {}
    if fp.get("inputs_from") != ".":
        return None
    changed = []
    for t, recorded in sorted(fp.get("inputs", {}).items()):
        try:
            now = table_fingerprint(root, t, manifest)
        except KeyError:
            now = None
        if now != recorded:
            changed.append(t)
    if not changed:
        return None
    stage = manifest["configs"][table].get("stage", "the stage that made it")
    return (f"{Path(root) / 'manifest.json'}: table {table!r} was made from other {', '.join(changed)} than the "
            f"dataset holds now; re-run {stage}")
