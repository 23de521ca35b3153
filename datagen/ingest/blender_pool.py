"""Blender child processes that each ingest many assets, with a timeout per asset.

A :class:`BlenderWorker` owns one ``python -m mimicbench.datagen.ingest.blender_child --serve`` process
(started on first use), sends it one job at a time and waits for the job's done line. The child
resets Blender to its factory state between assets, which is much cheaper than starting Blender
again. A job that runs past its timeout kills the process; a process that dies (a segfault in
Blender) ends only its job; either way the next job starts a fresh process, and the caller drops
whatever the failed job had written. ``assets_per_process`` bounds how many assets one process
handles before it is replaced (1 is the old one-process-per-asset behaviour).
"""
from __future__ import annotations

import collections
import os
import queue
import subprocess
import sys
import threading
import time

from mimicbench.datagen.ingest.job import DONE_MARKER, job_line

CHILD_MODULE = "mimicbench.datagen.ingest.blender_child"


class BlenderWorker:
    """One Blender child process fed jobs over stdin. Not thread-safe: one caller at a time."""

    def __init__(self, child_module: str = CHILD_MODULE, assets_per_process: int = 50):
        if assets_per_process < 1:
            raise ValueError(f"assets_per_process: expected at least 1, got {assets_per_process}")
        self.child_module = child_module
        self.assets_per_process = assets_per_process
        self.proc: subprocess.Popen | None = None
        self.lines: queue.Queue = queue.Queue()
        self.tail: collections.deque = collections.deque(maxlen=20)
        self.jobs_done = 0
        self.processes_started = 0

    def _start(self) -> None:
        env = dict(os.environ)
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        env["PYTHONPATH"] = os.pathsep.join([root] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
        self.proc = subprocess.Popen([sys.executable, "-m", self.child_module, "--serve"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
                                     env=env)
        self.lines = queue.Queue()
        self.tail.clear()
        self.jobs_done = 0
        self.processes_started += 1
        proc, lines = self.proc, self.lines

        def pump():
            for line in proc.stdout:
                lines.put(line.rstrip("\n"))
            lines.put(None)  # end of output: the process has exited

        threading.Thread(target=pump, daemon=True).start()

    def stop(self) -> None:
        """End the process (closing stdin lets it exit; killed if it does not)."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()
            proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()

    def _kill(self) -> None:
        proc, self.proc = self.proc, None
        if proc is not None:
            proc.kill()
            proc.wait()

    def run(self, asset: str, out_npz: str, options: dict, timeout: float) -> tuple[bool, str]:
        """Ingest one asset; returns (finished, reason). ``finished`` False: timed out or the
        process died (reason says which); the job's output must not be used."""
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        job = job_line(asset, out_npz, options)
        try:
            self.proc.stdin.write(job + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            code = self.proc.wait()
            self.proc = None
            return False, f"Blender process ended with code {code} before the job started"
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                self._kill()
                return False, f"timed out after {timeout:g} s"
            try:
                line = self.lines.get(timeout=left)
            except queue.Empty:
                continue
            if line is None:
                code = self.proc.wait() if self.proc is not None else None
                self.proc = None
                last = next((x for x in reversed(self.tail) if x.strip()), "no output")
                return False, f"Blender process ended with code {code} ({last[:200]})"
            if line.startswith(DONE_MARKER):
                self.jobs_done += 1
                if self.jobs_done >= self.assets_per_process:
                    self.stop()
                return True, ""
            self.tail.append(line)
