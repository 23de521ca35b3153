"""Benchmark protocols by name. Each protocol is a module with one :class:`BenchmarkProtocol`
subclass that builds its cases, its requests and its scores (see :mod:`.base`):

- ``h2h`` (:mod:`.h2h`): same-skeleton transfer against ground truth;
- ``h2h_xskel`` (:mod:`.h2h_xskel`): humanoid transfer across skeleton families against ground truth
  retargeted through the hidden roles;
- ``cct`` (:mod:`.cct`): cross-category transfer scored by cycle consistency;
- ``apparel`` (:mod:`.apparel`): motion transfer on characters with simulated apparel (PMD,
  PMD_a, PMD_b, ELS over a window of frames).

Protocols are listed as ``"module:Class"`` strings and imported only when asked for; a new one is
a module plus a line in ``BUILTIN`` (or :func:`register_protocol` at run time), looked up through
:data:`PROTOCOLS` (a :class:`mimicbench.runtime.registry.Registry`).
"""
from __future__ import annotations

from mimicbench.benchmark.protocols.base import BenchmarkProtocol
from mimicbench.runtime.registry import Registry

BUILTIN = {
    "h2h": "mimicbench.benchmark.protocols.h2h:SameSkeleton",
    "h2h_xskel": "mimicbench.benchmark.protocols.h2h_xskel:CrossSkeleton",
    "cct": "mimicbench.benchmark.protocols.cct:CrossCategoryCycle",
    "apparel": "mimicbench.benchmark.protocols.apparel:ApparelMotion",
}
DEFAULT_PROTOCOLS = ("h2h", "h2h_xskel", "cct")
"""What ``bench cases`` builds and ``bench run`` runs unless told otherwise."""

PROTOCOLS = Registry("protocol", BUILTIN)


def register_protocol(name: str, target) -> None:
    """Register a protocol class (or ``"module:Class"`` string) under ``name`` at run time."""
    PROTOCOLS.register(name, target)


def available_protocols() -> list[str]:
    """Every protocol name, built-in ones first."""
    return PROTOCOLS.names()


def answers(protocol_names, name: str) -> bool:
    """Whether a method whose metadata lists ``protocol_names`` answers protocol ``name``: listed, or
    listing the protocol whose requests ``name``'s are (its class's ``counts_as``)."""
    if name in protocol_names:
        return True
    counts_as = getattr(PROTOCOLS.get(name), "counts_as", None) if name in PROTOCOLS.names() else None
    return counts_as is not None and counts_as in protocol_names


def get_protocol(name: str) -> BenchmarkProtocol:
    """A protocol instance by name; :class:`~mimicbench.runtime.registry.UnknownName` naming the known ones."""
    proto = PROTOCOLS.get(name)()
    if proto.name != name:
        raise ValueError(f"protocol {name!r}: its class says its name is {proto.name!r}")
    return proto
