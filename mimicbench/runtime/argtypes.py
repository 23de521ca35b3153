"""argparse ``type=`` helpers that range-check numeric options and say what is allowed.

Every numeric option of the CLI goes through one of these, so ``--faces 0`` or ``--jobs -1`` is
an error naming the allowed range instead of a silent fallback or a crash later on::

    p.add_argument("--jobs", type=positive_int, default=1)
    p.add_argument("--temperature", type=float_in(0.0, None, low_open=True))
    p.add_argument("--faces", type=int_in(100, None))
    p.add_argument("--export", type=comma_choices(("obj", "bvh")), default=())

argparse turns the :class:`argparse.ArgumentTypeError` into
``mimicbench: error: argument --faces: expected an integer >= 100, got '0'`` with exit status 2.
"""
from __future__ import annotations

import argparse
import math
from typing import Callable, Iterable


def _num(x) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _range_text(kind: str, lo, hi, low_open: bool, high_open: bool) -> str:
    parts = []
    if lo is not None:
        parts.append(f"{'>' if low_open else '>='} {_num(lo)}")
    if hi is not None:
        parts.append(f"{'<' if high_open else '<='} {_num(hi)}")
    return f"{kind} " + " and ".join(parts) if parts else kind


def int_in(lo: int | None = None, hi: int | None = None) -> Callable[[str], int]:
    """An argparse type: an integer with ``lo <= value <= hi`` (``None``: unbounded on that side)."""
    what = _range_text("an integer", lo, hi, False, False)

    def parse(text: str) -> int:
        try:
            value = int(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    parse.__name__ = "integer"  # argparse names the type in some messages
    return parse


def float_in(lo: float | None = None, hi: float | None = None, low_open: bool = False,
             high_open: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite float in the range [lo, hi] (``low_open``/``high_open``: exclude the bound)."""
    what = _range_text("a finite number", lo, hi, low_open, high_open)

    def parse(text: str) -> float:
        try:
            value = float(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        bad = not math.isfinite(value)
        if lo is not None:
            bad |= value <= lo if low_open else value < lo
        if hi is not None:
            bad |= value >= hi if high_open else value > hi
        if bad:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    parse.__name__ = "number"
    return parse


positive_int = int_in(1)
positive_int.__doc__ = "An argparse type: an integer >= 1."
nonnegative_int = int_in(0)
nonnegative_int.__doc__ = "An argparse type: an integer >= 0."
positive_float = float_in(0.0, None, low_open=True)
positive_float.__doc__ = "An argparse type: a finite number > 0."

MAX_JOBS = 256  # more worker processes than this is a typo, and would exhaust the machine first
job_count = int_in(1, MAX_JOBS)
job_count.__doc__ = f"An argparse type for --jobs: an integer from 1 to {MAX_JOBS}."


def comma_choices(choices: Iterable[str], allow_empty: bool = True) -> Callable[[str], tuple[str, ...]]:
    """An argparse type: a comma-separated subset of ``choices`` (order kept, duplicates dropped).

    ``allow_empty=False`` rejects an empty list (e.g. ``--methods ""``).
    """
    choices = tuple(choices)

    def parse(text: str) -> tuple[str, ...]:
        items = tuple(dict.fromkeys(x.strip() for x in text.split(",") if x.strip()))
        bad = [x for x in items if x not in choices]
        if bad:
            raise argparse.ArgumentTypeError(f"unknown {', '.join(map(repr, bad))}; expected a comma-separated "
                                             f"list of {', '.join(choices)}")
        if not items and not allow_empty:
            raise argparse.ArgumentTypeError(f"expected at least one of {', '.join(choices)}, got {text!r}")
        return items

    parse.__name__ = "list"
    return parse
