"""Attach role-label files to a dataset's characters: their hidden ``bone_roles`` (ground truth,
never a method input) and, where a file gives one, their ``category``.

:func:`attach_roles` matches each file entry to characters (by character ID, or by the stem of
the character's source file or of its ID), resolves the entry's rules against the character's bone
names (:meth:`mimicbench.datagen.roles.labels.CharacterLabels.roles_for`), and rewrites the splits of the
``characters`` table whose rows changed through the shard writer (each split's shards written
under temporary names and renamed, the manifest updated atomically). While it writes, the dataset
is marked incomplete (``pending.stage`` = ``datagen roles``); a killed run leaves it so, and a
re-run with the same files finishes it. A run that changes nothing writes nothing.

Each labelled character's ``meta.roles`` says where its labels came from (file, its sha256, the
key, bones labelled); ``meta.category`` becomes ``{"value", "source": "labels", "file",
"inferred"}`` when the file gives the category.
"""
from __future__ import annotations

import dataclasses
import hashlib
import sys
from pathlib import Path

from mimicbench.datagen.roles.labels import CharacterLabels, RoleLabelError, load_labels
from mimicbench.datagen.roles.params import RolesParams
from mimicbench.datagen.stage_runner import Stage, StagePlan, StageRun, drive
from mimicbench.runtime.summary import StageSummary
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.fingerprint import stale_inputs
from mimicbench.schemas.manifest import is_complete, load_manifest, load_manifest_for_write
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.tables import rows_per_shard

STAGE = "datagen roles"  # the stage's name in the manifest's ``pending`` while it writes


def keys_of(record: CharacterRecord) -> list[str]:
    """The keys a label file may use for ``record``: its ID, its source file's stem, its ID's last part."""
    keys = [record.character_id, Path(record.source).stem, record.character_id.rsplit("/", 1)[-1]]
    return list(dict.fromkeys(keys))


def match_labels(records: list[CharacterRecord], files: list) -> tuple[dict, list[str]]:
    """``({character_id: (CharacterLabels, file)}, warnings)`` for parsed label ``files``.

    Raises:
        RoleLabelError: a character matched by two entries (in one file or across files), or an
            entry that names a zoo character (the zoo's roles are its own ground truth).
    """
    found: dict[str, tuple[CharacterLabels, object]] = {}
    warnings = []
    for f in files:
        for key, entry in f.characters.items():
            hits = [r for r in records if key in keys_of(r)]
            if not hits:
                warnings.append(f"{f.path}: character {key!r} is not in the dataset (labels not used)")
            for r in hits:
                if r.source.startswith("zoo:"):
                    raise RoleLabelError(f"{f.path}: {key!r} labels zoo character {r.character_id}, whose roles "
                                         f"are the zoo's own ground truth; label only ingested characters")
                if r.character_id in found:
                    other, other_file = found[r.character_id]
                    raise RoleLabelError(f"{r.character_id} is labelled twice: {other_file.path} ({other.key!r}) and "
                                         f"{f.path} ({key!r})")
                found[r.character_id] = (entry, f)
    return found, warnings


def file_digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def labelled_record(record: CharacterRecord, entry: CharacterLabels, file_path: str, digest: str) -> CharacterRecord:
    """``record`` with the roles (and category) of ``entry``; see the module docstring for ``meta``.

    Raises:
        RoleLabelError: the entry does not fit the character's bones (naming them).
    """
    roles = entry.roles_for(list(record.bone_names), record.character_id)
    meta = dict(record.meta or {})
    meta["roles"] = {"file": str(file_path), "sha256": digest, "key": entry.key,
                     "labelled": sum(bool(r) for r in roles), "bones": len(roles)}
    if entry.note:
        meta["roles"]["note"] = entry.note
    category = record.category
    if entry.category is not None:
        before = dict(meta.get("category") or {})
        inferred = before.get("inferred", before.get("value", record.category)) \
            if before.get("source") != "labels" else before.get("inferred")
        meta["category"] = {**{k: v for k, v in before.items() if k == "evidence"}, "value": entry.category,
                            "source": "labels", "file": str(file_path), "inferred": inferred}
        category = entry.category
    return dataclasses.replace(record, bone_roles=roles, category=category, meta=meta)


def carry_labels(old: list[CharacterRecord], new: list[CharacterRecord]) -> list[CharacterRecord]:
    """``new`` records (an asset ingested again) keeping the labels an earlier ``datagen roles``
    gave the same character (same ID and bone names): its ``bone_roles``, ``meta.roles`` and, when
    a label file gave it, its category. A character whose bones changed loses them (attach again)."""
    before = {r.character_id: r for r in old if (r.meta or {}).get("roles")}
    out = []
    for r in new:
        o = before.get(r.character_id)
        if o is None or list(o.bone_names) != list(r.bone_names):
            out.append(r)
            continue
        meta = {**(r.meta or {}), "roles": o.meta["roles"]}
        category = r.category
        if (o.meta.get("category") or {}).get("source") == "labels":
            inferred = (r.meta or {}).get("category", {}).get("inferred", r.category)
            meta["category"] = {**o.meta["category"], "inferred": inferred}
            category = o.category
        out.append(dataclasses.replace(r, bone_roles=list(o.bone_roles), category=category, meta=meta))
    return out


def _same(a: CharacterRecord, b: CharacterRecord) -> bool:
    return a.bone_roles == b.bone_roles and a.category == b.category and a.meta == b.meta


class RolesPlan(StagePlan):
    """The labels matched and resolved while planning (a label that does not fit any character is an
    error before anything is written); no per-item work; :meth:`write` rewrites the splits whose rows
    changed. A run that changes nothing (and finds the dataset complete) writes nothing."""

    status_config = None

    def __init__(self, run: StageRun):
        super().__init__(run.stage)
        root = run.out_dir
        manifest = load_manifest(root)
        if not is_complete(manifest) and (manifest.get("pending") or {}).get("stage") != STAGE:
            raise DatasetError(f"{root}: the dataset is incomplete ({(manifest.get('pending') or {}).get('stage')} "
                               f"did not finish); re-run that stage before attaching roles")
        files = [load_labels(p) for p in run.params.labels]
        digests = {f.path: file_digest(f.path) for f in files}
        records = read_records(root, "characters", allow_incomplete=True)
        found, self.warnings = match_labels(records, files)
        new, problems = [], []
        for r in records:
            if r.character_id not in found:
                new.append(r)
                continue
            entry, f = found[r.character_id]
            try:
                new.append(labelled_record(r, entry, f.path, digests[f.path]))
            except RoleLabelError as exc:
                problems.append(f"{f.path}: {exc}")
        if problems:
            raise RoleLabelError("labels that do not fit the dataset (nothing written):\n  " + "\n  ".join(problems))
        self.new, self.found = new, found
        self.changed = {r.split for r, n in zip(records, new) if not _same(r, n)}
        self.unchanged = not self.changed and is_complete(manifest)  # a killed run's re-run still marks it complete
        if self.unchanged:
            self.details = self.summary(root)

    def summary(self, root: Path) -> dict:
        manifest = load_manifest_for_write(root)
        stale = sorted({m for t in manifest["tables"] if (m := stale_inputs(root, manifest, t))})
        labelled = {}
        for n in self.new:
            if n.character_id in self.found:
                labelled[n.character_id] = {"bones": n.num_joints, "labelled": sum(bool(x) for x in n.bone_roles),
                                            "category": n.category,
                                            "category_source": ((n.meta or {}).get("category") or {}).get("source")}
        unlabelled = [n.character_id for n in self.new if not n.bone_roles or not any(n.bone_roles)]
        return {"labelled": labelled, "unlabelled": unlabelled, "warnings": self.warnings,
                "written_splits": sorted(self.changed), "stale": stale}

    def nothing_made(self, statuses) -> bool:
        return False

    def write(self, run, statuses):
        for split in sorted(self.changed):
            write_records(run.out_dir, "characters", [n for n in self.new if n.split == split], split,
                          rows_per_shard("characters"))
        self.details = {}
        return None, self.details

    def after(self, run) -> None:
        self.details.update(self.summary(run.out_dir))  # the summary's details, filled after finish()

    def counts(self, statuses) -> tuple[int, int]:
        return len(self.found), 0


STAGE_DECL = Stage(STAGE, RolesParams, inputs=("characters",), item=labelled_record, outputs=("characters",),
                   plan=RolesPlan, out_key="dataset", in_key="dataset", refuse_foreign=False, what="character",
                   command=("datagen", "roles"), function="mimicbench.datagen.roles.attach:run_command",
                   step_writes=("characters",))


def attach_roles(dataset, label_files) -> dict:
    """Attach ``label_files`` (paths of ``.toml``/``.json`` role-label files) to ``dataset``
    (:func:`drive` with the roles stage).

    Returns:
        ``{"labelled": {character_id: {"bones": K, "labelled": n, "category": c, "category_source": s}},
        "unlabelled": [character_id, ...] (no role at all: no semantic score), "warnings": [...],
        "written_splits": [...], "stale": [messages about tables made from the old characters]}``.

    Raises:
        RoleLabelError: a malformed file, or labels that do not fit a character (nothing written).
        DatasetError: the dataset is unreadable, or left incomplete by another stage.
    """
    return drive(STAGE_DECL, RolesParams(str(dataset), tuple(str(f) for f in label_files)), progress=False).details


def summary_lines(s: dict) -> list[str]:
    """The printed summary of :func:`attach_roles`'s result."""
    lines = [f"labelled {len(s['labelled'])} characters:"]
    for cid, x in sorted(s["labelled"].items()):
        cat = f"category {x['category']}" + (" (from the label file)" if x["category_source"] == "labels"
                                             else f" ({x['category_source'] or 'as stored'})")
        lines.append(f"  {cid}: {x['labelled']} of {x['bones']} bones labelled; {cat}")
    lines.append(f"characters without roles (no semantic score): {len(s['unlabelled'])}"
                 + (f": {', '.join(s['unlabelled'])}" if s["unlabelled"] else ""))
    lines.append("characters rewritten in split(s): " + (", ".join(s["written_splits"]) or "none (nothing changed)"))
    return lines


def print_warnings(s: dict) -> None:
    for w in s["warnings"] + s["stale"]:
        print(f"warning: {w}", file=sys.stderr)


def run_command(params: RolesParams) -> StageSummary:
    """``mimicbench datagen roles``: the stage on ``params`` and its report (what the command line and a
    pipeline step call)."""
    s = drive(STAGE_DECL, params, progress=False)
    print_warnings(s.details)
    print("\n".join(summary_lines(s.details)))
    return s
