"""Running robot components composed from the algorithm packages (ARCHITECTURE.md section 3):
streaming objects (``step(event)``, ``estimate()``) configured by one dataclass, with observer
hooks, that know nothing of ground truth, files, scoring or reports.

:class:`~slamkit.systems.lidar_slam.LidarSlam` (lidar_slam.py): 2D lidar SLAM (scan-to-submap
ICP, keyframes, loop closure, iSAM2 and a final batch solve, log-odds map)."""
