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
"""

from __future__ import annotations

import difflib
import importlib
import re
import warnings
from typing import Generic, Iterable, Iterator, Mapping, TypeVar

from slamkit.errors import ConfigError

#: every registered name: lower-case letters, digits and underscores, starting with a letter
NAME_RULE = re.compile(r"[a-z][a-z0-9_]*\Z")

T = TypeVar("T")


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
    """

    def __init__(self, what: str, entries: Mapping[str, T] | Iterable[tuple[str, T]],
                 deprecated: Mapping[str, str] | None = None):
        self.what = what
        self._entries: dict[str, T] = dict(entries)
        bad = [n for n in self._entries if not NAME_RULE.match(n)]
        if bad:
            raise ValueError(f"{what} names must be snake_case ({NAME_RULE.pattern}): {bad}")
        self._deprecated = dict(deprecated or {})
        missing = {o: n for o, n in self._deprecated.items() if n not in self._entries}
        if missing:
            raise ValueError(f"deprecated {what} spellings point to unknown names: {missing}")

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
            raise ConfigError(f"{self.what} {name!r} is already registered")
        self._entries[name] = entry

    def unregister(self, name: str) -> None:
        """Remove an entry added with :meth:`register` (unknown names are a ConfigError)."""
        del self._entries[self.canonical(name)]

    def __repr__(self) -> str:
        return f"Registry({self.what!r}, {self.names()})"
