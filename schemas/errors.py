"""The errors a user can fix: :class:`UserError` and, for dataset folders, :class:`DatasetError`.

The CLI prints a :class:`UserError` as ``mimicbench: error: <message>`` and exits with status 2
(``--debug`` shows the traceback); anything else is a bug and keeps its traceback. Raise one with
a message that says what was expected and what was found. It lives here, in the data contract
(the lowest layer), so every package can raise it; :mod:`mimicbench.runtime.errors` offers the same class.
"""
from __future__ import annotations


class UserError(Exception):
    """Bad input or a bad request, explained by the message; not a bug in mimicbench."""


def os_error_at(exc: OSError, path) -> OSError:
    """``exc`` as an OSError that names ``path`` (the file being written) when it names none, with
    the underlying reason kept (pyarrow's disk-full error carries no file name; its text has the
    "No space left on device")."""
    if exc.filename is not None:
        return exc
    reason = exc.strerror or str(exc) or type(exc).__name__
    return OSError(exc.errno, reason, str(path))


class DatasetError(UserError):
    """A dataset folder is not as its manifest and the schema say (the message names the file)."""
