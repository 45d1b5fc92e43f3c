"""Front-end: scan matching and loop closure.

icp.py (2D point-to-point / point-to-line ICP with covariance), registration3d.py (open3d
point-to-plane and generalized ICP), preprocess.py (despeckle), keyframes.py (distance/rotation
keyframes), loop_closure.py (candidates by distance, ICP-fitness verification),
benchmark.py (``slamkit bench scan-matching``).
"""
