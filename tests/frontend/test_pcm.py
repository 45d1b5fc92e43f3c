"""PCM-style pairwise consistency check of loop closures (slamkit.frontend.pcm)."""

from __future__ import annotations

import numpy as np

from slamkit.data.pose_graph import PoseGraph
from slamkit.frontend.pcm import dead_reckoning, greedy_max_clique, pcm
from slamkit.geometry import se2


def test_greedy_clique_finds_the_planted_clique():
    # vertices 0-3 form a clique; 4 and 5 each touch two of them and each other
    adj = np.zeros((6, 6), bool)
    for a in range(4):
        for b in range(4):
            adj[a, b] = True
    for a, b in ((4, 0), (4, 1), (5, 2), (5, 3), (4, 5)):
        adj[a, b] = adj[b, a] = True
    assert greedy_max_clique(adj).tolist() == [0, 1, 2, 3]


def test_true_loop_closures_are_kept_and_gross_outliers_dropped():
    # a noise-free spiral: the odometry and 6 true loop closures agree exactly; 4 false ones do not
    n = 120
    steps = np.tile([1.0, 0.0, 2 * np.pi / 40], (n - 1, 1))
    poses = [np.zeros(3)]
    for s in steps:
        poses.append(se2.compose(poses[-1], s))
    poses = np.array(poses)
    true_pairs = [(0, 40), (5, 45), (10, 90), (20, 100), (40, 80), (60, 100)]
    false = [(3, 70, [4.0, -2.0, 1.0]), (15, 33, [-6.0, 1.0, -2.0]), (50, 110, [2.0, 7.0, 0.5]),
             (8, 99, [0.0, 5.0, 3.0])]
    ef = list(range(n - 1)) + [a for a, _ in true_pairs] + [a for a, _, _ in false]
    et = list(range(1, n)) + [b for _, b in true_pairs] + [b for _, b, _ in false]
    z = np.vstack([steps, se2.between(poses[[a for a, _ in true_pairs]], poses[[b for _, b in true_pairs]]),
                   np.array([m for _, _, m in false])])
    info = np.broadcast_to(np.diag([100.0, 100.0, 1000.0]), (len(ef), 3, 3)).copy()
    g = PoseGraph(2, np.arange(n), poses, np.array(ef), np.array(et), z, info)
    assert np.allclose(dead_reckoning(g), poses)
    result = pcm(g)
    assert result.accepted[: n - 1 + len(true_pairs)].all()
    assert not result.accepted[n - 1 + len(true_pairs):].any()
    assert result.clique_size == 6
