"""The models-and-simulator notebook runs top to bottom and states its key numbers."""

from __future__ import annotations

from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "models_and_simulator.ipynb"


def test_notebook_runs_and_prints_the_worked_examples(run_notebook):
    out = run_notebook(NOTEBOOK, timeout_s=300)
    assert "v, omega        = [0.15 0.25]" in out
    assert "straight line   = [0.15 0.   0.25]" in out
    assert "range, bearing = [4.6098 0.6586]" in out
    assert "identical: True" in out
    assert "same seed, same file: True" in out
    assert "{'Scan': 251, 'WheelEncoders': 12500, 'Imu': 5000, 'Odometry': 500, 'Gps': 25}" in out
