"""Shared pieces of the back-end tests: the dataset table (with the MANIFEST's "gtsam local check"
anchors), slamkit loaders per format, plain-GTSAM reference solves, and a cache so each dataset
is solved once per test session."""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass
from pathlib import Path

import gtsam
import numpy as np

from slamkit.backend.solvers import OptimizeConfig, OptimizeResult, optimize
from slamkit.data.formats.g2o import read_g2o
from slamkit.data.formats.isam import read_isam
from slamkit.data.formats.toro import read_toro
from slamkit.data.pose_graph import PoseGraph

DATASETS = Path(__file__).resolve().parents[2].parent / "shared" / "datasets"

#: the settings the MANIFEST's "gtsam local check" anchors were computed with
MANIFEST_SETTINGS = dict(relative_error_tol=1e-10, absolute_error_tol=1e-10, max_iterations=1000,
                         prior_sigma=1e-6)
#: GTSAM's defaults (and slamkit's): what the tests use unless a case needs more iterations
DEFAULT_SETTINGS = dict(relative_error_tol=1e-5, absolute_error_tol=1e-5, max_iterations=100,
                        prior_sigma=1e-6)


def settings(manifest: bool) -> dict:
    return MANIFEST_SETTINGS if manifest else DEFAULT_SETTINGS


@dataclass(frozen=True)
class Case:
    file: str
    init: str = "file"
    solver: str = "lm"
    anchor_error: float | None = None      # MANIFEST gtsam local check graph.error() at optimum
    anchor_iterations: int | None = None
    anchor_F: float | None = None          # MANIFEST "SE-Sync objective F evaluated at that optimum"
    slow: bool = False
    #: solve with the MANIFEST's tolerances (needed where LM takes > 100 iterations)
    manifest_settings: bool = False
    #: odometry-only graph whose initial estimate is already optimal (error ~1e-21): iteration
    #: counts at that noise floor carry no meaning
    trivial: bool = False
    #: build raw GTSAM's problem from slamkit's parsed numbers rather than gtsam.readG2o (the
    #: bignoise case: see its comment)
    parsed_reference: bool = False

    @property
    def id(self) -> str:
        return Path(self.file).stem


CASES = [
    # 2D g2o
    Case("pose_graph_2d/intel.g2o", anchor_error=22.5021, anchor_iterations=4, anchor_F=54.5039),
    Case("pose_graph_2d/intel_g2o_943.g2o", anchor_error=273.232, anchor_iterations=4),
    # LM crawls on MITb (32 iterations at tolerance 1e-10): the default tolerances stop it where
    # F is still 1.2e-4 above the MANIFEST's value, so it is solved with the MANIFEST settings
    Case("pose_graph_2d/input_MITb_g2o.g2o", anchor_error=385.119, anchor_iterations=32,
         anchor_F=1360.85, manifest_settings=True),
    Case("pose_graph_2d/CSAIL.g2o", anchor_error=20.2754, anchor_iterations=5, anchor_F=53.4863),
    Case("pose_graph_2d/manhattan.g2o", anchor_error=1774.52, anchor_iterations=5, anchor_F=6610.21),
    Case("pose_graph_2d/input_M3500_g2o.g2o", anchor_error=68.9574, anchor_iterations=6),
    Case("pose_graph_2d/input_M3500b_g2o.g2o", anchor_error=4117.64, anchor_iterations=977, slow=True,
         manifest_settings=True),
    Case("pose_graph_2d/manhattanOlson3500.g2o", anchor_error=73.0394, anchor_iterations=6),
    Case("pose_graph_2d/city10000.g2o", anchor_error=255.994, anchor_iterations=7, anchor_F=649.359),
    Case("pose_graph_2d/ais2klinik.g2o", anchor_error=86.4065, anchor_iterations=251, anchor_F=195.069,
         slow=True, manifest_settings=True),
    Case("pose_graph_2d/ring.g2o", anchor_error=5.58155, anchor_iterations=6),
    Case("pose_graph_2d/ringCity.g2o", anchor_error=131.409, anchor_iterations=13),
    # 2D TORO
    Case("pose_graph_2d/CSAIL_P_toro.graph", anchor_error=19.5641, anchor_iterations=6),
    Case("pose_graph_2d/FR079_P_toro.graph", anchor_error=18.7859, anchor_iterations=5),
    Case("pose_graph_2d/FRH_P_toro.graph", anchor_error=9.65684e-05, anchor_iterations=3),
    # 2D KITTI
    Case("pose_graph_2d_kitti/kitti_00.g2o", anchor_error=49.1611, anchor_iterations=4),
    Case("pose_graph_2d_kitti/kitti_02.g2o", anchor_error=39.3823, anchor_iterations=5),
    Case("pose_graph_2d_kitti/kitti_05.g2o", anchor_error=78.5519, anchor_iterations=4),
    Case("pose_graph_2d_kitti/kitti_06.g2o", anchor_error=12.9735, anchor_iterations=3),
    Case("pose_graph_2d_kitti/kitti_07.g2o", anchor_error=6.33052, anchor_iterations=3),
    Case("pose_graph_2d_kitti/kitti_08.g2o", anchor_error=1.41187e-21, anchor_iterations=0,
         trivial=True),
    Case("pose_graph_2d_kitti/kitti_09.g2o", anchor_error=17.1914, anchor_iterations=4),
    # 3D
    Case("pose_graph_3d/sphere2500.g2o", anchor_error=675.701, anchor_iterations=7, anchor_F=1729.98),
    Case("pose_graph_3d/torus3D.g2o", init="chordal", anchor_error=12117.6, anchor_iterations=5,
         anchor_F=24227.0),
    Case("pose_graph_3d/parking-garage.g2o", anchor_error=0.634192, anchor_iterations=8,
         anchor_F=1.26608),
    Case("pose_graph_3d/cubicle.g2o", anchor_error=1372.78, anchor_iterations=40, anchor_F=2568.36,
         slow=True),
    # its quaternions are off unit length by up to 6.5e-7; slamkit's reader normalises them and
    # gtsam.readG2o does not. The chordal relaxation of a graph this noisy is ill-conditioned:
    # that 6.5e-7 moved the initial error by 8.6e-4 relative on the machine that wrote this case
    # and by 4.5e-3 on two later ones (1516479.0 vs readG2o's 1523364.8, issue 28), while the
    # final errors agreed to 3e-9. So the initial error is compared with GTSAM's own chordal
    # initialisation of the same parsed (normalised) measurements -- measured bit-identical,
    # checked at the default 1e-9 -- and the final error and iterations with readG2o's graph.
    Case("pose_graph_3d/sphere_bignoise_vertex3.g2o", init="chordal", anchor_error=1.49417e6,
         anchor_iterations=5, parsed_reference=True),
    Case("pose_graph_3d/smallGrid3D.g2o", init="chordal", anchor_error=517.925, anchor_iterations=7),
    Case("pose_graph_3d/tinyGrid3D.g2o", init="chordal", anchor_error=9.31391, anchor_iterations=7),
    # 3D iSAM text (no MANIFEST anchor; gtsam's own loaders misread its sqrt-information)
    Case("pose_graph_3d/sphere400.txt"),
]
CASE_BY_ID = {c.id: c for c in CASES}


@functools.lru_cache(maxsize=None)
def load(file: str) -> PoseGraph:
    path = DATASETS / file
    if path.suffix == ".g2o":
        return read_g2o(path)
    if path.suffix == ".graph":
        return read_toro(path)
    return read_isam(path)


def slamkit_solve(file: str, init: str = "file", solver: str = "lm",
                  linear_solver: str = "cholesky", manifest: bool = False) -> OptimizeResult:
    """slamkit's solve (GTSAM default or MANIFEST tolerances), cached for the session."""
    return _slamkit_solve(file, init, solver, linear_solver, manifest)


@functools.lru_cache(maxsize=None)
def _slamkit_solve(file, init, solver, linear_solver, manifest) -> OptimizeResult:
    config = OptimizeConfig(solver=solver, init=init, linear_solver=linear_solver,
                            **settings(manifest))
    return optimize(load(file), config)


def _prior(graph: gtsam.NonlinearFactorGraph, key: int, pose, sigma: float) -> None:
    if isinstance(pose, gtsam.Pose2):
        graph.add(gtsam.PriorFactorPose2(key, pose, gtsam.noiseModel.Isotropic.Sigma(3, sigma)))
    else:
        graph.add(gtsam.PriorFactorPose3(key, pose, gtsam.noiseModel.Isotropic.Sigma(6, sigma)))


def raw_problem(file: str, first_vertex: int, parsed: bool = False
                ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """The problem as a GTSAM user loads it: readG2o (g2o) or load2D with NoiseFormatTORO (TORO),
    plus the same gauge prior. iSAM files (gtsam misreads them) and ``parsed=True`` (3D only):
    the reference graph is built with plain GTSAM calls from slamkit's parsed numbers
    (information = R^T R for iSAM)."""
    path = str(DATASETS / file)
    if file.endswith(".g2o") and not parsed:
        is3d = "pose_graph_3d" in file
        graph, initial = gtsam.readG2o(path, is3d)
    elif file.endswith(".graph"):
        graph, initial = gtsam.load2D(path, None, 0, False, True, gtsam.NoiseFormat.NoiseFormatTORO)
    else:
        pg = load(file)
        graph, initial = gtsam.NonlinearFactorGraph(), gtsam.Values()
        perm = [3, 4, 5, 0, 1, 2]
        for v, p in zip(pg.vertex_ids.tolist(), pg.poses):
            initial.insert(v, gtsam.Pose3(gtsam.Rot3.Quaternion(*p[3:]), p[:3]))
        for i, j, z, info in zip(pg.edge_from.tolist(), pg.edge_to.tolist(), pg.measurements,
                                 pg.information):
            graph.add(gtsam.BetweenFactorPose3(
                i, j, gtsam.Pose3(gtsam.Rot3.Quaternion(*z[3:]), z[:3]),
                gtsam.noiseModel.Gaussian.Information(info[np.ix_(perm, perm)])))
    pose0 = initial.atPose2(first_vertex) if "pose_graph_2d" in file else initial.atPose3(first_vertex)
    _prior(graph, first_vertex, pose0, MANIFEST_SETTINGS["prior_sigma"])
    return graph, initial


def raw_solve(file: str, init: str = "file", solver: str = "lm",
              linear_solver: str = "MULTIFRONTAL_CHOLESKY", manifest: bool = False, parsed: bool = False,
              ) -> tuple[float, float, int, float]:
    """Plain GTSAM: ``(initial error, final error, iterations, seconds)``, cached; ``parsed``:
    on the graph built from slamkit's parsed numbers (see :func:`raw_problem`)."""
    return _raw_solve(file, init, solver, linear_solver, manifest, parsed)


@functools.lru_cache(maxsize=None)
def _raw_solve(file, init, solver, linear_solver, manifest, parsed) -> tuple[float, float, int, float]:
    s = settings(manifest)
    graph, initial = raw_problem(file, int(load(file).vertex_ids[0]), parsed)
    if init == "chordal":
        first = int(load(file).vertex_ids[0])
        chordal = gtsam.InitializePose3.initialize(graph)
        # InitializePose3 ignores where the prior puts the first pose; move the whole estimate
        # rigidly so it starts there (what slamkit's initialisation documents)
        correction = initial.atPose3(first).compose(chordal.atPose3(first).inverse())
        initial = gtsam.Values()
        for key in chordal.keys():
            initial.insert(key, correction.compose(chordal.atPose3(key)))
    params_cls, opt_cls = {"lm": (gtsam.LevenbergMarquardtParams, gtsam.LevenbergMarquardtOptimizer),
                           "gn": (gtsam.GaussNewtonParams, gtsam.GaussNewtonOptimizer),
                           "dogleg": (gtsam.DoglegParams, gtsam.DoglegOptimizer)}[solver]
    params = params_cls()
    params.setRelativeErrorTol(s["relative_error_tol"])
    params.setAbsoluteErrorTol(s["absolute_error_tol"])
    params.setMaxIterations(s["max_iterations"])
    params.setLinearSolverType(linear_solver)
    optimizer = opt_cls(graph, initial, params)
    t0 = time.perf_counter()
    optimizer.optimize()
    return graph.error(initial), optimizer.error(), optimizer.iterations(), time.perf_counter() - t0


def rel_close(a: float, b: float, rel: float, floor: float = 1e-12) -> bool:
    return abs(a - b) <= rel * abs(b) + floor
