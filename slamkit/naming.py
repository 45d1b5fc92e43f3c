"""The names users type, and the one small registry every name table is built on.

Architecture note (issue 18): estimators, filters, planners, controllers and pipelines used to
live in four tables with four spellings (``rrt-star`` beside ``ekf_slam``), each with its own
unknown-name message. They are now each a :class:`Registry`, and every registered name follows
one rule, :data:`NAME_RULE`: lower-case snake_case (``rrt_star``, ``dstar_lite``, ``mpc_osqp``),
as ARCHITECTURE.md section 6 writes them. A name that differs only by hyphens (``rrt-star``) or
case, or an explicitly listed old spelling, is still accepted: the lookup returns the canonical
name and emits one :class:`SlamkitDeprecationWarning` (a ``FutureWarning``, so Python shows it to
users by default; the CLI prints it as ``warning: ...``). An unknown name is a
:class:`~slamkit.errors.ConfigError` that lists the known names and suggests the closest one.

Registries hold whatever their layer needs per name (a spec dataclass, a lazy ``module:attr``
target); the registry itself only decides names.

Plug-ins (issue 32): users extend a registry without editing slamkit. A registry built with a
``group`` also holds the entries other installed packages declare as entry points of that group
(``[project.entry-points."slamkit.estimators"] my_ekf = "my_pkg.slamkit_plugin:SPEC"``; the
object is the registry's entry, adapted by the registry's ``adapt``, or a module whose import
registers its entries itself), read with :mod:`importlib.metadata` on first use. A module named
in a config's ``plugins:`` list or a ``--plugin`` option is imported by :func:`import_plugins`,
which also remembers it: the executors pass the list to their workers in ``$SLAMKIT_PLUGINS``
(:func:`plugin_env`), and a worker imports those modules before its first lookup.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.metadata
import os
import re
import sys
import warnings
from types import ModuleType
from typing import Any, Callable, Generic, Iterable, Iterator, Mapping, TypeVar

from slamkit.errors import ConfigError

#: every registered name: lower-case letters, digits and underscores, starting with a letter
NAME_RULE = re.compile(r"[a-z][a-z0-9_]*\Z")

T = TypeVar("T")

#: the environment variable listing plug-in modules (``os.pathsep``-separated) for child processes
PLUGINS_ENV = "SLAMKIT_PLUGINS"


#: the plug-in modules this process imported through :func:`import_plugins`, in order, and the
#: folders it was told to search for them (passed to workers on their PYTHONPATH)
_PLUGIN_MODULES: list[str] = []
_PLUGIN_DIRS: list[str] = []


def import_plugins(modules: Iterable[str], where: str = "plugins",
                   search_path: Iterable[str] = ()) -> list[ModuleType]:
    """Import each plug-in module (its import registers its entries) and remember it for the
    worker processes this process starts (:func:`plugin_env`). ``search_path``: folders also
    searched (appended to ``sys.path``, so spawned workers search them too), e.g. the config
    file's folder for a plug-in module beside it. A module that cannot be imported is a
    ConfigError naming it and ``where`` (the config field or option that listed it)."""
    modules = list(modules)
    if not modules:
        # nothing to import: the search folders are not remembered either (a resolved config
        # spells out `plugins: []`; its folder must not join the workers' PYTHONPATH)
        return []
    folders = [str(folder) for folder in search_path]
    for folder in folders:
        if folder not in sys.path:
            sys.path.append(folder)
        if folder not in _PLUGIN_DIRS:
            _PLUGIN_DIRS.append(folder)
    loaded = []
    for name in modules:
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"{where}: a plug-in is a module name such as 'my_pkg.slamkit_plugin', got {name!r}")
        name = name.strip()
        try:
            loaded.append(importlib.import_module(name))
        except ImportError as exc:
            looked = (f"looked beside the config too ({', '.join(folders)}); " if folders else "")
            raise ConfigError(f"{where}: plug-in module {name!r} cannot be imported ({exc}); {looked}is its "
                              "package installed in this environment, or its folder on PYTHONPATH?") from None
        if name not in _PLUGIN_MODULES:
            _PLUGIN_MODULES.append(name)
    return loaded


def plugin_env() -> dict[str, str]:
    """``{$SLAMKIT_PLUGINS: modules, PYTHONPATH: search folders + the current one}`` for the
    environment of worker processes (the executors set it for their workers only, so an
    unrelated child process never inherits a plug-in list)."""
    env = {PLUGINS_ENV: os.pathsep.join(_PLUGIN_MODULES)} if _PLUGIN_MODULES else {}
    if _PLUGIN_DIRS:
        current = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
        env["PYTHONPATH"] = os.pathsep.join([*current, *(d for d in _PLUGIN_DIRS if d not in current)])
    return env


def _import_env_plugins() -> None:
    """The modules a parent process passed down in ``$SLAMKIT_PLUGINS`` (imported once)."""
    modules = [m for m in os.environ.get(PLUGINS_ENV, "").split(os.pathsep) if m]
    if modules:
        import_plugins(modules, f"${PLUGINS_ENV}")


class SlamkitDeprecationWarning(FutureWarning):
    """An old spelling or API that still works and will be removed (shown to users by default)."""


def snake_case(name: str) -> str:
    """``"RRT-Star"`` -> ``"rrt_star"``: the spelling the naming rule asks for."""
    return re.sub(r"[-\s]+", "_", str(name).strip()).lower()


def load_target(target: str) -> object:
    """The object a lazy ``"package.module:attribute"`` registry target names (imported now)."""
    module_name, _, attr = target.partition(":")
    if not attr:
        raise ValueError(f"a registry target is 'module:attribute', got {target!r}")
    return getattr(importlib.import_module(module_name), attr)


def suggestion(name: str, options: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest option, or ``""``."""
    close = difflib.get_close_matches(str(name), list(options), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


class Registry(Mapping[str, T], Generic[T]):
    """An ordered name -> entry table under :data:`NAME_RULE`, read-only except for
    :meth:`register` / :meth:`unregister` (a user's own entries where a table accepts them).

    ``what`` names the kind of thing in messages (``"planner"``). ``deprecated`` maps old
    spellings that :func:`snake_case` does not already turn into a registered name.

    ``group`` is the entry-point group whose entries this registry discovers on first use
    (``"slamkit.planners"``); ``adapt(name, obj)`` turns a loaded entry-point object into an
    entry (or raises a ConfigError saying what the object should be). ``derived()`` returns
    entries another table of an inner layer owns (the estimation layer's filters for the
    estimator table): they are read from that table at every lookup, never copied, so an entry
    registered there is seen here too.
    """

    def __init__(self, what: str, entries: Mapping[str, T] | Iterable[tuple[str, T]],
                 deprecated: Mapping[str, str] | None = None, *, group: str | None = None,
                 adapt: Callable[[str, Any], T] | None = None,
                 derived: Callable[[], Mapping[str, T]] | None = None):
        self.what = what
        self.group = group
        self._adapt = adapt
        self._derived = derived
        self._own: dict[str, T] = dict(entries)
        self._discovered = group is None
        bad = [n for n in self._own if not NAME_RULE.match(n)]
        if bad:
            raise ValueError(f"{what} names must be snake_case ({NAME_RULE.pattern}): {bad}")
        self._deprecated = dict(deprecated or {})
        missing = {o: n for o, n in self._deprecated.items() if n not in self._own}
        if missing:
            raise ValueError(f"deprecated {what} spellings point to unknown names: {missing}")

    @property
    def _entries(self) -> dict[str, T]:
        self.discover()
        if self._derived is None:
            return self._own
        return {**self._derived(), **self._own}

    # -- plug-ins ------------------------------------------------------------------------------

    def discover(self, refresh: bool = False) -> None:
        """Register the entries of this registry's entry-point group (once per process unless
        ``refresh``) and the plug-in modules of ``$SLAMKIT_PLUGINS``."""
        if self._discovered and not refresh:
            return
        self._discovered = True  # before loading: a plug-in module registering itself re-enters
        _import_env_plugins()
        if self.group is None:
            return
        for ep in importlib.metadata.entry_points(group=self.group):
            where = f"entry point {ep.name!r} = {ep.value!r} (group {self.group!r}" + (
                f", package {ep.dist.name!r})" if getattr(ep, "dist", None) is not None else ")")
            try:
                obj = ep.load()
            except Exception as exc:  # a broken plug-in must name itself, not crash the lookup
                raise ConfigError(f"{where}: cannot be loaded ({type(exc).__name__}: {exc})") from None
            if isinstance(obj, ModuleType):
                continue  # its import registered what it provides
            try:
                entry = self._adapt(ep.name, obj) if self._adapt is not None else obj
            except ConfigError as exc:
                raise ConfigError(f"{where}: {exc}") from None
            self.register(ep.name, entry)  # the same entry twice (found twice on sys.path) is a no-op

    # -- lookup --------------------------------------------------------------------------------

    def _resolve(self, name: str) -> str | None:
        if not isinstance(name, str):
            return None
        if name in self._entries:
            return name
        if name in self._deprecated:
            return self._deprecated[name]
        key = snake_case(name)
        return key if key in self._entries else self._deprecated.get(key)

    def canonical(self, name: str) -> str:
        """The registered spelling of ``name`` (warning once per call for an old spelling)."""
        key = self._resolve(name)
        if key is None:
            raise ConfigError(f"unknown {self.what} {name!r}{suggestion(str(name), self._entries)}; "
                              f"known: {', '.join(self._entries)}")
        if key != name:
            warnings.warn(f"{self.what} name {name!r} is deprecated; write {key!r}",
                          SlamkitDeprecationWarning, stacklevel=3)
        return key

    def __getitem__(self, name: str) -> T:
        return self._entries[self.canonical(name)]

    def get(self, name: str, default: T | None = None) -> T | None:  # type: ignore[override]
        key = self._resolve(name)
        return default if key is None else self._entries[self.canonical(name)]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self._resolve(name) is not None

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def names(self) -> list[str]:
        return list(self._entries)

    # -- a user's own entries (tables that accept them, e.g. pipelines) --------------------------

    def register(self, name: str, entry: T) -> None:
        """Add ``name`` (under :data:`NAME_RULE`; a name already taken is a ConfigError)."""
        if not isinstance(name, str) or not NAME_RULE.match(name):
            raise ConfigError(f"{self.what} names must be snake_case ({NAME_RULE.pattern}), got {name!r}")
        if self._resolve(name) is not None:
            if self._same(self._own.get(name), entry):
                return  # the same object again (a plug-in both imported and found as an entry point)
            raise ConfigError(f"{self.what} {name!r} is already registered")
        self._own[name] = entry

    @staticmethod
    def _same(registered: object, entry: object) -> bool:
        """The very object registered again (or a wrapper of it: ``same_as``); an equal but
        separately made entry under a taken name is still a conflict."""
        if registered is entry:
            return True
        same_as = getattr(registered, "same_as", None)
        return callable(same_as) and bool(same_as(entry))

    def unregister(self, name: str) -> None:
        """Remove an entry added with :meth:`register` (unknown names are a ConfigError)."""
        del self._own[self.canonical(name)]

    def __repr__(self) -> str:
        return f"Registry({self.what!r}, {self.names()})"
