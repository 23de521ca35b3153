"""The option fields stages share, for their params dataclasses (:mod:`mimicbench.runtime.options`):
light to import, so a command's ``--help`` loads no stage code."""
from __future__ import annotations

import dataclasses

from mimicbench.engines import ENGINES
from mimicbench.runtime.argtypes import MAX_JOBS, job_count
from mimicbench.runtime.options import option


def omitted_unless_set(default=None, **kw):
    """A params field left out of the config while it holds ``default`` (old configs keep their
    fingerprint); ``kw``: its command-line form (:func:`~mimicbench.runtime.options.option`)."""
    return option(default, omit=default, **kw)


def not_a_param(default=dataclasses.MISSING, **kw):
    """A params field that does not change the output (folders, processes, exports): not in the
    config; ``kw``: its command-line form (:func:`~mimicbench.runtime.options.option`)."""
    return option(default, param=False, **kw)


def jobs_option(what: str = "worker processes"):
    """The ``--jobs`` field: ``what`` runs at once, 1 to ``MAX_JOBS``."""
    return not_a_param(1, type=job_count, help=f"{what}, 1 to {MAX_JOBS} (default 1)")


def engine_option():
    """The ``--engine`` field (:mod:`mimicbench.engines`)."""
    return not_a_param("local", choices=ENGINES,
                       help="where per-item work runs: local (default: this process, or --jobs processes) or ray "
                            "(Ray tasks, retried when a worker dies; output identical to local)")


def ray_address_option():
    """The ``--ray-address`` field."""
    return not_a_param(None, metavar="ADDRESS",
                       help="with --engine ray: a running cluster (e.g. ray://head:10001 or auto); default: start a "
                            "local Ray instance (with --jobs CPUs when given)")


def quiet_option():
    """The ``--quiet`` field."""
    return not_a_param(False, help="no progress bar")
