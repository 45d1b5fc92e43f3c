"""The runner: one ``Sequence`` feeds every configured estimator, and the scorer that turns each
estimate into the metrics of ARCHITECTURE.md section 6.

``run_estimators`` gives every online estimator (filters, iSAM2, fixed-lag) every event in time
order and times each ``step`` with ``time.perf_counter``; batch estimators ``solve`` the whole
sequence once and are timed in total. Observers that set ``wants_steps`` receive a
:class:`~slamkit.experiments.observers.StepSnapshot` every ``step_every`` events (default 10);
without such an observer the loop does nothing but step and time, so measured latencies are
the estimators' own.

``score`` compares an estimate with a reference trajectory (ground truth, or the batch solution
for datasets without it). Planar and 3D estimates are scored alike; the pose dimension d comes
from the estimate (:func:`pose_dof`: 3 for a planar trajectory, 6 otherwise):

* ``ate_rmse_m``, ``ate_rot_rmse_rad``: absolute trajectory error after an SE(2) (planar) or
  SE(3) Umeyama alignment (Sturm et al. IROS 2012; Zhang & Scaramuzza IROS 2018);
* ``rpe_rmse_m``: relative pose error over 1 m of travelled path;
* ``nees_mean``, ``nees_in_band_fraction``: pose NEES e^T P^-1 e (d dof) with the *unaligned*
  world-frame error of :func:`world_pose_error` -- the prior fixes the frame, and the covariance
  describes exactly that error -- and the fraction of steps inside the single-sample
  chi-square(d) 95% band (about 0.95 when consistent; Bar-Shalom, Li & Kirubarajan 2001,
  sec. 5.4). Filters are scored with the filtered covariance of every step, smoothers with their
  final marginals;
* ``nees_degenerate_fraction``: the fraction of steps whose covariance is not positive definite;
  they have no NEES and are left out of ``nees_mean`` (see ``metrics.consistency.nees_or_nan``);
* ``nis_mean``: mean normalised innovation squared per measurement (filters that record it);
* ``landmark_rmse_m``: RMS landmark position error after a Umeyama alignment (SE(2), or SE(3)
  for 3D estimates) of the estimated landmarks onto the true ones (SLAM estimators;
  localisation filters are handed the true map and have none);
* ``final_position_error_m``, ``final_heading_error_deg``: the unaligned world-frame error of
  the last scored pose (where a run ends up: the prior fixes the frame);
* ``step_latency_median_ms``, ``step_latency_p99_ms`` (online estimators), ``total_time_s``.

Architecture note (issue 18): the runner serves every pipeline that feeds estimators; the
calling pipeline names itself in ``run_estimators(kind=...)``, and nothing here assumes a planar
pose.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from slamkit.data.estimate import (BatchEstimator, Estimate, Estimator, LatestBelief, ParticleBelief,
                                   Prior)
from slamkit.data.sequence import RangeBearing, Sequence
from slamkit.data.trajectory import Trajectory
from slamkit.errors import DataError, SlamkitError
from slamkit.experiments.estimators import EstimatorFactory, prior_of
from slamkit.experiments.observers import BeliefSnapshot, PipelineObserver, StepSnapshot
from slamkit.geometry import so3
from slamkit.geometry.angles import wrap_angle
from slamkit.metrics.alignment import associate, umeyama
from slamkit.metrics.consistency import chi2_band, nees_or_nan
from slamkit.metrics.trajectory_score import score_trajectory

#: RPE segment length (m of travelled path)
RPE_DELTA_M = 1.0
#: at most this many particles go into a snapshot (drawing 10^4 points per step helps nobody)
SNAPSHOT_MAX_PARTICLES = 500


@dataclass(frozen=True)
class EstimatorRun:
    """One estimator on one sequence: its estimate and what it cost.

    ``step_latency_s`` holds the wall time of every ``step`` (online) or the single ``solve``
    (batch); ``failed`` holds the error message when the estimator raised a SlamkitError."""

    name: str
    kind: str
    estimate: Estimate | None
    step_latency_s: np.ndarray
    total_time_s: float
    failed: str | None = None

    @property
    def online(self) -> bool:
        return self.kind != "batch"


def _kind_of(factory: Callable, estimator: Any) -> str:
    """A registry factory says what it builds; a plain callable (a notebook's lambda) is judged
    by the protocol its estimator satisfies."""
    if isinstance(factory, EstimatorFactory):
        return factory.kind
    return "batch" if isinstance(estimator, BatchEstimator) and not isinstance(estimator, Estimator) else "filter"


def belief_snapshot(name: str, estimator: Any, event: Any) -> BeliefSnapshot:
    """What an observer may draw after ``event``: pose, covariance, landmarks, particles and the
    observation just processed (for association lines). Estimators with ``latest_estimate``
    (:class:`~slamkit.data.estimate.LatestBelief`) are asked only for their newest pose."""
    est = estimator.latest_estimate() if isinstance(estimator, LatestBelief) else estimator.estimate()
    traj = est.trajectory
    covariance = None
    if est.pose_covariances is not None and len(est.pose_covariances):
        covariance = np.asarray(est.pose_covariances[-1])
    fields: dict[str, Any] = {}
    if est.world_p_landmarks:
        ids = np.array(sorted(est.world_p_landmarks), dtype=np.int64)
        dim = 2 if traj.planar else 3
        fields["landmark_ids"] = ids
        fields["world_p_landmarks"] = np.array([np.asarray(est.world_p_landmarks[i]).reshape(-1)[:dim]
                                                for i in ids])
    particles = estimator.particles if isinstance(estimator, ParticleBelief) else None
    if isinstance(particles, np.ndarray) and particles.ndim == 2 and particles.shape[1] >= 3:
        step = max(1, len(particles) // SNAPSHOT_MAX_PARTICLES)
        fields["particles"] = particles[::step, :3].copy()
    return BeliefSnapshot(name, traj.subset(slice(len(traj) - 1, None)), covariance,
                          observation=event if isinstance(event, RangeBearing) else None, **fields)


def run_estimators(sequence: Sequence, estimators: Mapping[str, Callable[[Sequence], Any]],
                   prior: Prior | None = None, observer: PipelineObserver | None = None,
                   kind: str = "estimators", run_label: str | None = None
                   ) -> dict[str, EstimatorRun]:
    """Feed ``sequence`` to every estimator built by ``estimators`` (name -> factory, see
    ``slamkit.experiments.estimators.factory``); returns name -> :class:`EstimatorRun`.

    ``prior`` defaults to ``estimators.prior_of(sequence)``. ``observer.on_step`` is called only
    when ``observer.wants_steps`` is true, every ``observer.step_every`` events (and after the
    last), with ``StepSnapshot(kind, "<run_label>/<name>", k, stamp, BeliefSnapshot)``; ``kind``
    is the calling pipeline's name (``"estimators"`` when called directly)."""
    prior = prior_of(sequence) if prior is None else prior
    wants = observer is not None and observer.wants_steps
    every = max(1, observer.step_every) if wants else 0
    label = run_label or sequence.name
    events = sequence.events
    out: dict[str, EstimatorRun] = {}
    for name, make in estimators.items():
        estimator = make(sequence)
        run_kind = _kind_of(make, estimator)
        t_start = time.perf_counter()
        try:
            if run_kind == "batch":
                estimate = estimator.solve(sequence)
                total = time.perf_counter() - t_start
                latency = np.array([total])
            else:
                latency = np.empty(len(events))
                estimator.reset(prior)
                step = estimator.step
                clock = time.perf_counter
                if not wants:
                    for k, event in enumerate(events):
                        t0 = clock()
                        step(event)
                        latency[k] = clock() - t0
                else:
                    for k, event in enumerate(events):
                        t0 = clock()
                        step(event)
                        latency[k] = clock() - t0
                        if k % every == 0 or k == len(events) - 1:
                            observer.on_step(StepSnapshot(kind, f"{label}/{name}", k,
                                                          float(event.stamp_s),
                                                          belief_snapshot(name, estimator, event)))
                estimate = estimator.estimate()
                total = time.perf_counter() - t_start
        except (SlamkitError, np.linalg.LinAlgError) as exc:
            out[name] = EstimatorRun(name, run_kind, None, np.zeros(0),
                                     time.perf_counter() - t_start, failed=f"{type(exc).__name__}: {exc}")
            continue
        out[name] = EstimatorRun(name, run_kind, estimate, latency, total)
    return out


# --------------------------------------------------------------------------------------------
# scoring


@dataclass(frozen=True)
class ErrorSeries:
    """Per-pose errors of one estimate against its reference, in the world frame and unaligned:
    ``error`` (N, d) from :func:`world_pose_error` (x, y, theta for planar poses; x, y, z,
    rx, ry, rz for 3D ones), ``sigma`` (N, d) the estimator's standard deviations, ``nees`` (N,)
    the pose NEES (NaN where undefined)."""

    stamps_s: np.ndarray
    error: np.ndarray
    sigma: np.ndarray | None = None
    nees: np.ndarray | None = None

    @property
    def dof(self) -> int:
        """The pose dimension d (3 planar, 6 in 3D): the NEES's chi-square degrees of freedom."""
        return int(self.error.shape[1])

    @property
    def position_error_m(self) -> np.ndarray:
        """(N,) norm of the position part of the error."""
        return np.linalg.norm(self.error[:, :2 if self.dof == 3 else 3], axis=1)


@dataclass(frozen=True)
class Scored:
    metrics: dict[str, float]
    series: ErrorSeries | None = None
    notes: tuple[str, ...] = field(default=())


def pose_dof(trajectory: Trajectory) -> int:
    """The pose dimension of a trajectory: 3 (x, y, theta) when planar, else 6."""
    return 3 if trajectory.planar else 6


def world_pose_error(reference: Trajectory, estimate: Trajectory) -> np.ndarray:
    """The unaligned world-frame error of paired poses, the convention every estimator's
    covariance is reported in: (N, 3) estimate - reference in (x, y, theta), heading wrapped,
    for planar estimates; (N, 6) for 3D ones, translation first as in :mod:`slamkit.geometry.se3`:
    (x, y, z) = estimate - reference and (rx, ry, rz) = log(R_est R_ref^T), the rotation error
    as a world-frame (left) perturbation."""
    if estimate.planar:
        err = estimate.xytheta() - reference.xytheta()
        err[:, 2] = wrap_angle(err[:, 2])
        return err
    R_ref = so3.from_quat_wxyz(reference.world_q_body_wxyz)
    R_est = so3.from_quat_wxyz(estimate.world_q_body_wxyz)
    rot = so3.log(R_est @ np.swapaxes(R_ref, -1, -2))
    return np.column_stack([estimate.world_t_body - reference.world_t_body, rot])


def world_pose_covariances(estimate: Estimate) -> np.ndarray | None:
    """The estimate's (N, d, d) pose covariances (d = :func:`pose_dof`), or None when it has
    none of that shape.

    Every estimator reports them in the world convention of :func:`world_pose_error`; the GTSAM
    smoothers rotate their body-frame marginals themselves, with
    :func:`slamkit.geometry.se2.covariance_body_to_world` (the one place that conversion lives)."""
    P = estimate.pose_covariances
    if P is None:
        return None
    P = np.asarray(P, dtype=float)
    d = pose_dof(estimate.trajectory)
    if P.shape[-2:] != (d, d):
        return None
    return P


def landmark_rmse_m(estimated: Mapping[int, np.ndarray], truth: Mapping[int, np.ndarray],
                    dim: int = 2) -> float:
    """RMS error over the landmarks both maps contain after the Umeyama fit (SE(2) for
    ``dim`` 2, SE(3) for 3) of the estimated positions onto the true ones (NaN with fewer than
    ``dim`` common landmarks)."""
    common = sorted(set(int(k) for k in estimated) & set(int(k) for k in truth))
    if len(common) < dim:
        return float("nan")
    est = np.array([np.asarray(estimated[k], dtype=float).reshape(-1)[:dim] for k in common])
    ref = np.array([np.asarray(truth[k], dtype=float).reshape(-1)[:dim] for k in common])
    try:
        R, t, _ = umeyama(est, ref)
    except DataError:
        return float("nan")
    return float(np.sqrt(np.mean(np.sum((est @ R.T + t - ref) ** 2, axis=1))))


def score(run: EstimatorRun, reference: Trajectory | None,
          world_p_landmarks: Mapping[int, np.ndarray] | None = None,
          reference_is_truth: bool = True, max_diff_s: float = 1e-6) -> Scored:
    """The metrics of one run (see the module docstring); NEES only against ground truth."""
    metrics: dict[str, float] = {"total_time_s": float(run.total_time_s)}
    if run.online and len(run.step_latency_s):
        metrics["step_latency_median_ms"] = float(np.median(run.step_latency_s) * 1e3)
        metrics["step_latency_p99_ms"] = float(np.percentile(run.step_latency_s, 99) * 1e3)
    if run.estimate is None:
        return Scored(metrics, notes=(f"{run.name} failed: {run.failed}",))
    est = run.estimate
    planar = est.trajectory.planar
    notes: list[str] = []
    if est.nis is not None and len(est.nis):
        nis = np.asarray(est.nis, dtype=float)
        ok = np.isfinite(nis) & (nis >= 0)
        if ok.any():
            metrics["nis_mean"] = float(np.mean(nis[ok]))
        if not ok.all():
            metrics["nis_degenerate_fraction"] = float(1.0 - ok.mean())
    if "rejected_ranges" in est.extras:
        # range-only estimators: how many ranges the shared range gate rejected
        metrics["rejected_ranges"] = float(est.extras["rejected_ranges"])
    if "range_scale" in est.extras:
        # range-only estimators that estimated the ranges' unknown scale (no ground truth used)
        metrics["range_scale"] = float(est.extras["range_scale"])
    if world_p_landmarks and est.world_p_landmarks:
        metrics["landmark_rmse_m"] = landmark_rmse_m(est.world_p_landmarks, world_p_landmarks,
                                                     2 if planar else 3)
    if reference is None:
        return Scored(metrics, notes=tuple(notes))
    try:
        pairs = associate(reference, est.trajectory, max_diff_s=max_diff_s)
    except DataError as exc:
        return Scored(metrics, notes=(f"{run.name}: {exc}",))
    scores = score_trajectory(pairs.ref, pairs.est, "se2" if planar else "se3", rpe_delta=RPE_DELTA_M,
                              rpe_delta_unit="m", rpe_pairs_from_reference=True)
    metrics["ate_rmse_m"] = scores["ate_rmse_m"]
    metrics["ate_rot_rmse_rad"] = scores["ate_rot_rmse_rad"]
    if "rpe_rmse_m" in scores:
        metrics["rpe_rmse_m"] = scores["rpe_rmse_m"]
    else:
        notes.append(f"{run.name}: path shorter than {RPE_DELTA_M} m, no RPE")
    err = world_pose_error(pairs.ref, pairs.est)
    dof = err.shape[1]
    metrics["final_position_error_m"] = float(np.linalg.norm(err[-1, :2 if dof == 3 else 3]))
    metrics["final_heading_error_deg"] = float(np.degrees(abs(err[-1, 2]) if dof == 3
                                                          else np.linalg.norm(err[-1, 3:])))
    sigma = nees = None
    P = world_pose_covariances(est)
    if P is not None and len(P) == len(est.trajectory):
        P = P[pairs.est_index]
        sigma = np.sqrt(np.clip(np.diagonal(P, axis1=1, axis2=2), 0.0, None))
        if reference_is_truth:
            # no NEES where the covariance is not positive definite: counted, never averaged
            nees = nees_or_nan(err, P)
            finite = np.isfinite(nees)
            metrics["nees_degenerate_fraction"] = float(1.0 - finite.mean()) if len(nees) else 0.0
            if finite.any():
                band = chi2_band(err.shape[1], 1, 0.95)
                v = nees[finite]
                metrics["nees_mean"] = float(np.mean(v))
                metrics["nees_in_band_fraction"] = float(np.mean((v >= band.lower) & (v <= band.upper)))
    series = ErrorSeries(pairs.ref.stamps_s, err, sigma, nees)
    return Scored(metrics, series, tuple(notes))


def monte_carlo_nees(series: list[ErrorSeries], p: float = 0.95
                     ) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """Average NEES over M runs at every common step (Bar-Shalom et al. sec. 5.4.2): returns
    (stamps, ANEES (K,), band) with the two-sided ``p`` band of chi2(d M) / M (d: the pose
    dimension of the series, which must agree)."""
    usable = [s for s in series if s.nees is not None]
    if not usable:
        raise DataError("no run has a NEES series")
    dofs = {s.dof for s in usable}
    if len(dofs) != 1:
        raise DataError(f"NEES series of different pose dimensions {sorted(dofs)} cannot be averaged")
    n = min(len(s.nees) for s in usable)
    stack = np.stack([s.nees[:n] for s in usable])
    band = chi2_band(dofs.pop(), len(usable), p)
    return usable[0].stamps_s[:n], np.nanmean(stack, axis=0), (band.lower, band.upper)
