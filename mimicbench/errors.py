"""The exception type for errors the user can fix (bad input, a wrong folder, a bad option value).

The CLI prints these as ``mimicbench: error: <message>`` and exits with status 2 (``--debug``
shows the traceback); anything else is a bug and keeps its traceback. Raise :class:`UserError`
(or a subclass such as :class:`schemas.errors.DatasetError`) with a message that says what was
expected and what was found.
"""
from __future__ import annotations


class UserError(Exception):
    """Bad input or a bad request, explained by the message; not a bug in mimicbench."""
