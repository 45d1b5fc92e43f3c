"""The pose-graph tutorial runs top to bottom and its printed numbers are the expected ones."""

from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "pose_graph_slam.ipynb"


def test_pose_graph_notebook_runs(shared_datasets, run_notebook) -> None:
    text = run_notebook(NOTEBOOK, timeout_s=300)
    assert "434 poses, 460 factors" in text
    assert "published f* = 24230" in text
