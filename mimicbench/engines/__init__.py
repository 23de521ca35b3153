"""Engines that run a stage's per-item work: ``local`` (this machine's processes) or ``ray``.

Every stage with per-item work takes ``--engine local|ray`` (and ``--ray-address``) as fields of its
params dataclass; :func:`get_engine` builds the engine the stage driver
(:func:`mimicbench.datagen.stage_runner.drive`) runs the items on. Output does not depend on the engine.
"""
from __future__ import annotations

from mimicbench.engines.base import Engine, Outcome, TaskResources, call_item
from mimicbench.engines.local import LocalEngine
from mimicbench.runtime.registry import Registry


def _local(jobs: int, address: str | None) -> Engine:
    if address:
        raise ValueError("--ray-address: only with --engine ray")
    return LocalEngine(jobs)


def _ray(jobs: int, address: str | None) -> Engine:
    from mimicbench.engines.ray_engine import RayEngine

    return RayEngine(address=address, num_cpus=jobs if jobs > 1 and not address else None)


ENGINE_REGISTRY = Registry("engine", {"local": _local, "ray": _ray})
"""Engine factories ``(jobs, address) -> Engine`` by name."""
ENGINES = tuple(ENGINE_REGISTRY.names())

__all__ = ["ENGINES", "ENGINE_REGISTRY", "Engine", "LocalEngine", "Outcome", "TaskResources", "call_item", "get_engine"]


def get_engine(name: str = "local", jobs: int = 1, address: str | None = None) -> Engine:
    """The engine called ``name``: ``local`` with ``jobs`` processes, or ``ray`` (at ``address``, or a
    local Ray instance of ``jobs`` CPUs when ``jobs > 1``, else of all CPUs)."""
    return ENGINE_REGISTRY.get(name)(jobs, address)
