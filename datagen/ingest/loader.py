"""How ingest reads one kind of file (:data:`.loaders.LOADERS` maps suffixes to these)."""
from __future__ import annotations

import importlib
from dataclasses import dataclass


@dataclass(frozen=True)
class Loader:
    """How ingest reads one kind of file.

    Attributes:
        name: the route, e.g. ``blender`` or ``mmd model``.
        task: ``"module:function"`` of the per-item function the engine runs (None: not an item).
        in_blender: the task needs a Blender child process (a worker of the engine's).
        walked: a folder walk takes files of this kind.
    """

    name: str
    task: str | None
    in_blender: bool = False
    walked: bool = True

    def function(self):
        """The per-item function ``task`` names."""
        module, attr = self.task.split(":")
        return getattr(importlib.import_module(module), attr)
