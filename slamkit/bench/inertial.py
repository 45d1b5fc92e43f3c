"""``slamkit bench inertial``: GPS-aided inertial navigation on the KITTI IMU/GPS sequence of the
gtsam wheel (registry ``kitti-imu-gps``, 468.6 s, ~100 Hz IMU, 1 Hz GPS), timed against real
time: ``ratio`` = sequence duration / wall time to feed every event to the estimator and take
its final ``estimate()`` (the runner's total time). Goals from issue 13: ES-EKF >= 500x real
time, iSAM2 with IMU factors >= 50x. The sequence is loaded once, outside the timing; quick
mode uses the first 60 s.
"""

from __future__ import annotations

from slamkit.bench.cases import BenchCase, best_of, compare


def _run(make, sequence):
    def once():
        estimator = make(sequence)
        estimator.reset()
        step = estimator.step
        for event in sequence.events:
            step(event)
        return estimator.estimate()

    return once


def run(quick: bool = False) -> list[BenchCase]:
    from slamkit.data.formats.kitti_imu_gps import load_kitti_imu_gps
    from slamkit.experiments.estimators import factory

    sequence = load_kitti_imu_gps(max_duration_s=60.0 if quick else None)
    duration_s = sequence.events[-1].stamp_s - sequence.events[0].stamp_s
    cases = []
    for name, params, goal in (("es_ekf", {}, ">= 500"), ("isam2_imu", {}, ">= 50"),
                               ("fixed_lag_imu", {"lag_s": 10.0}, None)):
        seconds, estimate = best_of(_run(factory(name, params), sequence), repeat=1 if quick else 3)
        cases.append(compare(f"{name}_kitti_{duration_s:.0f}s", seconds, "s",
                             "real time (sequence duration)", duration_s, goal,
                             events=len(sequence.events), poses=len(estimate.trajectory)))
    return cases
