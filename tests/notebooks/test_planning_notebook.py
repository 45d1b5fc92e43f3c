"""The planning tutorial runs top to bottom and prints the numbers it promises."""

import re
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "planning.ipynb"


def test_planning_notebook_runs(run_notebook) -> None:
    text = run_notebook(NOTEBOOK, timeout_s=120)
    # the den312d map and scenario files' own counts: exact (read from the files, no arithmetic)
    w, h, free, n_scen = map(int, re.search(
        r"den312d: (\d+) x (\d+) cells, (\d+) free, (\d+) scenarios", text).groups())
    assert (w, h, free, n_scen) == (65, 81, 2445, 320)
    # the longest scenario's optimum as the .scen file states it (parsed from 127.87, printed
    # with 5 decimals): exact up to the print
    optimum = float(re.search(r"published optimum ([0-9.]+)", text).group(1))
    assert optimum == pytest.approx(127.87, abs=5e-6)
    # grid planners reproduce the published optimum to the file's 5 decimals
    errors = [float(e) for e in re.findall(r"\|error\| ([0-9.e+-]+)", text)]
    assert len(errors) == 3 and max(errors) < 1e-3
    exp = {n: int(v) for n, v in re.findall(r"^(dijkstra|astar)\s+solved: .* expansions (\d+)", text, re.M)}
    assert exp["astar"] < exp["dijkstra"]
    for name in ("rrt", "rrt_connect", "rrt_star", "informed_rrt_star", "prm"):
        assert re.search(rf"^{re.escape(name)}\s+solved", text, re.M), name
    assert text.count("collision-free True") == 3
    inc, scratch = map(int, re.search(r"incremental (\d+), from scratch (\d+)", text).groups())
    assert inc < scratch
    assert "recording written: planning.rrd True" in text
