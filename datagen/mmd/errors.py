"""The one error a hostile or broken MMD file raises."""
from __future__ import annotations


class MMDFormatError(ValueError):
    """A PMX/PMD/VMD file is not what its format says: wrong magic, truncated, a count or string
    longer than the file, an index out of range, a non-finite number, bad text encoding.

    The message names the file, the byte offset and what was expected.
    """
