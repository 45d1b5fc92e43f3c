"""RRT-Connect: two trees, one from the start and one from the goal, greedily connected.

J. J. Kuffner and S. M. LaValle, "RRT-Connect: An Efficient Approach to Single-Query Path
Planning", ICRA 2000. Each iteration EXTENDs one tree one step towards a random sample and then
CONNECTs the other tree to the new vertex (repeated steps until it reaches it or is blocked);
the trees swap roles every iteration. Fast at finding *a* path, not optimal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slamkit.errors import PlanningError
from slamkit.planning._sampling import SamplingPlanner, Budget, Tree, check_endpoints, default_step, steer
from slamkit.planning.protocols import Hook, PlanEvent, PlanResult, PlanStats, PlanStatus, PlanningProblem


@dataclass(frozen=True)
class RRTConnectConfig:
    max_iterations: int = 5000
    time_limit_s: float = 5.0
    max_step: float | None = None
    hook_every: int = 100

    def __post_init__(self) -> None:
        if self.max_iterations < 1 or not self.time_limit_s > 0:
            raise PlanningError("max_iterations must be >= 1 and time_limit_s > 0")


def _extend(world, tree: Tree, target: np.ndarray, eta: float) -> tuple[int, bool]:
    """One step of ``tree`` towards ``target``: (new vertex or -1, reached target)."""
    d = world.distance(target, tree.view)
    i = int(np.argmin(d))
    x_new = steer(world, tree.nodes[i], target, eta)
    if not world.motions_valid(tree.nodes[i][None], x_new[None])[0]:
        return -1, False
    step = float(world.distance(tree.nodes[i], x_new[None])[0])
    j = tree.add(x_new, i, tree.cost[i] + step)
    return j, bool(d[i] <= eta)


class RRTConnectPlanner(SamplingPlanner):
    name = "rrt_connect"

    def __init__(self, config: RRTConnectConfig = RRTConnectConfig(), rng: np.random.Generator | None = None,
                 hook: Hook | None = None):
        super().__init__(config, rng, hook)

    def plan(self, problem: PlanningProblem) -> PlanResult:
        cfg = self.config
        budget = Budget(cfg.max_iterations, cfg.time_limit_s)
        world, start, goal, bad = check_endpoints(problem, self.name)
        if bad is not None:
            return bad
        eta = cfg.max_step or default_step(world)
        ta, tb = Tree(start), Tree(goal)
        a_is_start = True
        it = 0
        joint: tuple[int, int] | None = None
        while not budget.exhausted(it):
            it += 1
            x_rand = world.sample_uniform(self.rng, 1)[0]
            ja, _ = _extend(world, ta, x_rand, eta)
            if ja >= 0:
                target = ta.nodes[ja]
                while True:  # CONNECT: keep stepping the other tree until reached or blocked
                    jb, reached = _extend(world, tb, target, eta)
                    if jb < 0:
                        break
                    if reached:
                        joint = (ja, jb) if a_is_start else (jb, ja)
                        break
                if joint is not None:
                    if not a_is_start:
                        ta, tb = tb, ta
                    break
            if self.hook is not None and it % cfg.hook_every == 0:
                both = np.vstack([ta.view, tb.view])
                parents = np.concatenate([ta.parent[:ta.n], np.where(tb.parent[:tb.n] >= 0, tb.parent[:tb.n] + ta.n, -1)])
                self.hook(PlanEvent("tree", it, both, parents))
            ta, tb = tb, ta
            a_is_start = not a_is_start
        stats = PlanStats(time_s=budget.elapsed(), samples=it, tree_size=ta.n + tb.n)
        if joint is None:
            return PlanResult(PlanStatus.TIMEOUT, np.zeros((0, world.dim)), float("inf"), stats, self.name)
        # ta is the start tree here; the goal tree's vertex coincides with the start tree's
        head = ta.path_to(joint[0])
        tail = tb.path_to(joint[1])[::-1]
        path = np.vstack([head, tail[1:]])
        cost = float(sum(world.distance(path[i], path[i + 1][None])[0] for i in range(len(path) - 1)))
        return PlanResult(PlanStatus.SOLVED, path, cost, stats, self.name)
