"""Trainable models by name.

A model registers its stages and config presets with :func:`register_trainable` when its
training module is imported. :func:`trainable` imports the bundled ones lazily by name
(``mimicat`` -> ``baselines.mimicat.training``), so the CLI stays fast and the core never imports
``baselines`` at module level.
"""
from __future__ import annotations

import copy
import difflib
import importlib
from dataclasses import dataclass

from mimicbench.errors import UserError
from mimicbench.training.stage import TrainStage

BUILTIN = {
    "mimicat": "baselines.mimicat.training",
    "mmdmc": "baselines.mmdmc.training",
    "npt": "baselines.npt.training",
    "cgt": "baselines.cgt.training",
    "sfpt": "baselines.sfpt.training",
}


@dataclass(frozen=True)
class Trainable:
    """A registered model: its stages in training order and its named config presets."""

    name: str
    stages: tuple[TrainStage, ...]
    configs: dict

    def stage(self, name: str) -> TrainStage:
        """The stage called ``name``; a UserError naming the known stages otherwise."""
        for s in self.stages:
            if s.name == name:
                return s
        raise UserError(f"model {self.name!r} has no stage {name!r}; its stages: "
                        f"{', '.join(s.name for s in self.stages)}")

    def config(self, preset: str) -> dict:
        """A deep copy of the preset ``preset`` (e.g. ``small``, ``paper``)."""
        if preset not in self.configs:
            raise UserError(f"model {self.name!r} has no config {preset!r}; its configs: "
                            f"{', '.join(sorted(self.configs))}")
        return copy.deepcopy(self.configs[preset])


_registered: dict[str, Trainable] = {}


def register_trainable(name: str, stages: list[TrainStage], configs: dict[str, dict]) -> Trainable:
    """Register (or replace) the trainable model ``name``.

    Args:
        name: the name ``mimicbench train NAME`` uses.
        stages: its stages in training order; a stage's ``needs`` must name earlier stages.
        configs: preset name -> config dict (JSON-serialisable).
    """
    seen: set[str] = set()
    for s in stages:
        if s.name in seen:
            raise ValueError(f"trainable {name!r}: stage {s.name!r} registered twice")
        missing = [n for n in s.needs if n not in seen]
        if missing:
            raise ValueError(f"trainable {name!r}: stage {s.name!r} needs {missing}, which must come "
                             f"earlier in the stage list")
        seen.add(s.name)
    model = Trainable(name, tuple(stages), dict(configs))
    _registered[name] = model
    return model


def available_trainables() -> list[str]:
    """Every name :func:`trainable` accepts."""
    return sorted(set(BUILTIN) | set(_registered))


def trainable(name: str) -> Trainable:
    """The trainable model ``name``, importing its bundled module on first use."""
    if name not in _registered and name in BUILTIN:
        try:
            importlib.import_module(BUILTIN[name])
        except ModuleNotFoundError as exc:
            if exc.name and BUILTIN[name].startswith(exc.name):
                raise UserError(f"trainable model {name!r} is not in this installation ({BUILTIN[name]} is "
                                f"missing)") from exc
            raise
    if name not in _registered:
        known = available_trainables()
        close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
        hint = f" Did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        raise UserError(f"unknown trainable model {name!r}.{hint} Available: {', '.join(known)}")
    return _registered[name]
