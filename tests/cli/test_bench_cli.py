"""`slamkit bench`: every registered suite resolves, and one suite's JSON has the documented
shape with ratios that are reference/value (times) or value/reference (rates)."""

from __future__ import annotations

import importlib
import inspect
import json

import pytest
from typer.testing import CliRunner

from slamkit.cli import app
from slamkit.bench import SUITES


@pytest.mark.parametrize("name", sorted(SUITES))
def test_every_suite_resolves_to_a_run_function(name: str) -> None:
    module_name, fn_name = SUITES[name].split(":")
    fn = getattr(importlib.import_module(module_name), fn_name)
    assert "quick" in inspect.signature(fn).parameters


def test_bench_json_shape_and_ratios() -> None:
    result = CliRunner().invoke(app, ["bench", "raycast", "--quick", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["bench"] == "raycast" and data["machine"]["cpus"] >= 1
    compared = [c for c in data["cases"] if c.get("reference_value")]
    assert compared
    for c in compared:
        higher_is_better = c["unit"].endswith("/s")
        expected = (c["value"] / c["reference_value"] if higher_is_better
                    else c["reference_value"] / c["value"])
        assert c["ratio"] == pytest.approx(expected, rel=1e-9)


def test_unknown_suite_is_a_usage_error() -> None:
    result = CliRunner().invoke(app, ["bench", "nope"])
    assert result.exit_code == 2
    assert "error: unknown bench 'nope'; choose from control, filters, inertial, planning" in result.output
