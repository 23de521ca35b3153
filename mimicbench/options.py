"""A command's options as a typed dataclass, derived from the argparse parser that declares them.

Each command declares its options once, on its parser. :func:`options_class` turns that parser
into a frozen dataclass (one field a destination, argparse's default as the field's default);
argparse fills it from a command line (:func:`from_namespace`) and a pipeline step fills it from
a TOML table (:func:`from_mapping`), both through the same ``type=`` checks (``--faces 0`` and
``faces = 0`` get the same message), so the precedence is simply given value > parser default::

    opts = from_mapping(command_parser(("datagen", "resample")), {"in_dataset": "a", "out_dataset": "b"}, "step 2")
    opts.faces  # 5000, the parser's default
"""
from __future__ import annotations

import argparse
import dataclasses
import difflib
from typing import Any

_NUMBER = (int, float)
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


def from_namespace(parser: argparse.ArgumentParser, args: argparse.Namespace):
    """The options ``argparse`` parsed (``args``) as an instance of :func:`options_class`."""
    cls = options_class(parser)
    return cls(**{f.name: getattr(args, f.name) for f in dataclasses.fields(cls)})


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


__all__ = ["from_mapping", "from_namespace", "options_class"]
