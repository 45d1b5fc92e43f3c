"""3D point-cloud registration through open3d: point-to-plane ICP and generalized ICP.

* Point-to-plane: Chen & Medioni, "Object modelling by registration of multiple range images",
  IVC 10(3), 1992 (``open3d.pipelines.registration.TransformationEstimationPointToPlane``;
  target normals estimated by PCA of a hybrid radius/k-nearest neighbourhood).
* Generalized ICP: Segal, Haehnel & Thrun, "Generalized-ICP", RSS 2009 -- plane-to-plane,
  each point modelled as a Gaussian flattened along its local surface
  (``TransformationEstimationForGeneralizedICP``).

Both return the transform ``target_T_source`` (4, 4), open3d's fitness (fraction of source
points with a correspondence within ``max_correspondence_m``), inlier RMSE, and the 6x6
information matrix of the constraint from ``get_information_matrix_from_point_clouds`` (Choi,
Zhou & Koltun, "Robust reconstruction of indoor scenes", CVPR 2015) -- in open3d's order
(rx, ry, rz, x, y, z), converted here to slamkit's PoseGraph order (x, y, z, rx, ry, rz).
Points are batch-first (N, 3) numpy arrays; the open3d objects stay inside this module.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from slamkit.errors import ConfigError, DataError

reg = o3d.pipelines.registration
METHODS_3D = ("point_to_plane", "gicp", "point_to_point")


@dataclass(frozen=True)
class Registration3dConfig:
    method: str = "point_to_plane"
    max_correspondence_m: float = 0.5
    max_iterations: int = 50
    relative_fitness: float = 1e-9
    relative_rmse: float = 1e-9
    normal_radius_m: float = 0.5
    normal_neighbours: int = 30

    def __post_init__(self) -> None:
        if self.method not in METHODS_3D:
            raise ConfigError(f"Registration3dConfig.method must be one of {METHODS_3D}, got {self.method!r}")
        if not self.max_correspondence_m > 0:
            raise ConfigError("Registration3dConfig.max_correspondence_m must be > 0")


@dataclass(frozen=True)
class Registration3dResult:
    target_T_source: np.ndarray
    fitness: float
    inlier_rmse_m: float
    num_correspondences: int
    information: np.ndarray


def _cloud(points: np.ndarray, name: str) -> o3d.geometry.PointCloud:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise DataError(f"{name} points must have shape (N, 3), got {p.shape}")
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) < 10:
        raise DataError(f"{name} needs at least 10 finite points, got {len(p)}")
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))


#: open3d's information is ordered (rx, ry, rz, x, y, z); PoseGraph 3D uses (x, y, z, rx, ry, rz)
_O3D_TO_POSEGRAPH = np.array([3, 4, 5, 0, 1, 2])


def register(source_xyz: np.ndarray, target_xyz: np.ndarray, initial_target_T_source: np.ndarray | None = None,
             config: Registration3dConfig = Registration3dConfig()) -> Registration3dResult:
    """Align ``source_xyz`` (N, 3) to ``target_xyz`` (M, 3) from the initial 4x4 guess."""
    src, tgt = _cloud(source_xyz, "source"), _cloud(target_xyz, "target")
    init = np.eye(4) if initial_target_T_source is None else np.asarray(initial_target_T_source, float)
    search = o3d.geometry.KDTreeSearchParamHybrid(radius=config.normal_radius_m, max_nn=config.normal_neighbours)
    criteria = reg.ICPConvergenceCriteria(relative_fitness=config.relative_fitness,
                                          relative_rmse=config.relative_rmse,
                                          max_iteration=config.max_iterations)
    if config.method == "point_to_plane":
        tgt.estimate_normals(search)
        result = reg.registration_icp(src, tgt, config.max_correspondence_m, init,
                                      reg.TransformationEstimationPointToPlane(), criteria)
    elif config.method == "gicp":
        # per-point covariances are left to open3d, which regularises them with its epsilon
        # (Segal et al.'s (1, 1, eps) plane model); our own estimate on noise-free planes is
        # exactly singular and makes the solve return NaN
        result = reg.registration_generalized_icp(src, tgt, config.max_correspondence_m, init,
                                                  reg.TransformationEstimationForGeneralizedICP(), criteria)
    else:
        result = reg.registration_icp(src, tgt, config.max_correspondence_m, init,
                                      reg.TransformationEstimationPointToPoint(), criteria)
    T = np.asarray(result.transformation).copy()
    info = np.asarray(reg.get_information_matrix_from_point_clouds(src, tgt, config.max_correspondence_m, T))
    info = info[np.ix_(_O3D_TO_POSEGRAPH, _O3D_TO_POSEGRAPH)]
    return Registration3dResult(T, float(result.fitness), float(result.inlier_rmse),
                                int(len(result.correspondence_set)), info)
