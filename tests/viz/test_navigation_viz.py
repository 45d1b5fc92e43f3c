"""The navigation recording, read back with the rerun CLI: the robot's map (and the true one
when they differ), costmap, particles and covariance, global path, DWA candidates or the MPC
horizon, lidar tracks with their trails, the true pose and obstacles, and a blueprint with one
2D view and one plot view per recorded episode."""

from __future__ import annotations

import os
import subprocess

import numpy as np

from slamkit.experiments.navigation import EpisodeConfig, _snapshots, make_navigation_scenario, run_episode
from slamkit.experiments.navigation.map_source import RobotMap
from slamkit.maps.occupancy_grid import OccupancyGrid
from slamkit.systems.navigation import NavigationConfig
from slamkit.viz.navigation import NavigationObserver


def test_recording_holds_what_the_blueprint_shows(tmp_path, verify_rrd, rerun_cli):
    sc = make_navigation_scenario(1, "office")
    # a robot's map that is not the world's (a SLAM map would differ the same way): one more box
    occ = sc.grid.occupied.copy()
    occ[10:14, 10:14] = True
    robot = RobotMap(OccupancyGrid(occ, sc.grid.resolution_m, sc.grid.origin_xy_m), "edited")
    path = tmp_path / "nav.rrd"
    obs = NavigationObserver(path)
    ep = EpisodeConfig(max_time_s=10.0)
    run_episode(sc, NavigationConfig(), ep, "dwa", _snapshots(obs, f"dwa/{sc.name}", sc), robot)
    # the crossing obstacles are tracked from the first scan on: a trail of one point per cycle
    # (measured: a live track 100 cycles long at 10 s; since yielding chooses where to wait the
    # robot is elsewhere by 12 s and that track has ended -- an ended track's trail drops out)
    assert max(len(t) for t in obs._track_trails.values()) >= 100
    run_episode(sc, NavigationConfig(controller="mpc_osqp"), EpisodeConfig(max_time_s=1.0), "mpc",
                _snapshots(obs, f"mpc/{sc.name}", sc))
    obs.close()
    entities = verify_rrd(path)
    for run in ("dwa", "mpc"):
        p = f"/{run}/{sc.name}"
        for e in ("world/map", "world/costmap", "world/goal", "world/ground_truth", "world/ground_truth/heading",
                  "world/estimate", "world/estimate/ellipse", "world/estimate/particles", "world/global_path",
                  "world/scan_unexplained", "world/tracks", "world/tracks/velocity", "world/tracks/trails",
                  "world/obstacles_true", "plots/localisation_error_m", "plots/sigma_xy_m", "plots/speed_mps"):
            assert f"{p}/{e}" in entities, (p, e)
    assert f"/dwa/{sc.name}/world/candidates" in entities and f"/dwa/{sc.name}/world/candidates/chosen" in entities
    assert f"/mpc/{sc.name}/world/mpc_horizon" in entities
    # the true map only where the robot's map is another
    assert f"/dwa/{sc.name}/world/map_true" in entities and f"/mpc/{sc.name}/world/map_true" not in entities
    # the blueprint: a 2D view of each episode's world/ (origin the episode, whose world/ carries
    # the y-flip: Rerun's 2D views draw y down) and two time-series views on its plots/
    # (localisation in metres, speed in m/s)
    env = dict(os.environ, RERUN_ANALYTICS="0")
    dump = subprocess.run([rerun_cli, "rrd", "print", "-vvv", str(path)], capture_output=True, text=True,
                          timeout=120, env=env).stdout
    for run in ("dwa", "mpc"):
        assert f"[{run}/{sc.name}]" in dump and f"[{run}/{sc.name}/plots]" in dump
        assert f"[{run}/{sc.name} localisation (m)]" in dump and f"[{run}/{sc.name} speed (m/s)]" in dump
    assert "[+ $origin/world/**]" in dump
    assert dump.count("[2D]") >= 2 and dump.count("[TimeSeries]") >= 4


def test_the_recorder_gets_typed_snapshots_not_the_live_stack():
    # issue 30, item 4: each step's state is a frozen NavigationSnapshot of copied, read-only
    # arrays; nothing in it is the stack, the plant or an array they go on writing
    import dataclasses

    import pytest

    from slamkit.experiments.navigation import SNAPSHOT_MAX_PARTICLES, NavigationSnapshot
    from slamkit.systems.navigation import CommandStatus, NavigationStack

    class Keep:
        wants_steps = True

        def __init__(self):
            self.snapshots = []

        def on_step(self, snapshot):
            self.snapshots.append(snapshot)

    sc = make_navigation_scenario(1, "office")
    keep = Keep()
    live = []
    hook = _snapshots(keep, f"dwa/{sc.name}", sc)

    def on_step(stack, plant, t_s, decision):
        live.append((stack, plant, stack.path))
        hook(stack, plant, t_s, decision)

    run_episode(sc, NavigationConfig(), EpisodeConfig(max_time_s=2.0), "dwa", on_step)
    assert len(keep.snapshots) == 20
    first, last = keep.snapshots[0].state, keep.snapshots[-1].state
    assert isinstance(first, NavigationSnapshot) and first.scene is last.scene
    stack, plant, _ = live[-1]
    for st in (first, last):
        for f in dataclasses.fields(st):
            value = getattr(st, f.name)
            assert not isinstance(value, NavigationStack) and value is not plant
            if isinstance(value, np.ndarray):
                assert not value.flags.writeable, f.name
        assert isinstance(st.status, CommandStatus) and st.covariance.shape == (3, 3)
        assert 0 < len(st.particles_xytheta) <= SNAPSHOT_MAX_PARTICLES
    # the last cycle's values, copied: the truth, the belief, the path, the command
    np.testing.assert_array_equal(last.true_xytheta, plant.world_xytheta_body)
    np.testing.assert_array_equal(last.estimate_xytheta, stack.current_pose()[0])
    assert last.path_xy_m is not None and not np.shares_memory(last.path_xy_m, stack.path)
    assert last.candidates_xytheta is not None and last.candidate_scores is not None
    assert first.scene.costmap_blocked.any() and first.obstacles_xy_m.shape == (len(sc.obstacles), 2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        first.status = CommandStatus.NO_GOAL


def test_the_snapshot_draws_the_episode_s_own_social_force_traffic():
    # social-force people react to the robot, so the plant runs its own copy of the scenario's
    # traffic: the true obstacles drawn are that copy's, not the template's (which walks as if
    # there were no robot)
    sc = make_navigation_scenario(1, "office", agents="social_force")
    seen = []

    class Keep:
        wants_steps = True

        def on_step(self, snapshot):
            seen.append(snapshot.state)

    hook = _snapshots(Keep(), f"dwa/{sc.name}", sc)
    plants = []

    def on_step(stack, plant, t_s, decision):
        plants.append((plant, t_s))
        hook(stack, plant, t_s, decision)

    run_episode(sc, NavigationConfig(), EpisodeConfig(max_time_s=3.0), "dwa", on_step)
    plant, t_s = plants[-1]
    np.testing.assert_array_equal(seen[-1].obstacles_xy_m, plant.obstacles.position_at(t_s))
