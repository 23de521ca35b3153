"""A pipeline file (TOML): settings and an ordered list of steps, each one `mimicbench` command.

```toml
[pipeline]
name = "demo"
workdir = "data/demo"   # folders of the steps are relative to it (itself relative to the current folder)
engine = "local"        # or "ray"; ray_address = "ray://head:10001"; jobs = 2

[[steps]]
run = "zoo"             # zoo | ingest | resample | apparel | correspond | cases | bench | leaderboard
out = "zoo"
characters = 16
```

Every other key of a step is the command's option with ``_`` for ``-`` (``all_pairs = true`` is
``--all-pairs``; a list is joined with commas). :data:`STEP_KINDS` says, per kind, which keys are
the command's folders (positional arguments or ``--out``), which tables of which folder the step
reads (its fingerprint) and what it writes (checked before a step is skipped).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@dataclass(frozen=True)
class StepKind:
    """How a step kind maps onto its command.

    Attributes:
        command: the `mimicbench` words before the options.
        positional: keys whose folder values are positional arguments, in order.
        folders: keys holding folders (positional or options), resolved against the workdir.
        reads: ``(key, tables)``: the step reads these tables of that folder (None: the whole folder).
        writes: ``(key, tables)``: the step writes these tables of that folder (None: the folder).
        engine: the command takes ``--engine``/``--ray-address`` (and ``--jobs`` where listed).
        jobs: the command takes ``--jobs``.
    """

    command: tuple[str, ...]
    positional: tuple[str, ...] = ()
    folders: tuple[str, ...] = ()
    reads: tuple[tuple[str, tuple[str, ...] | None], ...] = ()
    writes: tuple[tuple[str, tuple[str, ...] | None], ...] = ()
    engine: bool = False
    jobs: bool = False


STEP_KINDS = {
    "zoo": StepKind(("zoo",), folders=("out",), writes=(("out", ("characters", "motions")),), engine=True, jobs=True),
    "ingest": StepKind(("datagen", "ingest"), positional=("paths",), folders=("out", "paths"),
                       reads=(("paths", None),), writes=(("out", ("characters", "motions")),),
                       engine=True, jobs=True),
    "resample": StepKind(("datagen", "resample"), positional=("in", "out"), folders=("in", "out"),
                         reads=(("in", ("characters", "motions")),), writes=(("out", ("characters", "motions")),),
                         engine=True, jobs=True),
    "apparel": StepKind(("datagen", "apparel"), positional=("in", "out"), folders=("in", "out"),
                        reads=(("in", ("characters", "motions")),), writes=(("out", ("characters", "motions")),),
                        engine=True, jobs=True),
    "correspond": StepKind(("datagen", "correspond"), positional=("dataset",), folders=("dataset",),
                           reads=(("dataset", ("characters",)),), writes=(("dataset", ("pairs",)),), engine=True,
                           jobs=True),
    "cases": StepKind(("bench", "cases"), positional=("dataset",), folders=("dataset",),
                      reads=(("dataset", ("characters", "motions")),), writes=(("dataset", ("cases",)),)),
    "bench": StepKind(("bench", "run"), positional=("dataset",), folders=("dataset", "out"),
                      reads=(("dataset", ("characters", "motions", "cases")),), writes=(("out", None),), engine=True),
    "leaderboard": StepKind(("bench", "leaderboard"), positional=("results",), folders=("results", "out"),
                            reads=(("results", None),), writes=(("out", None),)),
}
ENGINE_KEYS = ("engine", "ray_address", "jobs")  # where, not what: never part of a fingerprint


@dataclass
class Step:
    """One step: its ``name`` (unique, default the kind), ``kind`` and the command's options."""

    name: str
    kind: str
    options: dict = field(default_factory=dict)

    @property
    def spec(self) -> StepKind:
        return STEP_KINDS[self.kind]

    def folder(self, key: str, workdir: Path) -> list[Path]:
        """The folders (or files) of ``key``, resolved against ``workdir`` ([] when unset)."""
        value = self.options.get(key)
        if value is None and key == "out" and self.kind == "leaderboard":
            value = self.options.get("results")
        if value is None:
            return []
        values = value if isinstance(value, list) else [value]
        return [Path(v) if Path(v).is_absolute() else workdir / v for v in values]


@dataclass
class Pipeline:
    """A parsed pipeline file: ``name``, ``workdir``, engine settings and the steps in order."""

    name: str
    workdir: Path
    steps: list[Step]
    engine: str = "local"
    ray_address: str | None = None
    jobs: int = 1
    source: Path | None = None


def load_pipeline(path, workdir=None) -> Pipeline:
    """Parse a pipeline TOML file; ``workdir`` overrides the file's ``[pipeline] workdir``.

    Raises:
        ValueError: naming the file and the step: not TOML, an unknown step kind or key, a step
            without its folders, a repeated step name.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not a TOML file ({exc})") from None
    head = data.get("pipeline", {})
    unknown = sorted(set(head) - {"name", "workdir", "engine", "ray_address", "jobs"})
    if unknown:
        raise ValueError(f"{path}: [pipeline] has unknown keys {unknown}; expected name, workdir, engine, "
                         f"ray_address, jobs")
    extra = sorted(set(data) - {"pipeline", "steps"})
    if extra:
        raise ValueError(f"{path}: unknown sections {extra}; expected [pipeline] and [[steps]]")
    raw_steps = data.get("steps")
    if not isinstance(raw_steps, list) or not raw_steps:
        raise ValueError(f"{path}: expected at least one [[steps]] table")
    steps, names = [], set()
    for i, raw in enumerate(raw_steps, 1):
        raw = dict(raw)
        kind = raw.pop("run", None)
        if kind not in STEP_KINDS:
            raise ValueError(f"{path}: step {i}: run = {kind!r}; expected one of {sorted(STEP_KINDS)}")
        name = str(raw.pop("name", kind))
        if name in names:
            raise ValueError(f"{path}: step {i}: name {name!r} used twice; give each step its own name = \"...\"")
        names.add(name)
        for key in STEP_KINDS[kind].positional + (("out",) if kind in ("zoo", "ingest") else ()):
            if key not in raw:
                raise ValueError(f"{path}: step {i} ({name}): missing {key} = \"...\" (a folder)")
        for key in ENGINE_KEYS:
            if key in raw:
                raise ValueError(f"{path}: step {i} ({name}): {key} belongs in [pipeline] (it applies to every step)")
        steps.append(Step(name, kind, raw))
    engine = head.get("engine", "local")
    if engine not in ("local", "ray"):
        raise ValueError(f"{path}: [pipeline] engine = {engine!r}; expected \"local\" or \"ray\"")
    jobs = head.get("jobs", 1)
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"{path}: [pipeline] jobs = {jobs!r}; expected an integer >= 1")
    root = Path(workdir if workdir is not None else head.get("workdir", "."))
    return Pipeline(str(head.get("name", path.stem)), root, steps, engine, head.get("ray_address"), jobs, path)


def step_argv(step: Step, pipeline: Pipeline) -> list[str]:
    """The `mimicbench` command line of ``step`` (folders resolved, engine settings added)."""
    spec = step.spec
    argv = list(spec.command)
    for key in spec.positional:
        argv += [str(p) for p in step.folder(key, pipeline.workdir)]
    for key, value in step.options.items():
        if key in spec.positional:
            continue
        flag = "--" + key.replace("_", "-")
        if key in spec.folders:
            argv += [flag, str(step.folder(key, pipeline.workdir)[0])]
        elif value is True:
            argv.append(flag)
        elif value is False:
            continue
        elif isinstance(value, list):
            argv += [flag, ",".join(str(v) for v in value)]
        else:
            argv += [flag, str(value)]
    if spec.engine:
        argv += ["--engine", pipeline.engine]
        if pipeline.ray_address:
            argv += ["--ray-address", pipeline.ray_address]
    if spec.jobs and pipeline.jobs > 1:
        argv += ["--jobs", str(pipeline.jobs)]
    return argv
