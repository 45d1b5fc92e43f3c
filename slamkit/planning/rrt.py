"""RRT: rapidly-exploring random tree with goal bias.

S. M. LaValle, "Rapidly-Exploring Random Trees: A New Tool for Path Planning", TR 98-11, Iowa
State University, 1998. Each iteration samples x_rand (the goal with probability
``goal_bias``), extends the nearest vertex towards it by at most ``max_step`` and keeps the
new vertex if the motion is collision-free; after each extension it tries to reach the goal
directly when it is within ``max_step``. It returns the first solution: RRT is probabilistically
complete but not asymptotically optimal, which is why its paths are well above the optimum
(see :mod:`slamkit.planning.rrt_star`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import PlanningError
from slamkit.planning._sampling import SamplingPlanner, Budget, Tree, check_endpoints, default_step, steer
from slamkit.planning.protocols import Hook, PlanEvent, PlanResult, PlanStats, PlanStatus, PlanningProblem


@dataclass(frozen=True)
class RRTConfig:
    max_iterations: int = 5000
    time_limit_s: float = 5.0
    max_step: float | None = None     # None: 20% of the world's extent (OMPL's default range)
    goal_bias: float = 0.05
    hook_every: int = 100             # iterations between tree snapshots sent to the hook

    def __post_init__(self) -> None:
        if self.max_iterations < 1 or not self.time_limit_s > 0:
            raise PlanningError("max_iterations must be >= 1 and time_limit_s > 0")
        if not 0.0 <= self.goal_bias <= 1.0:
            raise PlanningError(f"goal_bias must be in [0, 1], got {self.goal_bias}")
        if self.max_step is not None and not self.max_step > 0:
            raise PlanningError(f"max_step must be positive, got {self.max_step}")


class RRTPlanner(SamplingPlanner):
    name = "rrt"

    def __init__(self, config: RRTConfig = RRTConfig(), rng: np.random.Generator | None = None,
                 hook: Hook | None = None):
        super().__init__(config, rng, hook)

    def plan(self, problem: PlanningProblem) -> PlanResult:
        cfg = self.config
        budget = Budget(cfg.max_iterations, cfg.time_limit_s)
        world, start, goal, bad = check_endpoints(problem, self.name)
        if bad is not None:
            return bad
        eta = cfg.max_step or default_step(world)
        tol = problem.goal_tolerance
        tree = Tree(start)
        rng = self.rng
        it = 0
        goal_node = -1
        # draw samples in blocks: one numpy call per 256 iterations instead of one each
        block = world.sample_uniform(rng, 256)
        coins = rng.random(256)
        while not budget.exhausted(it):
            j = it & 255
            if j == 0 and it:
                block = world.sample_uniform(rng, 256)
                coins = rng.random(256)
            it += 1
            x_rand = goal if coins[j] < cfg.goal_bias else block[j]
            nodes = tree.view
            i_near = int(np.argmin(world.distance(x_rand, nodes)))
            x_new = steer(world, nodes[i_near], x_rand, eta)
            if not world.motions_valid(nodes[i_near][None], x_new[None])[0]:
                continue
            d_new = float(world.distance(nodes[i_near], x_new[None])[0])
            i_new = tree.add(x_new, i_near, tree.cost[i_near] + d_new)
            d_goal = float(world.distance(x_new, goal[None])[0])
            if d_goal <= tol:
                goal_node = i_new
            elif d_goal <= eta and world.motions_valid(x_new[None], goal[None])[0]:
                goal_node = tree.add(goal, i_new, tree.cost[i_new] + d_goal)
            if self.hook is not None and (it % cfg.hook_every == 0 or goal_node >= 0):
                self.hook(PlanEvent("tree", it, tree.view.copy(), tree.parent[:tree.n].copy(),
                                    tree.cost[goal_node] if goal_node >= 0 else np.inf))
            if goal_node >= 0:
                break
        stats = PlanStats(time_s=budget.elapsed(), samples=it, tree_size=tree.n)
        if goal_node < 0:
            return PlanResult(PlanStatus.TIMEOUT, np.zeros((0, world.dim)), float("inf"), stats, self.name)
        return PlanResult(PlanStatus.SOLVED, tree.path_to(goal_node), float(tree.cost[goal_node]),
                          stats, self.name)
