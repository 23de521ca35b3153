"""A dataset folder opened once: :class:`Dataset` reads and checks ``manifest.json`` when opened and
offers the tables, records and fingerprints without re-reading it.

Readers that take a dataset path also take a :class:`Dataset` (it is path-like); a handle reflects
the manifest as it was when opened, so a stage that writes into a folder opens it again to read.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Iterable

import pyarrow as pa

from mimicbench.schemas.columns import table_to_records
from mimicbench.schemas.fingerprint import table_fingerprint
from mimicbench.schemas.shards import checked_entries, entries_of, ordered_splits, read_entries, reader_manifest
from mimicbench.schemas.tables import record_type


class Dataset:
    """The dataset at ``root`` with its manifest (a dict, as read when opened).

    Use :meth:`open`; ``allow_incomplete`` reads a folder marked incomplete (a stage resuming its
    own output).
    """

    def __init__(self, root: str | os.PathLike, manifest: dict, allow_incomplete: bool = False):
        self._given = os.fspath(root)
        self.root = Path(root)
        self.manifest = manifest
        self.allow_incomplete = allow_incomplete
        self._fingerprints: dict[str, str] = {}

    @classmethod
    def open(cls, root: str | os.PathLike, allow_incomplete: bool = False) -> "Dataset":
        """Read and check ``root/manifest.json`` once.

        Raises:
            DatasetError: not a dataset folder, no or unreadable manifest, an unknown schema major,
                or (unless ``allow_incomplete``) a dataset marked incomplete.
        """
        return cls(root, reader_manifest(root, allow_incomplete), allow_incomplete)

    @classmethod
    def of(cls, dataset: "Dataset | str | os.PathLike") -> "Dataset":
        """``dataset`` itself when it is a handle, else :meth:`open` of the path."""
        return dataset if isinstance(dataset, Dataset) else cls.open(dataset)

    def __fspath__(self) -> str:
        return self._given

    def __str__(self) -> str:
        return self._given

    def __repr__(self) -> str:
        return f"Dataset({self._given!r}, tables={self.tables})"

    @property
    def tables(self) -> list[str]:
        """Names of the tables the manifest lists shards of, sorted."""
        return sorted(t for t, v in self.manifest.get("tables", {}).items() if v.get("shards"))

    def entries(self, table: str, split: str | None = None) -> list[dict]:
        """The manifest's entries of ``table``'s shards (of ``split``, or all); [] when none."""
        return entries_of(self.manifest, table, split)

    def has_table(self, table: str, split: str | None = None) -> bool:
        """Whether the manifest lists shards of ``table`` (of ``split``)."""
        return bool(self.entries(table, split))

    def splits(self, table: str) -> list[str]:
        """Splits present for ``table``, in train/val/test order first."""
        return ordered_splits(self.entries(table))

    def readable_entries(self, table: str, split: str | None = None) -> list[dict]:
        """The entries of ``table`` after the table-level checks of :func:`mimicbench.schemas.shards.read_table`
        (not stale, at least one shard): DatasetError naming the file otherwise."""
        return checked_entries(self.root, self.manifest, table, split)

    def read_table(self, table: str, split: str | None = None, columns: list[str] | None = None, *,
                   verify: bool | None = None) -> pa.Table:
        """``table`` (of ``split``) as an Arrow table, each shard checked as
        :func:`mimicbench.schemas.shards.read_table` does."""
        return read_entries(self.root, table, self.readable_entries(table, split), columns, verify)

    def records(self, table: str, split: str | None = None, *, verify: bool | None = None) -> list[Any]:
        """``table`` (of ``split``) as records (:func:`mimicbench.schemas.tables.record_type`)."""
        return table_to_records(self.read_table(table, split, verify=verify), record_type(table))

    def fingerprint(self, table: str) -> str:
        """The table's fingerprint (:func:`mimicbench.schemas.fingerprint.table_fingerprint`), computed once.

        Raises:
            KeyError: the manifest lists no shard of ``table``.
        """
        if table not in self._fingerprints:
            self._fingerprints[table] = table_fingerprint(self.root, table, self.manifest)
        return self._fingerprints[table]

    def fingerprints(self, tables: Iterable[str]) -> dict[str, str]:
        """``{table: fingerprint}`` for each of ``tables``."""
        return {t: self.fingerprint(t) for t in tables}
