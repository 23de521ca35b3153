"""Names to objects, one way for every kind: methods, protocols, trainables, encoders, matchers, engines.

A :class:`Registry` holds three layers of entries, each a name -> target, where a target is an
object or a lazy ``"module:attr"`` string (``attr`` may be dotted) imported on first use:

1. built-ins, given in code (so they resolve without any installed package metadata);
2. the entry-point group, when the registry has one (``[project.entry-points."mimicbench.methods"]``
   in a package's ``pyproject.toml``), read each time it is consulted, so a package installed after
   start-up is seen;
3. run-time registrations (:meth:`Registry.register`), which replace an earlier run-time entry.

A name in two layers with different targets is a :class:`NameCollision` (a built-in declared again
as an entry point with the same ``module:attr`` is fine: that is how the bundled methods are
declared). An unknown name raises :class:`UnknownName` with close matches (difflib) and the known
names; an entry whose import fails raises :class:`LoadError` naming the entry. All three are
:class:`~mimicbench.schemas.errors.UserError`, so the CLI prints ``mimicbench: error: ...`` and exits 2.
"""
from __future__ import annotations

import difflib
import importlib
from importlib.metadata import entry_points

from mimicbench.schemas.errors import UserError


class UnknownName(UserError, KeyError, ValueError):
    """A name no entry has; the message gives close matches and the known names. Also a KeyError
    and a ValueError, the two types the registries it replaced raised."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class NameCollision(UserError, ValueError):
    """Two entries (built-in, entry point, run time) claim one name with different targets."""


class LoadError(UserError, ImportError):
    """An entry's ``module:attr`` target could not be imported (the message names the entry)."""


def parse_target(spec: str) -> tuple[str, str]:
    """``"package.module:Attr.inner"`` -> ("package.module", "Attr.inner"); ValueError otherwise."""
    module, sep, attr = spec.partition(":")
    if not sep or not module or not attr or any(not p.isidentifier() for p in module.split(".") + attr.split(".")):
        raise ValueError(f"expected 'package.module:attr', got {spec!r}")
    return module, attr


def load_target(spec: str):
    """The object a ``"module:attr"`` string names (imports the module; ``attr`` may be dotted)."""
    module, attr = parse_target(spec)
    obj = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def _same(a, b) -> bool:
    return a is b or (isinstance(a, str) and isinstance(b, str) and a.replace(" ", "") == b.replace(" ", ""))


class Registry:
    """Names of one kind (``kind`` is used in messages, e.g. "method").

    Args:
        kind: what the names are, for messages ("method", "protocol", "encoder", ...).
        builtins: name -> target (an object or ``"module:attr"``), in the order :meth:`names` lists them.
        group: an entry-point group whose entries join the names (None: no entry points).
    """

    def __init__(self, kind: str, builtins: dict | None = None, group: str | None = None):
        self.kind = kind
        self.group = group
        self._builtins = dict(builtins or {})
        self._runtime: dict = {}
        self._loaded: dict = {}  # spec string -> loaded object

    def register(self, name: str, target) -> None:
        """Add ``name`` at run time (replacing an earlier run-time entry of that name).

        Raises:
            NameCollision: a built-in or entry point already has ``name`` with another target.
        """
        for layer, other in (("built-in", self._builtins.get(name)), ("entry point", self._entry_points().get(name))):
            if other is not None and not _same(other, target) and not _same(self._resolved(other), target):
                raise NameCollision(f"{self.kind} {name!r}: a {layer} already has that name ({_describe(other)}); "
                                    f"register it under another name")
        self._runtime[name] = target

    def _entry_points(self) -> dict[str, str]:
        """name -> ``module:attr`` of the group's entry points; NameCollision on two different targets."""
        if self.group is None:
            return {}
        out: dict[str, str] = {}
        for ep in entry_points(group=self.group):
            if ep.name in out and not _same(out[ep.name], ep.value):
                raise NameCollision(f"{self.kind} {ep.name!r}: two installed packages declare it in "
                                    f"{self.group!r} ({out[ep.name]} and {ep.value})")
            out[ep.name] = ep.value
        return out

    def _resolved(self, target):
        if not isinstance(target, str):
            return target
        if target not in self._loaded:
            self._loaded[target] = load_target(target)
        return self._loaded[target]

    def names(self) -> list[str]:
        """Every name :meth:`get` accepts: built-ins and entry points in their declared order, then the
        run-time registrations sorted."""
        declared = list(dict.fromkeys([*self._builtins, *self._entry_points()]))
        return declared + sorted(set(self._runtime) - set(declared))

    def __contains__(self, name: str) -> bool:
        return name in self._runtime or name in self._builtins or name in self._entry_points()

    def target(self, name: str):
        """The entry of ``name`` (an object or ``"module:attr"``), without importing it.

        Raises:
            UnknownName: no entry has ``name``.
            NameCollision: the built-in and an entry point of ``name`` name different targets.
        """
        eps = self._entry_points()
        if name in self._runtime:
            return self._runtime[name]
        if name in self._builtins:
            builtin = self._builtins[name]
            if name in eps and not _same(eps[name], builtin):
                raise NameCollision(f"{self.kind} {name!r}: the entry point {eps[name]} (group {self.group!r}) "
                                    f"collides with the built-in {_describe(builtin)}")
            return builtin
        if name in eps:
            return eps[name]
        raise UnknownName(self.unknown_message(name))

    def get(self, name: str):
        """The object registered as ``name`` (imported on first use).

        Raises:
            UnknownName, NameCollision: see :meth:`target`.
            LoadError: the entry's module or attribute could not be imported.
        """
        target = self.target(name)
        try:
            return self._resolved(target)
        except (ImportError, AttributeError, ValueError) as exc:
            raise LoadError(f"{self.kind} {name!r}: cannot load {_describe(target)} "
                            f"({type(exc).__name__}: {exc})") from exc

    def unknown_message(self, name: str) -> str:
        """"unknown <kind> 'x'. Did you mean 'y'? Available: ..." for a name no entry has."""
        try:
            known = self.names()
        except NameCollision:
            known = list(self._builtins) + sorted(set(self._runtime) - set(self._builtins))
        close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
        hint = f" Did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        return f"unknown {self.kind} {name!r}.{hint} Available: {', '.join(known)}"


def _describe(target) -> str:
    return target if isinstance(target, str) else getattr(target, "__qualname__", repr(target))
