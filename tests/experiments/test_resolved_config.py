"""A run's config.yaml is the resolved config (issue 30): every default of the pipeline's model
spelt out, the given values as validated, and the pipeline runs on that same mapping."""

from __future__ import annotations

from pathlib import Path

import yaml

from slamkit.backend.solvers import OptimizeConfig
from slamkit.config import resolved
from slamkit.experiments.config_models import runtime_config, with_defaults

from slamkit.experiments.pipeline import check_pipeline
from slamkit.experiments.pipeline import load_config, pipeline_of, run_pipeline


def test_defaults_are_filled_recursively_and_given_values_kept():
    config = {"pipeline": "local_planning", "controllers": ["dwa"], "scenarios": {"kinds": ["open"], "seeds": 2}}
    resolved = with_defaults(config, check_pipeline(dict(config)))
    assert resolved["controllers"] == ["dwa"]
    assert resolved["scenarios"] == {"kinds": ["open"], "seeds": 2, "n_obstacles": 3,
                                     "obstacle_speed_mps": [0.2, 0.5], "obstacle_min_side_m": 0.5}
    assert resolved["record"] is True and resolved["record_scenarios"] == 1
    # the closed loop's and the listed controller's every field, as the run builds them
    from slamkit.config import build, dump
    from slamkit.control.registry import controller_config
    from slamkit.experiments.closed_loop.episode import ClosedLoopConfig

    assert resolved["closed_loop"] == {k: v for k, v in dump(ClosedLoopConfig()).items() if v is not None}
    assert set(resolved["controller_params"]) == {"dwa"}
    assert controller_config("dwa", resolved["controller_params"]["dwa"]) == controller_config("dwa")
    for name in ("potential_fields", "rollout", "mpc", "mpc_osqp"):   # presets and tuple-valued fields too
        one = {"pipeline": "local_planning", "controllers": [name]}
        params = with_defaults(one, check_pipeline(dict(one)))["controller_params"][name]
        assert controller_config(name, params) == controller_config(name), name
    assert build(ClosedLoopConfig, resolved["closed_loop"]) == ClosedLoopConfig()
    assert "name" not in resolved          # a None default means "not set": left out
    assert config == {"pipeline": "local_planning", "controllers": ["dwa"],
                      "scenarios": {"kinds": ["open"], "seeds": 2}}   # the input is not modified


def test_the_run_folder_says_every_setting_and_reloads(tmp_path: Path):
    config = {"pipeline": "pose_graph", "name": "pg", "datasets": ["intel"], "options": {"max_iterations": 5},
              "record": False}
    run_pipeline(config, tmp_path / "out", progress=False)
    written = yaml.safe_load((tmp_path / "out" / "config.yaml").read_text())
    # options: every OptimizeConfig field the run does not set itself (solver, init, robust),
    # the given one as given and the others at the defaults build filled in
    options = written.pop("options")
    assert options == resolved(OptimizeConfig, {"max_iterations": 5}, exclude=("solver", "init", "robust"))
    assert options["max_iterations"] == 5 and options["relative_error_tol"] == OptimizeConfig().relative_error_tol
    assert written == {"pipeline": "pose_graph", "name": "pg", "datasets": ["intel"],
                       "record": False, "plugins": [],
                       "solvers": ["lm"], "inits": ["file"], "robust": "none", "certify": "auto"}
    written["options"] = options
    (tmp_path / "again.yaml").write_text((tmp_path / "out" / "config.yaml").read_text())
    assert load_config(tmp_path / "again.yaml") == written
    # its `plugins: []` imports nothing and leaves no search folder for worker processes (a Ray
    # sweep's workers lost their PYTHONPATH to it)
    from slamkit.naming import plugin_env

    assert str(tmp_path) not in plugin_env().get("PYTHONPATH", "")


def test_every_shipped_pipeline_runs_on_its_resolved_config_as_its_model():
    """What ``run`` receives (issue 30): the resolved config as the pipeline's typed model, with
    the values config.yaml records (a resolve() that wrote something its model refuses fails)."""
    shipped = sorted((Path(__file__).resolve().parents[2] / "pipelines").glob("*.yaml"))
    assert len(shipped) >= 10
    for path in shipped:
        config = load_config(path)
        model = check_pipeline(dict(config))
        resolved_config = with_defaults(config, model)
        typed = runtime_config(pipeline_of(config["pipeline"]).config_model, resolved_config)
        assert type(typed) is type(model), path.name
        for name in type(model).model_fields:
            if name in resolved_config:
                assert getattr(typed, name) is not None, (path.name, name)


def test_the_outlier_and_visual_odometry_sections_are_resolved_as_their_dataclasses_build_them():
    """pose_graph_outliers' ``outliers`` / ``solver`` and visual_odometry's ``vo`` sections come out
    with every field of OutlierConfig / RobustSolveConfig / VisualOdometryConfig spelt out, less
    the ones each cell sets (kind, count, backend), and build the same dataclasses again."""
    from slamkit.backend.robust import RobustSolveConfig
    from slamkit.config import build
    from slamkit.sim.outliers import OutlierConfig
    from slamkit.systems.visual_odometry import VisualOdometryConfig

    config = {"pipeline": "pose_graph_outliers", "datasets": ["intel"], "outliers": {"extent_m": 5.0},
              "solver": {"max_iterations": 7}}
    out = with_defaults(config, check_pipeline(dict(config)))
    assert out["outliers"] == {"extent_m": 5.0, "local_window": 50, "group_size": 10}
    assert out["solver"]["max_iterations"] == 7 and "backend" not in out["solver"]
    assert build(RobustSolveConfig, out["solver"]) == build(RobustSolveConfig, {"max_iterations": 7})
    assert build(OutlierConfig, out["outliers"]) == build(OutlierConfig, config["outliers"])
    vo = {"pipeline": "visual_odometry", "sequences": ["kitti-vo-a"], "vo": {"orb": {"fast_threshold": 12}}}
    out = with_defaults(vo, check_pipeline(dict(vo)))
    assert out["vo"]["orb"]["fast_threshold"] == 12 and len(out["vo"]) > 1
    assert build(VisualOdometryConfig, out["vo"]) == build(VisualOdometryConfig, vo["vo"])
