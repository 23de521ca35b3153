"""Test-only methods that misbehave: importable by module path, so they also run in worker processes.

``HostileMethod`` returns the target at rest (like ``identity``) except for the case IDs named in
the environment variable ``MIMICBENCH_HOSTILE``: ``"<case_id>=<act>|<case_id>=<act>|..."`` with
act one of ``hang``, ``exit`` (``sys.exit(3)``), ``segfault`` (``os.kill(os.getpid(), 11)``) and
``raise``. The variable is read at each call, so a test changes behaviour between runs.
"""
from __future__ import annotations

import os
import sys
import time

import numpy as np

from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod

ENV = "MIMICBENCH_HOSTILE"


def hostile_env(acts: dict[str, str]) -> str:
    """The value of :data:`ENV` for ``{case_id: act}``."""
    return "|".join(f"{cid}={act}" for cid, act in acts.items())


class HostileMethod(PoseTransferMethod):
    metadata = MethodMetadata(name="hostile", version="1", licence="MIT")

    def transfer(self, requests):
        acts = dict(item.rsplit("=", 1) for item in os.environ.get(ENV, "").split("|") if item)
        outs = []
        for r in requests:
            act = acts.get(r.case_id)
            if act == "hang":
                time.sleep(3600)
            elif act == "exit":
                sys.exit(3)
            elif act == "segfault":
                os.kill(os.getpid(), 11)
            elif act == "raise":
                raise RuntimeError(f"hostile failure on {r.case_id}")
            outs.append(np.array(r.target.vertices, dtype=np.float32))
        return outs


class MutatingMethod(PoseTransferMethod):
    """Scales the target's rest vertices, keypoints and the posed source in place, then answers
    with the (scaled) target: what broke identity's and name_copy's scores in issue 12."""

    metadata = MethodMetadata(name="mutate", version="1", licence="MIT")

    def transfer(self, requests):
        outs = []
        for r in requests:
            r.target.vertices *= 1000.0
            r.target.keypoints += 1.0
            r.source_posed[:] = 0.0
            outs.append(r.target.vertices)
        return outs


class AttributeSwapper(PoseTransferMethod):
    """Does not write into arrays, but replaces its request's rig attributes and extras (frozen
    dataclasses can be bypassed with ``object.__setattr__``); its own rows stay ``ok``."""

    metadata = MethodMetadata(name="swapper", version="1", licence="MIT")

    def transfer(self, requests):
        outs = []
        for r in requests:
            answer = np.array(r.target.vertices, dtype=np.float32)
            for rig in (r.source, r.target):
                object.__setattr__(rig, "vertices", np.zeros_like(rig.vertices))
                object.__setattr__(rig, "keypoints", np.zeros_like(rig.keypoints))
            object.__setattr__(r, "source_posed", np.zeros_like(r.source_posed))
            r.extras["m_sink"] = None
            outs.append(answer)
        return outs
