"""The exception type for errors the user can fix (bad input, a wrong folder, a bad option value).

Defined in :mod:`mimicbench.schemas.errors` (the lowest layer, so the data contract can raise it too) and
offered here under its public name: plug-in methods and scripts raise ``mimicbench.runtime.errors.UserError``.
"""
from __future__ import annotations

from mimicbench.schemas.errors import UserError, os_error_at

# Exceptions that mean "the user asked for something impossible", not "mimicbench has a bug".
# Any OSError (disk full, a read-only folder, a missing file) is the machine's state, not a bug:
# shown as ``<path>: <reason>``.
USER_ERRORS = (UserError, OSError, ValueError)


def error_text(exc: BaseException) -> str:
    """One line (or a few) for the user: the message, with the file for OS errors."""
    if isinstance(exc, OSError) and exc.filename is not None:
        return f"{exc.filename}: {exc.strerror or exc}"
    text = str(exc) or type(exc).__name__
    return text if isinstance(exc, (UserError, ValueError)) else f"{type(exc).__name__}: {text}"


__all__ = ["USER_ERRORS", "UserError", "error_text", "os_error_at"]
