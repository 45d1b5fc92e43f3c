"""slamkit.metrics.loop_closures: precision and recall of loop closures against benchmark-style
relations, on a worked example whose every count is known."""

from __future__ import annotations

import numpy as np
import pytest

from slamkit.errors import DataError
from slamkit.geometry import se2
from slamkit.metrics.loop_closures import loop_closure_counts
from slamkit.metrics.relations import Relations


def _square_tour():
    """A 400 s tour at 1 Hz around a 20 m x 20 m square (80 m per lap, 1 m/s): the robot passes
    the same places every 80 s. The estimate is the truth (the metric needs only short pieces
    of it to be right)."""
    t = np.arange(0.0, 400.0, 1.0)
    s = np.mod(t, 80.0)
    side, u = np.floor(s / 20.0), np.mod(s, 20.0)
    x = np.select([side == 0, side == 1, side == 2, side == 3], [u, 20 + 0 * u, 20 - u, 0 * u])
    y = np.select([side == 0, side == 1, side == 2, side == 3], [0 * u, u, 20 + 0 * u, 20 - u])
    th = side * np.pi / 2
    return t, np.column_stack([x, y, th])


def test_worked_example():
    """Relations: (10, 90), (10, 170) and (50, 130) are revisits (>= 60 s apart), (30, 33) is not.
    Closures: (11, 91) measured right -> verifiable, correct, recalls (10, 90); (49, 131) measured
    0.5 m off -> verifiable, wrong (error 0.5 m), but still recalls (50, 130) (recall counts where
    closures are, precision whether they are right); (200, 280) has no relation near -> not
    verifiable. Precision 1/2, recall 2/3."""
    t, poses = _square_tour()
    pairs = np.array([[10.0, 90.0], [10.0, 170.0], [50.0, 130.0], [30.0, 33.0]])
    idx = pairs.astype(int)
    rel = Relations(pairs[:, 0], pairs[:, 1], se2.between(poses[idx[:, 0]], poses[idx[:, 1]]))
    cl = np.array([[11.0, 91.0], [49.0, 131.0], [200.0, 280.0]])
    ci = cl.astype(int)
    meas = se2.between(poses[ci[:, 0]], poses[ci[:, 1]])
    meas[1] = se2.compose(meas[1], np.array([0.3, 0.4, 0.0]))
    c = loop_closure_counts(cl, meas, t, poses, rel)
    assert (c.closures, c.verifiable, c.correct, c.wrong, c.revisits, c.recalled) == (3, 2, 1, 1, 3, 2)
    assert c.precision == 0.5 and c.recall == pytest.approx(2 / 3)
    assert c.wrong_errors_m == pytest.approx((0.5,), abs=1e-9)
    d = c.to_dict()
    assert d["loop_precision"] == 0.5 and d["revisit_relations"] == 3
    # closures and relations given the other way round (t_j first) count the same
    c2 = loop_closure_counts(cl[:, ::-1], se2.inverse(meas), t, poses,
                             Relations(pairs[:, 1], pairs[:, 0], se2.inverse(rel.delta_xytheta)))
    assert (c2.verifiable, c2.correct, c2.recalled) == (2, 1, 2)


def test_no_closures_and_bad_input():
    t, poses = _square_tour()
    rel = Relations(np.array([10.0]), np.array([90.0]), np.zeros((1, 3)))
    c = loop_closure_counts(np.zeros((0, 2)), np.zeros((0, 3)), t, poses, rel)
    assert (c.closures, c.verifiable, c.recalled, c.revisits) == (0, 0, 0, 1)
    assert np.isnan(c.precision) and c.recall == 0.0
    with pytest.raises(DataError):
        loop_closure_counts(np.zeros((2, 2)), np.zeros((1, 3)), t, poses, rel)
    with pytest.raises(DataError):
        loop_closure_counts(np.zeros((0, 2)), np.zeros((0, 3)), t, poses, rel, window_s=0.0)
