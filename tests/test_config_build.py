"""slamkit.config.build: the one builder from a validated mapping to the algorithms' frozen
dataclasses (issue 30) -- defaults never restated, nested sections over their defaults."""

from __future__ import annotations

import re

from dataclasses import dataclass, field

import pytest

from slamkit.config import build
from slamkit.errors import ConfigError


@dataclass(frozen=True)
class Inner:
    a_m: float = 1.0
    b: int = 2
    names: tuple[str, ...] = ("x",)


@dataclass(frozen=True)
class Outer:
    inner: Inner = Inner(a_m=5.0)          # a non-class default: overrides keep its other fields
    optional: Inner | None = None          # typed as a dataclass, no default instance
    pairs: tuple[tuple[float, float], ...] = ()
    rate_hz: float = 10.0
    made: Inner = field(default_factory=lambda: Inner(b=7))

    def __post_init__(self) -> None:
        if self.rate_hz <= 0:
            raise ConfigError("rate_hz must be > 0")


def test_empty_and_null_give_the_defaults():
    assert build(Outer, None) == Outer() == build(Outer, {}) == build(Outer, {"rate_hz": None, "inner": None})


def test_nested_mapping_overrides_the_default_instance():
    out = build(Outer, {"inner": {"b": 3}, "made": {"a_m": 0.5}, "rate_hz": 20})
    assert out.inner == Inner(a_m=5.0, b=3)      # a_m kept from Outer's default, not Inner's 1.0
    assert out.made == Inner(a_m=0.5, b=7)
    assert out.rate_hz == 20


def test_dataclass_typed_field_without_default_and_lists_to_tuples():
    out = build(Outer, {"optional": {"names": ["p", "q"]}, "pairs": [[1.0, 2.0], [3.0, 4.0]]})
    assert out.optional == Inner(names=("p", "q"))
    assert out.pairs == ((1.0, 2.0), (3.0, 4.0)) and isinstance(out.pairs[0], tuple)
    hash(out)   # frozen and hashable all the way down


def test_base_supplies_the_defaults():
    base = Outer(rate_hz=50.0, inner=Inner(b=9))
    out = build(Outer, {"inner": {"a_m": 2.0}}, base=base)
    assert out == Outer(rate_hz=50.0, inner=Inner(a_m=2.0, b=9))


def test_errors_name_the_field_path():
    with pytest.raises(ConfigError, match=r"cfg\.inner: unknown parameter\(s\) \['c'\] for Inner; known: \['a_m', 'b', 'names'\]"):
        build(Outer, {"inner": {"c": 1}}, "cfg")
    with pytest.raises(ConfigError, match="Outer: expected a mapping of Outer fields"):
        build(Outer, [1, 2])
    with pytest.raises(ConfigError, match="rate_hz must be > 0"):   # the dataclass's own bound
        build(Outer, {"rate_hz": -1.0})


def test_a_moved_key_names_where_it_went_and_a_section_needs_a_mapping():
    with pytest.raises(ConfigError, match=r"cfg: unknown parameter\(s\) \['a_m'\] for Outer "
                                          r"\(moved into a section: a_m -> inner\.a_m\); known:"):
        build(Outer, {"a_m": 2.0}, "cfg", moved={"a_m": "inner.a_m"})
    with pytest.raises(ConfigError, match=r"cfg\.inner: expected a mapping of Inner fields, got 0\.3"):
        build(Outer, {"inner": 0.3}, "cfg")
    with pytest.raises(ConfigError, match=r"cfg\.optional: expected a mapping of Inner fields, got 'x'"):
        build(Outer, {"optional": "x"}, "cfg")
    assert build(Outer, {"inner": Inner(b=9)}).inner == Inner(b=9)   # an instance is taken as it is


def test_a_number_field_refuses_what_is_not_a_number_by_name():
    @dataclass(frozen=True)
    class Limits:
        speed_mps: float = 1.0
        count: int = 3
        maybe_s: float | None = None
        sigmas: tuple[float, float, float] = (1.0, 1.0, 0.2)
        label: str = "a"

        def __post_init__(self) -> None:
            if not 0 <= self.speed_mps <= 5:   # a str would fail here with Python's comparison message
                raise ConfigError("speed_mps must lie in [0, 5]")

    with pytest.raises(ConfigError, match=r"^lim\.speed_mps: expected a number, got 'fast'$"):
        build(Limits, {"speed_mps": "fast"}, "lim")
    with pytest.raises(ConfigError, match=r"^lim\.count: expected a number, got True$"):   # a bool is no count
        build(Limits, {"count": True}, "lim")
    with pytest.raises(ConfigError, match=r"^lim\.maybe_s: expected a number, got '2 s'$"):
        build(Limits, {"maybe_s": "2 s"}, "lim")
    with pytest.raises(ConfigError, match=r"^lim\.sigmas: expected a list of numbers, got \[1, 'x', 0\.2\]$"):
        build(Limits, {"sigmas": [1, "x", 0.2]}, "lim")
    with pytest.raises(ConfigError, match=r"^lim\.sigmas: expected a list of numbers, got 0\.5$"):
        build(Limits, {"sigmas": 0.5}, "lim")
    # numbers of every kind pass (ints for floats, numpy scalars and arrays), other types are the dataclass's
    import numpy as np

    out = build(Limits, {"speed_mps": 2, "count": np.int64(4), "maybe_s": np.float32(0.5),
                         "sigmas": np.array([0.1, 0.1, 0.05]), "label": "b"})
    assert (out.speed_mps, out.count, out.maybe_s, out.label) == (2, 4, 0.5, "b")
    np.testing.assert_array_equal(out.sigmas, [0.1, 0.1, 0.05])


def test_a_switch_refuses_what_is_not_true_or_false_by_name():
    """A bool field given a string or a number would count as on (``"no"`` and ``nan`` are
    truthy): refused by name; null keeps the default, numpy's bools pass."""
    import numpy as np

    @dataclass(frozen=True)
    class Switches:
        on: bool = False
        maybe: bool | None = None

    for bad in ("no", "abc", 1, 0, float("nan")):
        with pytest.raises(ConfigError, match=rf"^sw\.on: expected true or false, got {re.escape(repr(bad))}$"):
            build(Switches, {"on": bad}, "sw")
    with pytest.raises(ConfigError, match=r"^sw\.maybe: expected true or false, got 'yes'$"):
        build(Switches, {"maybe": "yes"}, "sw")
    assert build(Switches, {"on": None}).on is False
    assert build(Switches, {"on": True, "maybe": np.bool_(False)}) == Switches(True, False)


def test_a_value_error_of_the_dataclass_is_a_config_error_naming_where():
    @dataclass(frozen=True)
    class Picky:
        n: int = 1

        def __post_init__(self) -> None:
            if self.n > 5:
                raise ValueError("n at most 5")

    with pytest.raises(ConfigError, match=r"picky: n at most 5"):
        build(Picky, {"n": 6}, "picky")


@dataclass(frozen=True)
class Noise:
    """A config with named presets, as ImuNoise and Gps have."""

    sigma: float = 1.0
    rate_hz: float = 10.0

    @classmethod
    def preset(cls, name: str) -> "Noise":
        if name not in ("quiet", "loud"):
            raise ConfigError(f"unknown noise preset {name!r}")
        return cls(sigma=0.1 if name == "quiet" else 5.0, rate_hz=2.0)


@dataclass(frozen=True)
class Rig:
    noise: Noise = Noise(sigma=0.5)
    extra: Noise | None = Noise(rate_hz=3.0)
    inner: Inner | None = None


def test_a_preset_name_or_a_preset_with_overrides():
    assert build(Rig, {"noise": "quiet"}).noise == Noise(sigma=0.1, rate_hz=2.0)
    out = build(Rig, {"noise": {"preset": "loud", "rate_hz": 7.0}, "extra": {"sigma": 2.0}})
    assert out.noise == Noise(sigma=5.0, rate_hz=7.0)          # the preset's sigma, the given rate
    assert out.extra == Noise(sigma=2.0, rate_hz=3.0)          # no preset: over the field's default
    with pytest.raises(ConfigError, match=r"rig\.noise: unknown noise preset 'lukewarm'"):
        build(Rig, {"noise": "lukewarm"}, "rig")
    with pytest.raises(ConfigError, match=r"rig\.noise: unknown parameter\(s\) \['sigmaa'\] for Noise"):
        build(Rig, {"noise": {"preset": "loud", "sigmaa": 1.0}}, "rig")


def test_null_is_none_switches_an_optional_part_off():
    # a pipeline config's null means "the default"; a scenario file's null switches a sensor off
    assert build(Rig, {"extra": None}).extra == Noise(rate_hz=3.0)
    off = build(Rig, {"extra": None, "noise": {"sigma": 2.0}}, null_is_none=True)
    assert off.extra is None and off.noise == Noise(sigma=2.0)
    nested = build(Outer, {"optional": {"names": None}}, null_is_none=True)
    assert nested.optional == Inner(names=None)                # passed down to nested sections
