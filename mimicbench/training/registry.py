"""Trainable models by name: :data:`TRAINABLES`, a :class:`mimicbench.runtime.registry.Registry`.

A bundled model's training module builds its :class:`Trainable` (stages and config presets) with
:func:`make_trainable` as ``TRAINABLE``; each is an entry point of the group ``mimicbench.trainables``
(``mimicat = "mimicbench.baselines.mimicat.training:TRAINABLE"`` in ``pyproject.toml``), loaded on first
use, so this floor never names a model's module. :func:`register_trainable` adds a model at run time.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

from mimicbench.runtime.registry import Registry
from mimicbench.training.stage import TrainStage
from mimicbench.schemas.errors import UserError


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


TRAINABLES = Registry("trainable model", group="mimicbench.trainables")


def make_trainable(name: str, stages: list[TrainStage], configs: dict[str, dict]) -> Trainable:
    """The trainable model ``name`` (checked, not registered).

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
    return Trainable(name, tuple(stages), dict(configs))


def register_trainable(name: str, stages: list[TrainStage], configs: dict[str, dict]) -> Trainable:
    """Register (or replace) the trainable model ``name`` at run time (:func:`make_trainable`'s args)."""
    model = make_trainable(name, stages, configs)
    TRAINABLES.register(name, model)
    return model


def available_trainables() -> list[str]:
    """Every name :func:`trainable` accepts."""
    return TRAINABLES.names()


def trainable(name: str) -> Trainable:
    """The trainable model ``name``, importing its bundled module on first use.

    Raises:
        UnknownName: no model has that name; LoadError: its module is not in this installation.
    """
    model = TRAINABLES.get(name)
    if not isinstance(model, Trainable) or model.name != name:
        raise TypeError(f"trainable model {name!r}: expected a Trainable called {name!r}, got {model!r:.80}")
    return model
