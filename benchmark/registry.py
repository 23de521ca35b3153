"""Pose-transfer methods by name: :data:`METHODS`, a :class:`mimicbench.registry.Registry`.

The bundled methods are seeded here as lazy ``"module:Class"`` entries (and declared again, with
the same targets, in ``pyproject.toml``'s ``[project.entry-points."mimicbench.methods"]``, the group
third-party packages use: ``name = "package.module:Class"``); :func:`register` adds one at run
time. Unknown names raise :class:`~mimicbench.registry.UnknownName` with a "did you mean".
"""
from __future__ import annotations

from benchmark.method import PoseTransferLike, PoseTransferMethod
from mimicbench.registry import LoadError, NameCollision, Registry, UnknownName

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
    "probe_apparel_jitter": "baselines.mmdmc.probe_jitter:ProbeApparelJitter",
    "mimicat": "baselines.mimicat.method:Mimicat",
    "mimicat_naive_avg": "baselines.mimicat.method:MimicatNaiveAvg",
    "mimicat_no_prior": "baselines.mimicat.method:MimicatNoPrior",
    "mimicat_init_only": "baselines.mimicat.method:MimicatInitOnly",
    "npt": "baselines.npt.method:Npt",
    "cgt": "baselines.cgt.method:Cgt",
    "sfpt": "baselines.sfpt.method:Sfpt",
    "npt_constant_code": "baselines.npt.method:NptConstantCode",
    "cgt_no_attention": "baselines.cgt.method:CgtNoAttention",
    "sfpt_kabsch_only": "baselines.sfpt.method:SfptKabschOnly",
    "probe_role_transfer": "baselines.probes.methods:ProbeRoleTransfer",
    "probe_mirror": "baselines.probes.methods:ProbeMirror",
    "probe_fore_hind": "baselines.probes.methods:ProbeForeHind",
    "probe_frozen_limb": "baselines.probes.methods:ProbeFrozenLimb",
    "probe_noise15": "baselines.probes.methods:ProbeNoise15",
    "probe_half_angle": "baselines.probes.methods:ProbeHalfAngle",
    "probe_rest": "baselines.probes.methods:ProbeRest",
    "nearest_joint_mirrored": "baselines.probes.methods:NearestJointMirrored",
    "nearest_joint_fore_hind": "baselines.probes.methods:NearestJointForeHind",
}

METHODS = Registry("method", BUILTIN, ENTRY_POINT_GROUP)

__all__ = ["METHODS", "LoadError", "NameCollision", "UnknownName", "available_methods", "check_method_names",
           "get_method", "register"]


def register(name: str, target) -> None:
    """Register a method class (or ``"module:Class"`` string) under ``name`` at run time."""
    METHODS.register(name, target)


def available_methods() -> list[str]:
    """Every name that :func:`get_method` accepts: the bundled ones, then the others sorted."""
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
