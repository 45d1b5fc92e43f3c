"""The models-and-simulator notebook runs top to bottom and states its key numbers."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "models_and_simulator.ipynb"


def _outputs(nb) -> str:
    text = []
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            text.append(out.get("text", "") if out.get("output_type") == "stream" else "")
    return "".join(text)


@pytest.fixture()
def python3_kernel(tmp_path, monkeypatch):
    """Make sure a ``python3`` kernelspec running this interpreter exists: ipykernel installs one
    into the venv, but on a machine where it is missing we write one into a temporary Jupyter
    path instead of installing anything into the user's home."""
    from jupyter_client.kernelspec import KernelSpecManager

    if "python3" in KernelSpecManager().find_kernel_specs():
        return
    spec = tmp_path / "kernels" / "python3"
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "Python 3 (slamkit tests)", "language": "python"}))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path))


def test_notebook_runs_and_prints_the_worked_examples(python3_kernel, run_notebook):
    nb = run_notebook(NOTEBOOK, timeout_s=300)
    out = _outputs(nb)
    assert "v, omega        = [0.15 0.25]" in out
    assert "straight line   = [0.15 0.   0.25]" in out
    assert "range, bearing = [4.6098 0.6586]" in out
    assert "identical: True" in out
    assert "same seed, same file: True" in out
    assert "{'Scan': 251, 'WheelEncoders': 12500, 'Imu': 5000, 'Odometry': 500, 'Gps': 25}" in out
