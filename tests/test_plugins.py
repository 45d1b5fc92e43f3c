"""Plug-ins (issue 32 item 1): a real package, ``tests/plugins/slamkit_example_plugin``, installed
with pip into a temporary folder, its entries found through ``importlib.metadata`` entry points
(no monkeypatching), the registry contracts run over them, and ``slamkit run`` of a
filter_vs_smoother config that names its estimator."""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from slamkit.data import registry as datasets
from slamkit.errors import ConfigError
from slamkit.experiments import estimators
from slamkit.naming import PLUGINS_ENV
from slamkit.planning import registry as planners

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "tests" / "plugins" / "slamkit_example_plugin"
SLAMKIT = Path(sys.executable).with_name("slamkit")


def _forget_plugin() -> None:
    from slamkit.control.registry import CONTROLLERS
    from slamkit.experiments.pipeline import PIPELINES

    for name, table in (("odometry_only", estimators.REGISTRY), ("straight_line", planners.PLANNERS),
                        ("pure_pursuit", CONTROLLERS), ("odometry_drift", PIPELINES)):
        if name in table:
            table.unregister(name)
    if "example-square" in datasets.REGISTRY:
        datasets.unregister_dataset("example-square")
    sys.modules.pop("slamkit_example_plugin", None)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The plug-in installed by pip into a fresh folder on sys.path, discovered by every registry
    through its entry points; removed from this process afterwards."""
    target = tmp_path_factory.mktemp("site")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index", "--target",
                    str(target), str(PLUGIN)], check=True, capture_output=True, timeout=300)
    assert (target / "slamkit_example_plugin-0.1.0.dist-info" / "entry_points.txt").is_file()
    sys.path.insert(0, str(target))
    importlib.invalidate_caches()
    try:
        from slamkit.control.registry import CONTROLLERS
        from slamkit.experiments.pipeline import PIPELINES

        for table in (estimators.REGISTRY, planners.PLANNERS, CONTROLLERS, PIPELINES):
            table.discover(refresh=True)
        datasets.discover(refresh=True)
        yield target
    finally:
        sys.path.remove(str(target))
        _forget_plugin()


def test_entry_points_register_one_entry_per_kind(site):
    spec = estimators.spec("odometry_only")
    assert (spec.kind, spec.estimates, spec.needs_landmark_map) == ("filter", "pose", False)
    assert not estimators.is_builtin_filter("odometry_only")
    assert "straight_line" in planners.planner_names()
    from slamkit.control.registry import CONTROLLERS
    from slamkit.experiments.pipeline import PIPELINES

    assert "pure_pursuit" in CONTROLLERS and "odometry_drift" in PIPELINES
    # the dataset naming rule: '_' and '-' alike, case ignored
    assert datasets.get("Example_Square").name == "example-square"
    # a second discovery (the package found twice) registers nothing twice
    estimators.REGISTRY.discover(refresh=True)
    assert list(estimators.REGISTRY).count("odometry_only") == 1


def test_planner_contract_holds_for_the_plugin_planner(site):
    # the registry contract tests themselves, called with the plug-in's name
    contract = _contract_module("planning", "test_planner_contract")
    contract.test_start_equal_to_goal_is_solved_at_cost_zero("straight_line")
    contract.test_goal_inside_an_obstacle_is_a_status_not_an_exception("straight_line")
    # a worked example: 8 m along the free bottom row of the contract grid
    from slamkit.planning.protocols import PlanningProblem, PlanStatus

    result = planners.make_planner("straight_line").plan(
        PlanningProblem(contract._grid(), np.array([1.0, 1.0]), np.array([9.0, 1.0])))
    assert result.status is PlanStatus.SOLVED and result.cost == pytest.approx(8.0, abs=1e-12)
    blocked = planners.make_planner("straight_line").plan(
        PlanningProblem(contract._grid(), np.array([2.0, 5.0]), np.array([8.0, 5.0])))  # wall at x = 5.0-5.2
    assert blocked.status is PlanStatus.TIMEOUT and len(blocked.path) == 0


def _contract_module(folder: str, name: str):
    """A contract test module of the suite, imported to call its tests with a plug-in's name."""
    sys.path.insert(0, str(ROOT / "tests" / folder))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.pop(0)


def test_controller_contract_holds_for_the_plugin_controller(site):
    from slamkit.control.protocols import ControlStatus, LocalWorld, Reference, RobotState
    from slamkit.control.registry import make_controller

    contract = _contract_module("control", "test_controller_contract")
    for test in (contract.test_is_a_controller_and_explains_its_command, contract.test_goal_reached_stops,
                 contract.test_deterministic_after_reset, contract.test_never_raises_in_a_crowded_world):
        test(make_controller("pure_pursuit"))
    # a worked example: 0.5 m look-ahead to (0.5, 0.5) from the origin heading +x: curvature
    # 2 y / d^2 = 2 * 0.5 / 0.5 = 2 1/m, so omega = 2 v; at 0.6 m/s that is 1.2 rad/s (inside 1.5)
    out = make_controller("pure_pursuit", {"lookahead_m": 0.5}).compute(
        RobotState([0.0, 0.0, 0.0]), Reference([[0.0, 0.0], [0.5, 0.5], [0.5, 3.0]], speed_mps=0.6), LocalWorld())
    assert out.status is ControlStatus.OK
    np.testing.assert_allclose(out.command, [0.6, 1.2], atol=1e-12)


def test_pipeline_contract_holds_for_the_plugin_pipeline(site, tmp_path):
    """The pipeline registry's contract (name, config model, payload type) and a run through
    ``run_pipeline`` whose number is the closed form: a heading bias b over L metres ends
    (sin(bL)/b, (1 - cos(bL))/b) away from (L, 0)."""
    from slamkit.experiments.config_models import PipelineConfig
    from slamkit.experiments.pipeline import check_pipeline
    from slamkit.experiments.pipeline import pipeline_of, run_pipeline

    p = pipeline_of("odometry_drift")
    assert p.name == "odometry_drift" and issubclass(p.config_model, PipelineConfig)
    assert p.config_model.model_fields["pipeline"].annotation.__args__ == ("odometry_drift",)
    assert p.payload_type is dict and callable(p.run)
    with pytest.raises(ConfigError, match=r"distanc_m: unknown key"):
        check_pipeline({"pipeline": "odometry_drift", "distanc_m": 3.0})
    result = run_pipeline({"pipeline": "odometry_drift", "distance_m": 20.0, "heading_bias_radpm": 0.02},
                          tmp_path / "drift", progress=False)
    b, length = 0.02, 20.0
    expected = np.hypot(np.sin(b * length) / b - length, (1 - np.cos(b * length)) / b)
    # by hand: sin(0.4)/0.02 = 19.4709, (1 - cos 0.4)/0.02 = 3.9470 -> hypot(0.5291, 3.9470) = 3.9823
    assert expected == pytest.approx(3.9823, abs=1e-4)
    assert result.results["runs"][0]["metrics"]["final_position_error_m"] == pytest.approx(expected, rel=1e-12)


def test_estimator_table_contract_over_every_entry(site):
    """Every row (built in or plug-in) names a loadable class, a config dataclass whose fields
    the config check reads, and a legal kind/estimates pair."""
    import dataclasses

    for name, spec in estimators.REGISTRY.items():
        assert spec.name == name and spec.kind in estimators.KINDS and spec.estimates in estimators.ESTIMATES
        assert not (spec.needs_landmark_map and spec.estimates == "pose_and_map"), name
        if estimators.is_available(name):
            cls = estimators.config_class(name)
            assert cls is None or dataclasses.is_dataclass(cls), name


def test_plugin_dataset_loads_and_solves_to_the_square(site):
    from slamkit.backend.solvers import optimize
    from slamkit.data.registry import load_pose_graph_entry

    graph = load_pose_graph_entry(datasets.get("example_square"))
    assert (graph.num_poses, graph.num_edges) == (4, 4) and graph.edge_to[-1] == 0  # the loop closure
    # four exact 2 m legs turning 90 degrees: the optimum is the square itself, chi2 0
    result = optimize(graph)
    expected = np.array([[0, 0, 0], [2, 0, np.pi / 2], [2, 2, np.pi], [0, 2, -np.pi / 2]])
    error = result.poses - expected
    error[:, 2] = (error[:, 2] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(error).max() < 1e-6 and result.chi2 < 1e-9


def test_a_spec_takes_the_classes_themselves(site):
    """A one-file plug-in may write ``target=MyFilter, config=MyFilterConfig``: stored as names."""
    import slamkit_example_plugin as plugin

    spec = estimators.EstimatorSpec("odometry_only_2", "filter", plugin.OdometryOnly, False, plugin.OdometryOnlyConfig,
                                    False, "the example again", estimates="pose")
    assert (spec.target, spec.config) == ("slamkit_example_plugin:OdometryOnly", "OdometryOnlyConfig")
    estimators.register_estimator(spec)
    try:
        from slamkit.sim.landmark_world import mildly_nonlinear, simulate_landmark_sequence

        sequence = simulate_landmark_sequence(mildly_nonlinear(duration_s=2.0), np.random.default_rng(0))
        built = estimators.factory("odometry_only_2", {"covariance_scale": 2.0})(sequence)
        assert isinstance(built, plugin.OdometryOnly) and built.config.covariance_scale == 2.0
    finally:
        estimators.REGISTRY.unregister("odometry_only_2")
    with pytest.raises(ConfigError, match=r"config class NoiseParams must be defined in the estimator's module"):
        from slamkit.data.noise import NoiseParams

        estimators.EstimatorSpec("x", "filter", plugin.OdometryOnly, False, NoiseParams, False, "")


def test_bad_plugins_are_config_errors_naming_the_module(tmp_path):
    from slamkit.naming import import_plugins

    with pytest.raises(ConfigError, match=r"--plugin: plug-in module 'no_such_plugin_module' cannot be imported"):
        import_plugins(["no_such_plugin_module"], "--plugin")
    with pytest.raises(ConfigError, match=r"must be one of pose, pose_and_map"):
        estimators.EstimatorSpec("x", "filter", "m:C", False, None, False, "", estimates="map")
    with pytest.raises(ConfigError, match=r"'ekf' is already registered"):
        estimators.register_estimator(estimators.EstimatorSpec("ekf", "filter", "m:C", False, None, False, ""))


def _dead_reckoning_ate_m(seed: int) -> float:
    """The ATE the plug-in should score, computed here without the plug-in or the runner: the
    pipeline's sequence for ``seed``, its odometry integrated with the exact-arc model from the
    runner's prior, one pose per distinct stamp, SE(2)-aligned to the ground truth."""
    from slamkit.data.noise import prior_of
    from slamkit.data.sequence import Odometry
    from slamkit.data.trajectory import Trajectory
    from slamkit.experiments.filter_vs_smoother.config import ScenarioSpec
    from slamkit.experiments.filter_vs_smoother.monte_carlo import build_sequence
    from slamkit.metrics.ate import ate_rmse_m
    from slamkit.models.diff_drive import motion

    sequence = build_sequence(ScenarioSpec("mild", preset="mild", params={"duration_s": 20.0, "num_landmarks": 25}),
                              seed)
    x = np.asarray(prior_of(sequence).world_xytheta_body, float)
    poses: dict[float, np.ndarray] = {}
    for event in sequence:
        if isinstance(event, Odometry):
            x = motion(x, np.array([event.v_mps, event.omega_radps]), event.dt_s)
        poses[float(event.stamp_s)] = x
    est = Trajectory.from_se2(np.array(list(poses)), np.array(list(poses.values())))
    return ate_rmse_m(sequence.ground_truth, est, "se2")


# the plugins: path costs another ~15 s run (a worker is spawned): under slow
@pytest.mark.parametrize("how", ["entry_point", pytest.param("plugins_key", marks=pytest.mark.slow)])
def test_slamkit_run_reports_the_plugin_estimator_under_pose_only(site, tmp_path, how, verify_rrd):
    """The user's paths: the package installed (its folder on PYTHONPATH, found by its entry
    points), or the bare module on PYTHONPATH (no distribution metadata) named in the config's
    ``plugins:``; then one line in the config and ``slamkit run``. Seed 1 runs in a spawned worker,
    which finds the plug-in by itself (entry points, or the module passed down in $SLAMKIT_PLUGINS)."""
    config = {"pipeline": "filter_vs_smoother", "name": "plugin_check",
              "scenarios": [{"preset": "mild", "params": {"duration_s": 20.0, "num_landmarks": 25}}],
              "estimators": ["ekf", "odometry_only", "ekf_slam"], "seeds": 2, "workers": 2, "record": True}
    path = site if how == "entry_point" else PLUGIN / "src"
    if how == "plugins_key":
        config["plugins"] = ["slamkit_example_plugin"]
    (tmp_path / "fvs.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(path), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    env.pop(PLUGINS_ENV, None)
    done = subprocess.run([str(SLAMKIT), "run", str(tmp_path / "fvs.yaml"), "--out", str(tmp_path / "run"), "--quiet"],
                          capture_output=True, text=True, timeout=600, env=env)
    assert done.returncode == 0, done.stderr
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    runs = {(r["estimator"], r["seed"]): r for r in results["runs"]}
    assert {e for e, _ in runs} == {"ekf", "odometry_only", "ekf_slam"}
    settings = {e: runs[(e, 0)]["params"]["setting"] for e in ("ekf", "odometry_only", "ekf_slam")}
    assert settings == {"ekf": "localisation", "odometry_only": "pose_only", "ekf_slam": "slam"}
    for seed in (0, 1):
        ate_m = runs[("odometry_only", seed)]["metrics"]["ate_rmse_m"]
        # the same number as dead reckoning computed independently (measured 0.0656 m, 0.0628 m)
        assert ate_m == pytest.approx(_dead_reckoning_ate_m(seed), rel=1e-9)
        # odometry alone drifts: about 6x the landmark filters' error (measured 0.010 / 0.011 m)
        assert ate_m > 3 * max(runs[("ekf", seed)]["metrics"]["ate_rmse_m"],
                               runs[("ekf_slam", seed)]["metrics"]["ate_rmse_m"])
    # report.md files it under its own heading, between localisation and SLAM, in every table
    report = (tmp_path / "run" / "report.md").read_text()
    metrics = report.split("## Metrics", 1)[1].split("\n## ", 1)[0]
    localisation, rest = metrics.split("### Pose only (no map given or estimated)")
    pose_only, slam = rest.split("### SLAM (map estimated)")
    assert "| odometry_only |" in pose_only and "odometry_only" not in localisation + slam
    assert "| ekf |" in localisation and "| ekf_slam |" in slam
    assert (tmp_path / "run" / "trajectories" / "mild_odometry_only_seed1.tum").is_file()
    # and the recording draws it like the built-in estimators
    entities = verify_rrd(tmp_path / "run" / "recording.rrd")
    assert {"/mild/world/estimate/odometry_only", "/mild/plots/error/odometry_only",
            "/mild/world/estimate/ekf_slam"} <= entities


def test_config_plugins_key_imports_the_module(site, tmp_path, monkeypatch):
    """``plugins: [module]`` (or ``--plugin``): a module that is not an installed distribution
    registers its entries on import; the config check sees them, a missing one names file and line."""
    from slamkit.experiments.pipeline import load_config

    from slamkit import naming

    # what this process imported is passed to the workers it starts: a fresh list for this test
    monkeypatch.setattr(naming, "_PLUGIN_MODULES", [])
    monkeypatch.setattr(naming, "_PLUGIN_DIRS", [])
    path = tmp_path / "fvs.yaml"
    path.write_text("pipeline: filter_vs_smoother\nplugins: [slamkit_example_plugin]\nscenarios: [mild]\n"
                    "estimators: [odometry_only]\n")
    assert load_config(path)["plugins"] == ["slamkit_example_plugin"]
    path.write_text("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators: [ekf]\n"
                    "plugins:\n  - slamkit_no_such_plugin\n")
    with pytest.raises(ConfigError, match=rf"{path}:4: plugins: plug-in module 'slamkit_no_such_plugin' "
                                          "cannot be imported"):
        load_config(path)
    assert naming.plugin_env()[PLUGINS_ENV] == "slamkit_example_plugin"
    assert PLUGINS_ENV not in os.environ  # set for an executor's workers only, never process-wide
    from slamkit.experiments.executors import LocalExecutor

    with LocalExecutor(1) as ex:  # the workers import the plug-in before their first lookup
        ex.submit(os.getenv, PLUGINS_ENV)
        assert [value for _, value in ex.as_completed()] == ["slamkit_example_plugin"]
    assert PLUGINS_ENV not in os.environ


def test_run_plugin_option_names_a_missing_module(tmp_path):
    from typer.testing import CliRunner

    from slamkit.cli import app

    (tmp_path / "c.yaml").write_text("pipeline: filter_vs_smoother\nscenarios: [mild]\nestimators: [ekf]\n")
    result = CliRunner().invoke(app, ["run", str(tmp_path / "c.yaml"), "--plugin", "slamkit_no_such_plugin"])
    assert result.exit_code == 2
    assert "--plugin: plug-in module 'slamkit_no_such_plugin' cannot be imported" in result.output


def test_record_true_without_an_observer_factory_says_so(tmp_path):
    """Driven from Python with record: true and no observer factory, no recording can be written:
    a warning says so and how to get one (it used to be silent; issue 32)."""
    from slamkit.experiments.pipeline import run_pipeline

    config = {"pipeline": "filter_vs_smoother", "scenarios": [{"preset": "mild", "params": {"duration_s": 3.0}}],
              "estimators": ["ekf"], "seeds": 1, "workers": 1, "record": True}
    with pytest.warns(UserWarning, match=r"record: true, but run_pipeline was given no observer_factory.*"
                                         r"observer_factory=slamkit.viz.pipelines.observer_for"):
        result = run_pipeline(config, tmp_path / "run", progress=False)
    assert not (result.out_dir / "recording.rrd").exists()


def test_a_broken_plugin_names_its_entry_point_and_package(tmp_path):
    """An installed distribution whose entry point cannot be loaded, or names the wrong kind of
    object, is a ConfigError naming the entry point, its group and its package."""
    from slamkit.control.registry import CONTROLLERS

    info = tmp_path / "broken_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[slamkit.planners]\nbroken = slamkit_no_such_module:SPEC\n\n"
                                           "[slamkit.controllers]\nwrong = json:dumps\n")
    sys.path.insert(0, str(tmp_path))
    importlib.invalidate_caches()
    try:
        with pytest.raises(ConfigError, match=r"entry point 'broken' = 'slamkit_no_such_module:SPEC' \(group "
                                              r"'slamkit.planners', package 'broken-plugin'\): cannot be loaded "
                                              r"\(ModuleNotFoundError"):
            planners.PLANNERS.discover(refresh=True)
        with pytest.raises(ConfigError, match=r"entry point 'wrong' .*a controller entry point names a "
                                              r"ControllerSpec \(slamkit.control.registry\), got function"):
            CONTROLLERS.discover(refresh=True)
    finally:
        sys.path.remove(str(tmp_path))
        importlib.invalidate_caches()
    planners.PLANNERS.discover(refresh=True)  # without the broken package: fine again
    CONTROLLERS.discover(refresh=True)
