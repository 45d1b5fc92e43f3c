"""Dijkstra's algorithm on occupancy grids and costmaps.

E. W. Dijkstra, "A note on two problems in connexion with graphs", Numerische Mathematik 1,
1959: A* with the zero heuristic, so it closes vertices in order of cost-to-come. It is the
reference every other grid planner is checked against (same graph: see
:mod:`slamkit.planning.grid_search`).
"""

from __future__ import annotations

from dataclasses import dataclass

from slamkit.planning.astar import AStarConfig, AStarPlanner
from slamkit.planning.protocols import Hook


@dataclass(frozen=True)
class DijkstraConfig:
    connectivity: int = 8
    corner_cutting: bool = False
    hook_batches: int = 50
    edge_cost: str = "mean"   # or "enter" (see slamkit.planning.grid_search)


class DijkstraPlanner(AStarPlanner):
    name = "dijkstra"

    def __init__(self, config: DijkstraConfig = DijkstraConfig(), hook: Hook | None = None):
        super().__init__(AStarConfig(heuristic="zero", connectivity=config.connectivity,
                                     corner_cutting=config.corner_cutting,
                                     hook_batches=config.hook_batches,
                                     edge_cost=config.edge_cost), hook)
        self.dijkstra_config = config
