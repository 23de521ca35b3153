"""The correspondence methods by name: ``text`` (the paper's) and ``structure`` (the default).

- ``text``: MimiCAT / PokeAnimDB as published. Canonical bone names embedded by a text encoder,
  cosine matrix S_cos, Hungarian one-to-one matching of all min(K1, K2) slots, Sinkhorn of
  exp(S_cos / T) balanced to rows 1 and columns K1/K2.
- ``structure``: the same S_cos combined with what the skeleton says (:mod:`.structure`):

      S = text * S_cos - sum_f w_f (f_a - f_b)^2

  over the per-bone features of :data:`FEATURES`: side (a left bone meets a right one with a
  penalty of 4 x ``side``, a centre one with 1 x ``side``, so sides are kept), where a limb
  attaches along the body axis (``limb_axial``: arms / front legs / wings / pectoral fins high,
  legs / hind legs / pelvic fins low) and where a centre bone sits on it (``centre_axial``), the
  position along a limb (``along``), the segment index in a centre chain (``chain_hop``) and in a
  limb counted from its socket (``limb_hop``), the pelvis (``pelvis``), the body part of centre
  bones (``part``: trunk / neck / head / tail, each differing part costing ``part``), the depth from
  the root (``depth``) and the rest position in the normalised body frame (``position``).

  Then the skeleton as a structure (issue 35; :func:`.batched.chain_scores`,
  :func:`.batched.chain_hungarian_pairs`): every bone belongs to a chain kind (trunk with neck,
  head, tail, or a limb attached fore / mid / hind / on the head, with its side;
  :data:`.structure.CHAIN_KINDS`), and two bones of different kinds lose ``chain`` (1.0, more
  than any text score gains): the trunk never meets a hand or a foot, an arm never a hind leg.
  The trunk (pelvis to below the neck, arc-length positions 0..1) and each limb's main path are
  **sequences**: trunks score at least ``trunk - |position gap|`` with each other (0.7: a
  ``LowerBack`` meets an ``Abdomen`` whatever the words) and are aligned by a dynamic programme
  that keeps their order; limbs are paired within a chain kind and side by the Hungarian on the
  totals of their alignments and aligned link by link in order, so a link never jumps to another
  limb nor past its neighbour. What no sequence matched (fingers off the main path, heads, tails)
  goes to the Hungarian. Bones whose score stays at or below ``no_match`` are left unmatched,
  **except** two bones whose canonical names are the same or synonyms (``hips`` / ``pelvis`` /
  ``body``, ``chest`` / ``upper spine``; ``foot`` / ``ankle`` are one word already;
  :data:`.structure.NAME_SYNONYMS`): their score is raised to at least ``anchor`` (0.55, above
  the threshold), and after the matching any such pair whose bones both stayed free is paired,
  so the rule never drops ``Hips -> Hips`` or ``Body -> Body``. Sinkhorn runs on the same scores
  with a dustbin of ``no_match``, so M_sink's rows sum to at most 1 (several source bones may
  share a target, up to max(1, K1/K2) of mass each).

**No-match threshold: 0.45** on S. It sits between the scores of true counterparts (a shared
name scores near 1, a synonym or a cross-kind counterpart 0.5-0.9: "left upper arm" against
"left front upper leg" 0.75, "left wing 1" against "left front leg 1" 0.57, minus small structure
penalties) and those of bones with none (an insect's middle legs against a bird's legs, a finger
against a hoof: a structure penalty of 0.3 or more on top of a middling text score). Raise it
(``--no-match``) for fewer, surer matches. It was chosen, with ``anchor`` 0.1 above it, on the
real-rig labels of ``LABELLED`` and ``TUNED`` (tests/test_correspond_real_rigs.py) and on the
zoo (seed 0, 14 characters: its role map also tells which bones have no counterpart), never on
``HELD_OUT``: labelled agreement 97.1% at 0.35 and 0.40, 96.8% at 0.45, 95.7% at 0.50, but below
0.45 the zoo's apparel -> fish pairs fell to 0.70-0.73 role agreement (bones without a
counterpart matched), so 0.45, the lowest threshold keeping every zoo category pair at 0.8 or
more. The weights were chosen on the zoo's naming styles and on the same tuned labels; each pair
records the method and weights that made it (``pairs.method``, ``pairs.method_params``).
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass

import numpy as np

from mimicbench.datagen.correspond.batched import DEFAULT_TEMPERATURE, correspondence_batch
from mimicbench.datagen.correspond.canonical import canonicalize_names
from mimicbench.datagen.correspond.structure import skeleton_features
from mimicbench.runtime.registry import Registry

FEATURES = ("side", "limb_axial", "centre_axial", "along", "chain_hop", "limb_hop", "pelvis", "trunk", "neck", "head",
            "tail", "depth", "x", "y", "z", "seq_id", "seq_pos", "chain", "name_key")  # the last four: weight 0


@dataclass(frozen=True)
class MatchMethod:
    """A correspondence method: the weights of S's terms, the no-match threshold, temperature T."""

    name: str
    text: float = 1.0
    side: float = 0.0
    limb_axial: float = 0.0
    centre_axial: float = 0.0
    along: float = 0.0
    chain_hop: float = 0.0
    limb_hop: float = 0.0
    pelvis: float = 0.0
    part: float = 0.0
    depth: float = 0.0
    position: float = 0.0
    chain: float = 0.0
    anchor: float | None = None
    trunk: float | None = None
    no_match: float | None = None
    temperature: float = DEFAULT_TEMPERATURE

    @property
    def uses_structure(self) -> bool:
        return any(self.feature_weights())

    def feature_weights(self) -> list[float]:
        """Weights of :data:`FEATURES` (the columns of :meth:`SkeletonFeatures.matrix`)."""
        return [self.side, self.limb_axial, self.centre_axial, self.along, self.chain_hop, self.limb_hop,
                self.pelvis] + [self.part / 2] * 4 + [self.depth] + [self.position] * 3 + [0.0] * 4

    def params_json(self) -> str:
        """The method's name, weights, threshold and temperature as a JSON object (stored per pair)."""
        return json.dumps(asdict(self), sort_keys=True)


METHODS = {
    "text": MatchMethod("text"),
    "structure": MatchMethod("structure", text=1.0, side=0.5, limb_axial=0.6, centre_axial=0.3, along=0.2,
                             chain_hop=1.5, limb_hop=3.0, pelvis=0.6, part=0.3, depth=0.1, position=0.05,
                             chain=1.0, anchor=0.55, trunk=0.7, no_match=0.45),
}
DEFAULT_METHOD = "structure"
MATCHERS = Registry("matching method", METHODS)
"""Matching methods (:class:`MatchMethod`) by name; ``--method`` of ``datagen correspond``."""


def get_matcher(name: str = DEFAULT_METHOD, temperature: float | None = None,
                no_match: float | None = None) -> MatchMethod:
    """The matching method ``name`` (``text`` or ``structure``), optionally with another T or threshold."""
    m = MATCHERS.get(name)
    changes = {}
    if temperature is not None:
        changes["temperature"] = float(temperature)
    if no_match is not None:
        if name == "text":
            raise ValueError("no_match: the text method matches every slot as published; use --method structure")
        changes["no_match"] = float(no_match)
    return MatchMethod(**{**asdict(m), **changes}) if changes else m


def skeleton_feature_table(records) -> dict[str, np.ndarray]:
    """Per character ID its (K, F) structure features (:mod:`.structure`)."""
    return {r.character_id: skeleton_features(canonicalize_names(r.bone_names), r.parents, r.keypoints).matrix()
            for r in records if r.num_joints}


def match_batch(method: MatchMethod, emb_a, emb_b, feat_a=None, feat_b=None):
    """``correspondence_batch`` with ``method``'s weights, threshold and temperature."""
    if not method.uses_structure:
        return correspondence_batch(emb_a, emb_b, method.temperature)
    if feat_a is None or feat_b is None:
        raise ValueError(f"method {method.name!r} needs each skeleton's parents and keypoints")
    return correspondence_batch(emb_a, emb_b, method.temperature, feat_a=feat_a, feat_b=feat_b,
                                feature_weights=method.feature_weights(), text_weight=method.text,
                                no_match=method.no_match, chain_penalty=method.chain, anchor=method.anchor,
                                trunk_floor=method.trunk)
