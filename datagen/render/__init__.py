"""Pictures of characters through Blender: panels, cameras fitted to them, one child process a job.

- :mod:`datagen.render.panel`: :class:`Panel` (a mesh, its role colour, label, shared camera key).
- :mod:`datagen.render.camera`: the orthographic camera fitted to points (numpy only).
- :mod:`datagen.render.blender_child`: runs inside Blender, renders every panel of a job (Workbench).
- :mod:`datagen.render.render`: :func:`render_panels`, :func:`compose_sheet`, :func:`render_sheet`.
- :mod:`datagen.render.character`: a dataset character at rest or posed by a motion frame.
- :mod:`datagen.render.contact_sheet`: every character of a dataset on one labelled sheet.
"""
from datagen.render.panel import ROLE_COLOURS, Panel
from datagen.render.render import RenderError, compose_sheet, render_panels, render_sheet

__all__ = ["Panel", "ROLE_COLOURS", "RenderError", "compose_sheet", "render_panels", "render_sheet"]
