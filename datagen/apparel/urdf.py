"""A chain as a small URDF: an anchor link, then capsule links on spherical joints with limits.

pybullet has no 6-DOF spring constraint, and a spherical joint's limits exist only through URDF
(``<limit lower=swing upper=swing twist=twist/>``, Bullet's btMultiBodySphericalJointLimit), so
each chain is written as a URDF and loaded as one multibody. Link frames sit at bone heads with
Z along the bone (:func:`bone_frame`), so the limit's twist is about the bone and the capsule
(Z-aligned in Bullet) lies along it; the simulation maps a link's world orientation back to the
bone's rest-relative rotation (:mod:`mimicbench.datagen.apparel.world`). The anchor is a small sphere-
inertia link without collision, carried by a fixed constraint (see :mod:`mimicbench.datagen.apparel.world`).
"""
from __future__ import annotations

import functools
import warnings

import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from mimicbench.datagen.apparel.chain_spec import ChainSpec, LinkSpec

ANCHOR_MASS_SHARE = 10.0  # the anchor outweighs the chain, so the moved constraint turns it with the bone
LIMIT_IMPULSE = 1000.0  # Bullet reads a spherical joint's ``effort`` as its limit's largest impulse


def _f(x: float) -> str:
    return format(float(x), ".9g")


def _vec(v) -> str:
    return " ".join(_f(x) for x in v)


def bone_frame(axis: np.ndarray) -> Rotation:
    """The rest orientation of a link frame: the rotation taking +Z onto unit ``axis`` (shortest arc).

    Bullet's spherical joint limit bends about the joint frame's X and Y and twists about its Z,
    and its capsules lie along Z, so each link frame has Z along its bone. Remembered per axis
    (its exact bytes): building a world asks for each link's frame four times.
    """
    given = np.asarray(axis)
    return _bone_frame(given.dtype.str, given.shape, given.tobytes())


@functools.lru_cache(maxsize=4096)
def _bone_frame(dtype: str, shape: tuple, axis_bytes: bytes) -> Rotation:
    given = np.frombuffer(axis_bytes, dtype).reshape(shape)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.asarray(given, np.float64) / np.linalg.norm(given)
    cross = np.cross(z, axis)
    s, c = np.linalg.norm(cross), float(np.dot(z, axis))
    if s < 1e-12:
        return Rotation.identity() if c > 0 else Rotation.from_rotvec([np.pi, 0.0, 0.0])
    return Rotation.from_rotvec(cross / s * np.arctan2(s, c))


def capsule_inertia(mass: float, radius: float, length: float, axial_share: float = 0.0) -> tuple[float, float]:
    """(transverse, axial) principal moments (kg m^2) of a link: those of a solid cylinder of the
    capsule's full length, the axial one raised to ``axial_share`` of the transverse one.

    A thin cylinder's own axial moment m r^2 / 2 is hundreds of times smaller than its transverse
    one, so a contact on the edge of a hair link's hull spun it about its bone past the twist
    limit within a step, and putting it back each step pushed it into the body, step after step
    (282-319 m/s^2 on a zoo walk whose body peaks at 24). A link
    stands for a stretch of strand held by its neighbours, which turns about its bone no more
    easily than across it: every kind takes ``axial_share`` 1 by default
    (:class:`mimicbench.datagen.apparel.params.ChainParams` ``axial_inertia``; 0 keeps the capsule's).
    """
    full = length + 2 * radius
    transverse = mass * (3 * radius ** 2 + full ** 2) / 12.0
    return transverse, max(mass * radius ** 2 / 2.0, axial_share * transverse)


def hull_obj(link: LinkSpec) -> str:
    """Wavefront OBJ text of ``link.hull`` in the link frame (head at the origin, Z along the bone):
    its points and the triangles of their convex hull (Bullet collides with the hull of the points)."""
    local = bone_frame(link.axis).inv().apply(np.asarray(link.hull, np.float64))
    lines = [f"v {_vec(p)}" for p in local]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in ConvexHull(local).simplices]
    return "\n".join(lines) + "\n"


def _collision(link: LinkSpec, shift: np.ndarray, hull_file) -> str:
    if hull_file is not None and link.hull is not None:
        return (f'<collision><origin xyz="{_vec(shift)}"/><geometry><mesh filename="{hull_file}"/></geometry>'
                f'</collision>')
    return (f'<collision><origin xyz="{_vec(shift + [0.0, 0.0, 0.5 * link.length])}"/>'
            f'<geometry><capsule radius="{_f(link.radius)}" length="{_f(link.length)}"/></geometry></collision>')


def chain_urdf(chain: ChainSpec, anchor_head: np.ndarray, collision_offsets=None, hull_files=None) -> str:
    """The URDF text of ``chain``; the anchor link's frame sits at ``anchor_head`` (rest, metres).

    ``collision_offsets`` (L, 3) metres, in each link's frame: shifts of the links' collision
    shapes off the bone (the inertia stays on it); None for none. ``hull_files`` (L,) the path of
    each link's :func:`hull_obj` file, or None where the link collides as its capsule (a link
    without a hull always does; no list: every link does).
    """
    shifts = np.zeros((len(chain.links), 3)) if collision_offsets is None else np.asarray(collision_offsets)
    anchor_mass = max(ANCHOR_MASS_SHARE * sum(link.mass for link in chain.links), 1e-3)
    a_inertia = 0.4 * anchor_mass * max(link.length for link in chain.links) ** 2  # a sphere of a link's length
    out = [f'<robot name="{chain.kind}">',
           f'<link name="anchor"><inertial><origin xyz="0 0 0"/><mass value="{_f(anchor_mass)}"/>'
           f'<inertia ixx="{_f(a_inertia)}" iyy="{_f(a_inertia)}" izz="{_f(a_inertia)}" ixy="0" ixz="0" iyz="0"/>'
           f'</inertial></link>']
    frames = [bone_frame(link.axis) for link in chain.links]
    for i, (link, joint, parent) in enumerate(zip(chain.links, chain.joints, chain.link_parents)):
        it, ia = capsule_inertia(link.mass, link.radius, link.length, link.axial_share)
        centre = _vec([0.0, 0.0, 0.5 * link.length])
        parent_name, parent_head, parent_frame = (("anchor", anchor_head, Rotation.identity()) if parent < 0 else
                                                  (f"l{parent}", chain.links[parent].head, frames[parent]))
        offset = parent_frame.inv().apply(np.asarray(link.head) - np.asarray(parent_head))
        with warnings.catch_warnings():  # a quarter turn about Y is a gimbal lock; the angles stay exact
            warnings.simplefilter("ignore", UserWarning)
            rpy = (parent_frame.inv() * frames[i]).as_euler("xyz")  # URDF rpy: fixed-axis X, Y, Z
        out.append(
            f'<link name="l{i}"><inertial><origin xyz="{centre}"/><mass value="{_f(link.mass)}"/>'
            f'<inertia ixx="{_f(it)}" iyy="{_f(it)}" izz="{_f(ia)}" ixy="0" ixz="0" iyz="0"/></inertial>'
            + _collision(link, shifts[i], None if hull_files is None else hull_files[i]) + '</link>')
        out.append(
            f'<joint name="j{i}" type="spherical"><parent link="{parent_name}"/><child link="l{i}"/>'
            f'<origin xyz="{_vec(offset)}" rpy="{_vec(rpy)}"/><axis xyz="0 0 1"/>'
            f'<limit lower="{_f(joint.swing_limit)}" upper="{_f(joint.swing_limit)}" twist="{_f(joint.twist_limit)}" '
            f'effort="{_f(LIMIT_IMPULSE)}" velocity="100"/></joint>')
    out.append("</robot>")
    return "\n".join(out) + "\n"
