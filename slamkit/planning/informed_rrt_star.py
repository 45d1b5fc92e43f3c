"""Informed RRT*: once a solution of cost c_best exists, sample only where a better one can be.

J. D. Gammell, S. S. Srinivasa and T. D. Barfoot, "Informed RRT*: Optimal Sampling-based Path
Planning Focused via Direct Sampling of an Admissible Ellipsoidal Heuristic", IROS 2014. Every
state that can improve the solution lies in the prolate hyperspheroid with foci x_start,
x_goal and transverse diameter c_best (Eq. 4); it is sampled directly as x = C L x_ball +
x_centre (Alg. 2), C rotating the first axis onto the start-goal line, L = diag(c_best / 2,
sqrt(c_best^2 - c_min^2) / 2, ...).

In SE(2) with the weighted metric of :class:`~slamkit.planning.worlds.SE2World` the position
part alone already bounds the cost from below, so the ellipse is drawn in (x, y) and the heading
uniformly - a (looser) informed set that is still admissible. Samples falling outside the world
box are redrawn; while the ellipse is larger than the box, sampling stays uniform.
"""

from __future__ import annotations

import math

import numpy as np

from slamkit.planning.rrt_star import RRTStarConfig, RRTStarPlanner


def sample_ellipse(rng: np.random.Generator, focus_a: np.ndarray, focus_b: np.ndarray,
                   c_best: float, n: int) -> np.ndarray:
    """(n, 2) points uniform in the ellipse with the given foci and major axis ``c_best``."""
    c_min = float(np.linalg.norm(focus_b - focus_a))
    centre = 0.5 * (focus_a + focus_b)
    a = 0.5 * c_best
    b = 0.5 * math.sqrt(max(c_best * c_best - c_min * c_min, 0.0))
    angle = math.atan2(focus_b[1] - focus_a[1], focus_b[0] - focus_a[0])
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    # uniform in the unit disc: radius sqrt(u) keeps the density uniform in area
    r = np.sqrt(rng.random(n))
    phi = rng.uniform(0.0, 2.0 * math.pi, n)
    ball = np.column_stack([r * np.cos(phi) * a, r * np.sin(phi) * b])
    return centre + ball @ rot.T


class InformedRRTStarPlanner(RRTStarPlanner):
    name = "informed_rrt_star"

    def __init__(self, config: RRTStarConfig = RRTStarConfig(), rng: np.random.Generator | None = None,
                 hook=None):
        super().__init__(config, rng, hook)
        self._ell_cost: float | None = None
        self._ell_pts = np.zeros((0, 2))
        self._ell_i = 0

    def plan(self, problem):
        self._ell_cost = None  # never reuse ellipse samples across problems
        return super().plan(problem)

    def _sample(self, world, start: np.ndarray, goal: np.ndarray, best_cost: float) -> np.ndarray:
        if not math.isfinite(best_cost):
            return super()._sample(world, start, goal, best_cost)
        s, g = start[:2], goal[:2]
        c_min = float(np.linalg.norm(g - s))
        ellipse_area = math.pi * 0.25 * best_cost * math.sqrt(max(best_cost ** 2 - c_min ** 2, 0.0))
        box = world.bounds_m
        if ellipse_area >= float(np.prod(box[1] - box[0])):
            return super()._sample(world, start, goal, best_cost)
        # ellipse samples are drawn in blocks for the current c_best (redrawn when it improves,
        # since the informed set only shrinks, a block drawn for an older c_best is discarded)
        if getattr(self, "_ell_cost", None) != best_cost or self._ell_i >= len(self._ell_pts):
            pts = np.zeros((0, 2))
            for _ in range(100):
                xy = sample_ellipse(self.rng, s, g, best_cost, 256)
                pts = np.vstack([pts, xy[np.all((xy >= box[0]) & (xy <= box[1]), axis=1)]])
                if len(pts):
                    break
            if not len(pts):
                return super()._sample(world, start, goal, best_cost)
            self._ell_pts, self._ell_i, self._ell_cost = pts, 0, best_cost
        p = self._ell_pts[self._ell_i]
        self._ell_i += 1
        if world.dim == 3:
            return np.array([p[0], p[1], self.rng.uniform(-math.pi, math.pi)])
        return p
