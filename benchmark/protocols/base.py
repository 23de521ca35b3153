"""What a benchmark protocol is: a rule that builds cases from a dataset, turns a case into the
requests a method answers, and scores the answers.

A protocol never calls a method itself: :meth:`BenchmarkProtocol.evaluate` receives ``call``, the
evaluator's single call site (``call(requests) -> [(vertices | None, error | None, seconds)]``,
one tuple per request, in order), so how methods are run (in process, in a worker with a
timeout) is decided in one place for every protocol.
"""
from __future__ import annotations

import abc
import zlib
from dataclasses import dataclass, field
from typing import Callable, Iterator, Sequence

import numpy as np

from mimicbench.benchmark.normalisation import RestFrame
from mimicbench.benchmark.request import TransferRequest
from mimicbench.benchmark.rigs import CharacterData
from mimicbench.benchmark.semantic import character_role_classes, part_motion, part_regions, semantic_scores
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.case import CaseRecord
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.motion import SIM_SUFFIX
from mimicbench.schemas.shard_stream import checked_parquet_file, read_row_group
from mimicbench.schemas.dataset import Dataset


HIDDEN_ROLES_TAG = "probe:hidden_roles"
"""A method tag that makes the protocols put the characters' hidden roles into its requests: only
the bundled validity probes (:mod:`mimicbench.baselines.probes`) carry it."""

Call = Callable[[Sequence[TransferRequest]], list]
"""The evaluator's call site: requests in, ``[(array | None, error | None, seconds)]`` out."""


@dataclass
class Outcome:
    """One case scored (or failed) by a protocol, before it becomes a results row.

    Attributes:
        case: the case.
        status: ``ok`` or ``failed``.
        error: why it failed, in words; None when ok.
        seconds: wall-clock seconds the method spent on the case (both legs of a cycle).
        metrics: result columns by name (``pmd``, ``pmd_height``, ... see ``schemas/result.py``).
        outputs: the method's predictions by leg, for the leaderboard's pictures: ``forward``
            (Nt, 3) on the target, ``returned`` (Ns, 3) on the source (cycle protocols); a leg
            that failed is left out.
    """

    case: CaseRecord
    status: str
    error: str | None
    seconds: float
    metrics: dict = field(default_factory=dict)
    outputs: dict = field(default_factory=dict)


MOTION_INFO_COLUMNS = ("motion_id", "character_id", "name", "num_frames")
"""The motions table's columns :class:`MotionInfo` is read from (in its fields' order)."""


@dataclass(frozen=True)
class MotionInfo:
    """What drawing cases needs of a clip: its IDs, name and length, without its transforms."""

    motion_id: str
    character_id: str
    name: str
    num_frames: int


@dataclass(frozen=True)
class CaseDraw:
    """One drawn case before its poses are read: ``motions`` the clips it reads (one, or the
    apparel protocol's (kinematic, simulated) pair), ``frame`` the pose or the window's start."""

    source: object
    target: object
    motions: tuple
    frame: int


@dataclass
class CasePool:
    """Characters with a mesh, sorted by ID, and each one's motions (:class:`MotionInfo`) sorted
    by motion ID.

    The pool never holds the motions' transforms (a PokeAnimDB-size motions table is several
    gigabytes): protocols draw cases from the clips' IDs and lengths, and :meth:`cases_from`
    then streams the motions table one row group (16 clips) at a time and reads only the row
    groups holding a drawn clip, keeping a clip's transforms only while a drawn case still needs it.
    """

    characters: list
    motions: dict
    dataset: object = None

    @classmethod
    def load(cls, dataset, split: str = "test") -> "CasePool":
        """The characters of ``split`` (``all`` for every split) and their motions; ``dataset`` a
        :class:`~mimicbench.schemas.dataset.Dataset` or its path."""
        dataset = Dataset.of(dataset)
        chars = [c for c in dataset.records("characters") if len(c.faces) and split in ("all", c.split)]
        chars.sort(key=lambda c: c.character_id)
        ids = {c.character_id for c in chars}
        motions: dict[str, list] = {}
        if dataset.has_table("motions"):
            t = dataset.read_table("motions", columns=list(MOTION_INFO_COLUMNS))
            for row in zip(*(t.column(c).to_pylist() for c in MOTION_INFO_COLUMNS)):
                info = MotionInfo(*row)
                if info.character_id in ids:
                    motions.setdefault(info.character_id, []).append(info)
        for ms in motions.values():
            ms.sort(key=lambda m: m.motion_id)
        return cls(chars, motions, dataset)

    def frames_for(self, rng: np.random.Generator, character_id: str, n_poses: int) -> list[tuple]:
        """Up to ``n_poses`` (motion, frame) draws from a character's kinematic clips, never frame 0
        (rest). A simulated clip (``<clip>@sim``, :mod:`mimicbench.datagen.apparel`) is left out: its body pose
        is its kinematic twin's, so drawing both would count an apparel character's poses twice."""
        choices = [(m, f) for m in self.motions.get(character_id, []) if not m.name.endswith(SIM_SUFFIX)
                   for f in range(1, m.num_frames)]
        if not choices:
            return []
        idx = rng.choice(len(choices), size=min(n_poses, len(choices)), replace=False)
        return [choices[i] for i in sorted(idx)]

    def cases_from(self, protocol: "BenchmarkProtocol", draws: Sequence[CaseDraw]) -> list[CaseRecord]:
        """``protocol.make_case`` of each draw, in the draws' order, with its clips' full records
        (:class:`mimicbench.schemas.motion.MotionRecord`) read by streaming the motions table (see the class
        docstring)."""
        needed: dict[str, list[int]] = {}
        for i, d in enumerate(draws):
            for m in d.motions:
                needed.setdefault(m.motion_id, []).append(i)
        missing = {i: len({m.motion_id for m in d.motions}) for i, d in enumerate(draws)}
        held: dict[str, object] = {}
        seen: set[str] = set()
        out: list[CaseRecord | None] = [None] * len(draws)
        for record in self._records_of(set(needed)):
            if record.motion_id in seen:
                raise DatasetError(f"{self.dataset}: motion {record.motion_id!r} is stored twice; "
                                   f"run `mimicbench validate {self.dataset}`")
            seen.add(record.motion_id)
            held[record.motion_id] = record
            for i in needed[record.motion_id]:
                missing[i] -= 1
                if missing[i] == 0:
                    d = draws[i]
                    full = tuple(held[m.motion_id] for m in d.motions)
                    out[i] = protocol.make_case(d.source, d.target, full[0] if len(full) == 1 else full, d.frame)
            held = {k: v for k, v in held.items() if any(missing[i] for i in needed[k])}
        lost = sorted({m.motion_id for d, c in zip(draws, out) if c is None for m in d.motions} - seen)
        if lost:
            raise DatasetError(f"{self.dataset}: motions {lost[:5]} were listed but not found when read again "
                               "(the motions table changed while cases were built?)")
        return out

    def _records_of(self, motion_ids: set) -> Iterator:
        """The motion records with an ID in ``motion_ids``, in stored order, one row group at a time."""
        if not motion_ids:
            return
        dataset = Dataset.of(self.dataset)
        for entry in dataset.readable_entries("motions"):
            pf = checked_parquet_file(dataset.root, entry, "motions")
            for g in range(pf.num_row_groups):
                ids = pf.read_row_group(g, columns=["motion_id"]).column("motion_id").to_pylist()
                if motion_ids.intersection(ids):
                    yield from (r for r in read_row_group(pf, g, "motions") if r.motion_id in motion_ids)


@dataclass
class EvalData:
    """What protocols need to build requests and score them: rigs and the dataset's soft
    correspondences, with each character's rest frame derived once."""

    characters: dict[str, CharacterData]
    pairs: dict = field(default_factory=dict)
    rest_frames: dict = field(default_factory=dict, repr=False)
    motion_fps: dict = field(default_factory=dict)
    regions: dict = field(default_factory=dict, repr=False)
    dataset: object = field(default=None, repr=False)
    ranges: dict | None = field(default=None, repr=False)

    @classmethod
    def load(cls, dataset) -> "EvalData":
        """Rigs, pairs and clip rates of ``dataset`` (a :class:`~mimicbench.schemas.dataset.Dataset` or its path)."""
        from mimicbench.benchmark.rigs import load_characters

        dataset = Dataset.of(dataset)
        pairs = {}
        if dataset.has_table("pairs"):
            pairs = {(r.source_id, r.target_id): r.m_sink for r in dataset.records("pairs")}
        fps = {}
        if dataset.has_table("motions"):  # two scalar columns: the apparel protocol's requests state the fps
            t = dataset.read_table("motions", columns=["motion_id", "fps"])
            fps = dict(zip(t.column("motion_id").to_pylist(), t.column("fps").to_pylist()))
        return cls(load_characters(dataset), pairs, motion_fps=fps, dataset=dataset)

    def frame(self, char: CharacterData) -> RestFrame:
        """The character's rest frame (centre, height, largest extent, edges), cached."""
        cid = char.rig.character_id
        if cid not in self.rest_frames:
            self.rest_frames[cid] = RestFrame.of(char.rig.vertices, char.edges)
        return self.rest_frames[cid]

    def part_regions(self, char: CharacterData):
        """The character's :class:`mimicbench.benchmark.semantic.PartRegions` from its hidden role classes,
        cached; None for a character without role labels (it gets no semantic score)."""
        cid = char.rig.character_id
        if cid not in self.regions:
            classes = character_role_classes(char.record)
            self.regions[cid] = None if classes is None else part_regions(char.rig.weights, char.rig.parents, classes)
        return self.regions[cid]

    def semantic(self, source: CharacterData, source_posed: np.ndarray, target: CharacterData,
                 target_posed: np.ndarray) -> dict:
        """``semantic_deg`` and ``role_classes_scored`` (:mod:`mimicbench.benchmark.semantic`) of a target pose
        (Nt, 3) against the source pose (Ns, 3); both None when either character has no role labels."""
        src, tgt = self.part_regions(source), self.part_regions(target)
        if src is None or tgt is None:
            return {"semantic_deg": None, "role_classes_scored": None}
        return semantic_scores(part_motion(source.rig.vertices, source_posed, src),
                               part_motion(target.rig.vertices, target_posed, tgt))

    def forward_scores(self, source: CharacterData, source_posed: np.ndarray, target: CharacterData,
                       target_posed: np.ndarray) -> dict:
        """Every score of a forward prediction (Nt, 3) against hidden ground truth: the semantic
        columns (:meth:`semantic`) and ``out_of_range``."""
        scores = self.semantic(source, source_posed, target, target_posed)
        scores["out_of_range"] = self.out_of_range(target, target_posed)
        return scores

    def out_of_range(self, char: CharacterData, posed: np.ndarray) -> float | None:
        """Share of the character's bones that a pose (N, 3) rotates beyond the range its own clips
        reach (:func:`mimicbench.benchmark.motion_range.out_of_range_share`); None without clips to read a range
        from. The ranges of every character are read once, from the dataset's motions table."""
        from mimicbench.benchmark.motion_range import out_of_range_share, ranges_for_dataset

        if self.ranges is None:
            self.ranges = {} if self.dataset is None else ranges_for_dataset(self.dataset, self.characters)
        ranges = self.ranges.get(char.rig.character_id)
        share = None if ranges is None else out_of_range_share(posed, char.rig, ranges)
        return None if share is None or share != share else share

    @staticmethod
    def posed(char: CharacterData, transforms: np.ndarray) -> np.ndarray:
        """(N, 3) vertices of ``char`` posed by transforms (K, 7) through LBS."""
        r = char.rig
        return linear_blend_skinning(r.vertices, r.keypoints, r.weights, transforms)

    def request(self, source: CharacterData, source_posed: np.ndarray, target: CharacterData,
                case_id: str, hidden_roles: bool = False) -> TransferRequest:
        """A request, with the pair's ``m_sink`` (Ks, Kt) in ``extras`` when the dataset has it.

        ``hidden_roles`` (only for the validity probes, whose metadata carries
        :data:`HIDDEN_ROLES_TAG`): ``extras["hidden_roles"]`` holds both characters' ground-truth
        ``source_roles``/``target_roles`` and ``source_classes``/``target_classes`` (K lists, None
        for an unlabelled bone). No other method ever receives them.
        """
        extras = {}
        if hidden_roles:
            extras["hidden_roles"] = {"source_roles": list(source.record.bone_roles or []),
                                      "source_classes": character_role_classes(source.record),
                                      "target_roles": list(target.record.bone_roles or []),
                                      "target_classes": character_role_classes(target.record)}
        key = (source.rig.character_id, target.rig.character_id)
        if key in self.pairs:
            extras["m_sink"] = np.asarray(self.pairs[key]).reshape(len(source.rig.parents), len(target.rig.parents))
        return TransferRequest(source.rig, source_posed, target.rig, case_id, extras)


def wants_hidden_roles(call: Call) -> bool:
    """Whether the method behind ``call`` is a validity probe (:data:`HIDDEN_ROLES_TAG`)."""
    return HIDDEN_ROLES_TAG in getattr(call, "method_tags", ())


class BenchmarkProtocol(abc.ABC):
    """One way of scoring pose transfer. Subclasses set the class attributes and implement
    :meth:`candidate_pairs`, :meth:`make_case` and :meth:`evaluate`.

    Attributes:
        name: short name, the ``protocol`` column of cases and results (``h2h``, ``cct``, ...).
        title: what it measures, in words (docs, leaderboard).
        headline: normalisation of its ``pmd`` column: ``height`` or ``extent``
            (see :mod:`mimicbench.benchmark.normalisation`).
    """

    name: str
    title: str
    headline: str

    @abc.abstractmethod
    def candidate_pairs(self, pool: CasePool) -> list[tuple]:
        """Every ordered (source, target) character pair this protocol can make a case of."""

    @abc.abstractmethod
    def make_case(self, source, target, motion, frame: int) -> CaseRecord:
        """The case for one source pose (``motion.transforms[frame]``, ``motion`` a full
        :class:`mimicbench.schemas.motion.MotionRecord`, or the tuple of them a :class:`CaseDraw` names) and
        one target."""

    @abc.abstractmethod
    def evaluate(self, cases: Sequence[CaseRecord], data: EvalData, call: Call) -> list[Outcome]:
        """Build the requests of ``cases``, run them through ``call``, score the answers."""

    def rng(self, seed: int) -> np.random.Generator:
        """This protocol's own generator: cases of one protocol do not depend on the others'."""
        return np.random.default_rng([seed, zlib.crc32(self.name.encode())])

    def build_cases(self, pool: CasePool, pairs: int | None, poses: int, seed: int = 0) -> list[CaseRecord]:
        """The cases of :meth:`draw_cases`, with their poses read (:meth:`CasePool.cases_from`)."""
        return pool.cases_from(self, self.draw_cases(pool, pairs, poses, seed))

    def draw_cases(self, pool: CasePool, pairs: int | None, poses: int, seed: int = 0) -> list[CaseDraw]:
        """``pairs`` candidate pairs drawn with a seeded generator (None: every pair), each with
        ``poses`` frames of the source's clips (never the rest frame)."""
        rng = self.rng(seed)
        cands = [(a, b) for a, b in self.candidate_pairs(pool) if pool.motions.get(a.character_id)]
        if pairs is not None and len(cands) > pairs:
            cands = [cands[i] for i in sorted(rng.choice(len(cands), size=pairs, replace=False))]
        return [CaseDraw(a, b, (m,), f) for a, b in cands for m, f in pool.frames_for(rng, a.character_id, poses)]

    def case_id(self, source, target, motion, frame: int) -> str:
        """``<protocol>/<source_id>-><target_id>/<motion name>#<frame>``."""
        return f"{self.name}/{source.character_id}->{target.character_id}/{motion.name}#{frame}"
