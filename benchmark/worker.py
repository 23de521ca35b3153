"""Run a method away from the evaluator: in a worker process with a per-case timeout, or in process.

``bench run`` calls a method through a *runner*: ``run_batch(requests)`` returns a
:class:`BatchOutcome` (the outputs, or why the batch failed, and the seconds it took) and never
raises for what the method does.

- :class:`WorkerRunner` (the default) starts one worker process a method, through
  ``multiprocessing``'s ``spawn`` context: a fresh interpreter that imports the method's class by
  its import path (``module:Class``), builds it and calls ``setup(device)`` once. A batch of B
  requests may take ``B x case_timeout`` seconds. A batch that times out, or a worker that dies
  (``sys.exit`` is reported as such; ``os._exit``, a segfault, the OOM killer end the process),
  fails that batch with the reason ("timed out after 600 s", "worker died: signal 11 (SIGSEGV)");
  the next batch starts a fresh worker, which runs ``setup`` again. A ``setup`` that raises or
  times out fails every later batch of that method at once, with that reason.
- :class:`InProcessRunner` calls the method in this process (``--in-process``): no start-up cost,
  no timeout, no protection from a hang or a crash.

Requests travel efficiently: each rig is sent to a worker once and kept there by character ID;
a request then carries only the two IDs, the posed source vertices and the extras. Outputs come
back as numpy arrays (torch tensors are moved to the CPU in the worker).

The method is built twice: once in the evaluator (for its metadata; keep ``__init__`` light and
load weights in ``setup``) and once in the worker. The worker is not a member of the evaluator's
``torch.distributed`` process group (under torchrun each rank has its own worker, and
``on_distributed_init`` there only tells the method its rank): a method that needs collectives
runs with ``--in-process``.

A class that a fresh process cannot import (defined inside a function, in ``__main__``, or in an
``exec``'d string) cannot run in a worker: :func:`open_runner` then runs it in process and logs a
warning saying so. A script that calls the evaluator must guard its top level with
``if __name__ == "__main__":`` (the usual ``multiprocessing`` rule), because ``spawn`` imports the
script's ``__main__`` module in the worker. A worker is the harness's until it reports ``started``
(before it imports the method): one that ends before that is a start-up failure of the harness,
raised as :class:`WorkerStartError` (one line naming the cause and, for an unguarded script, the
fix: :mod:`mimicbench.schemas.spawn_guard`), never stored as the method's failure, so a re-run computes those
cases.
"""
from __future__ import annotations

import logging
import multiprocessing
import signal
import time
import traceback
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from mimicbench.benchmark.request import MotionRequest, Rig, TransferRequest
from mimicbench.runtime.errors import UserError
from mimicbench.runtime.registry import load_target
from mimicbench.schemas.spawn_guard import REIMPORT_EXIT, fix_text, leave_if_reimporting_main

log = logging.getLogger("mimicbench")

#: seconds a worker may take to import the method and run its ``setup`` (at least)
SETUP_TIMEOUT = 600.0
#: seconds to wait for a worker to end after ``close`` before killing it
CLOSE_TIMEOUT = 30.0
#: first field of a motion request's item in a ``transfer`` message (the apparel protocol)
MOTION = "__motion_request__"


class WorkerStartError(UserError):
    """The harness could not start a worker process (before the method was imported): not a method's failure."""


@dataclass
class BatchOutcome:
    """What one ``transfer`` call gave.

    Attributes:
        outputs: one array a request, in order, or None when the batch failed.
        error: why the batch failed (None when it did not).
        seconds: wall-clock seconds the method spent on the batch.
    """

    outputs: list | None
    error: str | None
    seconds: float


def describe_exception(exc: BaseException) -> str:
    """The reason a case fails when the method raised ``exc`` (one line)."""
    if isinstance(exc, SystemExit):
        return f"method called sys.exit({exc.code!r})"
    text = traceback.format_exception_only(type(exc), exc)[-1].strip()
    if isinstance(exc, ValueError) and "read-only" in str(exc):
        return f"method wrote into its read-only input (copy an array before changing it): {text}"
    return f"method raised: {text}"


def _transfer(method, requests) -> BatchOutcome:
    """One batch through ``method.transfer`` (``method.transfer_motion`` for motion requests)."""
    start = time.perf_counter()
    try:
        motion = bool(requests) and isinstance(requests[0], MotionRequest)
        outputs = list(method.transfer_motion(requests) if motion else method.transfer(requests))
    except Exception as exc:  # a method's failure fails its cases, never the run
        return BatchOutcome(None, describe_exception(exc), time.perf_counter() - start)
    except SystemExit as exc:
        return BatchOutcome(None, describe_exception(exc), time.perf_counter() - start)
    return BatchOutcome(outputs, None, time.perf_counter() - start)


class InProcessRunner:
    """Call the method in this process; ``setup`` and the distributed hook run at construction."""

    def __init__(self, method, device: str = "cpu", rank: int = 0, world_size: int = 1, setup: bool = True):
        self.method = method
        self.metadata = method.metadata
        if setup:
            method.setup(device)
            method.on_distributed_init(rank, world_size)

    def run_batch(self, requests: Sequence[TransferRequest]) -> BatchOutcome:
        return _transfer(self.method, requests)

    def close(self) -> None:
        self.method.on_run_end()

    def abort(self) -> None:
        """Nothing to stop in process."""


def import_path(method) -> str | None:
    """``"module:Qualname"`` that imports back to ``type(method)`` in a fresh process, or None."""
    cls = type(method)
    module, qualname = cls.__module__, cls.__qualname__
    if module == "__main__" or "<locals>" in qualname:
        return None
    try:
        obj = load_target(f"{module}:{qualname}")
    except Exception:
        return None
    return f"{module}:{qualname}" if obj is cls else None


def _poll(conn, timeout: float) -> bool:
    """``conn.poll(timeout)`` for any timeout (one poll may wait at most about 24 days)."""
    deadline = time.monotonic() + timeout
    while True:
        remaining = deadline - time.monotonic()
        if conn.poll(max(0.0, min(remaining, 3600.0))):
            return True
        if remaining <= 3600.0:
            return False


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return "unknown signal"


class WorkerRunner:
    """Call the method in a worker process with a per-case timeout (see the module docstring).

    Args:
        method: the method instance in this process (for its metadata and class).
        spec: its class as ``"module:Qualname"`` (see :func:`import_path`).
        device, rank, world_size: passed to ``setup`` and ``on_distributed_init`` in the worker.
        case_timeout: seconds a request may take; a batch of B gets ``B * case_timeout``.
    """

    def __init__(self, method, spec: str, device: str = "cpu", rank: int = 0, world_size: int = 1,
                 case_timeout: float = 600.0):
        if not case_timeout > 0:
            raise ValueError(f"case_timeout: expected seconds > 0, got {case_timeout}")
        self.metadata = method.metadata
        self.spec, self.device, self.rank, self.world_size = spec, device, rank, world_size
        self.case_timeout = float(case_timeout)
        self.context = multiprocessing.get_context("spawn")
        self.process = None
        self.conn = None
        self.sent: set[str] = set()  # character IDs whose rigs the current worker holds
        self.setup_error: str | None = None
        self.workers_started = 0
        self._last_exit: int | None = None  # exit status of the last worker that died

    # -- process management --
    def _start(self) -> None:
        leave_if_reimporting_main(f"the start of a worker for method {self.metadata.name!r}")
        parent, child = self.context.Pipe()
        self.process = self.context.Process(
            target=worker_main, args=(child, self.spec, self.device, self.rank, self.world_size),
            name=f"mimicbench-{self.metadata.name}", daemon=False)  # daemons may not start children
        self.process.start()
        child.close()
        self.conn, self.sent = parent, set()
        self.workers_started += 1
        self._started(max(SETUP_TIMEOUT, self.case_timeout))
        reply, error = self._receive(max(SETUP_TIMEOUT, self.case_timeout))
        if error is None and reply[0] != "ready":
            error = reply[1]
        if error is not None:
            self.setup_error = f"setup failed: {error}"
            self._stop()

    def _started(self, timeout: float) -> None:
        """Wait for the worker's ``started`` (sent before it imports the method).

        Raises:
            WorkerStartError: the process ended or hung before that: the harness's start-up failed
                (an unguarded script re-run by ``spawn``, an interpreter that cannot start).
        """
        reply, error = self._receive(timeout)
        if error is None and reply[0] == "started":
            return
        code = self._last_exit
        if code == REIMPORT_EXIT:
            why = fix_text()
        else:
            why = (f"{error or 'it sent ' + repr(reply[0])} before it ran mimicbench's worker code (its own output "
                   f"above says why). If the benchmark runs from a script: {fix_text()}")
        raise WorkerStartError(f"the harness could not start a worker process for method {self.metadata.name!r}: "
                               f"{why}. No case was run or stored; run again when fixed")

    def _stop(self) -> None:
        """Kill the worker (if any) and forget it; the next batch starts a fresh one."""
        if self.process is not None:
            if self.process.is_alive():
                self.process.kill()
            self.process.join()
            self.process.close()
        if self.conn is not None:
            self.conn.close()
        self.process = self.conn = None

    def _died(self) -> str:
        self.process.join(CLOSE_TIMEOUT)
        code = self._last_exit = self.process.exitcode
        self._stop()
        if code is None:
            return "worker stopped answering"
        if code < 0:
            return f"worker died: signal {-code} ({_signal_name(-code)})"
        return f"worker died: exit code {code}"

    def _receive(self, timeout: float):
        """(message, None), or (None, reason) when the worker timed out or died (it is then gone)."""
        try:
            ready = _poll(self.conn, timeout)
        except (EOFError, OSError):
            return None, self._died()
        if not ready:
            self._stop()
            return None, f"timed out after {timeout:g} s"
        try:
            return self.conn.recv(), None
        except Exception:  # EOF or a message cut short: the worker is gone
            return None, self._died()

    # -- the runner API --
    def run_batch(self, requests: Sequence[TransferRequest]) -> BatchOutcome:
        if self.setup_error is None and self.process is None:
            self._start()
        if self.setup_error is not None:
            return BatchOutcome(None, self.setup_error, 0.0)
        rigs = {}
        for r in requests:
            for rig in ((r.target,) if isinstance(r, MotionRequest) else (r.source, r.target)):
                if rig.character_id not in self.sent and rig.character_id not in rigs:
                    rigs[rig.character_id] = rig
        items = [(MOTION, r.target.character_id, np.asarray(r.transforms), np.asarray(r.body_bones), r.fps,
                  r.case_id, dict(r.extras)) if isinstance(r, MotionRequest) else
                 (r.source.character_id, np.asarray(r.source_posed), r.target.character_id, r.case_id,
                  dict(r.extras)) for r in requests]
        start = time.perf_counter()
        try:
            self.conn.send(("transfer", rigs, items))
        except Exception:
            return BatchOutcome(None, self._died(), time.perf_counter() - start)
        self.sent |= set(rigs)
        reply, error = self._receive(self.case_timeout * len(requests))
        if error is not None:
            return BatchOutcome(None, error, time.perf_counter() - start)
        kind, payload, seconds = reply
        if kind == "done":
            return BatchOutcome(payload, None, seconds)
        return BatchOutcome(None, payload, seconds)

    def close(self) -> None:
        """Ask the worker to run ``on_run_end`` and exit; kill it if it does not."""
        if self.process is None:
            return
        try:
            self.conn.send(("close",))
            self.conn.poll(CLOSE_TIMEOUT)
        except (EOFError, OSError):
            pass
        self.process.join(CLOSE_TIMEOUT)
        self._stop()

    def abort(self) -> None:
        """Kill the worker now (the run is being interrupted)."""
        self._stop()


def open_runner(method, device: str = "cpu", rank: int = 0, world_size: int = 1, case_timeout: float = 600.0,
                in_process: bool = False):
    """A :class:`WorkerRunner` for ``method``, or an :class:`InProcessRunner` when asked for or when
    the method's class cannot be imported by a fresh process (with a warning)."""
    if not in_process:
        spec = import_path(method)
        if spec is not None:
            return WorkerRunner(method, spec, device, rank, world_size, case_timeout)
        cls = type(method)
        log.warning("method %r: class %s.%s cannot be imported by a worker process (defined in a function, "
                    "in __main__ or by exec); running it in this process, without the per-case timeout and "
                    "crash isolation", method.metadata.name, cls.__module__, cls.__qualname__)
    return InProcessRunner(method, device, rank, world_size)


def _to_numpy(out):
    if hasattr(out, "detach"):  # a torch tensor, possibly on a GPU
        return out.detach().cpu().numpy()
    return out


def worker_main(conn, spec: str, device: str, rank: int, world_size: int) -> None:
    """The worker's loop: build the method, then answer ``transfer`` messages until ``close`` or EOF.

    Ctrl-C is left to the parent (which kills the worker), so it prints one message, not two.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    conn.send(("started",))  # the harness's part of the start is done: what fails from here is the method's
    try:
        method = load_target(spec)()
        method.setup(device)
        method.on_distributed_init(rank, world_size)
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which fails the cases
        conn.send(("setup_failed", describe_exception(exc)))
        return
    conn.send(("ready",))
    rigs: dict[str, Rig] = {}
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):  # the parent is gone
            return
        if message[0] == "close":
            try:
                method.on_run_end()
            finally:
                conn.send(("closed",))
            return
        _, new_rigs, items = message
        for cid, rig in new_rigs.items():
            rigs[cid] = replace(rig)  # unpickled arrays are writable: rebuild them read-only
        requests = [MotionRequest(rigs[item[1]], *item[2:]) if len(item) == 7 and item[0] == MOTION else
                    TransferRequest(rigs[item[0]], item[1], rigs[item[2]], item[3], item[4]) for item in items]
        outcome = _transfer(method, requests)
        if outcome.error is not None:
            conn.send(("raised", outcome.error, outcome.seconds))
            continue
        try:
            conn.send(("done", [_to_numpy(o) for o in outcome.outputs], outcome.seconds))
        except Exception as exc:  # an output that cannot be pickled
            conn.send(("raised", f"output could not be sent back from the worker: {describe_exception(exc)}",
                       outcome.seconds))
