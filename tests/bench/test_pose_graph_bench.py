"""``slamkit bench pose-graph`` in quick mode: the cases exist, slamkit and raw GTSAM reach the
same final error and iteration/update counts. Times are reported by the bench, never asserted."""

from __future__ import annotations

import pytest

from slamkit.bench.pose_graph import run


def test_quick_bench_compares_like_with_like():
    cases = {c.name: c for c in run(quick=True, repeat=1)}
    assert set(cases) == {"lm_end_to_end_w100", "lm_backend_only_w100", "isam2_replay_w100"}
    assert cases["lm_backend_only_w100"].extra["iterations"] == 3
    lm = cases["lm_end_to_end_w100"]
    assert lm.extra["final_error_rel_diff"] < 1e-9
    assert lm.extra["iterations"] == lm.extra["reference_iterations"] == 3
    assert lm.extra["final_error"] == pytest.approx(0.568927, rel=1e-5)
    isam = cases["isam2_replay_w100"]
    assert isam.extra["final_error_rel_diff"] < 1e-9
    assert isam.extra["updates"] == isam.extra["reference_updates"]
    for c in cases.values():
        assert c.unit == "s" and c.goal == ">= 0.91"
        assert c.ratio == c.reference_value / c.value
