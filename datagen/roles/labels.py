"""Read a role-label file (TOML or JSON) and resolve its rules against one character's bones.

The format (``docs/roles.md`` has the user's version)::

    version = 1                                  # optional; 1 is the only version

    [characters."assets/Fox"]                    # a character ID, or a source file stem ("Fox")
    category = "quadruped"                       # optional: wins over the inferred category
    note = "from bone names; rest keypoints"     # optional, free text
    [characters."assets/Fox".bones]
    b_Hip_01 = "hips"                            # bone name -> role
    b_LeftUpperArm_09 = "left/front_leg/1"       # a zoo role ...
    "b_Tail*" = "tail"                           # ... or a class; a glob labels every bone it matches
    b_Root_00 = ""                               # "" : no role (keeps a glob off this bone)

JSON holds the same tree: ``{"version": 1, "characters": {"assets/Fox": {"category": ...,
"bones": {...}}}}``. A key that is a bone's exact name labels that bone; a key with ``*``, ``?``
or ``[`` that is not a bone's name is a glob (:func:`fnmatch.fnmatchcase`, case-sensitive). A
bone named exactly takes that role; otherwise the first glob in file order that matches it
does; a bone no key matches has no role. Roles are checked by
:func:`mimicbench.datagen.roles.vocabulary.role_problem`.
"""
from __future__ import annotations

import difflib
import fnmatch
import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from mimicbench.datagen.roles.vocabulary import is_class_role, role_problem
from mimicbench.schemas.character import CATEGORIES
from mimicbench.schemas.errors import UserError

FORMAT_VERSION = 1
GLOB_CHARS = frozenset("*?[")
_ENTRY_KEYS = {"category", "note", "bones"}


class RoleLabelError(UserError):
    """A role-label file is malformed, or does not fit the character it labels."""


@dataclass(frozen=True)
class CharacterLabels:
    """The labels of one character: ``key`` (character ID or source stem, as in the file),
    optional ``category``, and ``bones``: (name or glob, role) in file order."""

    key: str
    category: str | None
    bones: tuple[tuple[str, str], ...]
    note: str = ""

    def roles_for(self, bone_names: list[str], character: str = "") -> list[str]:
        """K roles of a character with ``bone_names`` ("" for a bone no key matches).

        Args:
            bone_names: the character's K bone names as authored.
            character: its ID, for messages.

        Raises:
            RoleLabelError: a key that is no bone's name and no glob (naming the key and the
                closest bone names), a glob that matches no bone, or one zoo role given to two bones.
        """
        who = character or self.key
        index = {n: k for k, n in enumerate(bone_names)}
        roles: list[str | None] = [None] * len(bone_names)
        problems = []
        for key, role in self.bones:  # exact names first: they win over any glob
            if key in index:
                roles[index[key]] = role
            elif not GLOB_CHARS & set(key):
                close = difflib.get_close_matches(key, bone_names, n=3, cutoff=0.6)
                problems.append(f"bone {key!r} is not a bone of {who}"
                                + (f" (close: {', '.join(repr(c) for c in close)})" if close else ""))
        for key, role in self.bones:
            if key in index or not GLOB_CHARS & set(key):
                continue
            hits = [k for k, n in enumerate(bone_names) if fnmatch.fnmatchcase(n, key)]
            if not hits:
                problems.append(f"glob {key!r} matches no bone of {who}")
            for k in hits:
                if roles[k] is None:
                    roles[k] = role
        out = [r or "" for r in roles]
        taken: dict[str, int] = {}
        for k, r in enumerate(out):
            if r and not is_class_role(r):
                if r in taken:
                    problems.append(f"role {r!r} given to two bones of {who}: {bone_names[taken[r]]!r} and "
                                    f"{bone_names[k]!r} (a zoo role labels one bone; use a class such as "
                                    f"'left/forelimb' for several)")
                taken.setdefault(r, k)
        if problems:
            raise RoleLabelError("; ".join(problems))
        return out


@dataclass(frozen=True)
class RoleLabels:
    """A parsed role-label file: ``characters`` by key, in file order; ``path`` it came from."""

    path: str
    characters: dict[str, CharacterLabels] = field(default_factory=dict)


def _fail(path, where: str, what: str):
    raise RoleLabelError(f"{path}: {where}: {what} (format: docs/roles.md)")


def parse_labels(tree: dict, path: str = "<labels>") -> RoleLabels:
    """Check and convert the parsed tree of a label file (see the module docstring).

    Raises:
        RoleLabelError: naming the file, the character key and the field at fault.
    """
    if not isinstance(tree, dict):
        _fail(path, "top level", f"expected a table with 'characters', got {type(tree).__name__}")
    unknown = set(tree) - {"version", "characters"}
    if unknown:
        _fail(path, "top level", f"unknown key(s) {sorted(unknown)}; expected 'version' and 'characters'")
    if tree.get("version", FORMAT_VERSION) != FORMAT_VERSION:
        _fail(path, "version", f"expected {FORMAT_VERSION}, got {tree.get('version')!r}")
    chars = tree.get("characters")
    if not isinstance(chars, dict) or not chars:
        _fail(path, "characters", "expected a non-empty table of characters keyed by character ID or file stem")
    out = {}
    for key, entry in chars.items():
        where = f"character {key!r}"
        if not isinstance(entry, dict):
            _fail(path, where, f"expected a table with 'bones' (and optional 'category'), got {entry!r}")
        extra = set(entry) - _ENTRY_KEYS
        if extra:
            _fail(path, where, f"unknown key(s) {sorted(extra)}; expected {sorted(_ENTRY_KEYS)}")
        category = entry.get("category")
        if category is not None and category not in CATEGORIES:
            _fail(path, f"{where} category", f"expected one of {', '.join(CATEGORIES)}, got {category!r}")
        note = entry.get("note", "")
        if not isinstance(note, str):
            _fail(path, f"{where} note", f"expected a string, got {note!r}")
        bones = entry.get("bones", {})
        if not isinstance(bones, dict) or (not bones and category is None):
            _fail(path, f"{where} bones", "expected a table of bone name (or glob) = role")
        problems = []
        for name, role in bones.items():
            why = role_problem(role, category or "unknown")
            if why:
                problems.append(f"bone {name!r}: {why}")
        if problems:
            _fail(path, where, "; ".join(problems))
        out[key] = CharacterLabels(key, category, tuple(bones.items()), note)
    return RoleLabels(str(path), out)


def load_labels(path) -> RoleLabels:
    """Read and check a ``.toml`` or ``.json`` role-label file.

    Raises:
        RoleLabelError: the file is missing, not valid TOML/JSON, or breaks the format.
    """
    path = Path(path)
    if not path.is_file():
        raise RoleLabelError(f"{path}: no such role-label file")
    text = path.read_bytes()
    try:
        if path.suffix.lower() == ".toml":
            tree = tomllib.loads(text.decode("utf-8"))
        elif path.suffix.lower() == ".json":
            tree = json.loads(text.decode("utf-8"))
        else:
            raise RoleLabelError(f"{path}: expected a .toml or .json role-label file")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RoleLabelError(f"{path}: not valid {path.suffix[1:].upper()}: {exc}") from None
    return parse_labels(tree, str(path))
