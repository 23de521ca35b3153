"""Apparel physics: apparel bone chains simulated with Bullet (pybullet) while the body follows a clip.

``mimicbench datagen apparel IN OUT`` writes, beside every kinematic clip of a character with
apparel bones, a simulated clip ``<clip>@sim`` whose apparel bones come from the simulation and
whose body bones are untouched, so linear blend skinning of the stored transforms gives the
simulated mesh. Modules, one concept each:

- ``chain_spec``: the physics description of a character (links, joints, collision groups).
- ``params``: per-kind parameters with defaults and the JSON override file.
- ``selection``: apparel bones from ``--apparel-bones`` globs; the vertex mask from the weights.
- ``body_shapes``: kinematic convex collision pieces per body bone, from the vertices it owns.
- ``chains``: apparel chains (links sized from bone lengths and driven vertices) from a character.
- ``urdf``: a chain as a small URDF (spherical joints with swing/twist limits, capsules).
- ``springs``: the joints' springs toward rest (implicit torques from numpy, one batch a step).
- ``world``: the pybullet world of one character (body pieces, chains, springs, limits, moved anchors).
- ``world_cache``: one world per character, reset between its clips.
- ``relax``: the blend-in frames from rest into the clip's first pose.
- ``simulate``: the world protocol and the one clip loop of every world, with the explosion check.
- ``file_plan``, ``file_physics``: an MMD file's own rigid bodies and joints (the plan; its world).
- ``quality``: per-clip quality (penetration, stretch, jitter, secondary motion).
- ``stage`` and ``command``: the dataset stage with status rows and resume, and its CLI.
- ``joint_kernel``: the per-step joint arithmetic (rotation vectors, limit screen, spring torques), compiled.
"""
