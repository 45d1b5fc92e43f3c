"""A plug-in module beside the config (slamkit.naming.import_plugins' search_path): what the
own-estimator tutorial relies on, checked without running a pipeline."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from slamkit.errors import ConfigError
from slamkit.naming import import_plugins, plugin_env


@pytest.fixture
def clean_import_state(monkeypatch):
    monkeypatch.setattr(sys, "path", list(sys.path))
    yield
    for name in [m for m in sys.modules if m.startswith("beside_config_")]:
        del sys.modules[name]


def test_a_module_beside_the_config_is_found_and_passed_to_workers(tmp_path: Path, clean_import_state) -> None:
    (tmp_path / "beside_config_a.py").write_text("ANSWER = 42\n")
    [module] = import_plugins(["beside_config_a"], "cfg.yaml:3: plugins", [str(tmp_path)])
    assert module.ANSWER == 42
    assert str(tmp_path) in sys.path  # spawned workers inherit it
    assert "beside_config_a" in next(iter(plugin_env().values())).split(os.pathsep)


def test_a_missing_module_names_the_field_and_where_it_was_looked_for(tmp_path: Path, clean_import_state) -> None:
    with pytest.raises(ConfigError, match=r"cfg.yaml:3: plugins: plug-in module 'beside_config_none' cannot be imported"):
        import_plugins(["beside_config_none"], "cfg.yaml:3: plugins", [str(tmp_path)])


def test_an_import_error_inside_the_plugin_is_not_masked(tmp_path: Path, clean_import_state) -> None:
    (tmp_path / "beside_config_b.py").write_text("import no_such_dependency_xyz\n")
    with pytest.raises(ConfigError, match="no_such_dependency_xyz"):
        import_plugins(["beside_config_b"], "cfg.yaml:3: plugins", [str(tmp_path)])
