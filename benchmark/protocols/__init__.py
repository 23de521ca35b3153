"""Benchmark protocols by name. Each protocol is a module with one :class:`BenchmarkProtocol`
subclass that builds its cases, its requests and its scores (see :mod:`.base`):

- ``h2h`` (:mod:`.h2h`): same-skeleton transfer against ground truth;
- ``cct`` (:mod:`.cct`): cross-category transfer scored by cycle consistency;
- ``apparel`` (:mod:`.apparel`): motion transfer on characters with simulated apparel (PMD,
  PMD_a, PMD_b, ELS over a window of frames).

Protocols are listed as ``"module:Class"`` strings and imported only when asked for; a new one is
a module plus a line in ``BUILTIN`` (or :func:`register_protocol` at run time).
"""
from __future__ import annotations

import difflib
import importlib

from benchmark.protocols.base import BenchmarkProtocol

BUILTIN = {
    "h2h": "benchmark.protocols.h2h:SameSkeleton",
    "cct": "benchmark.protocols.cct:CrossCategoryCycle",
    "apparel": "benchmark.protocols.apparel:ApparelMotion",
}
DEFAULT_PROTOCOLS = ("h2h", "cct")
"""What ``bench cases`` builds and ``bench run`` runs unless told otherwise."""

_registered: dict[str, object] = {}


def register_protocol(name: str, target) -> None:
    """Register a protocol class (or ``"module:Class"`` string) under ``name`` at run time."""
    _registered[name] = target


def available_protocols() -> list[str]:
    """Every protocol name, built-in ones first."""
    return list(BUILTIN) + [n for n in _registered if n not in BUILTIN]


def get_protocol(name: str) -> BenchmarkProtocol:
    """A protocol instance by name; raises ValueError naming the known ones."""
    target = _registered.get(name, BUILTIN.get(name))
    if target is None:
        close = difflib.get_close_matches(name, available_protocols(), n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(f"unknown protocol {name!r}; expected one of {', '.join(available_protocols())}.{hint}")
    if isinstance(target, str):
        module, _, attr = target.partition(":")
        target = getattr(importlib.import_module(module), attr)
    proto = target()
    if proto.name != name:
        raise ValueError(f"protocol {name!r}: its class says its name is {proto.name!r}")
    return proto
