"""Seeded perturbations of a Sequence that cannot change what a good algorithm concludes.

A figure that flips when the log starts one scan later, or when a range moves by a micrometre,
is a knife edge, not a result (issue 28: Intel lidar-only measured 0.026 m on one machine and
0.999 m on another, from the last bits of floating-point sums). :func:`perturb` makes such
twins of a sequence on purpose, so a pipeline can rerun each dataset on them and report the
median and the worst of every metric beside the unperturbed run
(``slamkit.experiments.perturbation``).

Kinds (``PERTURBATION_KINDS``), applied together for perturbation ``index`` = 1, 2, ...:

* ``start_offset``: the sequence starts ``index`` steps of its densest stream later (a laser
  log's scans, a landmark world's odometry; :func:`start_later`): every event before that step
  in the sequence's order is dropped, odometry ending at the new start included (it brought the
  robot there).
  The ground truth keeps its poses from there on, and the initial pose moves to the truth at the
  new start (or, without truth, to the odometry integrated up to it).
* ``range_jitter``: every range (scan beams, range-bearing and range-only ranges) moves by
  ``N(0, range_jitter_m^2)``, 1e-6 m by default -- three orders below any lidar's resolution.
* ``event_order``: events that share a time stamp are shuffled among themselves (a recording
  does not say which of two simultaneous messages came first).

Perturbation 0 is the sequence itself. Everything is drawn from ``np.random.default_rng((seed,
index))``: the same (seed, index) gives the same twin on every machine.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from slamkit.data.sequence import Gps, Odometry, Range, RangeBearing, Scan, Sequence
from slamkit.errors import ConfigError
from slamkit.models import diff_drive

PERTURBATION_KINDS = ("start_offset", "range_jitter", "event_order")

#: at most this many twins per dataset (each is a whole rerun)
MAX_TWINS = 100
#: the largest range jitter (m) a twin may have
MAX_RANGE_JITTER_M = 1e-3

#: the kinds a start offset may count in steps, in the order that breaks a tie in frequency
_STEP_KINDS = (Scan, RangeBearing, Range, Gps, Odometry)


@dataclass(frozen=True)
class PerturbationConfig:
    """``count`` perturbed reruns of every dataset (0: none), each applying all of ``kinds``."""

    count: int = 0
    kinds: tuple[str, ...] = ("start_offset", "range_jitter")
    range_jitter_m: float = 1e-6
    seed: int = 0

    def __post_init__(self) -> None:
        unknown = sorted(set(self.kinds) - set(PERTURBATION_KINDS))
        if unknown:
            raise ConfigError(f"perturbations.kinds: unknown {unknown}; known: {list(PERTURBATION_KINDS)}")
        if not 0 <= self.count <= MAX_TWINS:
            raise ConfigError(f"perturbations.count: must lie in [0, {MAX_TWINS}], got {self.count}")
        # a twin must not change what a good algorithm concludes: jitter far below any range sensor
        if not (np.isfinite(self.range_jitter_m) and 0 <= self.range_jitter_m <= MAX_RANGE_JITTER_M):
            raise ConfigError(f"perturbations.range_jitter_m: must lie in [0, {MAX_RANGE_JITTER_M}] m, got "
                              f"{self.range_jitter_m}")
        if self.seed < 0:
            raise ConfigError(f"perturbations.seed: must be >= 0, got {self.seed}")


def perturb(sequence: Sequence, index: int, config: PerturbationConfig) -> Sequence:
    """Perturbation ``index`` of ``sequence`` (0: ``sequence`` itself); see the module docstring."""
    if index == 0:
        return sequence
    rng = np.random.default_rng((int(config.seed), int(index)))
    out = sequence
    if "start_offset" in config.kinds:
        out = start_later(out, index)
    if "range_jitter" in config.kinds and config.range_jitter_m > 0:
        out = jitter_ranges(out, config.range_jitter_m, rng)
    if "event_order" in config.kinds:
        out = shuffle_simultaneous(out, rng)
    meta = dict(out.metadata)
    meta["perturbation"] = {"index": int(index), "kinds": list(config.kinds), "seed": int(config.seed),
                            "range_jitter_m": float(config.range_jitter_m)}
    return replace(out, metadata=meta)


def start_later(sequence: Sequence, steps: int) -> Sequence:
    """``sequence`` from its ``steps``-th step on (0 keeps it whole): a step is an event of the
    sequence's most frequent kind (ties go to a measurement: scans, range-bearing, range, GPS;
    then odometry), so the start moves by a sampling period of its densest stream -- a landmark
    world's 10 Hz odometry, not its 0.5 Hz sightings (starting 5 of those later would cut 10 s of
    a 20 s run, which is no longer a small change)."""
    counts = {kind: sum(isinstance(e, kind) for e in sequence.events) for kind in _STEP_KINDS}
    kind = max(_STEP_KINDS, key=lambda k: counts[k])
    if counts[kind] == 0 or steps <= 0:
        return sequence
    at = [k for k, e in enumerate(sequence.events) if isinstance(e, kind)]
    if steps >= len(at):
        raise ConfigError(f"perturbations: cannot start {steps} {kind.__name__} events later: "
                          f"{sequence.name!r} has {len(at)}")
    # by position, not stamp (a log in the order it was taken may have late stamps). Odometry
    # stamped t covers the motion up to t and comes before what was measured at t: a cut at a
    # measurement drops the odometry that brought the robot there, a cut at an odometry step
    # drops that step too (the new start is where it ended)
    last = at[steps - 1] if kind is Odometry else at[steps]
    first = last + 1 if kind is Odometry else last
    start_s = sequence.events[last].stamp_s
    dropped, events = sequence.events[:first], sequence.events[first:]
    truth, initial = sequence.ground_truth, sequence.initial_world_xytheta_body
    if truth is not None:
        keep = np.flatnonzero(truth.stamps_s >= start_s - 1e-9)
        if len(keep):
            truth = truth.subset(keep)
            if initial is not None and np.size(initial) == 3:
                initial = truth.xytheta()[0]
    elif initial is not None and np.size(initial) == 3:
        pose = np.asarray(initial, float).reshape(3)
        for ev in dropped:
            if isinstance(ev, Odometry):
                pose = np.asarray(diff_drive.motion(pose, np.array([ev.v_mps, ev.omega_radps]), ev.dt_s))
        initial = pose
    return replace(sequence, events=tuple(events), ground_truth=truth, initial_world_xytheta_body=initial)


def jitter_ranges(sequence: Sequence, sigma_m: float, rng: np.random.Generator) -> Sequence:
    """Every range of ``sequence`` plus ``N(0, sigma_m^2)`` (NaN beams stay NaN)."""
    events = []
    for ev in sequence.events:
        if isinstance(ev, (Scan, RangeBearing, Range)):
            r = np.asarray(ev.range_m if not isinstance(ev, Scan) else ev.ranges_m, float)
            moved = r + rng.normal(0.0, sigma_m, r.shape)
            ev = replace(ev, ranges_m=moved) if isinstance(ev, Scan) else replace(ev, range_m=moved)
        events.append(ev)
    return replace(sequence, events=tuple(events))


def shuffle_simultaneous(sequence: Sequence, rng: np.random.Generator) -> Sequence:
    """Events that share a stamp in a random order among themselves (time order kept)."""
    events = list(sequence.events)
    stamps = np.array([e.stamp_s for e in events])
    if len(stamps) < 2:
        return sequence
    starts = np.flatnonzero(np.r_[True, np.diff(stamps) != 0])
    ends = np.r_[starts[1:], len(events)]
    out: list = []
    for a, b in zip(starts.tolist(), ends.tolist()):
        group = events[a:b]
        out.extend(group[k] for k in (rng.permutation(len(group)) if len(group) > 1 else [0]))
    return replace(sequence, events=tuple(out))
