"""The models-and-simulator notebook runs top to bottom and states its key numbers."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "models_and_simulator.ipynb"


def _printed_array(out: str, label: str) -> np.ndarray:
    """The numpy array printed after ``label =`` (``np.set_printoptions(precision=4)``)."""
    m = re.search(rf"^{re.escape(label)}\s*=\s*\[([^\]]*)\]", out, re.M)
    assert m, label
    return np.array([float(v) for v in m.group(1).split()])


def test_notebook_runs_and_prints_the_worked_examples(run_notebook):
    out = run_notebook(NOTEBOOK, timeout_s=300)
    # closed-form worked examples, printed at 4 decimals (the tolerance is the print's rounding,
    # not a spread: each is a handful of exact operations):
    # wheels (2, 1) rad/s, r = 0.1 m, b = 0.2 m: v = r (wr + wl) / 2 = 0.15, omega = r (wr - wl) / 2b = 0.25
    assert _printed_array(out, "v, omega") == pytest.approx([0.15, 0.25], abs=5e-5)
    # the straight-line model moves v dt along the start heading and turns by omega dt
    assert _printed_array(out, "straight line") == pytest.approx([0.15, 0.0, 0.25], abs=5e-5)
    # landmark (4, 3) from (0.5, 0, 0.05 rad): range hypot(3.5, 3) = 4.6098, bearing atan2(3, 3.5) - 0.05
    assert _printed_array(out, "range, bearing") == pytest.approx(
        [np.hypot(3.5, 3.0), np.arctan2(3.0, 3.5) - 0.05], abs=5e-5)
    assert "identical: True" in out
    assert "same seed, same file: True" in out
    # event counts of the seeded 25 s warehouse tour, exact by construction (rate x duration):
    # scans 10 Hz (251), encoders 500 Hz, IMU 200 Hz, odometry 20 Hz, GPS 1 Hz
    counts = ast.literal_eval(re.search(r"^(\{'Scan': .*\})$", out, re.M).group(1))
    assert counts == {"Scan": 251, "WheelEncoders": 12500, "Imu": 5000, "Odometry": 500, "Gps": 25}
