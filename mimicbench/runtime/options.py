"""A command's options as a typed dataclass, derived from the argparse parser that declares them.

Each command declares its options once, on its parser. :func:`options_class` turns that parser
into a frozen dataclass (one field a destination, argparse's default as the field's default);
argparse fills it from a command line (:func:`from_namespace`) and a pipeline step fills it from
a TOML table (:func:`from_mapping`), both through the same ``type=`` checks (``--faces 0`` and
``faces = 0`` get the same message), so the precedence is simply given value > parser default::

    opts = from_mapping(command_parser(("datagen", "resample")), {"in_dataset": "a", "out_dataset": "b"}, "step 2")
    opts.faces  # 5000, the parser's default

A stage declares its options the other way round: one frozen dataclass whose fields carry their
command-line form (:func:`option`: flag, help, type, choices, positional, group); :func:`add_options`
adds them to a parser (which then hands back that very dataclass), :func:`params_parser` builds a
bare parser from it for a pipeline file, so each option is declared once::

    @dataclass(frozen=True)
    class ResampleParams:
        in_dataset: str = option(positional=True, key="in", help="input dataset")
        faces: int = option(5000, type=int_in(100, 200_000), help="target face count")
"""
from __future__ import annotations

import argparse
import dataclasses
import difflib
from typing import Any

_NUMBER = (int, float)
_UNSET = dataclasses.MISSING
_NAMES = {bool: "true or false", int: "an integer", float: "a number", str: "a string", list: "a list",
          dict: "a table"}  # TOML's value types; a date or time is named by its Python type


def _actions(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The parser's own options: not --help/--version, sub-commands or the global flags (SUPPRESS)."""
    return [a for a in parser._actions
            if not isinstance(a, (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction))
            and a.default is not argparse.SUPPRESS]


def _kind(action: argparse.Action) -> tuple[type, tuple[type, ...]]:
    """(field type, the TOML value types accepted) of ``action``."""
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        return bool, (bool,)
    if action.nargs in ("+", "*"):
        return list, (list, str)
    name = getattr(action.type, "__name__", None)
    if action.type is int or name == "integer":
        return int, (int,)
    if action.type is float or name == "number":
        return float, _NUMBER
    if action.type is None:
        return str, (str,)
    return Any, (str, int, float, list)  # a list (--methods a,b; --export obj,bvh) is comma-joined


def options_class(parser: argparse.ArgumentParser) -> type:
    """A frozen dataclass with one field per option of ``parser`` (cached on the parser)."""
    if "_options_class" not in vars(parser):
        name = "".join(w.capitalize() for w in parser.prog.replace("-", " ").split()[1:]) + "Options"
        fields = [(a.dest, _kind(a)[0], dataclasses.field(default_factory=lambda d=a.default: type(d)(d))
                   if isinstance(a.default, (list, dict, set)) else dataclasses.field(default=a.default))
                  for a in _actions(parser)]
        parser._options_class = dataclasses.make_dataclass(name or "Options", fields, frozen=True)
    return parser._options_class


def option(default=_UNSET, *, help: str = "", flag: str | None = None, type=None, choices=None, nargs=None,
           metavar: str | None = None, positional: bool = False, required: bool = False, group: str | None = None,
           key: str | None = None, folder: bool = False, param: bool = True, omit=_UNSET, cli: bool = True):
    """A params field with its command-line form.

    Args:
        default: the value when not given (none: a required field, listed before the defaulted ones).
        help: the ``--help`` text.
        flag: the option's flag (default ``--`` and the name with ``-`` for ``_``).
        type, choices, nargs, metavar: as :meth:`argparse.ArgumentParser.add_argument` takes them; a
            bool field with default False is a ``store_true`` flag.
        positional: a positional argument (in field order) instead of a flag.
        required: a flag that must be given.
        group: fields of the same group are mutually exclusive.
        key: the pipeline file's key when it differs from the name (``in`` for ``in_dataset``).
        folder: the value is a folder (or file) a pipeline resolves against its workdir (a
            positional field always is).
        param: False for a field that does not change the output (folders, processes, progress):
            left out of the stage's config.
        omit: left out of the config while it holds this value (old configs keep their fingerprint).
        cli: False for a field with no command-line option (set from Python only).
    """
    meta = {"cli": cli, "help": help, "flag": flag, "type": type, "choices": choices, "nargs": nargs,
            "metavar": metavar, "positional": positional, "required": required, "group": group, "key": key,
            "folder": folder or positional, "param": param}
    if omit is not _UNSET:
        meta["omit"] = omit
    if isinstance(default, (list, dict, set)):
        return dataclasses.field(default_factory=lambda d=default: type_of(d)(d), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


type_of = type  # ``option`` shadows the builtin with its ``type`` argument


def option_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of the params dataclass ``cls`` that are command-line options, in order."""
    return [f for f in dataclasses.fields(cls) if f.metadata.get("cli", True)]


def toml_keys(cls: type) -> dict[str, str]:
    """``{pipeline-file key: field name}`` of the options of ``cls``."""
    return {f.metadata.get("key") or f.name: f.name for f in option_fields(cls)}


def add_options(parser: argparse.ArgumentParser, cls: type) -> argparse.ArgumentParser:
    """Add one argparse argument per option field of ``cls`` to ``parser``; :func:`options_class`
    of ``parser`` is then ``cls`` itself. Returns ``parser``."""
    groups: dict[str, argparse._MutuallyExclusiveGroup] = {}
    for f in option_fields(cls):
        m = f.metadata
        default = f.default if f.default is not dataclasses.MISSING else \
            f.default_factory() if f.default_factory is not dataclasses.MISSING else None
        kw = {"help": m.get("help") or None}
        if m.get("metavar"):
            kw["metavar"] = m["metavar"]
        if m.get("choices") is not None:
            kw["choices"] = m["choices"]
        if m.get("nargs") is not None:
            kw["nargs"] = m["nargs"]
        if m.get("type") is not None:
            kw["type"] = m["type"]
        target = parser
        if m.get("group"):
            if m["group"] not in groups:
                groups[m["group"]] = parser.add_mutually_exclusive_group()
            target = groups[m["group"]]
        if m.get("positional"):
            target.add_argument(f.name, **kw)
            continue
        flag = m.get("flag") or "--" + f.name.replace("_", "-")
        if default is False and m.get("type") is None:
            target.add_argument(flag, dest=f.name, action="store_true", help=kw["help"])
            continue
        target.add_argument(flag, dest=f.name, default=default, required=bool(m.get("required")), **kw)
    parser._options_class = cls
    return parser


def params_parser(cls: type) -> argparse.ArgumentParser:
    """A bare parser of the options of ``cls`` (cached on the class): what :func:`from_mapping`
    checks a pipeline step's values with, without building the whole command line."""
    if "_params_parser" not in vars(cls):
        parser = add_options(argparse.ArgumentParser(prog=cls.__name__, add_help=False), cls)
        type.__setattr__(cls, "_params_parser", parser)  # a frozen dataclass's class is not frozen
    return vars(cls)["_params_parser"]


def config_values(params) -> dict:
    """The fields of ``params`` that change a stage's output (``param``), less those holding their
    ``omit`` value: what the stage's config records."""
    return {f.name: getattr(params, f.name) for f in dataclasses.fields(params)
            if f.metadata.get("param", True) and getattr(params, f.name) != f.metadata.get("omit", ())}


def from_namespace(parser: argparse.ArgumentParser, args: argparse.Namespace):
    """The options ``argparse`` parsed (``args``) as an instance of :func:`options_class`."""
    cls = options_class(parser)
    return cls(**{f.name: getattr(args, f.name) for f in option_fields(cls)})


def _parse(action: argparse.Action, value):
    """``value`` (a TOML value of an accepted type) through the option's argparse ``type`` and choices."""
    if action.type is not None and not isinstance(value, bool):
        convert = action.type
        if isinstance(value, list) and action.nargs not in ("+", "*"):
            value = ",".join(str(v) for v in value)
        value = [convert(str(v)) for v in value] if isinstance(value, list) else convert(str(value))
    for item in (value if isinstance(value, list) else [value]):
        if action.choices is not None and item not in action.choices:
            raise argparse.ArgumentTypeError(f"expected one of {', '.join(map(str, action.choices))}, got {item!r}")
    return value


def from_mapping(parser: argparse.ArgumentParser, values: dict, where: str):
    """An instance of :func:`options_class` from ``values`` (destination -> TOML value).

    Raises:
        ValueError: starting with ``where``: an unknown option (with close matches), a value of
            the wrong type (``faces = "many"``), out of range, not a choice, a required option
            missing, or two options of a mutually exclusive group.
    """
    actions = {a.dest: a for a in _actions(parser)}
    given = {}
    for key, value in values.items():
        action = actions.get(key)
        if action is None:
            close = difflib.get_close_matches(key, actions, n=3, cutoff=0.6)
            raise ValueError(f"{where}: unknown option {key!r}" + (f" (did you mean {', '.join(close)}?)" if close else "")
                             + f"; expected one of {', '.join(sorted(actions))}")
        accepted = _kind(action)[1]
        if isinstance(value, bool) and bool not in accepted or not isinstance(value, accepted):
            raise ValueError(f"{where}: {key} = {value!r} is {_NAMES.get(type(value), type(value).__name__)}; expected "
                             f"{' or '.join(_NAMES[t] for t in accepted)} ({action.help or key})")
        if isinstance(value, list) and list in accepted and not all(isinstance(v, (str, int, float)) for v in value):
            raise ValueError(f"{where}: {key} = {value!r}; expected a list of strings or numbers")
        if isinstance(value, str) and action.nargs in ("+", "*"):
            value = [value]  # one item, as on a command line
        try:
            given[key] = value if isinstance(value, bool) else _parse(action, value)
        except (argparse.ArgumentTypeError, ValueError, TypeError) as exc:
            raise ValueError(f"{where}: {key} = {value!r}: {exc}") from None
    missing = [a.dest for a in actions.values() if a.required and a.dest not in given]
    if missing:
        raise ValueError(f"{where}: missing {', '.join(missing)}")
    for group in parser._mutually_exclusive_groups:
        both = [a.dest for a in group._group_actions if a.dest in given and given[a.dest] != a.default]
        if len(both) > 1:
            raise ValueError(f"{where}: {' and '.join(both)} cannot be used together")
    return options_class(parser)(**given)


__all__ = ["add_options", "config_values", "from_mapping", "from_namespace", "option", "option_fields",
           "options_class", "params_parser", "toml_keys"]
