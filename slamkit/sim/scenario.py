"""Scenario files: YAML at the edge, frozen dataclasses inside.

A scenario YAML has a ``kind`` (``landmark`` or ``grid``), for landmark scenarios an optional
``preset`` (``mild`` or ``strong``), and any fields of :class:`~slamkit.sim.landmark_world.
LandmarkScenario` or :class:`~slamkit.sim.grid_world.GridScenario`. Nested configs (``sensor``,
``robot``, ``encoder``, ``lidar`` with its ``beam_model``, ``gps``) are mappings of their own
fields; ``null`` switches an optional sensor off; ``imu_noise`` may be a preset name; ``gps`` may
say ``preset: rtk`` plus overrides. Unknown keys and bad values raise ``ConfigError`` naming the
file and the key path.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from slamkit.data.sequence import Sequence
from slamkit.paths import path_component
from slamkit.config import YamlDocument, build, load_yaml, model_of, validate
from slamkit.errors import ConfigError, SlamkitError
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.sim.grid_world import GridScenario, simulate_grid_sequence
from slamkit.sim.landmark_world import PRESETS, LandmarkScenario, simulate_landmark_sequence

Scenario = LandmarkScenario | GridScenario
def scenario_from_dict(data: Mapping[str, Any], source: str = "<scenario>", doc: YamlDocument | None = None
                       ) -> Scenario:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: a scenario must be a mapping, got {type(data).__name__}")
    values = dict(data)
    if "name" in values:
        # a scenario's name becomes file names (trajectories, plots, recordings)
        path_component(values["name"], f"{source}: name")
    kind = values.pop("kind", None)
    preset = values.pop("preset", None)
    if kind in ("landmark", "grid"):
        # types, unknown keys (with the nearest name), NaN/inf and bounds (a duration of 1e20 s
        # would simulate for ever), all before anything is built
        validate(model_of(LandmarkScenario if kind == "landmark" else GridScenario), values, doc, source)
    if kind == "landmark":
        base = None
        if preset is not None:
            if preset not in PRESETS:
                raise ConfigError(f"{source}: preset: unknown preset {preset!r}; known: {sorted(PRESETS)}")
            base = PRESETS[preset]()
        return build(LandmarkScenario, values, source, base=base, null_is_none=True)
    if kind == "grid":
        if preset is not None:
            raise ConfigError(f"{source}: preset: grid scenarios have no presets")
        return build(GridScenario, values, source, null_is_none=True)
    raise ConfigError(f"{source}: kind: expected 'landmark' or 'grid', got {kind!r}")


def _merged(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` applied; nested mappings are merged key by key."""
    out = dict(base)
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merged(out[key], value)
        else:
            out[key] = value
    return out


def load_scenario(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """The scenario of a YAML file; ``overrides`` (field -> value, nested configs as mappings
    merged into the file's) are applied before validation, so they are checked alike (an
    unknown or bad override names the file)."""
    path = Path(path)
    doc = load_yaml(path, "scenario")
    data = doc.data if doc.data is not None else {}
    if overrides:
        data, doc = _merged(data, overrides), None
    scenario = scenario_from_dict(data, str(path), doc)
    if isinstance(scenario, GridScenario) and scenario.map_file is not None:
        # a relative map path is relative to the scenario file, not to the working directory
        map_path = Path(scenario.map_file)
        if not map_path.is_absolute():
            scenario = dataclasses.replace(scenario, map_file=str((path.parent / map_path).resolve()))
    return scenario


@dataclass(frozen=True)
class SimulationResult:
    sequence: Sequence
    grid: OccupancyGrid | None
    scenario: Scenario
    seed: int


def simulate(scenario: Scenario, seed: int) -> SimulationResult:
    """Run a scenario with ``numpy.random.default_rng(seed)``; the seed goes into the metadata."""
    rng = np.random.default_rng(seed)
    try:
        if isinstance(scenario, LandmarkScenario):
            seq, grid = simulate_landmark_sequence(scenario, rng), None
        else:
            seq, grid = simulate_grid_sequence(scenario, rng)
    except SlamkitError:
        raise
    seq = dataclasses.replace(seq, metadata={**seq.metadata, "seed": int(seed)})
    return SimulationResult(seq, grid, scenario, int(seed))


@dataclass(frozen=True)
class SimulatedFile:
    """A simulation written to a sequence file: the run, where it went and its sha256."""

    scenario_path: Path
    simulation: SimulationResult
    path: Path
    sha256: str

    def summary(self) -> dict[str, Any]:
        """What ``slamkit simulate`` prints: events by type, duration, distance, landmarks."""
        seq = self.simulation.sequence
        gt = seq.ground_truth
        return {
            "scenario": str(self.scenario_path),
            "name": seq.name,
            "seed": self.simulation.seed,
            "out": str(self.path),
            "sha256": self.sha256,
            "num_events": len(seq),
            "events": dict(sorted(Counter(type(e).__name__ for e in seq).items())),
            "duration_s": float(gt.stamps_s[-1] - gt.stamps_s[0]) if gt is not None else 0.0,
            "path_length_m": gt.path_length_m() if gt is not None else 0.0,
            "num_landmarks": len(seq.world_p_landmarks or {}),
        }


def simulate_to_file(scenario_path: str | Path, seed: int, out: str | Path) -> SimulatedFile:
    """Load the scenario file, simulate it with ``seed`` and save the sequence to ``out`` (the
    slamkit sequence format; the same seed always writes the same bytes)."""
    from slamkit.data.formats.sequence import save_sequence

    result = simulate(load_scenario(scenario_path), seed)
    path = save_sequence(out, result.sequence)
    return SimulatedFile(Path(scenario_path), result, path, hashlib.sha256(path.read_bytes()).hexdigest())
