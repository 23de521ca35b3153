"""The exception type for errors the user can fix (bad input, a wrong folder, a bad option value).

Defined in :mod:`mimicbench.schemas.errors` (the lowest layer, so the data contract can raise it too) and
offered here under its public name: plug-in methods and scripts raise ``mimicbench.runtime.errors.UserError``.
"""
from __future__ import annotations

from mimicbench.schemas.errors import UserError, os_error_at

__all__ = ["UserError", "os_error_at"]
