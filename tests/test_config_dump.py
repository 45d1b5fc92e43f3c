"""slamkit.config.dump / resolved: a built config back to plain YAML data that builds the same
config again, so a run folder's ``config.yaml`` spells out the dataclass defaults the algorithms
used (issue 30) and the pipeline runs on it unchanged."""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml

from slamkit.backend.solvers import OptimizeConfig
from slamkit.config import build, dump, resolved
from slamkit.errors import ConfigError
from slamkit.experiments import estimators
from slamkit.experiments.config_models import with_defaults
from slamkit.experiments.lidar_slam import MclCheckConfig, slam_section_for
from slamkit.experiments.navigation import EpisodeConfig, _variants
from slamkit.experiments.navigation.map_source import MapSourceConfig
from slamkit.experiments.pipeline import _load_checked, check_pipeline
from slamkit.sim.inertial_world import InertialScenario
from slamkit.sim.landmark_world import LandmarkScenario
from slamkit.systems.lidar_slam import LidarSlamConfig
from slamkit.systems.navigation import NavigationConfig

PIPELINES = Path(__file__).resolve().parents[1] / "pipelines"


def _through_yaml(data):
    return yaml.safe_load(yaml.safe_dump(data))


def _same(a, b) -> bool:
    """Equal, NaN equal to NaN (a YAML .nan is a new float object, so == on dataclasses fails)."""
    return _nan_free(dump(a)) == _nan_free(dump(b))


def _nan_free(x):
    if isinstance(x, float) and math.isnan(x):
        return "nan"
    if isinstance(x, list):
        return [_nan_free(v) for v in x]
    if isinstance(x, dict):
        return {k: _nan_free(v) for k, v in x.items()}
    return x


# --- every algorithm config class the four pipelines build ----------------------------------------

def _roots() -> list[type]:
    roots = [LidarSlamConfig, MclCheckConfig, NavigationConfig, EpisodeConfig, MapSourceConfig,
             OptimizeConfig, LandmarkScenario, InertialScenario]
    for name in estimators.REGISTRY:   # filter_vs_smoother's estimators
        try:
            cls = estimators.config_class(name)
        except (ImportError, AttributeError):
            continue
        if cls is not None:
            roots.append(cls)
    return roots


def _reachable() -> list[type]:
    seen: dict[type, None] = {}

    def walk(cls: type) -> None:
        if cls in seen:
            return
        seen[cls] = None
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            hint = hints.get(f.name)
            for tp in (hint, *typing.get_args(hint)):
                if dataclasses.is_dataclass(tp) and isinstance(tp, type):
                    walk(tp)

    for root in _roots():
        walk(root)
    return list(seen)


CLASSES = _reachable()


def _variations(value):
    """A few other values of a field's dumped default (some refused by the class: skipped)."""
    if isinstance(value, bool):
        return [not value]
    if isinstance(value, int):
        return [value + 1, max(0, value - 1)]
    if isinstance(value, float):
        return [value * 0.5, value * 1.5 + 0.25] if math.isfinite(value) else [1.0]
    if isinstance(value, list):
        return [value[:-1], value + value[-1:]] if value else []
    if isinstance(value, dict):
        return [{k: v} for k, v0 in value.items() for v in _variations(v0)]
    return []


def test_the_classes_cover_nested_sections():
    names = {c.__name__ for c in CLASSES}
    # nested sections of LidarSlamConfig and NavigationConfig, estimator configs, scenario sensors
    assert {"IcpConfig", "LoopClosureConfig", "KeyframeConfig", "SafetyConfig", "GlobalPlanningConfig",
            "RangeBearingSensor", "EKFLocalizationConfig", "NoiseParams"} <= names


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: f"{c.__module__}.{c.__name__}")
def test_build_dump_build_is_build(cls):
    """build(cls, dump(build(cls, d))) == build(cls, d), through YAML text, for the defaults and
    for every field changed on its own (to each value the class accepts), nested sections too."""
    defaults = dump(build(cls, {}))
    cases = [{}]
    for key, value in defaults.items():
        cases += [{key: v} for v in _variations(value)]
    checked = 0
    for data in cases:
        try:
            built = build(cls, data)
        except ConfigError:
            continue  # a value the class refuses (out of its bounds)
        again = build(cls, _through_yaml(dump(built)))
        assert _same(again, built), (cls.__name__, data)
        assert again == built or "nan" in yaml.safe_dump(dump(built)), (cls.__name__, data)
        # resolved: the same less the None fields (a null means "the default" when rebuilt)
        assert _same(build(cls, _through_yaml(resolved(cls, data))), built), (cls.__name__, data)
        checked += 1
    assert checked >= 1


# --- the values YAML has to carry ---------------------------------------------------------------

@dataclass(frozen=True)
class Sensor:
    rate_hz: float = 10.0
    gate_m: float = math.inf


@dataclass(frozen=True)
class Odd:
    big: float = math.inf
    low: float = -math.inf
    missing: float = math.nan
    maybe: float | None = None
    pairs: tuple[tuple[float, float], ...] = ((0.0, 1.0), (2.0, 3.5))
    names: tuple[str, ...] = ("a", "b")
    sensor: Sensor = Sensor(rate_hz=5.0)
    extra: Sensor | None = None
    table: typing.Mapping[str, typing.Any] = field(default_factory=lambda: {"k": [1, 2]})


def test_non_finite_numpy_tuples_and_none_round_trip_through_yaml():
    built = build(Odd, {"maybe": np.float64(2.5), "pairs": np.array([[1.0, 2.0]]), "names": ("c",),
                        "sensor": {"gate_m": np.float32(-np.inf)}, "extra": {"rate_hz": np.int64(3)},
                        "low": float("-inf")})
    data = dump(built)
    text = yaml.safe_dump(data)
    assert ".inf" in text and ".nan" in text and "numpy" not in text and "!!python" not in text
    back = build(Odd, yaml.safe_load(text))
    assert _same(back, built)
    assert back.pairs == ((1.0, 2.0),) and back.names == ("c",) and back.maybe == 2.5
    assert back.sensor == Sensor(rate_hz=5.0, gate_m=-math.inf) and back.extra == Sensor(rate_hz=3.0)
    assert math.isnan(back.missing) and back.big == math.inf
    assert type(data["maybe"]) is float and type(data["extra"]["rate_hz"]) is int
    # None where None is the default stays None
    assert dump(build(Odd, {}))["maybe"] is None and build(Odd, _through_yaml(dump(build(Odd, {})))).extra is None


def test_resolved_leaves_out_what_the_pipeline_sets():
    options = resolved(OptimizeConfig, {"max_iterations": 7}, exclude=("solver", "init", "robust"))
    assert options["max_iterations"] == 7 and not {"solver", "init", "robust"} & set(options)
    assert set(options) == {k for k, v in dump(OptimizeConfig()).items() if v is not None} - {"solver", "init", "robust"}
    assert "robust_k" not in options   # None: "the default", as the pipeline models' None defaults


# --- the pipelines: config.yaml spells the sections out and the runs build the same -------------

def _configs(kind: str) -> list[Path]:
    out = []
    for path in sorted(PIPELINES.glob("*.yaml")):
        if yaml.safe_load(path.read_text()).get("pipeline") == kind:
            out.append(path)
    assert out, kind
    return out


def _before_and_after(path: Path):
    config, model = _load_checked(path)
    from slamkit.experiments.config_models import _model_defaults

    before = _model_defaults(config, model)           # the model's defaults only (as before)
    after = with_defaults(config, model)
    written = _through_yaml(after)                     # what config.yaml holds, read back
    again = with_defaults(written, check_pipeline(written))
    assert again == after                              # valid, and a fixed point
    return before, _through_yaml(after)


@pytest.mark.parametrize("path", _configs("lidar_slam"), ids=lambda p: p.stem)
def test_lidar_slam_sections_resolved(path):
    before, after = _before_and_after(path)
    assert set(after["slam"]) == {k for k, v in dump(LidarSlamConfig()).items() if v is not None}
    assert "max_iterations" in after["slam"]["icp"]
    for prior in ("odometry", "constant_velocity", "identity"):
        assert build(LidarSlamConfig, slam_section_for(after.get("slam"), after.get("slam_by_motion_prior"), prior)) == \
            build(LidarSlamConfig, slam_section_for(before.get("slam"), before.get("slam_by_motion_prior"), prior))
    if before.get("mcl"):
        mcl = before["mcl"] if isinstance(before["mcl"], dict) else None
        assert build(MclCheckConfig, after["mcl"]) == build(MclCheckConfig, mcl)


@pytest.mark.parametrize("path", _configs("navigation"), ids=lambda p: p.stem)
def test_navigation_sections_resolved(path):
    before, after = _before_and_after(path)
    assert set(after["navigation"]) == {k for k, v in dump(build(NavigationConfig, {})).items() if v is not None}
    assert set(after["episode"]) >= {k for k, v in dump(EpisodeConfig()).items() if v is not None}
    assert _variants(after) == _variants(before)
    map_after, map_before = build(MapSourceConfig, after["map"]), build(MapSourceConfig, before.get("map"))
    assert dataclasses.replace(map_after, slam={}) == dataclasses.replace(map_before, slam={})
    assert build(LidarSlamConfig, map_after.slam) == build(LidarSlamConfig, map_before.slam)


@pytest.mark.parametrize("path", _configs("pose_graph"), ids=lambda p: p.stem)
def test_pose_graph_options_resolved(path):
    before, after = _before_and_after(path)
    assert "max_iterations" in after["options"]
    for solver in ("lm", "gn", "dogleg", "isam2"):
        for init in ("file", "odometry", "lago", "chordal"):
            base = OptimizeConfig(solver=solver, init=init, robust=before.get("robust", "none"))
            assert build(OptimizeConfig, after["options"], base=base) == \
                build(OptimizeConfig, before.get("options", {}), base=base)


@pytest.mark.parametrize("path", _configs("filter_vs_smoother"), ids=lambda p: p.stem)
def test_filter_vs_smoother_preset_params_resolved(path):
    from slamkit.experiments.filter_vs_smoother.config import preset_scenario, scenarios_of

    before, after = _before_and_after(path)
    old, new = scenarios_of(before["scenarios"]), scenarios_of(after["scenarios"])
    assert [s.name for s in old] == [s.name for s in new]
    for a, b in zip(old, new):
        if a.preset is None:
            assert a == b
            continue
        cls, preset = preset_scenario(a.preset)
        assert set(b.params) == {k for k, v in dump(preset).items() if v is not None} - {"name"}
        assert build(cls, {**b.params, "name": b.name}, base=preset) == \
            build(cls, {**a.params, "name": a.name}, base=preset)
