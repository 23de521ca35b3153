"""Role labels for real characters: which bone is which part of the body.

The zoo stores a hidden role per bone (``bone_roles``: ``left/upper_arm``, ``tail/3``); ingested
characters get theirs from a role-label file (format in :mod:`.labels` and ``docs/roles.md``).
Roles are ground truth only (the semantic score, correspondence reports), never a method input.

- :mod:`.vocabulary`: which roles a file may give (zoo roles, or classes such as ``left/forelimb``);
- :mod:`.labels`: reading and checking a file, resolving its names and globs against a character;
- :mod:`.attach`: writing the roles (and a file's categories) into a dataset's characters;
- :mod:`.command`: ``mimicbench datagen roles DATASET --labels FILE``.

A character's role classes: :func:`mimicbench.datagen.correspond.roles.record_role_classes`.
"""
