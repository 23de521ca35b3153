"""Pictures of characters through Blender: panels, cameras fitted to them, one child process a job.

- :mod:`mimicbench.datagen.render.panel`: :class:`Panel` (a mesh, its role colour, label, shared camera key).
- :mod:`mimicbench.datagen.render.camera`: the orthographic camera fitted to points (numpy only).
- :mod:`mimicbench.datagen.render.blender_child`: runs inside Blender, renders every panel of a job (Workbench).
- :mod:`mimicbench.datagen.render.render`: :func:`render_panels`, :func:`compose_sheet`, :func:`render_sheet`.
- :mod:`mimicbench.datagen.render.character`: a dataset character at rest or posed by a motion frame.
- :mod:`mimicbench.datagen.render.contact_sheet`: every character of a dataset on one labelled sheet.
"""
from mimicbench.datagen.render.panel import ROLE_COLOURS, Panel
from mimicbench.datagen.render.render import RenderError, compose_sheet, render_panels, render_sheet

__all__ = ["Panel", "ROLE_COLOURS", "RenderError", "compose_sheet", "render_panels", "render_sheet"]
