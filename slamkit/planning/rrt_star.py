"""RRT*: asymptotically optimal RRT with a shrinking connection radius and rewiring.

S. Karaman and E. Frazzoli, "Sampling-based Algorithms for Optimal Motion Planning", IJRR
30(7), 2011, Alg. 6. A new vertex x_new connects to the neighbour within radius

    r_n = min(gamma_RRT* (log n / n)^(1/d), max_step),
    gamma_RRT* = rewire_factor * 2 (1 + 1/d)^(1/d) (mu(X) / zeta_d)^(1/d)        (Thm. 38)

(mu(X): measure of the space - OMPL uses the same upper bound of mu(X_free); zeta_d: volume of
the unit d-ball). ``RRTStarConfig.gamma`` sets gamma_RRT* directly instead (the course's
r_n = gamma (log n / n)^(1/d) with gamma = 5); below the bound of Thm. 38 the planner is still
correct but no longer guaranteed asymptotically optimal. that gives it the cheapest cost-to-come, then every neighbour that would be
cheaper through x_new is rewired to it; cost changes propagate to the rewired subtrees. The
goal is a sink: any vertex within ``max_step`` of it with a free straight motion offers a
solution, and the best one is tracked as rewiring lowers costs, so the returned cost keeps
falling with iterations (anytime). ``cost_history`` in the stats records it over time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slamkit.errors import PlanningError
from slamkit.planning._sampling import SamplingPlanner, Budget, Tree, check_endpoints, default_step
from slamkit.planning.protocols import Hook, PlanEvent, PlanResult, PlanStats, PlanStatus, PlanningProblem


@dataclass(frozen=True)
class RRTStarConfig:
    max_iterations: int = 5000
    time_limit_s: float = 5.0
    max_step: float | None = None     # None: 20% of the world's extent (OMPL's default range)
    goal_bias: float = 0.05
    rewire_factor: float = 1.1        # OMPL's default: 10% above the theoretical bound
    #: gamma_RRT* itself (same units as the space's distance); None: computed from rewire_factor
    gamma: float | None = None
    stop_at_first_solution: bool = False
    hook_every: int = 100

    def __post_init__(self) -> None:
        if self.max_iterations < 1 or not self.time_limit_s > 0:
            raise PlanningError("max_iterations must be >= 1 and time_limit_s > 0")
        if not 0.0 <= self.goal_bias <= 1.0:
            raise PlanningError(f"goal_bias must be in [0, 1], got {self.goal_bias}")
        if self.rewire_factor < 1.0:
            raise PlanningError("rewire_factor < 1 loses asymptotic optimality")
        if self.gamma is not None and not (math.isfinite(self.gamma) and self.gamma > 0):
            raise PlanningError(f"gamma must be a positive finite number or None, got {self.gamma}")


def unit_ball_volume(d: int) -> float:
    return math.pi ** (d / 2) / math.gamma(d / 2 + 1)


def gamma_rrt_star(measure: float, d: int, rewire_factor: float = 1.1) -> float:
    return rewire_factor * 2.0 * (1.0 + 1.0 / d) ** (1.0 / d) * (measure / unit_ball_volume(d)) ** (1.0 / d)


def connection_radius(gamma: float, n: int, d: int, max_step: float) -> float:
    """r_n = min(gamma (log n / n)^(1/d), max_step) for a tree of n vertices."""
    return min(gamma * (math.log(n) / n) ** (1.0 / d), max_step)


class RRTStarPlanner(SamplingPlanner):
    name = "rrt_star"

    def __init__(self, config: RRTStarConfig = RRTStarConfig(), rng: np.random.Generator | None = None,
                 hook: Hook | None = None):
        super().__init__(config, rng, hook)

    # Informed RRT* overrides this (the only difference between the two)
    def _sample(self, world, start: np.ndarray, goal: np.ndarray, best_cost: float) -> np.ndarray:
        # uniform samples drawn 256 at a time (one numpy call instead of one per iteration)
        if self._block_i >= len(self._block_pts):
            self._block_pts = world.sample_uniform(self.rng, 256)
            self._block_i = 0
        self._block_i += 1
        return self._block_pts[self._block_i - 1]

    def plan(self, problem: PlanningProblem) -> PlanResult:
        cfg = self.config
        budget = Budget(cfg.max_iterations, cfg.time_limit_s)
        world, start, goal, bad = check_endpoints(problem, self.name)
        if bad is not None:
            return bad
        rng = self.rng
        d = world.dim
        self._block_pts, self._block_i = np.zeros((0, d)), 0
        eta = cfg.max_step or default_step(world)
        tol = problem.goal_tolerance
        gamma = cfg.gamma if cfg.gamma is not None else gamma_rrt_star(world.measure, d, cfg.rewire_factor)
        tree = Tree(start, capacity=min(cfg.max_iterations + 2, 1 << 16))
        children: list[list[int]] = [[]]
        goal_idx: list[int] = []          # vertices offering a solution ...
        goal_gap: list[float] = []        # ... and their remaining distance to the goal
        best_cost, best_node, best_gap = math.inf, -1, 0.0
        history: list[tuple[float, int, float]] = []
        it = 0
        coins = rng.random(256)
        while not budget.exhausted(it):
            it += 1
            j = it & 255
            if j == 0:
                coins = rng.random(256)   # goal-bias coins in blocks: one call per 256 iterations
            if coins[j] < cfg.goal_bias:
                x_rand = goal
            else:
                x_rand = self._sample(world, start, goal, best_cost)
            n = tree.n
            nodes = tree.nodes[:n]
            costs = tree.cost[:n]
            d_rand = world.distance(x_rand, nodes)
            i_nearest = int(np.argmin(d_rand))
            if d_rand[i_nearest] <= eta:
                x_new, d_all = x_rand.copy(), d_rand   # no steering: distances already known
            else:
                x_new = world.interpolate(nodes[i_nearest], x_rand, eta / d_rand[i_nearest])
                d_all = None
            if not world.point_valid(x_new):
                continue
            if d_all is None:
                d_all = world.distance(x_new, nodes)
            r = connection_radius(gamma, n + 1, d, eta)
            near = np.flatnonzero(d_all <= r)
            if d_all[i_nearest] > r:
                near = np.append(near, i_nearest)
            ok = world.edges_free(nodes[near], x_new[None])
            if not ok.any():
                continue
            near, d_near = near[ok], d_all[near[ok]]
            via = costs[near] + d_near
            k = int(np.argmin(via))
            parent, c_new = int(near[k]), float(via[k])
            i_new = tree.add(x_new, parent, c_new)
            children[parent].append(i_new)
            children.append([])
            # rewire: neighbours that get cheaper through x_new (straight motions are
            # symmetric, so the checks above also cover x_new -> neighbour)
            costs = tree.cost[:tree.n]
            better = c_new + d_near < costs[near] - 1e-12
            changed = False
            for j, dj in zip(near[better].tolist(), d_near[better].tolist()):
                old = int(tree.parent[j])
                children[old].remove(j)
                children[i_new].append(j)
                tree.parent[j] = i_new
                delta = c_new + dj - tree.cost[j]
                stack = [j]
                while stack:               # the whole subtree gets cheaper by delta
                    u = stack.pop()
                    tree.cost[u] += delta
                    stack.extend(children[u])
                changed = True
            d_goal = float(world.distance(x_new, goal[None])[0])
            if d_goal <= tol:
                goal_idx.append(i_new)
                goal_gap.append(0.0)
                changed = True
            elif d_goal <= eta and world.edges_free(x_new[None], goal[None])[0]:
                goal_idx.append(i_new)
                goal_gap.append(d_goal)
                changed = True
            if changed and goal_idx:
                total = tree.cost[goal_idx] + np.asarray(goal_gap)
                m = int(np.argmin(total))
                if total[m] < best_cost - 1e-12:
                    best_cost, best_node, best_gap = float(total[m]), goal_idx[m], goal_gap[m]
                    history.append((budget.elapsed(), it, best_cost))
            if self.hook is not None and it % cfg.hook_every == 0:
                self.hook(PlanEvent("tree", it, tree.view.copy(), tree.parent[:tree.n].copy(), best_cost))
            if cfg.stop_at_first_solution and best_node >= 0:
                break
        stats = PlanStats(time_s=budget.elapsed(), samples=it, tree_size=tree.n,
                          extra={"cost_history": history})
        if self.hook is not None:
            self.hook(PlanEvent("tree", it, tree.view.copy(), tree.parent[:tree.n].copy(), best_cost))
        if best_node < 0:
            return PlanResult(PlanStatus.TIMEOUT, np.zeros((0, d)), math.inf, stats, self.name)
        path = tree.path_to(best_node)
        if best_gap > 0:
            path = np.vstack([path, goal])
        return PlanResult(PlanStatus.SOLVED, path, best_cost, stats, self.name)
