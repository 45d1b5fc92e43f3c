"""MovingAI .map/.scen loaders: counts from the MANIFEST, coordinates, and typed errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slamkit.errors import DataError
from slamkit.maps.movingai import load_map, load_scenarios, scenario_problem_points


@pytest.fixture(scope="module")
def movingai(shared_datasets: Path) -> Path:
    return shared_datasets / "grid_planning" / "movingai"


@pytest.mark.parametrize("name, shape, free, n_scen, max_opt", [
    ("dao/arena", (49, 49), 2054, 160, 62.15),
    ("dao/den312d", (81, 65), 2445, 320, 127.87),
    ("dao/den520d", (257, 256), 28178, 888, 355.53),
    ("street/Berlin_0_256", (256, 256), None, 930, 371.63),
])
def test_counts_match_manifest(movingai, name, shape, free, n_scen, max_opt):
    grid = load_map(movingai / f"{name}.map")
    assert grid.shape == shape  # (height, width)
    if free is not None:
        assert int((~grid.occupied).sum()) == free
    scen = load_scenarios(movingai / f"{name}.map.scen")
    assert len(scen) == n_scen
    assert max(s.optimal_length for s in scen) == pytest.approx(max_opt, abs=0.006)
    # every scenario endpoint is a passable cell: x indexes columns, y rows
    for s in scen:
        assert not grid.occupied[s.start_ixy[1], s.start_ixy[0]]
        assert not grid.occupied[s.goal_ixy[1], s.goal_ixy[0]]


def test_first_arena_scenario_and_precision(movingai):
    s = load_scenarios(movingai / "dao/arena.map.scen")[2]
    # "0  maps/dao/arena.map  49  49  1  13  4  12  3.41421"
    assert (s.bucket, s.map_name, s.start_ixy, s.goal_ixy) == (0, "maps/dao/arena.map", (1, 13), (4, 12))
    assert s.optimal_length == 3.41421 and s.decimals == 5 and s.line == 4
    berlin = load_scenarios(movingai / "street/Berlin_0_256.map.scen")[0]
    assert berlin.decimals == 8 and berlin.optimal_length == 2.0
    grid = load_map(movingai / "dao/arena.map")
    start, goal = scenario_problem_points(grid, s)
    np.testing.assert_allclose(start, [1.5, 13.5])
    np.testing.assert_allclose(goal, [4.5, 12.5])


def _write(tmp_path: Path, text: str, name: str = "t.map") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_small_map_worked_example(tmp_path):
    p = _write(tmp_path, "type octile\nheight 2\nwidth 3\nmap\n.@G\nTS.\n")
    grid = load_map(p)
    np.testing.assert_array_equal(grid.occupied, [[False, True, False], [True, False, False]])
    assert grid.resolution_m == 1.0 and grid.name == "t"


@pytest.mark.parametrize("text, line, match", [
    ("type octile\nheight 2\nwidth 3\nmap\n.@.\n..\n", 6, "2 characters"),
    ("type octile\nheight 2\nwidth 3\nmap\n.@.\n.X.\n", 6, "unknown terrain 'X'"),
    ("type octile\nheight 3\nwidth 3\nmap\n...\n...\n", 6, "expected 3 map rows"),
    ("type octile\nheight two\nwidth 3\nmap\n...\n", 3, "integers"),
    ("type octile\nwidth 3\nmap\n...\n", 3, "missing 'height'"),
    ("type octile\nbogus\n", 2, "header"),
])
def test_malformed_map_names_file_and_line(tmp_path, text, line, match):
    p = _write(tmp_path, text)
    with pytest.raises(DataError, match=match) as err:
        load_map(p)
    assert err.value.path == str(p) and err.value.line == line


@pytest.mark.parametrize("text, line, match", [
    ("version 1\n0\tm.map\t3\t3\t0\t0\t2\t2\n", 2, "9 fields"),
    ("version 1\n0\tm.map\t3\t3\t0\t0\t2\t2\t2.8\n0\tm.map\t3\t3\t0\t0\t2\t2\tx\n", 3, "field optimal_length is 'x', expected a number"),
    ("version 1\n0\tm.map\t3\t3\t0\t0\t5\t2\t2.8\n", 2, "outside"),
    ("0\tm.map\t3\t3\t0\t0\t2\t2\t2.8\n", 1, "version 1"),
])
def test_malformed_scen_names_file_and_line(tmp_path, text, line, match):
    p = _write(tmp_path, text, "t.map.scen")
    with pytest.raises(DataError, match=match) as err:
        load_scenarios(p)
    assert err.value.line == line


def test_missing_file_is_data_error(tmp_path):
    with pytest.raises(DataError, match="no such file"):
        load_map(tmp_path / "nope.map")


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.sampled_from(".@GSTWO"), min_size=1, max_size=12), min_size=1, max_size=12)
       .filter(lambda rows: len({len(r) for r in rows}) == 1))
def test_roundtrip_random_maps(tmp_path_factory, rows):
    text = "".join(f"{''.join(r)}\n" for r in rows)
    p = tmp_path_factory.mktemp("m") / "r.map"
    p.write_text(f"type octile\nheight {len(rows)}\nwidth {len(rows[0])}\nmap\n{text}")
    grid = load_map(p)
    expected = np.array([[c not in ".GS" for c in r] for r in rows])
    np.testing.assert_array_equal(grid.occupied, expected)


@settings(max_examples=100, deadline=None)
@given(st.text(alphabet=st.characters(min_codepoint=9, max_codepoint=126), max_size=80))
def test_garbage_scen_raises_only_data_error(tmp_path_factory, junk):
    p = tmp_path_factory.mktemp("s") / "g.scen"
    p.write_text("version 1\n" + junk + "\n")
    try:
        load_scenarios(p)
    except DataError:
        pass
