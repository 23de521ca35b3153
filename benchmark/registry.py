"""Pose-transfer methods by name: :data:`METHODS`, a :class:`mimicbench.runtime.registry.Registry`.

Every method, bundled or a plug-in's, is an entry point of the group ``mimicbench.methods``
(``name = "package.module:Class"``; the bundled ones are in this distribution's ``pyproject.toml``),
so this floor never names a method module; :func:`register` adds one at run time. Unknown names raise :class:`~mimicbench.runtime.registry.UnknownName` with a "did you mean".
"""
from __future__ import annotations

from mimicbench.benchmark.method import PoseTransferLike, PoseTransferMethod
from mimicbench.runtime.registry import LoadError, NameCollision, Registry, UnknownName

ENTRY_POINT_GROUP = "mimicbench.methods"


METHODS = Registry("method", group=ENTRY_POINT_GROUP)

__all__ = ["METHODS", "LoadError", "NameCollision", "UnknownName", "available_methods", "check_method_names",
           "get_method", "register"]


def register(name: str, target) -> None:
    """Register a method class (or ``"module:Class"`` string) under ``name`` at run time."""
    METHODS.register(name, target)


def available_methods() -> list[str]:
    """Every name that :func:`get_method` accepts: the entry points in their declared order, then run-time ones."""
    return METHODS.names()


def check_method_names(names) -> None:
    """UnknownName (or NameCollision) for the first name no entry has, before anything is loaded."""
    for name in names:
        METHODS.target(name)


def get_method(name: str) -> PoseTransferMethod:
    """Instantiate the method registered as ``name``.

    Raises:
        UnknownName: no method has that name (the message names close matches and the available ones).
        LoadError: its entry (e.g. a plug-in's entry point) could not be imported.
        TypeError: the registered object does not implement the adapter API.
    """
    method = METHODS.get(name)()
    if not isinstance(method, PoseTransferLike):
        raise TypeError(f"method {name!r}: expected an object with `metadata` and `transfer(requests)`")
    return method
