"""What an inertial sequence adds to a filter-vs-smoother recording (``slamkit.viz.filter_vs_smoother``
calls :func:`log_inertial` for sequences with ``metadata["inertial"]``).

Entities (under the scenario prefix; static or time series on the ``time`` timeline):

    world/gps                        the GPS fixes the estimators saw (static)
    world/gps_withheld               the fixes withheld in outage windows (static, red)
    plots/outage                     1 inside an outage window, 0 outside (send_columns)
    plots/bias/<name>/accel_{x,y,z}  every estimator's accelerometer bias estimate (m/s^2)
    plots/bias/<name>/gyro_{x,y,z}   and gyro bias estimate (rad/s)
    plots/bias/truth/...             the simulator's true biases, when known
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import rerun as rr

from slamkit.data.sequence import Gps

TIMELINE = "time"
COLOR_GPS = (90, 90, 90)
COLOR_WITHHELD = (230, 40, 40)
BIAS_NAMES = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")
#: at most this many samples per bias curve (a 100 Hz filter over minutes is thinned)
MAX_CURVE_POINTS = 5000


def _series(stream, path: str, stamps: np.ndarray, values: np.ndarray) -> None:
    step = max(1, len(stamps) // MAX_CURVE_POINTS)
    stream.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(stamps)[::step])],
                        columns=rr.Scalars.columns(scalars=np.asarray(values)[::step]))


def log_inertial(stream, sequence, runs: Mapping[str, Any]) -> None:
    """GPS fixes, withheld fixes, outage windows and bias estimates (see the module docstring)."""
    fixes = [np.asarray(e.world_p_body, float).reshape(-1) for e in sequence.events if isinstance(e, Gps)]
    if fixes:
        stream.log("world/gps", rr.Points3D(np.array(fixes), radii=[0.15], colors=[COLOR_GPS]), static=True)
    withheld = sequence.metadata.get("withheld_gps")
    if withheld is not None and len(withheld["stamps_s"]):
        stream.log("world/gps_withheld", rr.Points3D(np.asarray(withheld["world_p_body"]), radii=[0.25],
                                                     colors=[COLOR_WITHHELD]), static=True)
        windows = np.asarray(withheld["windows_s"], dtype=float).reshape(-1, 2)
        # a step function: 0 before each window, 1 inside it
        t = np.repeat(windows.reshape(-1), 2)
        level = np.tile([0.0, 1.0, 1.0, 0.0], len(windows))
        stream.send_columns("plots/outage", indexes=[rr.TimeColumn(TIMELINE, duration=t)],
                            columns=rr.Scalars.columns(scalars=level))
    truth = sequence.metadata.get("true_imu_bias")
    if truth is not None:
        true = np.column_stack([np.asarray(truth["accel_mps2"]), np.asarray(truth["gyro_radps"])])
        for k, label in enumerate(BIAS_NAMES):
            _series(stream, f"plots/bias/truth/{label}", truth["stamps_s"], true[:, k])
    for name, run in runs.items():
        est = run.estimate
        if est is None or est.extras.get("bias") is None:
            continue
        bias = np.asarray(est.extras["bias"])
        for k, label in enumerate(BIAS_NAMES):
            _series(stream, f"plots/bias/{name}/{label}", est.extras["bias_stamps_s"], bias[:, k])
