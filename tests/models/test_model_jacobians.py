"""Contract: every analytic Jacobian in slamkit.models equals a central finite difference.

One parametrised test over a registry of (function, its Jacobian(s), evaluation points).
Outputs that are angles are compared after wrapping the difference to (-pi, pi].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest

from slamkit.geometry import se3, so3
from slamkit.models import diff_drive as dd
from slamkit.models import gps
from slamkit.models import lidar
from slamkit.models import planar
from slamkit.models import range_bearing as rb
from slamkit.models import range_only as ro
from slamkit.models import strapdown
from slamkit.models.bicycle import Bicycle
from slamkit.models.camera import PinholeCamera
from slamkit.models.stereo import StereoCamera
from slamkit.models.mecanum import Mecanum
from slamkit.models.omni import Omni3
from slamkit.models.tracked import Tracked


@dataclass(frozen=True)
class Case:
    name: str
    f: Callable  # f(*args) -> (m,)
    jac: Callable  # jac(*args) -> tuple of (m, n_i) matrices, one per differentiated argument
    args: tuple  # evaluation point (1-D arrays)
    wrt: tuple  # which arguments the returned Jacobians are with respect to
    angle_outputs: tuple = ()  # output indices that are angles
    tol: float = 1e-6


def _motion_case(name, f, jac, u):
    x = np.array([0.3, -1.2, 2.9])
    return Case(name, lambda x, u: f(x, u, 0.7), lambda x, u: jac(x, u, 0.7), (x, np.asarray(u)), (0, 1), (2,))


_CAR = Bicycle(wheelbase_m=2.5, max_steer_rad=0.6)
_TANK = Tracked(track_width_m=0.5, slip_left=0.1, slip_right=0.05, icr_left_m=0.35, icr_right_m=-0.3, icr_x_m=0.05)

_CAM = PinholeCamera(458.6, 457.3, 367.2, 248.4, k1=-0.28, k2=0.074, k3=0.01, p1=2e-4, p2=-3e-4)
_STEREO = StereoCamera(700.0, 690.0, 320.0, 240.0, 0.12)
_T_CAM = se3.exp(np.array([0.5, -0.2, 1.0, 0.1, -0.3, 0.2]))
_P_WORLD = se3.transform_points(_T_CAM, np.array([0.4, -0.3, 3.0]))  # 3 m in front of the camera

# strapdown: one IMU step from a moving, tilted state with biases; the function is the 15-dim
# error (true - nominal, world-frame attitude error) after the step, as a function of the error
# dx before it and of the step's noise n = (n_a, n_g, w_ba, w_bg)
_SD_STATE = (np.array([1.0, -2.0, 0.5]), np.array([3.0, 1.0, -0.2]), so3.exp(np.array([0.2, -0.4, 1.1])),
             np.array([0.05, -0.02, 0.1]), np.array([0.003, -0.001, 0.002]))
_SD_ACC, _SD_GYR, _SD_DT, _SD_G = np.array([0.9, -0.6, 9.5]), np.array([0.7, -0.3, 0.9]), 0.01, np.array([0, 0, -9.81])


def _strapdown_error(dx, n):
    p, v, R, ba, bg = _SD_STATE
    Rt, bat, bgt = so3.exp(dx[6:9]) @ R, ba + dx[9:12], bg + dx[12:15]
    true = strapdown.propagate(p + dx[0:3], v + dx[3:6], Rt, _SD_ACC - bat - n[0:3], _SD_GYR - bgt - n[3:6],
                               _SD_DT, _SD_G)
    nominal = strapdown.propagate(p, v, R, _SD_ACC - ba, _SD_GYR - bg, _SD_DT, _SD_G)
    return np.concatenate([true[0] - nominal[0], true[1] - nominal[1], so3.log(true[2] @ nominal[2].T),
                           bat + n[6:9] - ba, bgt + n[9:12] - bg])


def _strapdown_jacobians(dx, n):
    _, _, R, ba, bg = _SD_STATE
    return (strapdown.error_transition(R, _SD_ACC - ba, _SD_GYR - bg, _SD_DT),
            strapdown.noise_jacobian(R, _SD_GYR - bg, _SD_DT))


CASES = [
    _motion_case("diff_drive.motion", dd.motion, dd.motion_jacobians, [1.3, 0.8]),
    _motion_case("diff_drive.motion(omega=1e-9)", dd.motion, dd.motion_jacobians, [1.3, 1e-9]),
    _motion_case("diff_drive.motion(omega=0)", dd.motion, dd.motion_jacobians, [-0.4, 0.0]),
    _motion_case("diff_drive.motion_straight", dd.motion_straight, dd.motion_straight_jacobians, [1.3, 0.8]),
    _motion_case("planar.motion_twist", planar.motion_twist, planar.motion_twist_jacobians, [1.3, -0.4, 0.8]),
    _motion_case("planar.motion_twist(omega=1e-9)", planar.motion_twist, planar.motion_twist_jacobians,
                 [1.3, -0.4, 1e-9]),
    _motion_case("bicycle.motion", _CAR.motion, _CAR.motion_jacobians, [2.0, 0.3]),
    _motion_case("bicycle.motion(straight)", _CAR.motion, _CAR.motion_jacobians, [2.0, 0.0]),
    _motion_case("tracked.motion", _TANK.motion, _TANK.motion_jacobians, [1.0, 0.4]),
    _motion_case("omni.motion", Omni3().motion, Omni3().motion_jacobians, [3.0, -1.0, 2.0]),
    _motion_case("mecanum.motion", Mecanum().motion, Mecanum().motion_jacobians, [3.0, -1.0, 2.0, 0.5]),
    Case("diff_drive.forward", lambda w: dd.DiffDrive(0.1, 0.2).forward(w),
         lambda w: (dd.DiffDrive(0.1, 0.2).forward_jacobian(),), (np.array([2.0, 1.0]),), (0,)),
    Case("gps.observe(lever arm)", lambda x: gps.observe(x, (0.4, -0.3)),
         lambda x: (gps.observe_jacobian(x, (0.4, -0.3)),), (np.array([1.0, 2.0, 0.7]),), (0,)),
    Case("lidar.scan_endpoints", lambda x: lidar.scan_endpoints(x, [2.0, 3.5], [0.3, -1.2], (0.2, 0.1, 0.05)).ravel(),
         lambda x: (lidar.scan_endpoints_jacobian(x, [2.0, 3.5], [0.3, -1.2], (0.2, 0.1, 0.05)).reshape(4, 3),),
         (np.array([1.0, 2.0, 0.7]),), (0,)),
    Case("camera.project", _CAM.project, lambda p: (_CAM.project_jacobian(p),), (np.array([0.4, -0.3, 2.0]),), (0,)),
    Case("camera.distort", _CAM.distort, lambda xy: (_CAM.distort_jacobian(xy),), (np.array([0.3, -0.4]),), (0,)),
    Case("camera.project_world(pose, right perturbation)",
         lambda xi: _CAM.project_world(se3.retract(_T_CAM, xi), _P_WORLD),
         lambda xi: (_CAM.project_world_jacobians(_T_CAM, _P_WORLD)[0],), (np.zeros(6),), (0,), tol=1e-4),
    Case("camera.project_world(point)", lambda p: _CAM.project_world(_T_CAM, p),
         lambda p: (_CAM.project_world_jacobians(_T_CAM, p)[1],), (_P_WORLD,), (0,), tol=1e-4),
    Case("stereo.project", _STEREO.project, lambda p: (_STEREO.project_jacobian(p),),
         (np.array([0.4, -0.3, 2.0]),), (0,), tol=1e-5),
    Case("stereo.triangulate", _STEREO.triangulate, lambda m: (_STEREO.triangulate_jacobian(m),),
         (np.array([400.0, 200.0, 30.0]),), (0,)),
    Case("range_bearing.observe", rb.observe, rb.observe_jacobians,
         (np.array([1.0, 2.0, 0.4]), np.array([-3.0, 5.0])), (0, 1), (1,)),
    Case("range_bearing.inverse_observe", rb.inverse_observe, rb.inverse_observe_jacobians,
         (np.array([1.0, 2.0, 0.4]), np.array([4.0, -2.5])), (0, 1)),
    Case("range_only.observe", lambda p, m: np.atleast_1d(ro.observe(p, m)),
         lambda p, m: tuple(J[None] for J in ro.observe_jacobians(p, m)),
         (np.array([1.0, 2.0]), np.array([-3.0, 5.0])), (0, 1)),
    Case("range_only.observe_scaled_jacobians", lambda p, m, s: s * np.atleast_1d(ro.observe(p, m)),
         lambda p, m, s: (lambda Jp, Jm, d: (Jp[None], Jm[None], np.array([[d]])))(
             *ro.observe_scaled_jacobians(p, m, s[0])),
         (np.array([1.0, 2.0]), np.array([-3.0, 5.0]), np.array([1.07])), (0, 1, 2)),
    Case("strapdown.error_transition and noise_jacobian (one IMU step)", _strapdown_error, _strapdown_jacobians,
         (np.zeros(15), np.zeros(12)), (0, 1), tol=1e-8),
]


def numerical_jacobian(f, args, i, angle_outputs, h=1e-6):
    x = np.asarray(args[i], dtype=float)
    cols = []
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx.flat[k] = h
        plus = list(args)
        minus = list(args)
        plus[i], minus[i] = x + dx, x - dx
        diff = np.asarray(f(*plus), float) - np.asarray(f(*minus), float)
        for j in angle_outputs:
            diff[..., j] = np.angle(np.exp(1j * diff[..., j]))
        cols.append(diff.reshape(-1) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_jacobian_matches_central_difference(case: Case) -> None:
    analytic = case.jac(*case.args)
    assert len(analytic) == len(case.wrt)
    for J, i in zip(analytic, case.wrt):
        numeric = numerical_jacobian(case.f, case.args, i, case.angle_outputs)
        np.testing.assert_allclose(J, numeric, atol=case.tol, err_msg=f"{case.name} wrt arg {i}")


# Every public Jacobian in slamkit.models must be exercised by a case above; a new one that is
# not listed here fails this test until a finite-difference case is added for it.
COVERED = {
    "diff_drive.motion_jacobians", "diff_drive.motion_straight_jacobians", "diff_drive.DiffDrive.forward_jacobian",
    "planar.motion_twist_jacobians", "planar.LinearWheelKinematics.motion_jacobians",
    "bicycle.Bicycle.motion_jacobians", "tracked.Tracked.motion_jacobians",
    "omni.Omni3.motion_jacobians", "mecanum.Mecanum.motion_jacobians",
    "range_bearing.observe_jacobians", "range_bearing.inverse_observe_jacobians",
    "range_only.observe_jacobians", "range_only.observe_scaled_jacobians", "gps.observe_jacobian", "lidar.scan_endpoints_jacobian",
    "camera.PinholeCamera.project_jacobian", "camera.PinholeCamera.distort_jacobian",
    "camera.PinholeCamera.project_world_jacobians",
    "stereo.StereoCamera.project_jacobian", "stereo.StereoCamera.triangulate_jacobian",
    "strapdown.noise_jacobian",
}
EXEMPT = {
    # the same broadcasting function with a shape check; compared slice by slice in test_diff_drive
    "diff_drive.motion_jacobians_batch",
}


def _public_jacobians():
    import importlib
    import inspect
    import pkgutil

    import slamkit.models as pkg

    found = set()
    for info in pkgutil.iter_modules(pkg.__path__):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"slamkit.models.{info.name}")
        for name, obj in vars(mod).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != mod.__name__:
                continue
            if callable(obj) and "jacobian" in name:
                found.add(f"{info.name}.{name}")
            if inspect.isclass(obj):
                for attr in dir(obj):
                    if "jacobian" in attr and not attr.startswith("_"):
                        found.add(f"{info.name}.{name}.{attr}")
    return found


def test_every_jacobian_has_a_finite_difference_case():
    missing = _public_jacobians() - COVERED - EXEMPT
    assert not missing, f"Jacobians without a finite-difference case: {sorted(missing)}"
