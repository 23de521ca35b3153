"""Methods by name: bundled baselines, third-party entry points, runtime registration.

Bundled methods are listed as ``"module:Class"`` strings and imported only when asked for.
Third-party packages add methods through the entry-point group ``mimicbench.methods``
(``name = "package.module:Class"``). Unknown names raise with a "did you mean" suggestion.
"""
from __future__ import annotations

import difflib
import importlib
from importlib.metadata import entry_points

from benchmark.method import PoseTransferLike, PoseTransferMethod

ENTRY_POINT_GROUP = "mimicbench.methods"

BUILTIN = {
    "identity": "baselines.identity:Identity",
    "name_copy": "baselines.name_copy:NameCopy",
    "nearest_joint": "baselines.nearest_joint:NearestJoint",
    "text_soft": "baselines.text_soft:TextSoft",
    "lbs_kinematic": "baselines.lbs_kinematic:LbsKinematic",
    "body_only": "baselines.body_only:BodyOnly",
    "mmdmc": "baselines.mmdmc.method:Mmdmc",
    "mmdmc_body_only": "baselines.mmdmc.method:MmdmcBodyOnly",
    "mmdmc_no_refine": "baselines.mmdmc.method:MmdmcNoRefine",
    "mmdmc_no_apparel": "baselines.mmdmc.method:MmdmcNoApparel",
    "mmdmc_gt_mask": "baselines.mmdmc.method:MmdmcGtMask",
    "mimicat": "baselines.mimicat.method:Mimicat",
    "mimicat_naive_avg": "baselines.mimicat.method:MimicatNaiveAvg",
    "mimicat_no_prior": "baselines.mimicat.method:MimicatNoPrior",
}

_registered: dict[str, object] = {}


def register(name: str, target) -> None:
    """Register a method class (or ``"module:Class"`` string) under ``name`` at run time."""
    _registered[name] = target


def available_methods() -> list[str]:
    """Every name that :func:`get_method` accepts, sorted."""
    names = set(BUILTIN) | set(_registered)
    names |= {ep.name for ep in entry_points(group=ENTRY_POINT_GROUP)}
    return sorted(names)


def _load(target):
    if isinstance(target, str):
        module, _, attr = target.partition(":")
        return getattr(importlib.import_module(module), attr)
    return target


def get_method(name: str) -> PoseTransferMethod:
    """Instantiate the method registered as ``name``.

    Raises:
        KeyError: unknown name, with close matches and the list of available methods.
        TypeError: the registered object does not implement the adapter API.
    """
    if name in _registered:
        target = _registered[name]
    elif name in BUILTIN:
        target = BUILTIN[name]
    else:
        eps = {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}
        if name not in eps:
            known = available_methods()
            close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
            hint = f" Did you mean {', '.join(repr(c) for c in close)}?" if close else ""
            raise KeyError(f"unknown method {name!r}.{hint} Available: {', '.join(known)}")
        target = eps[name].load()
    method = _load(target)()
    if not isinstance(method, PoseTransferLike):
        raise TypeError(f"method {name!r}: expected an object with `metadata` and `transfer(requests)`")
    return method
