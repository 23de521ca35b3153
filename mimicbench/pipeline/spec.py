"""A pipeline file (TOML): settings and an ordered list of steps, each one `mimicbench` command.

```toml
[pipeline]
name = "demo"
workdir = "data/demo"   # folders of the steps are relative to it (itself relative to the current folder)
engine = "local"        # or "ray"; ray_address = "ray://head:10001"; jobs = 2

[[steps]]
run = "zoo"             # zoo | ingest | retarget | roles | resample | apparel | correspond | cases | bench | ...
out = "zoo"
characters = 16
```

Every other key of a step is the command's option with ``_`` for ``-`` (``all_pairs = true`` is
``--all-pairs``; a list gives several values, or one comma-separated value), typed and checked
when the file is loaded (:mod:`mimicbench.runtime.options`); ``help`` is refused (it would print the help and
run nothing). The folders a step writes must lie inside the workdir (``../../etc`` or an absolute
path elsewhere is refused) unless the step says ``allow_outside = true``. A step with
``restart = true`` (the demo's bench steps) deletes the folders it writes before it runs again
after it finished from other inputs or options (results scored on other cases). A leaderboard step
without ``out`` writes beside its results, into ``<results>-leaderboard``, never into the
results folder it reads (that would change the bench step's output and its own input, so a
finished pipeline would redo both on every run). :data:`STEP_KINDS` says, per kind, which keys are
the command's folders (positional arguments or ``--out``), which tables of which folder the step
reads (its fingerprint) and what it writes (checked before a step is skipped): the datagen stages'
kinds come from their declarations (:func:`stage_kind`), the bench steps' are declared here.
"""
from __future__ import annotations

import argparse
import functools
import importlib
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

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
        versions: ``"module:NAME"`` version constants of the code that makes the step's output; a
            finished step runs again when one of them (or the toolkit's version) changed.
        params: a datagen stage's params dataclass (its fields are the step's keys), else None.
        function: ``"module:attr"`` the step calls with its params (a stage's command function).
        module: for a command that is not a stage, the module whose ``register`` declares its parser.
        required: option keys (not positional) a step must give.
    """

    command: tuple[str, ...]
    positional: tuple[str, ...] = ()
    folders: tuple[str, ...] = ()
    reads: tuple[tuple[str, tuple[str, ...] | None], ...] = ()
    writes: tuple[tuple[str, tuple[str, ...] | None], ...] = ()
    engine: bool = False
    jobs: bool = False
    versions: tuple[str, ...] = ()
    params: type | None = None
    function: str = ""
    module: str = ""
    required: tuple[str, ...] = ()

    @property
    def needs(self) -> tuple[str, ...]:
        """The keys a step must give: the positional folders and the required options."""
        return self.positional + tuple(k for k in self.required if k not in self.positional)


BENCH = "mimicbench.benchmark.command"  # declares the bench steps' parsers


def stage_kind(stage) -> StepKind:
    """The step kind of a datagen stage, from its declaration (:class:`~mimicbench.datagen.stage_runner.Stage`):
    its params dataclass gives the keys (positional and folder fields, ``engine``/``jobs``), its
    tables what the step reads and writes."""
    from mimicbench.runtime.options import option_fields

    fields = option_fields(stage.params)
    key = {f.name: f.metadata.get("key") or f.name for f in fields}
    positional = tuple(key[f.name] for f in fields if f.metadata.get("positional"))
    folders = positional + tuple(key[f.name] for f in fields if f.metadata.get("folder") and key[f.name] not in positional)
    reads = stage.step_reads if stage.step_reads is not None else \
        (((stage.in_key, stage.inputs),) if stage.in_key else ())
    writes = ((stage.out_key, stage.step_writes or tuple(t for t in stage.outputs if t != "status")),)
    names = {f.name for f in fields}
    return StepKind(stage.command, positional, folders, tuple((key[k], t) for k, t in reads),
                    tuple((key[k], t) for k, t in writes), engine="engine" in names, jobs="jobs" in names,
                    versions=stage.versions, params=stage.params, function=stage.function,
                    required=tuple(key[f.name] for f in fields if f.metadata.get("required")))


def _stage_kinds() -> dict[str, StepKind]:
    from mimicbench.datagen.stages import STAGES

    return {name: stage_kind(STAGES.get(name)) for name in STAGES.names()}


STEP_KINDS = {
    **_stage_kinds(),
    "cases": StepKind(("bench", "cases"), positional=("dataset",), folders=("dataset",),
                      reads=(("dataset", ("characters", "motions")),), writes=(("dataset", ("cases",)),),
                      versions=("mimicbench.benchmark.protocols.apparel:CASES_VERSION",), module=BENCH),
    "bench": StepKind(("bench", "run"), positional=("dataset",), folders=("dataset", "out"),
                      reads=(("dataset", ("characters", "motions", "cases")),), writes=(("out", None),), engine=True,
                      module=BENCH),
    "validity": StepKind(("bench", "validity"), positional=("dataset",), folders=("dataset", "out"),
                         reads=(("dataset", ("characters", "motions", "cases")),), writes=(("out", None),),
                         module=BENCH),
    "leaderboard": StepKind(("bench", "leaderboard"), positional=("results",), folders=("results", "out"),
                            reads=(("results", None),), writes=(("out", None),), module=BENCH),
}
ENGINE_KEYS = ("engine", "ray_address", "jobs")  # where, not what: never part of a fingerprint
HELP = "help"  # --help, or an abbreviation argparse expands to it, prints and runs nothing
LEADERBOARD_SUFFIX = "-leaderboard"


@dataclass
class Step:
    """One step: its ``name`` (unique, default the kind), ``kind`` and the command's options."""

    name: str
    kind: str
    options: dict = field(default_factory=dict)
    allow_outside: bool = False
    restart: bool = False

    @property
    def spec(self) -> StepKind:
        return STEP_KINDS[self.kind]

    def folder(self, key: str, workdir: Path) -> list[Path]:
        """The folders (or files) of ``key``, resolved against ``workdir`` ([] when unset)."""
        value = self.options.get(key)
        if value is None and key == "out" and self.kind == "leaderboard" and self.options.get("results") is not None:
            value = str(self.options["results"]).rstrip("/\\") + LEADERBOARD_SUFFIX
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
        for key in STEP_KINDS[kind].needs:
            if key not in raw:
                raise ValueError(f"{path}: step {i} ({name}): missing {key} = \"...\" (a folder)")
        for key in ENGINE_KEYS:
            if key in raw:
                raise ValueError(f"{path}: step {i} ({name}): {key} belongs in [pipeline] (it applies to every step)")
        for key in raw:
            if key and HELP.startswith(key.replace("_", "-")):
                raise ValueError(f"{path}: step {i} ({name}): {key} = ... is not a step option (it would print and "
                                 f"run nothing); see `mimicbench {' '.join(STEP_KINDS[kind].command)} --help`")
        flags = {key: raw.pop(key, False) for key in ("allow_outside", "restart")}
        for key, value in flags.items():
            if not isinstance(value, bool):
                raise ValueError(f"{path}: step {i} ({name}): {key} = {value!r}; expected true or false")
        if flags["restart"] and (flags["allow_outside"] or not all(t is None for _, t in STEP_KINDS[kind].writes)):
            raise ValueError(f"{path}: step {i} ({name}): restart = true only for a step that writes whole folders "
                             f"inside the workdir (bench, leaderboard)")
        steps.append(Step(name, kind, raw, **flags))
    engine = head.get("engine", "local")
    if engine not in ("local", "ray"):
        raise ValueError(f"{path}: [pipeline] engine = {engine!r}; expected \"local\" or \"ray\"")
    jobs = head.get("jobs", 1)
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"{path}: [pipeline] jobs = {jobs!r}; expected an integer >= 1")
    root = Path(workdir if workdir is not None else head.get("workdir", "."))
    name = check_record_name(head.get("name", path.stem), f"{path}: [pipeline] name")
    for i, step in enumerate(steps, 1):
        _check_step_folders(path, i, step, root)
    _check_shared_outputs(path, steps, root)
    pipeline = Pipeline(name, root, steps, engine, head.get("ray_address"), jobs, path)
    for step in steps:
        _, options = step_options(step, pipeline)  # every option typed and checked before anything runs
        if step.kind == "bench":
            _check_methods(step, pipeline, options)
    return pipeline


def check_record_name(name, where: str) -> str:
    """``name`` when it is a plain file name (a non-empty string, no path separator, not ``.``/``..``,
    no NUL): it names the record ``WORKDIR/.pipeline/<name>.json`` and must stay in that folder.

    Raises:
        ValueError: starting with ``where``, saying what a name may hold.
    """
    if (not isinstance(name, str) or not name.strip() or name in (".", "..") or "/" in name or "\\" in name
            or "\0" in name or Path(name).is_absolute() or Path(name).name != name):
        raise ValueError(f"{where} = {name!r}: expected a plain name (letters, digits, '-', '_', '.'; no '/', "
                         f"'\\', '..' or absolute path): it names the record WORKDIR/.pipeline/<name>.json")
    return name


def _writes_overlap(a: tuple[Path, tuple[str, ...] | None], b: tuple[Path, tuple[str, ...] | None]) -> bool:
    """Whether two writes ``(folder, tables)`` (None: the whole folder) can touch the same file."""
    (pa, ta), (pb, tb) = a, b
    if ta is None and tb is None:
        return pa.is_relative_to(pb) or pb.is_relative_to(pa)
    if ta is None or tb is None:
        (whole, _), (part, tables) = (a, b) if ta is None else (b, a)
        return part.is_relative_to(whole) or any(whole.is_relative_to(part / t) for t in tables)
    return pa == pb and bool(set(ta) & set(tb))


def _check_shared_outputs(path: Path, steps: list[Step], workdir: Path) -> None:
    """Refuse two steps that write the same tables of one folder (or one folder inside the other's
    whole-folder output): the second would replace the first's output, and each re-run would redo both."""
    writes = [(i, step, key, (folder.resolve(), tables)) for i, step in enumerate(steps, 1)
              for key, tables in step.spec.writes for folder in step.folder(key, workdir)]
    for n, (i, a, key_a, wa) in enumerate(writes):
        for j, b, key_b, wb in writes[n + 1:]:
            if a is not b and _writes_overlap(wa, wb):
                what = "the folder" if wa[1] is None or wb[1] is None else \
                    f"the tables {sorted(set(wa[1]) & set(wb[1]))} of"
                raise ValueError(f"{path}: step {j} ({b.name}) {key_b} = {str(b.options.get(key_b, wb[0]))!r} writes "
                                 f"{what} {wb[0]}, which step {i} ({a.name}) {key_a} = "
                                 f"{str(a.options.get(key_a, wa[0]))!r} writes too; give each step its own output "
                                 f"folder")


def _check_methods(step: Step, pipeline: Pipeline, options) -> None:
    """Refuse a bench step naming a method the registry does not know (checked before any step runs;
    the method's module is imported only when the step runs)."""
    from mimicbench.benchmark.registry import METHODS
    from mimicbench.runtime.registry import NameCollision, UnknownName

    index = pipeline.steps.index(step) + 1
    raw = step.options.get("methods")
    if not (isinstance(raw, str) or isinstance(raw, list) and all(isinstance(m, str) for m in raw)):
        raise ValueError(f"{pipeline.source}: step {index} ({step.name}): methods = {raw!r}; expected method names: "
                         f"a string \"a,b\" or a list [\"a\", \"b\"] (see `mimicbench bench methods`)")
    for name in options.methods:
        try:
            METHODS.target(name)
        except (UnknownName, NameCollision) as exc:
            raise ValueError(f"{pipeline.source}: step {index} ({step.name}): methods = "
                             f"{step.options.get('methods')!r}: {exc}") from None


def _check_step_folders(path: Path, i: int, step: Step, workdir: Path) -> None:
    """Refuse a step that writes outside ``workdir`` (unless ``allow_outside``), and a leaderboard
    that writes into (or under) the results folder it reads."""
    where = f"{path}: step {i} ({step.name})"
    root = workdir.resolve()
    if not step.allow_outside:
        for key, _ in step.spec.writes:
            for folder in step.folder(key, workdir):
                if not folder.resolve().is_relative_to(root):
                    raise ValueError(f"{where}: {key} = {str(step.options.get(key, folder))!r} resolves to "
                                     f"{folder.resolve()}, outside the workdir {root}; a step writes inside the "
                                     f"workdir (add allow_outside = true to the step to write there on purpose)")
    if step.kind == "leaderboard":
        results = [f.resolve() for f in step.folder("results", workdir)]
        for out in step.folder("out", workdir):
            if any(out.resolve().is_relative_to(r) for r in results):
                raise ValueError(f"{where}: out = {str(step.options.get('out'))!r} is inside the results folder it "
                                 f"reads; give another folder (the default is beside it: "
                                 f"<results>{LEADERBOARD_SUFFIX})")


@functools.lru_cache(maxsize=None)
def command_parser(module: str, words: tuple[str, ...]) -> argparse.ArgumentParser:
    """The parser of the command ``words`` that ``module``'s ``register`` declares (only that
    module's commands are built, not the whole command line; a group word such as ``datagen``,
    which the command line adds around the module's own, is skipped)."""
    root = argparse.ArgumentParser(add_help=False)
    sub = root.add_subparsers()
    importlib.import_module(module).register(sub)
    parser = root
    for word in words[list(words).index(next(w for w in words if w in sub.choices)):]:
        parser = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[word]
    return parser


def step_options(step: Step, pipeline: Pipeline) -> tuple[Callable, object]:
    """The function ``step`` calls and its options dataclass (folders resolved, engine settings
    added): a datagen stage's params dataclass, checked through the options it declares
    (:func:`mimicbench.runtime.options.params_parser`), or the options of another command's parser.

    Raises:
        ValueError: naming the file and the step: an unknown option, a wrong-typed or out-of-range value.
    """
    from mimicbench.runtime.options import from_mapping, params_parser, toml_keys
    from mimicbench.runtime.registry import load_target

    spec = step.spec
    if spec.params is not None:
        parser, names, func = params_parser(spec.params), toml_keys(spec.params), load_target(spec.function)
    else:
        parser = command_parser(spec.module, spec.command)
        positional = [a.dest for a in parser._actions if not a.option_strings]
        names = {key: positional[spec.positional.index(key)] for key in spec.positional}
        func = parser.get_default("func")
    options = dict(step.options)
    if step.kind == "leaderboard":
        options.setdefault("out", None)  # beside the results (step.folder), never into them
    values = {}
    for key, value in options.items():
        if key in spec.folders:
            folders = [str(p) for p in step.folder(key, pipeline.workdir)]
            value = folders if isinstance(value, list) or key == "paths" else folders[0]
        values[names.get(key, key)] = value
    if spec.engine:
        values.update(engine=pipeline.engine, **{"ray_address": pipeline.ray_address} if pipeline.ray_address else {})
    if spec.jobs and pipeline.jobs > 1:
        values["jobs"] = pipeline.jobs
    index = pipeline.steps.index(step) + 1
    where = f"{pipeline.source}: step {index} ({step.name})" if pipeline.source else f"step {index} ({step.name})"
    return func, from_mapping(parser, values, where)


def step_argv(step: Step, pipeline: Pipeline) -> list[str]:
    """The `mimicbench` command line equivalent to ``step`` (folders resolved, engine settings added), for
    ``--dry-run`` and the progress lines; the pipeline itself calls :func:`step_options`' function."""
    spec = step.spec
    argv = list(spec.command)
    for key in spec.positional:
        argv += [str(p) for p in step.folder(key, pipeline.workdir)]
    options = dict(step.options)
    if step.kind == "leaderboard" and "out" not in options:
        options["out"] = str(step.folder("out", pipeline.workdir)[0])  # beside the results, not into them
    for key, value in options.items():
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
