"""Experiments feed systems and estimators with data, score them and report (ARCHITECTURE.md
section 3); they hold no algorithm, simulator, loader or metric of their own.

What lives here: one module (or package) per pipeline kind, registered in
:data:`slamkit.experiments.pipeline.PIPELINES` (``pose_graph``, ``pose_graph_outliers``,
``filter_vs_smoother/``, ``closed_loop`` = ``local_planning``, ``lidar_slam``, ``visual_odometry``,
``navigation``), and the machinery they share: config validation (``config_models``; the run
folder's ``config.yaml`` is the resolved config, :func:`config_models.with_defaults`), the
estimator runner and registry (``runner``, ``estimators``), results folders (``results``),
perturbed reruns, sweeps and executors, observers, the ``slamkit plan`` function (``planning``)
and the navigation benchmark protocol. ``tests/test_layers.py`` keeps it that way.

Where the rest went (issue 30): trajectory scoring is :func:`slamkit.metrics.score_trajectory`
(one metric vocabulary, the table in :mod:`slamkit.metrics`); camera sequences on disk are
:mod:`slamkit.data.formats.image_sequence`; the stereo-VO and VIO drivers are
:mod:`slamkit.systems.stereo_vo` and :func:`slamkit.systems.visual_inertial.run_vio`; the
local-planning world (maps, obstacle sensor, clearance) is :mod:`slamkit.sim.local_planning_world`;
building an algorithm's frozen config from a validated mapping is :func:`slamkit.config.build`.
``navigation_map`` is the navigation pipeline's map source: the map SLAM builds is the system
:mod:`slamkit.systems.slam_map`, the mapping tour it is built on :func:`slamkit.sim.grid_world.mapping_tour`;
what is left scores that map against the true world (ground truth, so not a system's business)
and caches it in the results folder, and moves with the navigation pipeline into its package.
"""
