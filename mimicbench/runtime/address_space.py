"""Run within an address-space limit (``ulimit -v``, ``RLIMIT_AS``) instead of spinning against it.

An address-space limit counts memory a process reserves, not only what it uses. Left to their
defaults, the libraries mimicbench loads reserve far more than they touch: pyarrow's mimalloc pool
reserves 1 GiB at its first allocation, glibc gives every thread that allocates its own 64 MiB
arena, and each thread of the OpenMP, OpenBLAS and numba pools holds a stack and an OpenBLAS
buffer (32 MiB). ``datagen correspond`` on a 4-character zoo reached 3.1 GiB of address space while
using 0.8 GiB; under ``ulimit -v 3145728`` OpenBLAS then retried a failed buffer allocation
forever.

:func:`fit_to_address_space_limit` (called by the CLI before any of those libraries is imported)
does nothing without a limit. Under one it makes those reservations small: pyarrow's system
allocator, at most two glibc arenas, and one thread per pool (what a job under a memory limit
wants anyway). :func:`limit_text` names the limit in the error a job that still runs out of memory
ends with.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import resource
import sys

M_ARENA_MAX = -8  # glibc's mallopt parameter number (malloc.h)
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS",
                    "RAYON_NUM_THREADS")


def address_space_limit() -> int | None:
    """This process's soft ``RLIMIT_AS`` in bytes, or None when there is none."""
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return None if soft == resource.RLIM_INFINITY else int(soft)


def limit_text(limit: int | None = None) -> str:
    """``"the address-space limit (ulimit -v) of 3.0 GiB"``, or ``""`` without a limit."""
    limit = address_space_limit() if limit is None else limit
    if limit is None:
        return ""
    return f"the address-space limit (ulimit -v {limit // 1024}) of {limit / 2**30:.1f} GiB"


def fit_to_address_space_limit() -> int | None:
    """Under an address-space limit, keep the libraries' reservations small (module docstring); returns
    the limit in bytes, or None (and changes nothing) without one. Settings the user made win."""
    limit = address_space_limit()
    if limit is None:
        return None
    os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "system")
    os.environ.setdefault("MALLOC_ARENA_MAX", "2")  # for child processes; this one is set below
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    libc = ctypes.util.find_library("c")
    if libc:
        try:
            ctypes.CDLL(libc).mallopt(M_ARENA_MAX, int(os.environ["MALLOC_ARENA_MAX"]))
        except (OSError, AttributeError, ValueError):
            pass  # not glibc: its allocator has no arenas to cap
    if "pyarrow" in sys.modules:  # imported before the limit was seen: switch the pool before first use
        import pyarrow

        pyarrow.set_memory_pool(pyarrow.system_memory_pool())
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(int(os.environ["OMP_NUM_THREADS"]))
    return limit


__all__ = ["address_space_limit", "fit_to_address_space_limit", "limit_text"]
