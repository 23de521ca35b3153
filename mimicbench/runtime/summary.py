"""What a stage returns: items done and failed, seconds, its output folder (read by the pipeline)."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class StageSummary:
    """How a stage went. ``ok``/``failed``: items (characters, clips, pairs, cases) done and failed;
    ``seconds``: wall time in s (None: not reported); ``out``: the folder written. ``exit_code`` is the command's exit
    status: by default 1 when some items failed (the output is written, a re-run retries them), else 0.
    ``skipped``: items reused from an earlier run (counted in ``ok``); ``statuses``: this run's status
    rows; ``details``: the stage's own figures (mean Hausdorff distance, clips...), by name."""

    ok: int
    failed: int = 0
    seconds: float | None = None
    out: str = ""
    exit_code: int | None = None
    skipped: int = 0
    statuses: tuple = ()
    details: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.exit_code is None:
            object.__setattr__(self, "exit_code", 1 if self.failed else 0)


def exit_code(result) -> int:
    """A command function's exit status: its :class:`StageSummary`'s, or the int it returned."""
    return result.exit_code if isinstance(result, StageSummary) else int(result or 0)


__all__ = ["StageSummary", "exit_code"]
