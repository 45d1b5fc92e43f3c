"""Relation error (Kuemmerle et al. 2009): a worked example and the MANIFEST's raw-odometry check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slamkit.data.formats.carmen import read_carmen
from slamkit.errors import DataError
from slamkit.metrics.relations import Relations, read_relations, relation_errors


def test_worked_example() -> None:
    # three poses; relation A says the robot moved 1 m forward, relation B says it turned 90 deg
    stamps = np.array([10.0, 11.0, 12.0])
    poses = np.array([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0], [1.1, 0.0, math.pi / 2 + 0.1]])
    rel = Relations(np.array([10.0, 11.0]), np.array([11.0, 12.0]),
                    np.array([[1.0, 0.0, 0.0], [0.0, 0.0, math.pi / 2]]))
    r = relation_errors(stamps, poses, rel)
    # A: estimated 1.1 m forward vs 1.0 -> 0.1 m, 0 deg; B: 0 m, 0.1 rad = 5.729578 deg
    np.testing.assert_allclose(r.errors_m, [0.1, 0.0], atol=1e-12)
    np.testing.assert_allclose(r.errors_deg, [0.0, math.degrees(0.1)], atol=1e-9)
    assert r.translation_m.mean == pytest.approx(0.05) and r.translation_m.std == pytest.approx(0.05)
    assert r.rotation_deg.mean == pytest.approx(2.864789, abs=1e-6)
    assert r.translation_sq_m2.mean == pytest.approx(0.005)
    assert (r.matched, r.unmatched) == (2, 0)
    # the error is delta*^-1 delta in the frame at t1: a relation seen turned gives a lateral error
    rel_side = Relations(np.array([10.0]), np.array([11.0]), np.array([[0.0, 1.1, 0.0]]))
    assert relation_errors(stamps, poses, rel_side).errors_m[0] == pytest.approx(1.1 * math.sqrt(2))


def test_stamps_outside_the_tolerance_are_unmatched() -> None:
    rel = Relations(np.array([10.0, 10.5]), np.array([11.0, 11.0]), np.zeros((2, 3)))
    r = relation_errors(np.array([10.0, 11.0]), np.zeros((2, 3)), rel)
    assert (r.matched, r.unmatched) == (1, 1)
    # the error kept belongs to relation 0 (the map plot draws it between the poses at its stamps)
    assert r.index.tolist() == [0]
    with pytest.raises(DataError, match="no relation has estimate poses within 0.001 s"):
        relation_errors(np.array([0.0, 1.0]), np.zeros((2, 3)), rel)


def test_relations_file_errors_name_the_line(tmp_path) -> None:
    bad = tmp_path / "r.relations"
    bad.write_text("1 2 0.1 0 0 0 0 0.2\n1 2 0.1 0 0.5 0 0 0.2\n")
    with pytest.raises(DataError, match=r"r.relations:2: z, roll and pitch must be 0"):
        read_relations(bad)


@pytest.mark.parametrize("log, trans, rot", [("intel", (7.37, 14.35), (39.2, 53.8)),
                                             ("fr079", (6.51, 13.66), (30.3, 45.5))])
def test_raw_odometry_scores_the_manifest_check(shared_datasets, log, trans, rot) -> None:
    # MANIFEST "local check": the laser poses by odometry that every FLASER line carries
    laser = read_carmen(shared_datasets / "lidar_2d" / f"{log}.clf.bz2").front
    r = relation_errors(laser.stamps_s, laser.world_xytheta_laser,
                        read_relations(shared_datasets / "lidar_2d" / f"{log}.relations"))
    assert r.matched == {"intel": 2984, "fr079": 1685}[log] and r.unmatched == 0
    assert (round(r.translation_m.mean, 2), round(r.translation_m.std, 2)) == trans
    assert (round(r.rotation_deg.mean, 1), round(r.rotation_deg.std, 1)) == rot
