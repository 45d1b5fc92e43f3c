"""File formats: pose graphs (g2o, TORO, iSAM) and trajectories (TUM, KITTI).

``load_pose_graph(path, format='auto')`` reads any supported pose-graph file into a
:class:`slamkit.data.pose_graph.PoseGraph`.
"""

from slamkit.data.formats._records import connected_components
from slamkit.data.formats.g2o import read_g2o, write_g2o

__all__ = ["connected_components", "read_g2o", "write_g2o"]
