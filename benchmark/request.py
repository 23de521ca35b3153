"""What a method receives: rigs at rest and the posed source vertices (:class:`TransferRequest`),
or a rig at rest and its body motion over a window of frames (:class:`MotionRequest`).

Every array a method receives is read-only, and every request carries its own :class:`Rig`
objects (read-only views of one shared copy): a method that writes into its input raises
``ValueError: ... read-only`` (the evaluator fails that case saying so) and cannot change what
another case or another method sees. A method that needs to edit an array copies it first
(``np.array(r.target.vertices)``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from mimicbench.benchmark.normalisation import largest_extent
from mimicbench.schemas.weights import SparseWeights


def read_only(array, dtype=None) -> np.ndarray:
    """A read-only view of ``array`` whose memory cannot be made writable through the view.

    An array that is already such a view (its owner is a read-only ndarray) is viewed again
    without copying; anything else is copied once into a new read-only owner.
    """
    a = np.asarray(array, dtype=dtype)
    owner = a.base if isinstance(a.base, np.ndarray) else None
    if a.flags.writeable or owner is None or owner.flags.writeable or not owner.flags.owndata:
        owner = np.array(a, copy=True)
        owner.flags.writeable = False
    view = owner.view()
    view.flags.writeable = False
    return view


def read_only_extras(extras: dict) -> dict:
    """A new dict of ``extras`` with every array value made read-only (see :func:`read_only`)."""
    return {k: read_only(v) if isinstance(v, np.ndarray) else v for k, v in extras.items()}


class _RestMeshSize:
    """``height`` and ``size`` of a rest mesh held in ``vertices`` (N, 3), metres."""

    vertices: np.ndarray

    @property
    def height(self) -> float:
        """Y extent of the rest mesh, metres."""
        return float(self.vertices[:, 1].max() - self.vertices[:, 1].min())

    @property
    def size(self) -> float:
        """Largest side of the rest mesh's bounding box, metres: the size the benchmark scales
        translations by between two characters (:func:`mimicbench.benchmark.normalisation.size_ratio`)."""
        return largest_extent(self.vertices)


@dataclass(frozen=True)
class Rig(_RestMeshSize):
    """A character at rest with its skeleton (dataset frame: metres, Y up, +Z forward).

    Attributes:
        character_id: stable ID.
        category: e.g. ``humanoid``, ``bird``.
        vertices: (N, 3) float32 rest vertices.
        faces: (M, 3) int32 triangles.
        keypoints: (K, 3) float32 joint heads at rest.
        parents: (K,) int32, -1 for roots, ``parents[k] < k``.
        weights: skin weights, :class:`SparseWeights` of N rows over K keypoints.
        bone_names: K names as authored.
    """

    character_id: str
    category: str
    vertices: np.ndarray
    faces: np.ndarray
    keypoints: np.ndarray
    parents: np.ndarray
    weights: SparseWeights
    bone_names: tuple[str, ...]

    def __post_init__(self):
        for name in ("vertices", "faces", "keypoints", "parents"):
            object.__setattr__(self, name, read_only(getattr(self, name)))
        w = self.weights
        object.__setattr__(self, "weights", SparseWeights(read_only(w.indices), read_only(w.values), w.num_keypoints))
        object.__setattr__(self, "bone_names", tuple(self.bone_names))

    def fresh(self) -> "Rig":
        """A new Rig over the same read-only memory (no copy): one per request."""
        return dataclasses.replace(self)


class RigWithheld(RuntimeError):
    """A mesh-only method (``MethodMetadata.reads_rig`` False) read a rig field of its request."""


RIG_FIELDS = ("keypoints", "parents", "weights", "bone_names")
"""The fields of a :class:`Rig` that a mesh-only method's requests do not carry."""


def _withheld(name: str) -> property:
    def get(self):
        raise RigWithheld(f"{self.character_id}: the request carries no {name}: the method declares "
                          f"reads_rig=False (meshes only), so its requests carry no rig (keypoints, parents, "
                          f"weights, bone names); declare reads_rig=True in its MethodMetadata to read them")

    return property(get, doc="Not given to a mesh-only method: reading it raises :class:`RigWithheld`.")


@dataclass(frozen=True)
class MeshOnlyRig(_RestMeshSize):
    """A character at rest without its rig: what a mesh-only method receives in place of a :class:`Rig`.

    Attributes:
        character_id: stable ID.
        category: e.g. ``humanoid``, ``bird``.
        vertices: (N, 3) float32 rest vertices.
        faces: (M, 3) int32 triangles.

    ``keypoints``, ``parents``, ``weights`` and ``bone_names`` raise :class:`RigWithheld` (a
    method that declares meshes only and reads the rig fails the case saying so, never silently).
    """

    character_id: str
    category: str
    vertices: np.ndarray
    faces: np.ndarray

    keypoints = _withheld("keypoints")
    parents = _withheld("parents")
    weights = _withheld("weights")
    bone_names = _withheld("bone_names")

    def __post_init__(self):
        for name in ("vertices", "faces"):
            object.__setattr__(self, name, read_only(getattr(self, name)))

    @classmethod
    def of(cls, rig: "Rig | MeshOnlyRig") -> "MeshOnlyRig":
        """The rest mesh of ``rig`` without its rig (the same read-only memory, no copy)."""
        return cls(rig.character_id, rig.category, rig.vertices, rig.faces)

    def fresh(self) -> "MeshOnlyRig":
        """A new MeshOnlyRig over the same read-only memory (no copy): one per request."""
        return dataclasses.replace(self)


@dataclass(frozen=True)
class TransferRequest:
    """Pose the target like the posed source.

    Attributes:
        source: the source rig at rest (a :class:`MeshOnlyRig` for a method that reads meshes only,
            see :func:`mesh_only`).
        source_posed: (Ns, 3) float32 posed source vertices (a method that needs transforms
            estimates them, so the cycle's return leg is the same problem as the forward leg).
        target: the target rig at rest (a :class:`MeshOnlyRig` likewise).
        case_id: the case this request serves (for logging; methods must not parse it).
        extras: optional precomputed data keyed by name, e.g. ``"m_sink"``: (Ks, Kt) soft
            correspondence from the dataset's ``pairs/`` table.

    The rigs are this request's own (see :meth:`Rig.fresh`), ``source_posed`` and array extras
    are read-only, and ``extras`` is this request's own dict.
    """

    source: Rig
    source_posed: np.ndarray
    target: Rig
    case_id: str = ""
    extras: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "source", self.source.fresh())
        object.__setattr__(self, "target", self.target.fresh())
        object.__setattr__(self, "source_posed", read_only(self.source_posed))
        object.__setattr__(self, "extras", read_only_extras(self.extras))


def mesh_only(request: "TransferRequest | MotionRequest") -> "TransferRequest | MotionRequest":
    """The request as a mesh-only method (``MethodMetadata.reads_rig`` False) receives it.

    A :class:`TransferRequest` gets both rigs replaced by :class:`MeshOnlyRig` (rest vertices and
    faces, ID and category) and no ``extras`` (they are bone-indexed, e.g. ``m_sink`` (Ks, Kt));
    the posed source vertices are kept. A :class:`MotionRequest` is returned as it is: its input
    is the motion as bone transforms, which mean nothing without the bones and skin weights, so
    every method that answers the ``apparel`` protocol reads the rig there. The evaluator scores
    with its own full rigs, never with the method's copy.
    """
    if isinstance(request, MotionRequest):
        return request
    return TransferRequest(MeshOnlyRig.of(request.source), request.source_posed, MeshOnlyRig.of(request.target),
                           request.case_id, {})


@dataclass(frozen=True)
class MotionRequest:
    """Pose a character over a window of frames from its body motion (the ``apparel`` protocol).

    The method returns the posed mesh for every frame, (F, N, 3) float32, with whatever its
    apparel (skirts, hair, capes) does: follows the bones, lags, swings.

    Attributes:
        target: the character at rest with its rig (which vertices are apparel is not given).
        transforms: (F, K, 7) float32 the clip over the window as authored, (q_w, q_x, q_y, q_z,
            t) per frame and bone: body bones exact, apparel bones as the clip keys them (without
            physics).
        body_bones: (K,) bool, the bones whose motion is the body's; the others are apparel
            bones whose motion a simulation would give.
        fps: frames per second of the window.
        case_id: the case this request serves (for logging; methods must not parse it).
        extras: optional precomputed data keyed by name.
    """

    target: Rig
    transforms: np.ndarray
    body_bones: np.ndarray
    fps: float
    case_id: str = ""
    extras: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "target", self.target.fresh())
        object.__setattr__(self, "transforms", read_only(np.asarray(self.transforms, np.float32)))
        object.__setattr__(self, "body_bones", read_only(np.asarray(self.body_bones, bool)))
        object.__setattr__(self, "extras", read_only_extras(self.extras))

    @property
    def expected_shape(self) -> tuple[int, int, int]:
        """(F, N, 3): the shape of the answer."""
        return (int(self.transforms.shape[0]), int(len(self.target.vertices)), 3)
