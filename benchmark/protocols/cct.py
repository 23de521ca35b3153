"""``cct``: cross-category transfer, scored by cycle consistency.

Cases: ordered pairs with a humanoid on exactly one side (humanoid -> any other category and any
other category -> humanoid; ``apparel`` characters count as humanoids). There is no ground
truth: the method transfers the posed source to the target (forward leg), then the forward
prediction back to the source (return leg), and the returned source is compared with the posed
source.

Scores are in the **source's** rest frame with the largest extent as headline: the cycle
compares two source meshes, and kinds of characters as different as a snake (a few centimetres
tall) and a bird must share one scale for the category pairs to be comparable. ``els_forward``
is the forward prediction's ELS against the target's rest edge lengths (no stretching).

The cycle round-trips any one-to-one bone mapping, so a mirrored or fore/hind-swapped transfer
costs it nothing: the forward prediction is also scored against hidden ground truth
(:meth:`EvalData.forward_scores`: ``semantic_deg``, which part moved, and ``out_of_range``,
whether the pose is one the target's own clips reach).
"""
from __future__ import annotations

from typing import Sequence

from mimicbench.benchmark.metrics import els
from mimicbench.benchmark.protocols.base import BenchmarkProtocol, Call, CasePool, EvalData, Outcome, wants_hidden_roles
from mimicbench.benchmark.scoring import score_pose
from mimicbench.schemas.case import CaseRecord
from mimicbench.schemas.character import HUMANOID_LIKE


class CrossCategoryCycle(BenchmarkProtocol):
    name = "cct"
    title = "cross-category transfer, scored by the cycle source -> target -> source"
    headline = "extent"

    def candidate_pairs(self, pool: CasePool) -> list[tuple]:
        return [(a, b) for a in pool.characters for b in pool.characters
                if a is not b and (a.category in HUMANOID_LIKE) != (b.category in HUMANOID_LIKE)]

    def make_case(self, source, target, motion, frame: int) -> CaseRecord:
        return CaseRecord(self.case_id(source, target, motion, frame), self.name, source.character_id,
                          target.character_id, motion.motion_id, frame, motion.transforms[frame], None,
                          source.category, target.category)

    def evaluate(self, cases: Sequence[CaseRecord], data: EvalData, call: Call) -> list[Outcome]:
        src = [data.characters[c.source_id] for c in cases]
        tgt = [data.characters[c.target_id] for c in cases]
        posed = [data.posed(s, c.source_transforms) for s, c in zip(src, cases)]
        hidden = wants_hidden_roles(call)
        forward = call([data.request(s, p, t, c.case_id, hidden) for s, p, t, c in zip(src, posed, tgt, cases)])
        ok = [i for i, (_, err, _) in enumerate(forward) if err is None]
        back = call([data.request(tgt[i], forward[i][0], src[i], cases[i].case_id, hidden) for i in ok]) if ok else []
        back_of = dict(zip(ok, back))
        out = []
        for i, c in enumerate(cases):
            pred, err, sec = forward[i]
            if err:
                out.append(Outcome(c, "failed", f"forward leg: {err}", sec))
                continue
            returned, err2, sec2 = back_of[i]
            if err2:
                out.append(Outcome(c, "failed", f"return leg: {err2}", sec + sec2, outputs={"forward": pred}))
                continue
            metrics = score_pose(returned, posed[i], data.frame(src[i]), self.headline)
            t = data.frame(tgt[i])
            metrics["els_forward"] = els(pred, tgt[i].rig.vertices, t.edges)
            metrics.update(data.forward_scores(src[i], posed[i], tgt[i], pred))
            out.append(Outcome(c, "ok", None, sec + sec2, metrics, {"forward": pred, "returned": returned}))
        return out
