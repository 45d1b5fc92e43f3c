"""Running robot components composed from the algorithm packages (ARCHITECTURE.md section 3):
streaming objects (``step(event)``, ``estimate()``) configured by one dataclass, with observer
hooks, that know nothing of ground truth, files, scoring or reports.

:class:`~slamkit.systems.lidar_slam.LidarSlam` (lidar_slam.py): 2D lidar SLAM (scan-to-submap
ICP, keyframes, loop closure, iSAM2 and a final batch solve, log-odds map);
:class:`~slamkit.systems.visual_odometry.VisualOdometry` (visual_odometry.py): monocular VO
(ORB or KLT front-end, 5-point RANSAC, PnP, sliding-window bundle adjustment);
:class:`~slamkit.systems.visual_inertial.VisualInertialOdometry` (visual_inertial.py):
visual-inertial odometry (static initialisation, IMU preintegration and smart projection
factors in iSAM2, zero-velocity updates);
:class:`~slamkit.systems.navigation.NavigationStack` (navigation/, a package): MCL, tracked
obstacles, global and local planning, with one module per responsibility (``stack``,
``global_planning``, ``yielding``, ``safety``, ``goal``, ``recovery``; the table in its
docstring)."""
