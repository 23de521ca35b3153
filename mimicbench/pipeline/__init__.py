"""``mimicbench pipeline``: one command from raw assets (or the zoo) to a leaderboard (see :mod:`.spec`)."""
from mimicbench.pipeline.runner import StepResult, format_summary, run_pipeline
from mimicbench.pipeline.spec import STEP_KINDS, Pipeline, Step, load_pipeline, step_argv, step_options

__all__ = ["STEP_KINDS", "Pipeline", "Step", "StepResult", "format_summary", "load_pipeline", "run_pipeline",
           "step_argv", "step_options"]
