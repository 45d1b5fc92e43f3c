"""The planning tutorial runs top to bottom and prints the numbers it promises."""

import re
from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "planning.ipynb"


def test_planning_notebook_runs(run_notebook) -> None:
    text = run_notebook(NOTEBOOK, timeout_s=120)
    assert "den312d: 65 x 81 cells, 2445 free, 320 scenarios" in text
    assert "published optimum 127.87" in text
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
