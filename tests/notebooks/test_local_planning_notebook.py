"""The local-planning tutorial (DWA vs MPC) runs top to bottom and prints its numbers."""

from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "local_planning.ipynb"


def test_local_planning_notebook_runs(run_notebook) -> None:
    text = run_notebook(NOTEBOOK, timeout_s=120)
    assert "DWA window: v in [0.35, 0.45], omega in [-0.10, 0.10]" in text
    assert "open_2: path" in text and "3 moving obstacles" in text
    for name in ("dwa", "mpc", "mpc_osqp"):
        assert f"{name:9s} reached goal: True" in text
    assert "DWA: 231 candidates" in text
    assert "MPC: horizon 20 steps" in text
    assert "success" in text and "collisions" in text
    assert "recording written: local_planning.rrd True" in text
