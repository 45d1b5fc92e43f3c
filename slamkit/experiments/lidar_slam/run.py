"""The ``lidar_slam`` pipeline's run: every world x seed and every log, once per robust kernel
and motion prior (and per perturbed twin), through :func:`~.slam.run_slam`; trajectories
written as TUM files."""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping

import numpy as np

from slamkit.config import build
from slamkit.data import registry
from slamkit.data.formats.tum import write_tum
from slamkit.data.perturb import perturb
from slamkit.data.sequence import Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.experiments.config_models import seed_list
from slamkit.experiments.lidar_slam.config import LidarSlamPipeline, MclCheckConfig, log_entry, slam_section_for
from slamkit.experiments.lidar_slam.mcl_check import localize_on_map
from slamkit.experiments.lidar_slam.report import _plot, report_markdown
from slamkit.experiments.lidar_slam.slam import LidarSlamResult, run_slam
from slamkit.experiments.perturbation import (perturbation_config, perturbation_indices, twin_params, twin_suffix,
                                              unperturbed)
from slamkit.experiments.pipeline import PipelineOutput
from slamkit.experiments.results import RunRecord
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.metrics.relations import read_relations
from slamkit.paths import file_in
from slamkit.sim.grid_world import simulate_grid_sequence
from slamkit.sim.scenario import scenario_from_dict, simulate
from slamkit.systems.lidar_slam import LidarSlamConfig


def _simulate(world: Mapping[str, Any], seed: int):
    data = {"kind": "grid", "encoder": None, "imu_rate_hz": None, "gps": None, **dict(world)}
    sim = simulate(scenario_from_dict(data, "lidar_slam.worlds"), seed)
    return sim


def first_seconds(sequence: Sequence, duration_s: float) -> Sequence:
    """The events of the first ``duration_s`` seconds of ``sequence`` (a slice of a log)."""
    if not sequence.events:
        return sequence
    end = sequence.events[0].stamp_s + duration_s
    return replace(sequence, events=tuple(e for e in sequence.events if e.stamp_s <= end),
                   metadata={**sequence.metadata, "duration_s": duration_s})


def _label(robust: str, prior: str) -> str:
    return f"lidar_slam/{robust}" + ("" if prior == "odometry" else f"/{prior}")


def run(config: LidarSlamPipeline, folder, progress, observer=None):
    """The ``lidar_slam`` pipeline on its validated, resolved model: every world x seed and every
    log through :func:`run_slam`, once per robust kernel (``robust_variants``) and motion prior
    (``motion_priors``); with an ``mcl`` mapping (fields of :class:`MclCheckConfig`) also global
    localization on each map built in a simulated world."""
    worlds = config.worlds
    logs = [log_entry(x if isinstance(x, str) else x.model_dump(exclude_none=True), f"lidar_slam.logs[{k}]")
            for k, x in enumerate(config.logs)]
    seeds = seed_list(config.seeds)
    slam_cfg = build(LidarSlamConfig, config.slam, "lidar_slam.slam")
    robusts = config.robust_variants or [slam_cfg.robust]
    priors = config.motion_priors or [slam_cfg.motion_prior]
    variants = [(r, p) for r in robusts for p in priors]
    slam_by_prior = {p: build(LidarSlamConfig, slam_section_for(config.slam, config.slam_by_motion_prior, p),
                              "lidar_slam.slam") for p in priors}
    n_false, false_seed = config.false_loop_closures, config.false_loop_seed
    mcl_cfg = None if not config.mcl else build(
        MclCheckConfig, config.mcl if isinstance(config.mcl, Mapping) else None, "lidar_slam.mcl")
    twins = perturbation_config(config.perturbations)
    indices = perturbation_indices(twins)
    advance = progress.task("lidar_slam", (len(worlds) * len(seeds) + len(logs)) * len(variants) * len(indices))
    runs: list[RunRecord] = []
    results: list[LidarSlamResult] = []
    for world in worlds:
        for seed in seeds:
            sim = _simulate(world, int(seed))
            seq, grid = _sim_parts(sim)
            second = None
            if mcl_cfg is not None:
                second, _ = simulate_grid_sequence(sim.scenario,
                                                   np.random.default_rng(int(seed) + mcl_cfg.seed_offset), grid=grid)
                second = trim_to_free_space(second, grid)
            for (robust, prior), twin in ((v, t) for v in variants for t in indices):
                label = _label(robust, prior)
                tag = twin_suffix(twin)
                res = run_slam(perturb(seq, twin, twins), grid, replace(slam_by_prior[prior], robust=robust),
                               observer if twin == 0 else None, n_false, false_seed,
                               label=f"{seq.name}_{robust}" + ("" if prior == "odometry" else f"_{prior}") + tag)
                if twin == 0:
                    results.append(res)
                metrics = dict(res.metrics)
                if second is not None:
                    metrics.update(localize_on_map(res, second, mcl_cfg))
                runs.append(RunRecord(seq.name, label, metrics, seed=int(seed),
                                      params={"robust": robust, "motion_prior": prior,
                                              "false_loop_closures": n_false, **twin_params(twin)}))
                stem = f"{seq.name}_s{seed}_{robust}" + ("" if prior == "odometry" else f"_{prior}") + tag
                _write_trajectory(folder, res.stamps_s, res.optimised_poses, stem)
                _write_trajectory(folder, res.stamps_s, res.frontend_poses, f"{stem}_frontend")
                advance()

    for entry in logs:
        seq = replace(registry.load_recording(entry.source, scan_topic=entry.scan_topic,
                                              odom_topic=entry.odom_topic), name=entry.name)
        if entry.duration_s is not None:
            seq = first_seconds(seq, entry.duration_s)
        relations = read_relations(entry.relations) if entry.relations else None
        for (robust, prior), twin in ((v, t) for v in variants for t in indices):
            suffix = (("" if len(robusts) == 1 else f"_{robust}") + ("" if prior == "odometry" else f"_{prior}")
                      + twin_suffix(twin))
            # a twin is scored, not drawn: only the log as given builds its maps (for the plots)
            res = run_slam(perturb(seq, twin, twins), None, replace(slam_by_prior[prior], robust=robust),
                           observer if twin == 0 else None, relations=relations, label=f"{entry.name}{suffix}",
                           build_maps=twin == 0)
            if twin == 0:
                results.append(res)
            runs.append(RunRecord(entry.name, _label(robust, prior), dict(res.metrics),
                                  params={"robust": robust, "motion_prior": prior, "source": entry.source,
                                          "relations": entry.relations or "", **twin_params(twin)}))
            _write_trajectory(folder, res.scan_stamps_s, res.scan_poses, f"{entry.name}{suffix}")
            advance()
    _plot(folder.plots, results)
    # the tables show the data as given; the runner adds the perturbation table beside them
    report = report_markdown(config, [r for r in unperturbed(runs) if r.seed is not None],
                             [r for r in unperturbed(runs) if r.seed is None])
    # the runner hands this output (``payload``: the LidarSlamResult list) to observer.on_output
    return PipelineOutput(runs, report, payload=results)


def _sim_parts(sim):
    seq = getattr(sim, "sequence", None)
    grid = getattr(sim, "grid", None)
    if seq is None:
        seq, grid = sim
    return trim_to_free_space(seq, grid), grid


def trim_to_free_space(sequence: Sequence, grid: OccupancyGrid | None) -> Sequence:
    """Drop the events from the first ground-truth pose that is not in free space of ``grid``
    on (a robot driving through a wall or off the map is a simulator fault, not something a
    SLAM front-end should be scored on); the sequence is returned unchanged when it stays free.
    The number of dropped seconds is recorded in ``metadata['trimmed_s']``."""
    gt = sequence.ground_truth
    if gt is None or grid is None:
        return sequence
    bad = np.flatnonzero(~grid.is_free_world(gt.world_t_body[:, :2]))
    if len(bad) == 0:
        return sequence
    end_s = float(gt.stamps_s[bad[0]])
    keep = np.flatnonzero(gt.stamps_s < end_s)
    meta = dict(sequence.metadata)
    meta["trimmed_s"] = float(gt.stamps_s[-1] - end_s)
    return Sequence(sequence.name, tuple(e for e in sequence.events if e.stamp_s < end_s),
                    gt.subset(keep), sequence.world_p_landmarks, sequence.initial_world_xytheta_body, meta)


def _write_trajectory(folder, stamps_s: np.ndarray, poses: np.ndarray, stem: str) -> None:
    """``poses`` at ``stamps_s`` as a TUM file, in stamp order (a log processed in the order it
    was taken has late stamps: slamkit.data.formats.carmen)."""
    order = np.argsort(stamps_s, kind="stable")
    write_tum(file_in(folder.trajectories, stem, ".tum", "run name"),
              Trajectory.from_se2(np.asarray(stamps_s)[order], np.asarray(poses)[order]))
