"""The adapter API: one abstract class a pose-transfer method implements.

Modelled on a small batch interface: requests in, one (Nt, 3) float32 array per request out, in
the same order. ``setup(device)`` is called once before the first batch; the distributed hooks
default to no-ops so single-process methods need nothing more.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import Protocol, Sequence, runtime_checkable

import numpy as np

from mimicbench.benchmark.request import MotionRequest, TransferRequest


@dataclass(frozen=True)
class MethodMetadata:
    """What the leaderboard shows about a method.

    Attributes:
        name: registry name (lowercase, ``[a-z0-9_]``).
        version: results are stored per version; bump it when outputs change.
        licence: SPDX identifier or free text.
        needs_training: whether the method must be trained before it is evaluated.
        citation: how to cite it (BibTeX or a reference line).
        description: one line.
        tags: free-form labels.
        protocols: the benchmark protocols the method supports (names from
            :func:`mimicbench.benchmark.protocols.available_protocols`); the evaluator does not run it on
            the others and records those cases as ``not_supported``, not failed. The default is
            every protocol whose requests a general pose-transfer method can answer
            (``h2h``, ``cct``); a humanoid-only method would declare ``("h2h",)``.
        reads_rig: whether :meth:`PoseTransferMethod.transfer` reads the rig (keypoints, parents,
            skin weights, bone names, or the bone-indexed ``extras`` such as ``m_sink``) or only
            meshes. The default, True, is safe for any method. A method that declares False gets
            transfer requests whose rigs carry no rig (:func:`mimicbench.benchmark.request.mesh_only`):
            reading one raises :class:`mimicbench.benchmark.request.RigWithheld`, so the declaration
            cannot be wrong. Motion requests (``apparel``) state the motion as bone transforms,
            so they always carry the rig; the leaderboard marks the methods that read it.
    """

    name: str
    version: str
    licence: str = "unknown"
    needs_training: bool = False
    citation: str = ""
    description: str = ""
    tags: tuple[str, ...] = field(default_factory=tuple)
    protocols: tuple[str, ...] = ("h2h", "cct")
    reads_rig: bool = True

    def __post_init__(self):
        protocols = (self.protocols,) if isinstance(self.protocols, str) else tuple(self.protocols)
        if not protocols or not all(isinstance(p, str) and p for p in protocols):
            raise ValueError(f"MethodMetadata.protocols: expected a non-empty tuple of protocol names, "
                             f"got {self.protocols!r}")
        object.__setattr__(self, "protocols", protocols)
        if not isinstance(self.reads_rig, bool):
            raise ValueError(f"MethodMetadata.reads_rig: expected True or False, got {self.reads_rig!r}")


@runtime_checkable
class PoseTransferLike(Protocol):
    """Structural type of a method: anything with ``metadata`` and ``transfer``."""

    metadata: MethodMetadata

    def transfer(self, requests: Sequence[TransferRequest]) -> list[np.ndarray]: ...


class PoseTransferMethod(abc.ABC):
    """Base class of every method. Subclasses set ``metadata`` and implement :meth:`transfer`."""

    metadata: MethodMetadata

    def setup(self, device: str = "cpu") -> None:
        """Load weights and move to ``device`` (``cpu`` or ``cuda[:i]``); called once."""

    def weights_fingerprint(self) -> str | None:
        """Fingerprint of the weights this instance will load (e.g.
        :func:`mimicbench.schemas.fingerprint.files_fingerprint` of its checkpoint files), None for a method
        without weights (the default).

        Results are stored per method version and resumed, so ``bench run`` records it in the
        results' ``meta.json`` and refuses to add rows made with other weights (a user's own
        checkpoint given by option or environment variable) to a folder holding rows of the
        shipped ones. Called in the driver, before :meth:`setup`; it must not load the weights.
        """
        return None

    @abc.abstractmethod
    def transfer(self, requests: Sequence[TransferRequest]) -> list[np.ndarray]:
        """Return, for each request, the posed target vertices (Nt, 3) float32, in order."""

    def transfer_motion(self, requests: Sequence[MotionRequest]) -> list[np.ndarray]:
        """Return, for each motion request, the posed vertices of every frame (F, N, 3) float32.

        Only methods that list ``apparel`` in ``metadata.protocols`` are asked; the default says
        the method does not answer motion requests.
        """
        raise NotImplementedError(f"{type(self).__name__} does not implement transfer_motion (motion requests)")

    # Distributed hooks: called by the evaluator under torchrun; no-ops by default.
    def on_distributed_init(self, rank: int, world_size: int) -> None:
        """Called once per process after torch.distributed is initialised."""

    def on_run_end(self) -> None:
        """Called once per process after its last batch."""
