"""Factor-graph back-end: the only slamkit package that imports gtsam.

Pose graphs: :func:`build_graph` (graph.py) -> :func:`initial_values` (initialisation.py) ->
:func:`optimize` with an :class:`OptimizeConfig` (solvers.py; LM, GN, dog-leg, iSAM2 replay,
QR fallback, marginals) -> :class:`OptimizeResult`; :func:`sesync_objective` (objective.py)
scores any solution in SE-Sync's objective. ``slamkit bench pose-graph`` lives in benchmark.py.

Landmark SLAM smoothers (landmark_slam.py), Estimator-protocol objects fed a Sequence:
:class:`BatchLandmarkSLAM` (``batch``, also ``solve(sequence)``), :class:`Isam2LandmarkSLAM`
(``isam2``) and :class:`FixedLagLandmarkSLAM` (``fixed_lag``), configured by
:class:`BatchLandmarkSLAMConfig`, :class:`Isam2LandmarkSLAMConfig` and
:class:`FixedLagLandmarkSLAMConfig` (shared fields in :class:`LandmarkSmootherConfig`); their noise
is :class:`slamkit.data.noise.NoiseParams`, as the filters'.
"""

from slamkit.backend.graph import build_graph
from slamkit.backend.initialisation import InitialEstimate, initial_values
from slamkit.backend.landmark_slam import (BatchLandmarkSLAM, BatchLandmarkSLAMConfig,
                                           FixedLagLandmarkSLAM, FixedLagLandmarkSLAMConfig,
                                           Isam2LandmarkSLAM, Isam2LandmarkSLAMConfig,
                                           LandmarkSmootherConfig)
from slamkit.backend.objective import sesync_objective, sesync_weights
from slamkit.backend.isam2 import Isam2Params, Isam2PoseGraph
from slamkit.backend.solvers import OptimizeConfig, OptimizeResult, optimize

__all__ = ["build_graph", "initial_values", "InitialEstimate", "optimize", "OptimizeConfig",
           "OptimizeResult", "Isam2Params", "Isam2PoseGraph", "sesync_objective", "sesync_weights", "BatchLandmarkSLAM",
           "BatchLandmarkSLAMConfig", "Isam2LandmarkSLAM", "Isam2LandmarkSLAMConfig",
           "FixedLagLandmarkSLAM", "FixedLagLandmarkSLAMConfig", "LandmarkSmootherConfig"]
