"""Shared test fixtures."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATASETS = ROOT.parent / "shared" / "datasets"


def _rerun_cli() -> str:
    exe = Path(sys.executable).with_name("rerun")
    return str(exe) if exe.exists() else (shutil.which("rerun") or "rerun")


@pytest.fixture(scope="session")
def rerun_cli() -> str:
    """Path of the rerun CLI, with analytics disabled so it never waits on the network."""
    cli = _rerun_cli()
    subprocess.run([cli, "analytics", "disable"], capture_output=True, timeout=60)
    return cli


@pytest.fixture(scope="session")
def verify_rrd(rerun_cli):
    """``verify_rrd(path) -> set[str]``: runs ``rerun rrd verify`` (must pass) and returns the
    entity paths the recording contains (from ``rerun rrd stats``)."""

    def _verify(path: str | Path) -> set[str]:
        path = Path(path)
        assert path.exists() and path.stat().st_size > 0, f"no recording at {path}"
        env = dict(os.environ, RERUN_ANALYTICS="0")
        done = subprocess.run([rerun_cli, "rrd", "verify", str(path)], capture_output=True,
                              text=True, timeout=120, env=env)
        assert done.returncode == 0, f"rerun rrd verify failed: {done.stderr}\n{done.stdout}"
        stats = subprocess.run([rerun_cli, "rrd", "stats", str(path)], capture_output=True,
                               text=True, timeout=120, env=env)
        assert stats.returncode == 0, stats.stderr
        section = stats.stdout.split("Num chunks per entity", 1)[1].split("\n\n", 1)[0]
        return set(re.findall(r"^(/[^:\s]+):", section, flags=re.M))

    return _verify


@pytest.fixture(scope="session")
def shared_datasets() -> Path:
    if not SHARED_DATASETS.is_dir():
        pytest.skip("../shared/datasets is not beside the checkout")
    return SHARED_DATASETS


@pytest.fixture(scope="session")
def run_notebook(tmp_path_factory):
    """``run_notebook(path, timeout_s=300) -> str``: execute a notebook top to bottom in a kernel
    running this interpreter (fails the test on the first cell error) and return everything its
    cells printed, for the test to state numbers against."""
    import json

    import nbformat
    from jupyter_client.kernelspec import KernelSpecManager
    from nbclient import NotebookClient

    if "python3" not in KernelSpecManager().find_kernel_specs():
        # ipykernel installs one into the venv; where it is missing, write one into a temporary
        # Jupyter path instead of installing anything into the user's home
        root = tmp_path_factory.mktemp("jupyter")
        spec = root / "kernels" / "python3"
        spec.mkdir(parents=True)
        (spec / "kernel.json").write_text(json.dumps({
            "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
            "display_name": "Python 3 (slamkit tests)", "language": "python"}))
        os.environ["JUPYTER_PATH"] = str(root)

    def _run(path: str | Path, timeout_s: int = 300) -> str:
        nb = nbformat.read(str(path), as_version=4)
        client = NotebookClient(nb, timeout=timeout_s, kernel_name="python3",
                                resources={"metadata": {"path": str(Path(path).parent)}})
        client.execute()
        return "".join(out.get("text", "") for cell in nb.cells if cell.cell_type == "code"
                       for out in cell.get("outputs", []) if out.get("output_type") == "stream")

    return _run
