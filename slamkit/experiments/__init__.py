"""Experiments feed systems and estimators with data, score them and report (ARCHITECTURE.md
section 3); they hold no algorithm, simulator, loader or metric of their own.

What lives here: one package per pipeline kind, registered in
:data:`slamkit.experiments.pipeline.PIPELINES` (``pose_graph/``, ``pose_graph_outliers/``,
``filter_vs_smoother/``, ``closed_loop/`` = ``local_planning``, ``lidar_slam/``,
``visual_odometry/``, ``navigation/``), each running on its validated config model, and the
machinery they share: config validation (``config_models``; the run folder's ``config.yaml`` is
the resolved config, :func:`config_models.with_defaults`, and ``run`` receives it as the model,
:func:`config_models.runtime_config`), the estimator runner and registry (``runner``,
``estimators``), results folders (``results``), perturbed reruns, sweeps and executors,
observers, the ``slamkit plan`` function (``planning``). ``tests/test_layers.py`` keeps it that
way.

Where the rest went (issue 30): trajectory scoring is :func:`slamkit.metrics.score_trajectory`
(one metric vocabulary, the table in :mod:`slamkit.metrics`); camera sequences on disk are
:mod:`slamkit.data.formats.image_sequence`; the stereo-VO and VIO drivers are
:mod:`slamkit.systems.stereo_vo` and :func:`slamkit.systems.visual_inertial.run_vio`; the
local-planning world (maps, obstacle sensor, clearance) is :mod:`slamkit.sim.local_planning_world`;
building an algorithm's frozen config from a validated mapping is :func:`slamkit.config.build`;
the navigation pipeline's map source (``navigation/map_source.py``) scores against the true world
the map the system :mod:`slamkit.systems.slam_map` builds on a tour the simulator drives
(:func:`slamkit.sim.grid_world.mapping_tour`) and caches it in the results folder.
"""
