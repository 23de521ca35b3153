"""A dataset character as a :class:`Panel`: at rest, or posed by one frame of one of its motions."""
from __future__ import annotations

import difflib

import numpy as np
import pyarrow.compute as pc

from mimicbench.datagen.render.panel import Panel
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.columns import table_to_records
from mimicbench.schemas.shards import has_table, read_table
from mimicbench.schemas.tables import record_type


def _rows(dataset, table: str, column: str, value: str) -> list:
    t = read_table(dataset, table)
    return table_to_records(t.filter(pc.equal(t[column], value)), record_type(table))


def load_character(dataset, character_id: str):
    """The CharacterRecord ``character_id`` of ``dataset``.

    Raises:
        KeyError: no such character (the message lists close IDs).
    """
    rows = _rows(dataset, "characters", "character_id", character_id)
    if not rows:
        ids = read_table(dataset, "characters", columns=["character_id"]).column("character_id").to_pylist()
        close = difflib.get_close_matches(character_id, ids, n=3, cutoff=0.4)
        hint = f"; did you mean {', '.join(close)}?" if close else f"; it has {len(ids)} characters, e.g. {', '.join(ids[:3])}"
        raise KeyError(f"{dataset}: no character {character_id!r}{hint}")
    return rows[0]


def posed_vertices(character, motion=None, frame: int = 0) -> np.ndarray:
    """(N, 3) float32 vertices of ``character`` posed by ``motion.transforms[frame]`` (rest if no motion).

    Raises:
        IndexError: ``frame`` outside the motion.
    """
    if motion is None:
        return np.asarray(character.vertices, np.float32)
    if not 0 <= frame < motion.num_frames:
        raise IndexError(f"motion {motion.name!r} has frames 0..{motion.num_frames - 1}; got --frame {frame}")
    return linear_blend_skinning(np.asarray(character.vertices, np.float32), np.asarray(character.keypoints, np.float32),
                                 character.weights, np.asarray(motion.transforms[frame], np.float32)).astype(np.float32)


def find_motion(dataset, character_id: str, motion: str):
    """The MotionRecord of ``character_id`` whose name or motion_id is ``motion``.

    Raises:
        KeyError: no such motion (the message lists the character's motions).
    """
    rows = _rows(dataset, "motions", "character_id", character_id) if has_table(dataset, "motions") else []
    for m in rows:
        if motion in (m.name, m.motion_id):
            return m
    names = ", ".join(m.name for m in rows) or "none"
    raise KeyError(f"{character_id} has no motion {motion!r}; its motions: {names}")


def character_panel(dataset, character_id: str, motion: str | None = None, frame: int = 0,
                    label: str | None = None) -> Panel:
    """A panel of one character, at rest (grey) or posed by ``motion`` at ``frame`` (blue)."""
    char = load_character(dataset, character_id)
    if len(char.faces) == 0:
        raise ValueError(f"{character_id} has no mesh (a skeleton-only source such as BVH); nothing to render")
    m = find_motion(dataset, character_id, motion) if motion is not None else None
    verts = posed_vertices(char, m, frame)
    text = label if label is not None else (f"{character_id} ({char.category})\n"
                                            + (f"{m.name} frame {frame}" if m else "rest pose"))
    return Panel(verts, char.faces, text, role="source" if m else "rest")
