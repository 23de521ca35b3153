"""Engines that run a stage's per-item work: ``local`` (this machine's processes) or ``ray``.

Every stage with per-item work takes ``--engine local|ray`` (and ``--ray-address``) through
:func:`add_engine_arguments` and builds its engine with :func:`engine_from_args`; the stage then
hands the engine to :func:`mimicbench.datagen.stage_runner.run_stage`. Output does not depend on the engine.
"""
from __future__ import annotations

import argparse

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

__all__ = ["ENGINES", "ENGINE_REGISTRY", "Engine", "LocalEngine", "Outcome", "TaskResources", "add_engine_arguments", "call_item",
           "engine_from_args", "get_engine"]


def get_engine(name: str = "local", jobs: int = 1, address: str | None = None) -> Engine:
    """The engine called ``name``: ``local`` with ``jobs`` processes, or ``ray`` (at ``address``, or a
    local Ray instance of ``jobs`` CPUs when ``jobs > 1``, else of all CPUs)."""
    return ENGINE_REGISTRY.get(name)(jobs, address)


def add_engine_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--engine`` and ``--ray-address`` to a stage's parser."""
    parser.add_argument("--engine", choices=ENGINES, default="local",
                        help="where per-item work runs: local (default: this process, or --jobs processes) or ray "
                             "(Ray tasks, retried when a worker dies; output identical to local)")
    parser.add_argument("--ray-address", default=None, metavar="ADDRESS",
                        help="with --engine ray: a running cluster (e.g. ray://head:10001 or auto); default: start a "
                             "local Ray instance (with --jobs CPUs when given)")


def engine_from_args(args: argparse.Namespace) -> Engine:
    """The engine the parsed ``--engine``, ``--ray-address`` and ``--jobs`` (if any) ask for."""
    return get_engine(args.engine, getattr(args, "jobs", 1) or 1, args.ray_address)
