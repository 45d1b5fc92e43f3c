"""Filters and filter-SLAM, every one an ``Estimator`` (``reset(prior)``, ``step(event)``,
``estimate()``) fed the same ``Sequence`` as the smoothers.

One module per algorithm: ``kalman`` (KF, Joseph form, DARE steady-state gain), ``ekf``
(generic EKF, EKF localization), ``ukf`` (sigma points with circular means, UKF localization),
``histogram_filter`` (grid Bayes filter), ``particle_filter`` (log weights, resampling schemes,
PF localization), ``mcl`` (global MCL, KLD-sampling, augmented MCL), ``ekf_slam`` (O(n^2)
updates, ML association), ``fastslam`` (FastSLAM 1.0). ``registry.make_estimator(name, sequence)``
builds any of them by its config name; ``benchmark.run`` is ``slamkit bench filters``.
"""
