"""Notice a process that ``multiprocessing``'s ``spawn`` started re-running its parent's script.

``spawn`` starts a child by importing the parent's main script as ``__mp_main__``; a script whose
top level is not under ``if __name__ == "__main__":`` then runs again in the child. If that top
level starts a writer or a worker of its own (``bench run``, a stage), the child would wait for the
folder lock its parent holds, or fail with ``multiprocessing``'s nested ``RuntimeError``, and the
parent would see its worker die. :func:`leave_if_reimporting_main` stops such a child at once with one
line on stderr and the exit status :data:`REIMPORT_EXIT`, which the parent reports as a start-up
failure of the harness (naming the script and the fix), never as a method's failure.
"""
from __future__ import annotations

import multiprocessing
import os
import sys

REIMPORT_EXIT = 87  # a child ended because it was re-running its parent's unguarded script


def reimporting_main() -> bool:
    """Whether this process is a ``spawn`` child still importing its parent's main script."""
    return bool(getattr(multiprocessing.current_process(), "_inheriting", False))


def main_script() -> str:
    """The path of the script being run (``__mp_main__`` in a spawn child, else ``__main__``), or ``"?"``."""
    for name in ("__mp_main__", "__main__"):
        path = getattr(sys.modules.get(name), "__file__", None)
        if path:
            return str(path)
    return "?"


def fix_text(script: str | None = None) -> str:
    """How to fix a script that starts work at import: put its top level under the main guard."""
    return (f"the script {script or main_script()} starts mimicbench work at its top level; multiprocessing's spawn "
            f"re-runs that top level in every worker process it starts. Put the script's top-level code under "
            f"`if __name__ == \"__main__\":`")


def leave_if_reimporting_main(what: str) -> None:
    """End this process with :data:`REIMPORT_EXIT` (one line on stderr naming ``what`` it was about
    to do and the fix) when it is a ``spawn`` child re-running its parent's script; else return."""
    if reimporting_main():
        print(f"mimicbench: error: a worker process, while starting, re-ran the parent's script and reached "
              f"{what}; {fix_text()}", file=sys.stderr, flush=True)
        os._exit(REIMPORT_EXIT)


__all__ = ["REIMPORT_EXIT", "fix_text", "leave_if_reimporting_main", "main_script", "reimporting_main"]
