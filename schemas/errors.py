"""The error raised when a dataset folder is not what its manifest and the schema promise."""
from __future__ import annotations

from mimicbench.errors import UserError


class DatasetError(UserError):
    """A dataset folder is not as its manifest and the schema say (the message names the file)."""
