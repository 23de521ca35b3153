"""A bounded little-endian reader over the bytes of one MMD file.

Every count and string length is checked against the bytes left *before* anything is
allocated, so a hostile header (a count of 2**31 vertices) costs nothing; every read past the
end, every undecodable string and every non-finite float raises :class:`MMDFormatError` naming
the file, the offset and what was expected.
"""
from __future__ import annotations

import struct

import numpy as np

from mimicbench.datagen.mmd.errors import MMDFormatError


class BoundedReader:
    """Reads fields from ``data`` (bytes) at a moving offset; ``name`` appears in every error."""

    def __init__(self, data: bytes, name: str):
        self.data = memoryview(data)
        self.name = name
        self.pos = 0

    @property
    def left(self) -> int:
        """Bytes not read yet."""
        return len(self.data) - self.pos

    def fail(self, what: str) -> MMDFormatError:
        return MMDFormatError(f"{self.name}: at byte {self.pos}: {what}")

    def take(self, n: int, what: str) -> memoryview:
        """The next ``n`` bytes; raises when fewer are left (a truncated file)."""
        if n < 0 or n > self.left:
            raise self.fail(f"expected {n} bytes for {what}, {self.left} left (file truncated?)")
        out = self.data[self.pos:self.pos + n]
        self.pos += n
        return out

    def unpack(self, fmt: str, what: str) -> tuple:
        size = struct.calcsize("<" + fmt)
        return struct.unpack("<" + fmt, self.take(size, what))

    def int(self, size: int, what: str, signed: bool = True) -> int:
        """A 1, 2 or 4 byte integer."""
        code = {1: "b", 2: "h", 4: "i"}[size]
        return self.unpack(code if signed else code.upper(), what)[0]

    def floats(self, n: int, what: str) -> np.ndarray:
        """``n`` float32 values (n,), all finite."""
        a = np.frombuffer(self.take(4 * n, what), "<f4").astype(np.float32)
        if not np.all(np.isfinite(a)):
            raise self.fail(f"non-finite number in {what}")
        return a

    def float(self, what: str) -> float:
        return float(self.floats(1, what)[0])

    def count(self, what: str, min_item_bytes: int) -> int:
        """A 4-byte element count, checked: 0 <= count and count * min_item_bytes <= bytes left."""
        n = self.int(4, f"count of {what}")
        if n < 0 or n * max(1, min_item_bytes) > self.left:
            raise self.fail(f"count of {what} is {n}, but {self.left} bytes are left "
                            f"(each takes at least {min_item_bytes}): file truncated or count corrupt")
        return n

    def text(self, encoding: str, what: str) -> str:
        """A length-prefixed string (PMX): int32 byte length, then the bytes in ``encoding``."""
        n = self.int(4, f"length of {what}")
        if n < 0 or n > self.left:
            raise self.fail(f"length of {what} is {n}, but {self.left} bytes are left (file truncated or length corrupt)")
        raw = bytes(self.take(n, what))
        try:
            return raw.decode(encoding)
        except UnicodeDecodeError as e:
            raise self.fail(f"{what} is not valid {encoding} text ({e.reason})") from None

    def fixed_text(self, size: int, what: str) -> str:
        """A NUL-padded Shift-JIS field of ``size`` bytes (PMD, VMD); bytes after the first NUL are
        ignored, as MMD does (files often carry garbage there)."""
        raw = bytes(self.take(size, what)).split(b"\0", 1)[0]
        try:
            return raw.decode("cp932")
        except UnicodeDecodeError:
            # Names cut at the field's end can split a two-byte character: drop the last byte.
            try:
                return raw[:-1].decode("cp932")
            except UnicodeDecodeError as e:
                raise self.fail(f"{what} is not valid Shift-JIS text ({e.reason})") from None

    def array(self, dtype: str, shape: tuple, what: str) -> np.ndarray:
        """A little-endian array of ``shape`` (floats checked finite)."""
        dt = np.dtype(dtype).newbyteorder("<")
        n = int(np.prod(shape))
        a = np.frombuffer(self.take(n * dt.itemsize, what), dt).reshape(shape)
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            raise self.fail(f"non-finite number in {what}")
        return a.astype(a.dtype.newbyteorder("="))


def check_indices(values: np.ndarray, upper: int, what: str, name: str, allow_minus_one: bool = True) -> None:
    """Raise :class:`MMDFormatError` unless every value is in [0, upper) (or -1 when allowed)."""
    v = np.asarray(values)
    if v.size == 0:
        return
    low = -1 if allow_minus_one else 0
    bad = (v < low) | (v >= upper)
    if bad.any():
        first = int(v[bad].ravel()[0])
        raise MMDFormatError(f"{name}: {what}: index {first} out of range (expected {low}..{upper - 1})")
