"""Yielding to crossing traffic (:class:`Yielding`, configured by :class:`YieldingConfig`, the
``yielding`` section of :class:`~slamkit.systems.navigation.NavigationConfig`): a moving track's
predicted sweep meets the path ahead about when the robot would get there, so the robot's
command is capped at the speed that stops it where it can wait -- it waits rather than races
(:meth:`Yielding.decision`). A track the tracker has seen reversing (a shuttler) is not trusted
to keep going: its sweep is hedged (``reversed_hedge``, the reachable-set prediction of
:class:`LocalWorld`), so the robot does not cross right behind it (``span_shuttle`` would also
predict it shuttling along the span it was seen on: measured, and off). The robot waits only
outside every track's predicted sweep and seen span (the next shuttler's line is no place to
stop); standing inside one, it goes on when it gets clear in time, or backs off along the way it
came (its ``trail``, :meth:`record_trail`; :meth:`back_off_place`, :meth:`back_off_aim`,
:meth:`drive_to`).
With ``speed_plan`` the crossing is decided by a speed plan along the path against the
predicted sweeps instead (:meth:`Yielding.planned_speed`), the rules above deciding only where
no plan keeps clear.

The prediction of the tracks is the stack's (:meth:`NavigationStack.local_world`, with this
section's hedges); the stack applies the cap (:mod:`.stack`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from slamkit.control.path_following import arc_length_m, point_at, project_on_path
from slamkit.errors import ConfigError
from slamkit.estimation.obstacle_tracker import Tracks
from slamkit.geometry.angles import wrap_angle
from slamkit.geometry.segments import point_segment_distance
from slamkit.planning.speed_profile import plan_speed_along_path

if TYPE_CHECKING:
    from slamkit.systems.navigation.stack import NavigationStack


@dataclass(frozen=True)
class YieldingConfig:
    #: a moving track whose constant-velocity sweep over ``horizon_s`` covers the path
    #: ``lookahead_m`` ahead within ``slack_s`` of when the robot (at cruise speed) would be there
    #: makes the robot stop short of the crossing (decelerating at ``decel_mps2``) and wait until
    #: it has passed
    horizon_s: float = 6.0
    lookahead_m: float = 3.0
    slack_s: float = 2.0
    decel_mps2: float = 0.5
    #: the hedge (lam of :class:`LocalWorld`, see ``NavigationConfig.prediction_hedge``) of
    #: yielding's sweep of a track seen reversing (the others' sweeps stay constant-velocity).
    #: Measured on pipelines/navigation.yaml's 30 x 3 seeds (success office/warehouse/Willow,
    #: moving collisions; no static ones): all 0 (main) .900/.933/.867, 2/1/3; yielding 0.3:
    #: .967/.900/.900, 0/2/1 (crossing behind a shuttler waits until its trailing edge, moving at
    #: 0.4 v, has cleared: office 19/24, Willow 10/17 reached; +1.5-3 s, +0.14-0.19 m on the seeds
    #: both reach); 0.5: .933/.900/.900, 1/1/2 and a static hit; 1.0: office 3 moving + 5
    #: timeouts (a reachable set between two shuttlers never clears)
    reversed_hedge: float = 0.3
    #: yielding's hedge for a track not (yet) seen reversing (issue 33: on fresh seeds the robot
    #: crossed close behind shuttlers the tracker had not seen turn, just before they turned back).
    #: Measured 0.3 with back_off_along_trail, paired with off on warehouse seeds 400-429 (never
    #: developed on): successes 26 -> 29, moving hits 4 -> 0 (McNemar exact p 0.125 on the hits,
    #: 0.375 on success; 1 seed lost, 4 gained), mean time of the successes 35.1 -> 37.5 s;
    #: warehouse dev seeds 0-29 30 -> 30. Off until office / Willow / social-force agree; yielding's
    #: worked-example tests are computed for the constant-velocity sweep
    hedge: float = 0.0
    #: yielding also predicts a track seen reversing as a shuttler: along its seen span at its
    #: typical speed, turning at the span's ends (:func:`shuttle_centres`), beside the hedged
    #: constant-velocity guess (a span end may not be a turning point yet). Measured and off:
    #: over the 30 x 3 seeds with the waiting places below, success .967/.867/.800, moving
    #: collisions 0/1/2 (off: .967/.900/.900, 0/1/1) -- a short, fast shuttler's return leaves
    #: no crossing window 2 s wide (warehouse 5, Willow 14/15 waited to the 90 s limit). Again on
    #: development seeds 3000-3089 (270 runs, paired with off: successes / moving / static /
    #: timeouts): 232 / 23 / 3 / 12 against 245 / 21 / 3 / 1; with the stack's wall turns
    #: (``NavigationConfig.wall_turn_horizon_s``, where the rest are) 228 / 11 / 3 / 28
    span_shuttle: bool = False
    #: where yielding waits: outside every moving track's predicted sweep and its seen span, each
    #: grown by the track's radius, ``moving_margin_m``, the robot radius and this margin; a robot
    #: standing inside one backs off along the way it came (free when it drove it) up to
    #: ``back_off_m``, at up to ``back_off_speed_mps``, to the nearest such place
    #: (:meth:`Yielding.decision`). Measured over pipelines/navigation.yaml's 30 x 3
    #: seeds (success / static / moving collisions): before .967/0/0, .900/0/2, .900/0/1; with
    #: waiting places .967/0/0, .900/0/1, .900/0/1 (warehouse 5/29 and Willow 19 no longer hit,
    #: warehouse 6 and Willow 10 are; +0.3 / +2.3 / +0.7 s and +0.9 / +1.1 / +0.3 m on the seeds
    #: both reach)
    wait_margin_m: float = 0.05
    #: a robot inside a sweep or span leaves forwards when it passes each point of the way to the
    #: next waiting place at least this long before or after the sweep covers it
    escape_slack_s: float = 0.5
    #: the sweep a waiting place keeps out of is the first ``wait_horizon_s`` of the prediction
    #: (a tracked velocity's noise, 0.1-0.2 m/s sideways, over the whole yield horizon would
    #: sweep a metre wide; the robot re-chooses every cycle)
    wait_horizon_s: float = 3.0
    back_off_m: float = 2.0
    back_off_speed_mps: float = 0.3
    #: the back-off retraces the robot's trail (steering 0.25 m back along it) rather than
    #: driving straight at its place (:meth:`Yielding.back_off_aim`)
    back_off_along_trail: bool = False
    #: yielding gives way to a track slowed below ``blocking_speed_mps`` whose typical speed is
    #: above it (a shuttler at its turn), predicted by the reachable set of the speed it lost
    #: (:meth:`NavigationStack.local_world`, ``turning``). Without it a shuttler braking to turn
    #: drops out of yielding while its filtered speed passes 0, and the robot, released, drives
    #: into its lane as it comes back (issue 33, warehouse development seed 412: released at
    #: 18.9 s, the shuttler under 0.15 m/s at 19.2-19.4 s, hit at 19.8 s). Measured on development
    #: seeds 400-429 (constant-velocity traffic), paired with off: moving hits office 1 -> 3,
    #: warehouse 4 -> 0, Willow 2 -> 2 (7 -> 5 of 90), failures 8 -> 8; the new office hits are
    #: other mechanisms (backing off at 0.3 m/s from a 0.48 m/s shuttler, a head-on approach).
    #: On the first evaluation block of then (seeds 1000-1029 per world; development seeds since the
    #: blocks moved to 5000-5089), paired with
    #: off: moving hits 4 -> 2 of 90 (office 1 -> 0, warehouse 3 -> 1, Willow 0 -> 1), successes
    #: 86 -> 88, McNemar exact p 0.625 (3 pairs one way, 1 the other); on office's second and
    #: third blocks (35 of 60 seeds run) 4 moving hits against off's 3 in all 60. No evidence that
    #: it helps where the robot was not developed: off. With the ramped evasion
    #: (``safety.evasion``, where the figures of both are) 9 moving hits in the 270 evaluation runs
    #: against the defaults' 12, 257 successes against 255: off, still no evidence.
    turning: bool = False
    #: the crossing decision as a speed plan along the path (issue 33): instead of the
    #: +-``slack_s`` gate at cruise speed, the fastest way along the stretch ahead, at any speed
    #: up to cruise changing by at most ``decel_mps2``, that keeps ``plan_slack_s`` before or after
    #: every predicted sweep (:meth:`sweep`) and stands still only at waiting places
    #: (:func:`~slamkit.planning.speed_profile.plan_speed_along_path`); its next speed caps the
    #: command. Where no such plan exists the gate's rules (wait, leave, back off) decide.
    #: Why: with turns predicted (``span_shuttle`` and the stack's ``wall_turn_horizon_s``) the gate
    #: halved the moving hits but found no window to cross in (timeouts 1 -> 28 of 270). Measured on
    #: development seeds 3000-3089 x 3 worlds, paired with the defaults' 245 / 21 / 3 / 1
    #: (successes / moving / static / timeouts), all with both turn predictions and
    #: ``reversed_hedge`` 0 (a hedge growing with the look-ahead covers the whole future: no plan):
    #: ``plan_margin_m`` None 243 / 11 / 1 / 15 (hits 16 removed, 6 new, sign test p 0.05; Willow
    #: 12 timeouts: a track walking beside the path inside the 0.25 m margin blocks the robot's own
    #: place); ``plan_slack_s`` 1.0 241 / 16 / 1 / 12; no wall turns 244 / 20 / 1 / 5; wall turns for
    #: yielding only 242 / 13 / 3 / 12; ``plan_margin_m`` 0 248 / 17 / 1 / 4; **0.1: 249 / 15 / 1 / 5**
    #: (hits 17 removed, 11 new, p 0.35; successes 15 better, 11 worse, p 0.56). That one, fixed
    #: before, on the evaluation blocks (5000-5089 x 3 worlds): 249 / 10 / 0 / 11 against the
    #: defaults' 250 / 19 / 0 / 1 -- moving hits 7.0% -> 3.7% (15 removed, 6 new, p 0.08), the
    #: successes the same, timeouts 1 -> 11 (Willow 6, warehouse 4). Off: fewer hits bought with
    #: waiting, no more successes; the timeouts are what to look at next
    speed_plan: bool = False
    plan_slack_s: float = 0.5
    #: the speed plan's time step
    plan_dt_s: float = 0.2
    #: the clearance the speed plan keeps from a moving track beyond both radii (None: the local
    #: planner's ``moving_margin_m``); ``plan_slack_s`` is its margin in time
    plan_margin_m: float | None = None
    #: the plan's robot, standing inside a seen span or sweep where it may not wait, may wait where
    #: it is when no prediction covers that point over the horizon (without it no plan exists there
    #: and the gate's stop-short rule holds it standing anyway: Willow development seeds 3020 /
    #: 3066, 307 / 274 of their no-plan cycles). Measured with ``plan_margin_m`` 0.1 on development
    #: seeds 3000-3089, paired with it without: 248 / 16 / 2 / 4 against 249 / 15 / 1 / 5 (7 better,
    #: 8 worse); Willow 3020 and 3058 turn from timeouts into moving hits -- a seen span is no place
    #: to wait, even where nothing is predicted: off
    plan_rest_in_place: bool = False
    #: yielding's sweep predicts tracks turning back short of walls over this horizon
    #: (``NavigationConfig.wall_turn_horizon_s`` for yielding alone; None: the stack's)
    wall_turn_horizon_s: float | None = None
    #: a back-off goes no deeper into any sweep or seen span than where the robot stands (a
    #: trail that crossed a lane leads back across it: issue 33, Willow development seed 3016, the
    #: robot 0.66 m beside a shuttler's line -- clear of it, inside its span grown by the margins --
    #: backed along its trail onto the line as the shuttler turned back at its end; 6 of the speed
    #: plan's 15 moving hits on development seeds 3000-3089 were the robot backing, by the back-off
    #: or the held evasion, into a lane). Measured with the speed plan (``plan_margin_m`` 0.1, both
    #: turn predictions), paired with it without on those seeds (successes / moving / static /
    #: timeouts of 270; both with a goal rule since dropped, which changed 2 of the 270 outcomes):
    #: 246 / 13 / 1 / 10 against 248 / 15 / 1 / 6 -- hits 7 removed (the 5 traced ones still hit
    #: without it among them), 5 new, Willow timeouts 6 -> 9 (refused a back-off, the robot stands); with the
    #: gate (the defaults, and that goal rule) 242 / 24 / 3 / 1 against 245 / 21 / 3 / 1. Off: no
    #: evidence that it helps
    back_off_outward: bool = False
    #: the freezing robot (Trautman & Krause, IROS 2010): a robot that has not got
    #: ``patience_progress_m`` nearer the goal along its path for ``patience_s`` stops hedging
    #: yielding's prediction (``hedge`` and ``reversed_hedge`` taken as 0: constant velocity) and
    #: crosses with ``escape_slack_s`` instead of ``slack_s`` until it gains that much again -- it
    #: crosses behind a shuttler as soon as the shuttler's way is predicted clear instead of
    #: waiting for a window a short shuttle never leaves (the local planner, the evasion and the
    #: safe-stop check keep their own prediction). 0: never (the robot waits as long as it takes).
    #: Measured with ``planning.narrow_passages`` on development seeds 3000-3089 x 3 worlds, paired
    #: with the defaults' 256 / 5 / 0 / 9 (successes / moving / static / timeouts): 10 s 263 / 6 / 0 / 1
    #: (9 better, 2 worse, sign test p 0.065; timeouts 9 -> 1) -- but both new moving hits (office
    #: 3049, warehouse 3058) came within 3.5 s of an impatient spell: crossing on a 0.5 s slack
    #: behind a shuttler is what the hedge and the 2 s slack were for. Hedges only (``slack_s``
    #: kept), 20 s: 258 / 5 / 0 / 7 (5 better, 3 worse; a slow shuttler, 0.22 m/s, still leaves no
    #: 2 s window). Off: timeouts traded for moving hits
    patience_s: float = 0.0
    patience_progress_m: float = 0.5

    def __post_init__(self) -> None:
        if self.wall_turn_horizon_s is not None and not 0.0 <= self.wall_turn_horizon_s <= 20.0:
            raise ConfigError(f"YieldingConfig.wall_turn_horizon_s must lie in [0, 20] s, got {self.wall_turn_horizon_s}")
        if self.plan_margin_m is not None and not 0.0 <= self.plan_margin_m <= 2.0:
            raise ConfigError(f"YieldingConfig.plan_margin_m must lie in [0, 2] m, got {self.plan_margin_m}")
        if not 0.0 < self.plan_dt_s <= 1.0:
            raise ConfigError(f"YieldingConfig.plan_dt_s must lie in (0, 1] s, got {self.plan_dt_s}")
        if not self.patience_s >= 0:
            raise ConfigError(f"YieldingConfig.patience_s must be >= 0 s (0: never), got {self.patience_s}")
        if not self.patience_progress_m > 0:
            raise ConfigError(f"YieldingConfig.patience_progress_m must be > 0 m, got {self.patience_progress_m}")
        for name in ("wait_margin_m", "back_off_m", "escape_slack_s", "wait_horizon_s", "plan_slack_s"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"YieldingConfig.{name} must be >= 0, got {getattr(self, name)}")
        for name in ("reversed_hedge", "hedge"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"YieldingConfig.{name} must be in [0, 1], got {getattr(self, name)}")
        if not self.back_off_speed_mps > 0:
            raise ConfigError(f"YieldingConfig.back_off_speed_mps must be > 0, got {self.back_off_speed_mps}")


@dataclass(frozen=True)
class YieldDecision:
    """What yielding to crossing traffic decides (:meth:`Yielding.decision`):
    ``v_max_mps`` the speed cap (+inf: nothing to yield to); ``wait_gap_m`` how far along the path
    ahead the robot stops (nan: it does not wait there); ``back_off_xy_m`` the place on the way it
    came that it backs off to, because it stands inside a track's sweep or span (None: it does not)."""

    v_max_mps: float
    wait_gap_m: float = math.nan
    back_off_xy_m: np.ndarray | None = None


class Yielding:
    """Yielding's decisions and its state: the ``trail``, the estimated positions 5 cm apart,
    oldest first, that a back-off retraces."""

    def __init__(self, stack: NavigationStack):
        self.stack = stack

    @property
    def config(self) -> YieldingConfig:
        return self.stack.config.yielding

    def reset(self) -> None:
        #: the way the robot came: estimated positions 5 cm apart, oldest first (yielding backs off along it)
        self.trail: list[np.ndarray] = []
        #: the length of path to the goal when the robot last gained ``patience_progress_m``, and
        #: since when (``patience_s``)
        self.progress_reference_m = math.inf
        self.progress_since_s = 0.0

    def watch_progress(self, remaining_m: float) -> None:
        """Note the length of path left to the goal: ``patience_progress_m`` less than at the
        last gain restarts the patience clock (:meth:`impatient`); backing off and coming back
        is no gain, nor is creeping less than that."""
        if not remaining_m > self.progress_reference_m - self.config.patience_progress_m:
            self.progress_reference_m, self.progress_since_s = remaining_m, self.stack.now_s

    @property
    def stalled_s(self) -> float:
        """How long the robot has not gained ``patience_progress_m`` towards the goal."""
        return self.stack.now_s - self.progress_since_s

    @property
    def impatient(self) -> bool:
        """The robot has not gained ``patience_progress_m`` towards the goal for ``patience_s``."""
        return self.config.patience_s > 0 and self.stalled_s >= self.config.patience_s

    def record_trail(self, pose: np.ndarray, back_off_xy_m: np.ndarray | None) -> None:
        """Extend the trail by the estimate every 5 cm; backing off, forget the part of it the
        robot has driven back over (it drives the rest again, the other way, to its place)."""
        if back_off_xy_m is not None:
            trail = np.asarray(self.trail)
            j = int(np.argmin(np.linalg.norm(trail - back_off_xy_m, axis=1)))
            if self.config.back_off_along_trail:
                # keep the stretch between the place and the robot: it drives back along it
                j += int(np.argmin(np.linalg.norm(trail[j:] - pose[:2], axis=1)))
            del self.trail[j + 1:]
        elif not self.trail or np.linalg.norm(pose[:2] - self.trail[-1]) >= 0.05:
            self.trail.append(pose[:2].copy())
            del self.trail[:-int(math.ceil((self.config.back_off_m + 1.0) / 0.05))]

    def moving(self, tracks: Tracks) -> np.ndarray:
        """(K,) the tracks yielding gives way to (:meth:`NavigationStack.moving`, typical speeds
        with ``turning``)."""
        return self.stack.moving(tracks, typical=self.config.turning)

    def _accel_max_mps2(self) -> float:
        """The local planner's acceleration limit (1 m/s^2 for a controller without one)."""
        return float(getattr(self.stack.controller.config, "accel_max_mps2", 1.0))

    def sweep(self, tracks: Tracks, tau_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where yielding predicts the moving tracks over the look-ahead times ``tau_s`` (T,): each
        one's disc as :meth:`NavigationStack.local_world` predicts it (constant velocity; a track
        seen reversing hedged by ``reversed_hedge``) and, with ``span_shuttle``, for a track seen
        reversing along a span of at least the tracker's ``reverse_span_m`` a second guess:
        shuttling along that span at its typical speed (:func:`shuttle_centres`), the same disc.
        Returns centres (T, M, 2) and reach (T, M) (disc radius, ``moving_margin_m`` and the
        robot radius: closer, the robot touches it)."""
        c, stack = self.config, self.stack
        moving = np.flatnonzero(self.moving(tracks))
        hedges = (0.0, 0.0) if self.impatient else (c.hedge, c.reversed_hedge)
        world = stack.local_world(tracks, stack.now_s, hedges=hedges, turning=c.turning,
                                  wall_turn_horizon_s=c.wall_turn_horizon_s)
        discs = np.flatnonzero(stack.moving_discs(tracks, world, typical=c.turning))
        centres = world.circles_at(tau_s)[:, discs]
        reach = world.radii_at(tau_s)[:, discs] + stack.config.robot_radius_m
        if c.span_shuttle:
            span = tracks.span_xy_m[moving]
            shuttle = (tracks.reversals[moving] > 0) & (np.linalg.norm(span[:, 1] - span[:, 0], axis=1)
                                                         >= stack.tracker.config.reverse_span_m)
            k = moving[shuttle]
            speed = np.maximum(np.linalg.norm(tracks.velocity_mps[k], axis=1), tracks.speed_typical_mps[k])
            centres = np.concatenate([centres, shuttle_centres(tracks.xy_m[k], tracks.velocity_mps[k], speed,
                                                               span[shuttle], tau_s)], axis=1)
            reach = np.concatenate([reach, reach[:, :len(moving)][:, shuttle]], axis=1)
        return centres, reach

    def wait_clearance_m(self, xy_m: np.ndarray, tracks: Tracks, centres: np.ndarray,
                         reach: np.ndarray) -> np.ndarray:
        """(P,) how far points (P, 2) are from where the robot may not wait: the predicted sweep
        (``centres``, ``reach`` of :meth:`sweep`, at any of its times) and every moving
        track's seen span grown by its radius, ``moving_margin_m`` and the robot radius (<= 0:
        inside one; +inf: no moving track)."""
        nav = self.stack.config
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        out = np.full(len(xy), np.inf)
        if centres.shape[1]:
            d = np.linalg.norm(xy[:, None, None, :] - centres[None], axis=-1) - reach[None]
            out = np.minimum(out, d.min(axis=(1, 2)))
        moving = self.moving(tracks)
        if moving.any():
            span = tracks.span_xy_m[moving]
            d = (point_segment_distance(xy, span[:, 0], span[:, 1])
                 - (tracks.radius_m[moving] + nav.moving_margin_m + nav.robot_radius_m)[None])
            out = np.minimum(out, d.min(axis=1))
        return out

    def decision(self, pose: np.ndarray, tracks: Tracks) -> YieldDecision:
        """Yielding to crossing traffic, and where the robot waits.

        Waiting places (:meth:`wait_clearance_m`): outside every moving track's predicted sweep
        (its first ``wait_horizon_s``) and its seen span, ``wait_margin_m`` clear. The stretch the
        robot commits to is the path ``lookahead_m`` ahead, longer when that ends where the
        robot could not wait: on to the next waiting place (at most twice as far), so it does not
        stop between two shuttlers. A moving track conflicts when its predicted sweep
        (:meth:`sweep`, over ``horizon_s``) occupies some point of that stretch
        within ``slack_s`` of the time the robot would reach it at cruise speed (the robot
        does not race it). Then:

        * standing at a waiting place, the robot stops short of the first point ahead that is
          not one, braking at ``decel_mps2``: v = sqrt(2 a (gap - 5 cm));
        * standing inside a sweep or span (or where a track's constant-velocity sweep touches
          it), it leaves forwards when driving on at cruise speed to the next waiting place
          keeps it out of the sweep within ``escape_slack_s`` (+inf: no cap), else backs
          off along the way it came to the nearest waiting place within ``back_off_m``
          if it gets there at ``back_off_speed_mps`` clear of the sweep; failing both, it
          stops short of the first conflicting sweep -- or, when a track's constant-velocity
          sweep would touch it where it stands (stopping would not help), it leaves the traffic
          to the local planner's evasion (+inf)."""
        c, stack = self.config, self.stack
        nav = stack.config
        moving = self.moving(tracks)
        if stack.path is None:
            return YieldDecision(math.inf)
        s0 = project_on_path(stack.path, pose[:2])
        self.watch_progress(float(arc_length_m(stack.path)[-1]) - s0)
        if not moving.any():
            return YieldDecision(math.inf)
        s = s0 + np.arange(0.0, 2.0 * c.lookahead_m, 0.5 * stack.grid.resolution_m + 0.05)
        ahead = point_at(stack.path, s)  # (S, 2)
        tau = np.arange(0.0, c.horizon_s + 1e-9, 0.1)  # (T,)
        centres, reach = self.sweep(tracks, tau)
        wait = tau <= c.wait_horizon_s + 1e-9
        clear = self.wait_clearance_m(np.vstack([pose[None, :2], ahead]), tracks, centres[wait], reach[wait])
        here, place = clear[0], clear[1:] > c.wait_margin_m
        first_not = int(np.argmin(place)) if not place.all() else len(s)
        next_place = first_not + int(np.argmax(place[first_not:])) if place[first_not:].any() else len(s)
        n = max(int(np.sum(s - s0 < c.lookahead_m)), min(next_place + 1, len(s)))
        s, ahead = s[:n], ahead[:n]
        distance = np.linalg.norm(ahead[:, None, None, :] - centres[None], axis=-1)  # (S, T, M)
        occupied = distance <= reach[None]
        if c.speed_plan and occupied.any():
            closer = 0.0 if c.plan_margin_m is None else nav.moving_margin_m - c.plan_margin_m
            planned = self.planned_speed(s - s0, (distance <= reach[None] - closer).any(axis=2), place[:n], tau)
            if planned is not None:
                return planned
        lag = tau[None, :, None] - ((s - s0) / nav.cruise_speed_mps)[:, None, None]  # sweep time - robot time
        slack_s = c.escape_slack_s if self.impatient else c.slack_s
        conflict = (occupied & (np.abs(lag) <= slack_s)).any(axis=(0, 1))  # (M,)
        if not conflict.any():
            return YieldDecision(math.inf)
        contact = tracks.radius_m[moving] + nav.robot_radius_m
        cv = tracks.xy_m[moving][None] + tau[:, None, None] * tracks.velocity_mps[moving][None]
        at_robot = bool((np.linalg.norm(cv - pose[:2], axis=-1) <= contact).any())
        if here > 0.0 and not at_robot:
            gap = float(s[first_not] - s0) if first_not < len(s) else float(s[-1] - s0)
            return YieldDecision(math.sqrt(2.0 * c.decel_mps2 * max(gap - 0.05, 0.0)), gap)
        if not (occupied & (np.abs(lag) <= c.escape_slack_s)).any():
            return YieldDecision(math.inf)
        target = self.back_off_place(pose, tracks, centres, reach, tau, wait)
        if target is not None:
            return YieldDecision(0.0, back_off_xy_m=target)
        if at_robot:
            return YieldDecision(math.inf)
        first = np.argmax(occupied[:, :, conflict].any(axis=1), axis=0)  # first occupied point per sweep
        gap = float(s[first.min()] - s0)
        return YieldDecision(math.sqrt(2.0 * c.decel_mps2 * max(gap - 0.05, 0.0)), gap)

    def planned_speed(self, arc_m: np.ndarray, occupied: np.ndarray, place: np.ndarray,
                      tau_s: np.ndarray) -> YieldDecision | None:
        """The speed plan's decision (``speed_plan``): ``occupied`` (S, T) where the sweep (its
        discs with ``plan_margin_m`` for the local planner's margin) covers the stretch's points at
        ``arc_m`` (S,) ahead at the look-ahead times ``tau_s`` (T,, 0.1 s apart), ``place`` (S,)
        where the robot may wait. The blocked table is the sweep grown by
        ``plan_slack_s`` each way in time, sampled every ``plan_dt_s``; the plan is to get past
        the stretch's end (at most as far as cruise speed gets in the horizon less 1 s).
        +inf when the plan is a free path's (full acceleration to cruise), its next speed
        otherwise; None when no plan exists."""
        c, nav = self.config, self.stack.config
        if len(tau_s) < 2 or len(arc_m) < 2:  # no look-ahead to plan over
            return None
        dtau = float(tau_s[1] - tau_s[0])
        grow = int(round(c.plan_slack_s / dtau))
        occ = occupied.T  # (T, S)
        blocked = occ.copy()
        for shift in range(1, grow + 1):
            blocked[shift:] |= occ[:-shift]
            blocked[:-shift] |= occ[shift:]
        stride = max(int(round(c.plan_dt_s / dtau)), 1)
        blocked = blocked[::stride]
        dt = stride * dtau
        v0 = min(max(float(self.stack.last_command[0]), 0.0), nav.cruise_speed_mps)
        horizon = (len(blocked) - 1) * dt
        goal = min(float(arc_m[-1]), nav.cruise_speed_mps * max(horizon - 1.0, dt))
        if c.plan_rest_in_place and not place[0] and not blocked[:, 0].any():
            place = place.copy()
            place[0] = True  # nothing predicted where it stands: it may wait there for a window
        plan = plan_speed_along_path(blocked, place, float(arc_m[1] - arc_m[0]), dt, v0, nav.cruise_speed_mps,
                                     c.decel_mps2, goal)
        if not plan.feasible:
            return None
        return YieldDecision(math.inf if plan.unhindered else plan.next_speed_mps)

    def back_off_place(self, pose: np.ndarray, tracks: Tracks, centres: np.ndarray, reach: np.ndarray,
                       tau_s: np.ndarray, wait: np.ndarray) -> np.ndarray | None:
        """The nearest place on the way the robot came (its trail, newest first, within
        ``back_off_m``) that is ``wait_margin_m`` clear of every sweep and span, if the
        robot gets there at ``back_off_speed_mps`` without touching the predicted sweep (and,
        with ``back_off_outward``, without going deeper into a sweep or span on the way)."""
        c, stack = self.config, self.stack
        if not self.trail:
            return None
        way = np.vstack([pose[None, :2], np.asarray(self.trail)[::-1]])
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(way, axis=0), axis=1))])
        way, arc = way[arc <= c.back_off_m], arc[arc <= c.back_off_m]
        clear = self.wait_clearance_m(way, tracks, centres[wait], reach[wait])
        ok = clear > c.wait_margin_m
        ok[0] = False
        if not ok.any():
            return None
        j = int(np.argmax(ok))
        if c.back_off_outward and (clear[1:j] < clear[0] - 0.02).any():  # 2 cm: the trail's wiggle
            return None
        # on the way there: first the stop from the current speed (at the controller's
        # acceleration, on along the path), then back at the back-off speed; against the sweep
        # at each time (its last past the horizon)
        a = self._accel_max_mps2()
        v0 = max(float(stack.last_command[0]), 0.0)
        t_stop, overshoot = v0 / a, 0.5 * v0**2 / a
        s0 = project_on_path(stack.path, pose[:2])
        ahead = point_at(stack.path, s0 + np.linspace(0.0, overshoot, 4))
        t_way = t_stop + (overshoot + arc[:j + 1]) / c.back_off_speed_mps + 0.5 * c.back_off_speed_mps / a
        route = np.vstack([ahead, way[:j + 1]])
        t_route = np.concatenate([np.linspace(0.0, t_stop, 4), t_way])
        k = np.minimum(np.round(t_route / 0.1).astype(int), len(tau_s) - 1)
        d = np.linalg.norm(route[:, None, :] - centres[k], axis=-1) - reach[k]
        return way[j].copy() if (d > 0.0).all() else None

    def back_off_aim(self, pose: np.ndarray, target_xy: np.ndarray, lookahead_m: float = 0.25) -> np.ndarray:
        """Where the back-off steers now: the trail point ``lookahead_m`` back along the way the
        robot came towards ``target_xy`` (the place it backs off to), so it retraces that way --
        free when it drove it -- instead of cutting its bends (measured: office 300 and 305 of
        seeds 300-329 backed straight at a place round a corner and scraped the wall);
        ``target_xy`` itself with ``back_off_along_trail`` off."""
        if not self.config.back_off_along_trail or not self.trail:
            return target_xy
        trail = np.asarray(self.trail)
        j = int(np.argmin(np.linalg.norm(trail - target_xy, axis=1)))
        way = trail[j:][::-1]  # from the newest point back to the place
        far = np.linalg.norm(way - pose[:2], axis=1) >= lookahead_m
        k = int(np.argmin(np.linalg.norm(way - pose[:2], axis=1)))  # the robot's point on the way
        ahead = np.flatnonzero(far[k:])
        return way[k + int(ahead[0])] if len(ahead) else np.asarray(target_xy, float)

    def drive_to(self, pose: np.ndarray, target_xy: np.ndarray, aim_xy: np.ndarray | None = None) -> np.ndarray:
        """The back-off command towards ``target_xy``, steering at ``aim_xy`` (default the target):
        forwards or backwards, whichever faces it with the smaller turn, at most
        ``back_off_speed_mps`` and slow enough to stop on the target at ``decel_mps2``,
        changing v by at most the controller's acceleration per 0.1 s."""
        c, last = self.config, self.stack.last_command
        d = target_xy - pose[:2]
        a = d if aim_xy is None else aim_xy - pose[:2]
        e = float(wrap_angle(math.atan2(a[1], a[0]) - pose[2]))
        sign = 1.0 if abs(e) <= 0.5 * math.pi else -1.0
        if sign < 0:
            e = float(wrap_angle(e - math.pi))
        v = sign * min(c.back_off_speed_mps, math.sqrt(2.0 * c.decel_mps2 * float(np.linalg.norm(d))))
        v *= max(math.cos(e), 0.0) if abs(e) < 0.5 else 0.0
        dv = 0.1 * self._accel_max_mps2()
        v = float(np.clip(v, last[0] - dv, last[0] + dv))
        return np.array([v, float(np.clip(1.5 * e, -0.8, 0.8))])


def shuttle_centres(xy_m: np.ndarray, velocity_mps: np.ndarray, speed_mps: np.ndarray, span_xy_m: np.ndarray,
                    tau_s: np.ndarray, open_end_m: float = 0.02) -> np.ndarray:
    """Tracks shuttling along their seen spans: (K, 2) positions, velocities, (K,) speeds,
    (K, 2, 2) span end points, (T,) look-ahead times -> (T, K, 2) centres. Each starts from its
    position's projection on the span a -> b and moves at its speed in the direction of its
    velocity's component along the span, turning at the ends -- except at the end it is
    pushing out (within ``open_end_m`` of it, moving towards it: the span is still growing
    there, it goes on along the span's line)."""
    a, b = span_xy_m[:, 0], span_xy_m[:, 1]
    length = np.maximum(np.linalg.norm(b - a, axis=1), 1e-9)
    u = (b - a) / length[:, None]
    p0 = np.clip(np.einsum("kj,kj->k", xy_m - a, u), 0.0, length)
    sign = np.where(np.einsum("kj,kj->k", velocity_mps, u) >= 0.0, 1.0, -1.0)
    pushing = np.where(sign > 0, p0 >= length - open_end_m, p0 <= open_end_m)
    q = p0[None] + sign[None] * speed_mps[None] * np.asarray(tau_s, float)[:, None]  # (T, K)
    bounced = np.mod(q, 2.0 * length[None])
    bounced = np.where(bounced > length[None], 2.0 * length[None] - bounced, bounced)  # turned at an end
    q = np.where(pushing[None], q, bounced)
    return a[None] + q[..., None] * u[None]
