"""Config files at the edge: safe YAML loading and validation into typed models (pydantic v2).

Every config slamkit reads from a file -- pipeline configs, scenarios, ROS map YAML -- goes
through :func:`load_yaml` and :func:`validate`, and every error is a
:class:`~slamkit.errors.ConfigError` that names the file, the line (from the YAML node marks),
the field path and, for an unknown key, the nearest valid name::

    pipelines/pose_graph.yaml:9: options.max_iteratons: unknown key (did you mean 'max_iterations'?)

YAML is read strictly: UTF-8 only, and an alias budget (:data:`MAX_EXPANDED_NODES`) so that a
few hundred bytes of nested aliases ("billion laughs") cannot expand into gigabytes, and a
self-referencing alias (``&a [*a]``) is refused instead of recursing forever.

The algorithms keep their frozen, SI-unit config dataclasses; :func:`model_of` derives the
pydantic model of such a dataclass from its fields (one source of truth), with
``extra='forbid'``, no NaN/inf, and the bounds of :func:`_bounds_for` on fields whose unit
suffix says what they are (durations ``_s``, rates ``_hz``, lengths ``_m``, counts), so a
``duration_s: 1e20`` that would run for ever is refused before anything runs.

This is a base module (usable from ``slamkit.sim`` and ``slamkit.experiments``, the packages
that read config files); algorithm packages never import it.
"""

from __future__ import annotations

import dataclasses
import difflib
import enum
import functools
import math
import numbers
import types
import typing
from pathlib import Path
from typing import Annotated, Any, Literal, Mapping

import numpy as np
import pydantic
import yaml
from pydantic import ConfigDict, Field

from slamkit.errors import ConfigError

#: the largest number of nodes a YAML document may expand to (aliases counted each time used)
MAX_EXPANDED_NODES = 200_000
#: the largest config file read (bytes)
MAX_CONFIG_BYTES = 4 * 1024 * 1024

STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, arbitrary_types_allowed=True)


# --- YAML --------------------------------------------------------------------------------------


class _BudgetLoader(yaml.SafeLoader):
    """A SafeLoader that refuses self-referencing aliases (checked while composing)."""

    def __init__(self, stream):
        super().__init__(stream)
        self._open_anchors: list[str] = []

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            if event.anchor in self._open_anchors:
                raise ConfigError(f"line {event.start_mark.line + 1}: alias *{event.anchor} refers to the node "
                                  "that contains it (a recursive structure)")
            return super().compose_node(parent, index)
        event = self.peek_event()
        anchor = getattr(event, "anchor", None)
        if anchor is not None:
            self._open_anchors.append(anchor)
        try:
            return super().compose_node(parent, index)
        finally:
            if anchor is not None:
                self._open_anchors.pop()


def _expanded_size(node: yaml.Node, memo: dict[int, int]) -> int:
    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = 1  # guards against cycles (already refused while composing)
    if isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(n, memo) for n in node.value)
    elif isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
    else:
        size = 1
    memo[key] = min(size, MAX_EXPANDED_NODES + 1)
    return memo[key]


def _lines(node: yaml.Node, path: tuple, out: dict[tuple, int], seen: set[int]) -> None:
    """Field path -> one-based line of its value (keys' lines for mappings)."""
    if id(node) in seen:
        return
    seen.add(id(node))
    out.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            name = k.value if isinstance(k, yaml.ScalarNode) else str(k)
            out[path + (name,)] = k.start_mark.line + 1
            _lines(v, path + (name,), out, seen)
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            _lines(v, path + (i,), out, seen)


@dataclasses.dataclass(frozen=True)
class YamlDocument:
    """A parsed config file: its data, its path and the line of every field path."""

    data: Any
    path: str
    lines: Mapping[tuple, int]

    def where(self, loc: tuple) -> str:
        """``FILE:LINE`` of the deepest field on ``loc`` whose line is known."""
        loc = tuple(loc)
        while loc and loc not in self.lines:
            loc = loc[:-1]
        line = self.lines.get(loc)
        return f"{self.path}:{line}" if line is not None else self.path


def load_yaml(path: str | Path, what: str = "config") -> YamlDocument:
    """Read and parse a YAML config file strictly (see the module docstring)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"{what} {path} does not exist") from None
    except IsADirectoryError:
        raise ConfigError(f"{what} {path} is a directory, not a file") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(f"{path}: {len(raw)} bytes; a {what} file is at most {MAX_CONFIG_BYTES} bytes")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ConfigError(f"{path}:{line}: not UTF-8 text (byte 0x{raw[exc.start]:02x})") from None
    try:
        loader = _BudgetLoader(text)
    except yaml.YAMLError as exc:  # the reader refuses control characters up front
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        line = text[:getattr(exc, "position", 0)].count("\n") + 1
        raise ConfigError(f"{path}:{line}: invalid YAML: {problem}") from None
    try:
        try:
            node = loader.get_single_node()
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
            where = f":{mark.line + 1}" if mark is not None else ""
            problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
            raise ConfigError(f"{path}{where}: invalid YAML: {problem}") from None
        if node is None:
            return YamlDocument(None, str(path), {})
        if _expanded_size(node, {}) > MAX_EXPANDED_NODES:
            raise ConfigError(f"{path}: the YAML expands to more than {MAX_EXPANDED_NODES} nodes through its "
                              "aliases; refused (an alias bomb?)")
        try:
            data = loader.construct_document(node)
        except (yaml.YAMLError, ValueError, TypeError, RecursionError) as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f":{mark.line + 1}" if mark is not None else ""
            raise ConfigError(f"{path}{where}: invalid YAML value: {str(exc).splitlines()[0]}") from None
        lines: dict[tuple, int] = {}
        _lines(node, (), lines, set())
        return YamlDocument(data, str(path), lines)
    finally:
        loader.dispose()


# --- validation --------------------------------------------------------------------------------


def _suggest(key: str, options: list[str]) -> str:
    close = difflib.get_close_matches(str(key), options, n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else (f"; valid keys: {', '.join(sorted(options))}"
                                                          if options else "")


def _known_keys(model: type, loc: tuple) -> list[str]:
    """The field names valid at ``loc`` (the mapping that holds the unknown key)."""
    current: Any = model
    for part in loc:
        if isinstance(part, int):
            continue
        fields = getattr(current, "model_fields", None)
        if not fields or part not in fields:
            return []
        current = _inner_model(fields[part].annotation)
    return list(getattr(current, "model_fields", {}) or [])


def _inner_model(annotation: Any) -> Any:
    for arg in (typing.get_args(annotation) or (annotation,)):
        if isinstance(arg, type) and issubclass(arg, pydantic.BaseModel):
            return arg
        inner = _inner_model(arg) if typing.get_args(arg) else None
        if inner is not None:
            return inner
    return None


def validate(model: type, data: Any, doc: YamlDocument | None = None, source: str = "<config>",
             prefix: tuple = ()) -> Any:
    """``model.model_validate(data)``; a ValidationError becomes one ConfigError whose lines
    name the file, line, field path and problem of every error."""
    try:
        return model.model_validate(data)
    except pydantic.ValidationError as exc:
        messages = []
        for err in exc.errors()[:10]:
            loc = tuple(x for x in err["loc"] if not (isinstance(x, str) and (
                x.startswith(("function-", "tagged-")) or (x.startswith("<") and x.endswith(">")))))
            full = prefix + loc
            where = doc.where(full) if doc is not None else source
            dotted = ".".join(str(x) for x in full) or "(top level)"
            if err["type"] == "extra_forbidden":
                problem = "unknown key" + _suggest(str(loc[-1]), _known_keys(model, loc[:-1]))
            elif err["type"] == "missing":
                problem = "required but missing"
            elif err["type"] == "model_type":
                problem = f"a section of fields (key: value), got {err.get('input')!r}"[:200]
            else:
                problem = err["msg"]
                if "input" in err and err["type"] not in ("model_type", "dict_type"):
                    problem += f" (got {err['input']!r})"[:200]
            messages.append(f"{where}: {dotted}: {problem}")
        raise ConfigError("\n".join(messages)) from None


def write_back(data: Any, validated: Any) -> None:
    """Make the raw mapping ``data`` say what validation understood, in place: a number written
    as a string (PyYAML reads ``1e-8`` as a string) becomes the number, an explicit ``null``
    (meaning "the default") is dropped, nested sections likewise. So the code that reads the
    mapping later meets the values the validation accepted, not the raw ones."""
    if not isinstance(data, dict) or not isinstance(validated, pydantic.BaseModel):
        return
    for key in list(data):
        if data[key] is None:
            del data[key]
            continue
        value = getattr(validated, str(key), None)
        if isinstance(value, pydantic.BaseModel):
            write_back(data[key], value)
        elif isinstance(value, (int, float)) and not isinstance(value, bool) and isinstance(data[key], str):
            data[key] = value


# --- models from the algorithms' dataclasses -----------------------------------------------------

#: bounds by field-name suffix: a duration of 1e20 s or a 1e9 Hz rate would run for ever
_SUFFIX_BOUNDS: tuple[tuple[str, float | None, float | None], ...] = (
    ("resolution_m", 1e-3, 1e3),
    ("_s", 0.0, 86_400.0),       # durations, time steps, lags: at most one day
    ("_hz", 0.0, 10_000.0),
    ("_mps", -100.0, 100.0),
    ("_radps", -100.0, 100.0),
    ("_m", -1e5, 1e5),
    ("_rad", -100.0, 100.0),
)
_COUNT_PREFIXES = ("num_", "n_", "max_")
_MAPPING_TAG, _NAME_TAG = "<fields>", "<preset name>"
MAX_COUNT = 1_000_000


#: suffixes of a cut of the data to its first N seconds: 0 keeps nothing and every estimator then
#: ran on an empty sequence (exit 0, only total_time_s in the results)
_POSITIVE_SUFFIXES = ("max_duration_s",)


def _bounds_for(name: str, tp: Any) -> Any:
    if tp is int and name.startswith(_COUNT_PREFIXES):
        return Annotated[int, Field(ge=0, le=MAX_COUNT)]
    if tp is float and name.endswith(_POSITIVE_SUFFIXES):
        return Annotated[float, Field(gt=0.0, le=86_400.0)]
    if tp is float:
        for suffix, lo, hi in _SUFFIX_BOUNDS:
            if name.endswith(suffix):
                return Annotated[float, Field(ge=lo, le=hi)]
        return float
    return tp


def _field_type(name: str, tp: Any) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if dataclasses.is_dataclass(tp) and not callable(getattr(tp, "preset", None)):
        # a nested config without named presets: a mapping of its fields only (``slam.map: x``
        # passed as a name and failed at run time)
        return model_of(tp)
    if dataclasses.is_dataclass(tp):
        # a nested config, or the name of one of its presets (imu_noise: consumer_mems); the
        # discriminator picks the branch by the input's type, so errors speak of that one only
        return Annotated[typing.Union[Annotated[model_of(tp), pydantic.Tag(_MAPPING_TAG)],
                                      Annotated[str, pydantic.Tag(_NAME_TAG)]],
                         pydantic.Discriminator(lambda v: _NAME_TAG if isinstance(v, str) else _MAPPING_TAG)]
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        return typing.Union[tuple(_field_type(name, a) for a in args)]  # type: ignore[return-value]
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple[_field_type(name, args[0]), ...]  # type: ignore[misc]
        return tuple[tuple(_field_type(name, a) for a in args)]  # type: ignore[misc]
    if origin is Literal or tp in (str, bool, type(None)):
        return tp
    if tp in (int, float):
        return _bounds_for(name, tp)
    return Any  # arrays, callables, enums: checked by the dataclass itself


@functools.lru_cache(maxsize=None)
def model_of(cls: type) -> type[pydantic.BaseModel]:
    """The pydantic model of the config dataclass ``cls``: every init field optional (a config
    names only what it overrides), unknown keys and NaN/inf refused, suffix bounds applied."""
    hints = typing.get_type_hints(cls)
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.init:
            fields[f.name] = (typing.Optional[_field_type(f.name, hints.get(f.name, Any))], None)
    if callable(getattr(cls, "preset", None)) and "preset" not in fields:
        # classes with named presets (Gps, ImuNoise) accept {preset: name, <overrides>}
        fields["preset"] = (typing.Optional[str], None)
    return pydantic.create_model(f"{cls.__name__}Fields", __config__=STRICT, **fields)


def params_model_of(fn: Any, exclude: typing.Iterable[str] = ()) -> type[pydantic.BaseModel]:
    """The pydantic model of the keyword parameters of the function ``fn`` (a dataset reader whose
    parameters a config may set), as :func:`model_of` makes one of a dataclass: the parameters
    with a default, less ``exclude``, all optional; unknown keys and NaN/inf refused, suffix
    bounds applied."""
    import inspect

    hints = typing.get_type_hints(fn)
    skip = set(exclude)
    fields: dict[str, Any] = {}
    for p in inspect.signature(fn).parameters.values():
        if (p.default is inspect.Parameter.empty or p.name in skip
                or p.kind in (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)):
            continue
        fields[p.name] = (typing.Optional[_field_type(p.name, hints.get(p.name, Any))], None)
    return pydantic.create_model(f"{getattr(fn, '__name__', 'reader')}_params", __config__=STRICT, **fields)


def finite(x: float) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


# --- from the validated mapping to the algorithms' dataclasses ---------------------------------

T = typing.TypeVar("T")


def _tupled(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return tuple(_tupled(v) for v in value)
    return value


def _dataclass_in(hint: Any) -> type | None:
    """The dataclass a field's type names (``X`` or ``X | None``), else None."""
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        return hint
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        found = [a for a in typing.get_args(hint) if dataclasses.is_dataclass(a) and isinstance(a, type)]
        return found[0] if len(found) == 1 else None
    return None


def _numeric_hint(hint: Any) -> str | None:
    """What a numeric field's type asks for: "number" (``float``, ``int``, either ``| None``),
    "numbers" (a tuple of them), "bool" (``bool``, ``| None``: a switch, where any string or
    number would otherwise count as on), else None (any other type is the dataclass's to check)."""
    args = [a for a in (typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType)
                        else (hint,)) if a is not type(None)]
    if args and all(a in (int, float) for a in args):
        return "number"
    if args == [bool]:
        return "bool"
    if len(args) == 1 and typing.get_origin(args[0]) is tuple:
        items = [a for a in typing.get_args(args[0]) if a is not Ellipsis]
        if items and all(a in (int, float) for a in items):
            return "numbers"
    return None


def _is_number(value: Any) -> bool:
    """A real number (numpy's scalars too), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _are_numbers(value: Any) -> bool:
    """A sequence of real numbers (a list, tuple or numpy array)."""
    return (not isinstance(value, (str, bytes, Mapping)) and hasattr(value, "__iter__")
            and all(map(_is_number, value)))


def build(cls: type[T], data: Mapping[str, Any] | None, where: str | None = None, base: T | None = None,
          moved: Mapping[str, str] | None = None, null_is_none: bool = False) -> T:
    """The frozen config dataclass ``cls`` from a validated mapping: the one dict-to-dataclass
    builder (issue 30), so the pipelines restate neither defaults nor nesting.

    * a key that is absent or null keeps its default (``base``'s value when given, else the
      field's default), as a null means in a pipeline config; with ``null_is_none`` a null sets
      the field to None instead (a scenario file's ``gps: null`` switches the GPS off), in nested
      sections too;
    * a mapping for a field whose default is a dataclass overrides *that default's* fields,
      recursively (``orb: {fast_threshold: 12}`` keeps the system's other ORB settings); a
      mapping for a field typed as a dataclass without one builds it from its class defaults;
    * for a field whose dataclass has named presets (a ``preset`` classmethod: ``ImuNoise``,
      ``Gps``), a string is the preset's name (``imu_noise: consumer_mems``) and a mapping may
      start from one (``gps: {preset: rtk, rate_hz: 5}``: the preset with its fields overridden);
    * lists become tuples (frozen configs hold tuples), recursively;
    * an unknown key is a :class:`~slamkit.errors.ConfigError` naming ``where`` and the known
      fields ("unknown parameter(s)"; ``moved``: a former key -> the dotted path it moved to,
      named in the message), as is a value the dataclass refuses by type (or by ValueError), a
      value that is not a number for a field typed as one (``float``, ``int``, a tuple of them), and
      a value that is not a mapping for a field holding a dataclass (a preset's name aside); the
      dataclass's own ConfigError is prefixed with ``where`` unless it starts with it.

    Bounds are checked where they are declared: by the pydantic model (:func:`model_of`) at the
    edge and by the dataclass's own ``__post_init__``.
    """
    name = where or cls.__name__
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{name}: expected a mapping of {cls.__name__} fields, got {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(map(str, data)) - set(fields))
    if unknown:
        went = [f"{k} -> {moved[k]}" for k in unknown if moved and k in moved]
        hint = f" (moved into a section: {', '.join(went)})" if went else ""
        raise ConfigError(f"{name}: unknown parameter(s) {unknown} for {cls.__name__}{hint}; "
                          f"known: {sorted(fields)}")
    hints = typing.get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if value is None:
            if null_is_none:
                kwargs[key] = None
            continue
        f = fields[key]
        if base is not None:
            default = getattr(base, key)
        elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
            default = f.default_factory()  # type: ignore[misc]
        else:
            default = f.default
        here = f"{name}.{key}"
        has_default = dataclasses.is_dataclass(default) and not isinstance(default, type)
        nested = type(default) if has_default else _dataclass_in(hints.get(key))
        presets = nested is not None and callable(getattr(nested, "preset", None))
        if isinstance(value, Mapping):
            if presets and "preset" in value:
                rest = {k: v for k, v in value.items() if k != "preset"}
                value = build(nested, rest, here, base=_preset(nested, value["preset"], here),
                              null_is_none=null_is_none)
            elif has_default:
                value = build(type(default), value, here, base=default, null_is_none=null_is_none)
            elif nested is not None:
                value = build(nested, value, here, null_is_none=null_is_none)
        elif presets and isinstance(value, str):
            value = _preset(nested, value, here)
        else:
            if nested is not None and not isinstance(value, nested):
                raise ConfigError(f"{here}: expected a mapping of {nested.__name__} fields, got {value!r}")
            # a string where a number belongs would otherwise surface as the dataclass's
            # comparison error ("'<=' not supported between 'int' and 'str'")
            wants = _numeric_hint(hints.get(key))
            if wants == "number" and not _is_number(value):
                raise ConfigError(f"{here}: expected a number, got {value!r}")
            if wants == "numbers" and not _are_numbers(value):
                raise ConfigError(f"{here}: expected a list of numbers, got {value!r}")
            if wants == "bool" and not isinstance(value, (bool, np.bool_)):
                raise ConfigError(f"{here}: expected true or false, got {value!r}")
            value = _tupled(value)
        kwargs[key] = value
    try:
        return dataclasses.replace(base, **kwargs) if base is not None else cls(**kwargs)
    except ConfigError as exc:  # the dataclass's own check: named by where it is, once
        raise (exc if str(exc).startswith(name) else ConfigError(f"{name}: {exc}")) from None
    except (TypeError, ValueError, ArithmeticError) as exc:
        raise ConfigError(f"{name}: {exc}") from None


def _preset(cls: type, name: Any, where: str) -> Any:
    """``cls.preset(name)``, its refusal named by ``where``."""
    try:
        return cls.preset(name)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}: preset {name!r}: {exc}") from None


# --- from the algorithms' dataclasses back to the mapping ----------------------------------------


def dump(value: Any) -> Any:
    """A built config as plain YAML-able data that :func:`build` reads back to an equal config:
    the inverse of ``build`` (issue 30), so a run folder's ``config.yaml`` can say every setting
    an algorithm used, its dataclass defaults included (:func:`resolved`).

    * a dataclass -> a mapping of its init fields, recursively (nested sections too; a field
      holding a preset class becomes the preset's fields, which ``build`` reads as overrides of
      the field's default, hence the same values);
    * tuples and lists -> lists (``build`` makes them tuples again); mappings -> dicts with
      string keys; numpy scalars and arrays -> Python numbers and (nested) lists; a ``Path`` ->
      its string; an enum -> its value;
    * floats stay floats, non-finite ones included (YAML writes ``.inf``/``.nan`` and reads them
      back as floats); ``None`` stays ``None`` (``build`` reads a null as "the default", so a field
      whose value is None dumps as None only where None is its default).
    """
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: dump(getattr(value, f.name)) for f in dataclasses.fields(value) if f.init}
    if isinstance(value, (list, tuple)):
        return [dump(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): dump(v) for k, v in value.items()}
    if type(value).__module__ == "numpy" and hasattr(value, "tolist"):
        return dump(value.tolist())  # np.float64(1.0).tolist() -> 1.0; arrays -> nested lists
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, enum.Enum):
        return value.value
    return value


def resolved(cls: type, data: Mapping[str, Any] | None, where: str | None = None, base: Any = None,
             exclude: typing.Iterable[str] = (), **build_options: Any) -> dict[str, Any]:
    """``data`` (a config section that holds ``cls``'s fields, as the user wrote them) with every
    field ``build`` fills from its defaults spelt out: ``dump(build(cls, data, ...))``, less the
    fields in ``exclude`` (those a pipeline sets itself, e.g. pose_graph's solver per run) and
    less the fields that are None, in nested sections too: a null means "the default" to
    ``build`` and to :func:`write_back`, and a field built as None is at a None default (so
    ``config.yaml`` reloads to itself, as the pipeline model's None defaults stay absent). So
    ``build(cls, resolved(cls, d))`` equals ``build(cls, d)`` (tests/test_config_dump.py)."""
    out = _without_none(dump(build(cls, data, where, base=base, **build_options)))
    skip = set(exclude)
    return {k: v for k, v in out.items() if k not in skip}


def _without_none(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _without_none(v) for k, v in data.items() if v is not None}
    return data
