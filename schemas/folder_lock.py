"""One writer at a time per output folder (a dataset, a results folder): an advisory ``flock`` lock.

Every stage that writes a dataset (:class:`mimicbench.datagen.stage_runner.StageRun`), ``bench cases`` and
``bench run`` hold the lock of the folder they write from before they read what it holds until they
finish. A second writer of the same folder waits, after one line on stderr naming the holder
(process ID, its command line and since when)::

    waiting: data/zoo is being written by pid 4121 (mimicbench datagen ingest a.pmx --out data/zoo,
    since 2026-12-07 12:01:09 UTC); this run goes on when it ends (Ctrl-C to stop)

The lock file is ``.<folder name>.lock`` beside the folder (in its parent), so the folder holds only
what the writer puts there; it holds the holder's pid, command and start time as JSON, and is
removed when the last holder releases it. The kernel drops a ``flock`` lock when its process ends,
so a killed writer never leaves a folder locked (its lock file, left behind, is reused).

Within one process the lock is re-entrant (a pipeline runs its steps in-process; a stage calls
another stage's writer on the same folder): the process that holds it takes it again at once.
"""
from __future__ import annotations

import fcntl
import json
import os
import sys
import threading
import time
import weakref
from pathlib import Path

from mimicbench.schemas.spawn_guard import leave_if_reimporting_main

_HELD: dict[Path, list] = {}  # lock file -> [file descriptor, holders in this process, pid that took it]
_GUARD = threading.Lock()


def lock_path(folder) -> Path:
    """The lock file of ``folder``: ``<parent>/.<name>.lock`` of its resolved path."""
    folder = Path(folder).resolve()
    return folder.parent / f".{folder.name}.lock"


def holder_of(folder) -> dict | None:
    """What the lock file of ``folder`` says about its holder (``pid``, ``command``, ``since``), or None."""
    try:
        return json.loads(lock_path(folder).read_text() or "null")
    except (OSError, ValueError):
        return None


def describe_holder(info: dict | None) -> str:
    """``"pid N (COMMAND, since T)"`` for a holder record, or ``"another process"`` when unknown."""
    if not isinstance(info, dict) or "pid" not in info:
        return "another process"
    return f"pid {info['pid']} ({info.get('command', '?')}, since {info.get('since', '?')})"


def _open_locked(path: Path, folder: Path, wait: bool) -> int:
    """A descriptor of ``path`` holding its exclusive lock; the file re-opened when a releasing holder
    removed it between our open and our lock (so two processes never hold two different files)."""
    told = False
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                if not wait:
                    raise FolderBusy(f"{folder} is being written by {describe_holder(holder_of(folder))}; "
                                     f"run again when it has finished") from None
                if not told:
                    print(f"waiting: {folder} is being written by {describe_holder(holder_of(folder))}; this run "
                          f"goes on when it ends (Ctrl-C to stop)", file=sys.stderr, flush=True)
                    told = True
                fcntl.flock(fd, fcntl.LOCK_EX)
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                return fd
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)


class FolderBusy(OSError):
    """Another process writes the folder and the caller asked not to wait."""


class FolderLock:
    """The writer's lock of one folder, held from :func:`hold` until :meth:`release` (idempotent; also
    released when the object is garbage-collected, and by the kernel when the process ends)."""

    def __init__(self, folder, wait: bool = True):
        leave_if_reimporting_main(f"a writer of {folder}")  # its parent holds this lock: never wait for it
        self.folder = Path(folder)
        self.path = lock_path(folder)
        self._released = False
        with _GUARD:
            held = _HELD.get(self.path)
            if held is not None:
                held[1] += 1
            else:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                fd = _open_locked(self.path, self.folder, wait)
                record = {"pid": os.getpid(), "command": " ".join(Path(a).name if i == 0 else a
                                                                  for i, a in enumerate(sys.argv)) or "python",
                          "since": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())}
                try:
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, json.dumps(record).encode(), 0)
                except OSError:
                    pass  # a full disk: the lock holds all the same, only its holder goes unnamed
                _HELD[self.path] = [fd, 1, os.getpid()]
        self._finalizer = weakref.finalize(self, _release, self.path)

    def release(self) -> None:
        """Give the lock up (the file is removed when no holder of this process is left)."""
        if not self._released:
            self._released = True
            self._finalizer.detach()
            _release(self.path)

    def __enter__(self) -> "FolderLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _release(path: Path) -> None:
    with _GUARD:
        held = _HELD.get(path)
        if held is None or held[2] != os.getpid():
            return  # a forked child's copy: the lock stays its parent's
        held[1] -= 1
        if held[1] > 0:
            return
        del _HELD[path]
        fd = held[0]
        try:
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                os.unlink(path)  # still holding the lock: a waiter that opened it re-opens a new file
        except OSError:
            pass
        os.close(fd)


def hold(folder, wait: bool = True) -> FolderLock:
    """Take the writer's lock of ``folder`` (waiting for another process's writer when ``wait``).

    Raises:
        FolderBusy: ``wait`` is False and another process holds it (the message names the holder).
        OSError: the lock file cannot be made (a read-only parent folder).
    """
    return FolderLock(folder, wait)


__all__ = ["FolderBusy", "FolderLock", "describe_holder", "hold", "holder_of", "lock_path"]
