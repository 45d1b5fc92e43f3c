"""The import arrows of ARCHITECTURE.md section 3: an import may only point to an earlier layer,
and gtsam / casadi / osqp / rerun / typer / yaml / matplotlib stay in their own packages."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "slamkit"

# package -> slamkit packages it may import (besides itself and the shared base modules)
ALLOWED = {
    "geometry": set(),
    "models": {"geometry"},
    "maps": {"geometry", "models"},
    "sim": {"geometry", "models", "maps", "data"},
    "data": {"geometry", "models", "maps"},
    "estimation": {"geometry", "models", "maps", "data"},
    "backend": {"geometry", "models", "data"},
    "frontend": {"geometry", "models", "maps", "data"},
    "planning": {"geometry", "maps"},
    "control": {"geometry", "models", "maps"},
    # image basics, features (ORB via OpenCV), two-view geometry, triangulation, PnP
    "vision": {"geometry", "models"},
    # running robot components (lidar SLAM ...): everything above but metrics, experiments, viz
    "systems": {"geometry", "models", "maps", "sim", "data", "estimation", "backend", "frontend",
                "planning", "control", "vision"},
    "metrics": {"geometry", "data"},
    "experiments": {"geometry", "models", "maps", "sim", "data", "estimation", "backend",
                    "frontend", "planning", "control", "vision", "systems", "metrics"},
    # benchmarks time slamkit against same-run references (raw GTSAM, casadi.Opti, peers)
    "bench": {"geometry", "models", "maps", "sim", "data", "estimation", "backend", "frontend",
              "planning", "control", "vision", "systems", "metrics", "experiments"},
    "viz": {"geometry", "models", "maps", "sim", "data", "estimation", "backend", "frontend",
            "planning", "control", "vision", "systems", "metrics", "experiments"},
    "cli": None,  # may import everything
}
BASE_MODULES = {"errors", "timing", "config", "paths", "naming", "_native", "_text", "__init__"}
# third-party packages confined to one slamkit package
CONFINED = {
    "gtsam": {"backend", "bench"},
    "casadi": {"control", "bench"},
    "osqp": {"control"},
    "rerun": {"viz"},
    "typer": {"cli"},
    "matplotlib": {"experiments", "viz", "cli"},
    "yaml": {"experiments", "cli", "sim", "viz"},
    # config validation lives at the edge (slamkit.config, the pipelines, the sim's file loaders)
    "pydantic": {"experiments", "sim"},
    "PIL": {"data"},  # image files are a file format (slamkit.data.formats.image)
    "cv2": {"vision"},  # and within vision only the ORB module (test below)
}


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module))
    return out


def _files():
    return sorted(p for p in PACKAGE.rglob("*.py") if p.parent != PACKAGE)


@pytest.mark.parametrize("path", _files(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_follow_layers(path: Path) -> None:
    layer = path.relative_to(PACKAGE).parts[0]
    allowed = ALLOWED[layer]
    for lineno, name in _imports(path):
        top = name.split(".")[0]
        if top == "slamkit":
            parts = name.split(".")
            if len(parts) < 2 or parts[1] in BASE_MODULES or parts[1] == layer or allowed is None:
                continue
            assert parts[1] in allowed, f"{path}:{lineno} ({layer}) imports {name}"
        elif top in CONFINED:
            assert layer in CONFINED[top], f"{path}:{lineno} ({layer}) imports {top}"


def test_only_the_orb_module_imports_cv2() -> None:
    importers = {str(p.relative_to(PACKAGE)) for p in _files()
                 if any(name.split(".")[0] == "cv2" for _, name in _imports(p))}
    assert importers <= {"vision/orb.py"}, importers


def test_layer_table_covers_every_package() -> None:
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and not p.name.startswith("_")}
    assert packages - {"__pycache__"} == set(ALLOWED)


# --- protocols are read through their declared attributes, not getattr (issue 18) --------------

_PROTOCOL_OBJECTS = ("observer", "estimator", "factory", "output", "run", "snapshot", "payload")


@pytest.mark.parametrize("path", [p for p in _files() if p.relative_to(PACKAGE).parts[0] in ("experiments", "viz")],
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_getattr_reads_of_protocol_objects(path: Path) -> None:
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "hasattr")
                and node.args and isinstance(node.args[0], ast.Name) and node.args[0].id in _PROTOCOL_OBJECTS):
            raise AssertionError(f"{path}:{node.lineno}: {node.func.id}({node.args[0].id}, ...) reads a protocol "
                                 "by name; declare the attribute on the protocol and read it directly")


def test_every_recorder_and_the_null_observer_satisfy_the_observer_protocol(tmp_path) -> None:
    from slamkit.experiments.observers import NullObserver, PipelineObserver
    from slamkit.experiments.pipeline import PIPELINES, pipeline_of, recorder_of
    from slamkit.viz.pipelines import observer_for

    assert isinstance(NullObserver(), PipelineObserver)
    for kind in PIPELINES:
        assert recorder_of(kind) is not None, f"no recorder registered against {kind}"
        observer = observer_for(kind, tmp_path / f"{kind}.rrd")
        assert isinstance(observer, PipelineObserver), kind
        assert isinstance(observer.wants_steps, bool) and observer.step_every >= 1
        # the recorder reads the payload its pipeline declares
        assert observer.payload_type == pipeline_of(kind).payload_type, kind
        observer.close()


def test_every_registry_estimator_satisfies_its_protocol() -> None:
    import numpy as np

    from slamkit.data.estimate import BatchEstimator, Estimator
    from slamkit.experiments.estimators import REGISTRY, factory
    from slamkit.sim.landmark_world import mildly_nonlinear, simulate_landmark_sequence

    from slamkit.sim.inertial_world import PRESETS, simulate_inertial_sequence

    seq = simulate_landmark_sequence(mildly_nonlinear(duration_s=1.0), np.random.default_rng(0))
    inertial = simulate_inertial_sequence(PRESETS["car3d"](duration_s=1.0), np.random.default_rng(0))
    for name, spec in REGISTRY.items():
        built = factory(name)
        est = built(inertial if spec.sequence_kind == "inertial" else seq)
        assert built.kind == spec.kind
        assert isinstance(est, BatchEstimator if spec.kind == "batch" else Estimator), name


def test_angle_wrapping_is_written_once() -> None:
    """``(a + pi) % (2 pi) - pi`` is ``slamkit.geometry.angles.wrap_angle``; copies (PRM's
    sampler and the potential-field controller had one each, issue 30) are not written again."""
    import re

    copy = re.compile(r"\+ *(np|math)\.pi\) *% *\(?2(\.0)? *\* *(np|math)\.pi")
    found = [f"{path.relative_to(PACKAGE.parent)}:{no}"
             for path in PACKAGE.rglob("*.py") if path.parent.name != "geometry"
             for no, line in enumerate(path.read_text().splitlines(), 1) if copy.search(line)]
    assert not found, f"angle wrapped by hand (use slamkit.geometry.angles.wrap_angle): {found}"


# --- experiments feed, score and report (issue 30) -----------------------------------------------

#: experiments modules that are not a pipeline: the machinery that feeds systems and estimators,
#: scores them and writes results (runner, sweeps, executors, result folders, config validation)
_EXPERIMENT_MACHINERY = {"__init__", "config_models", "estimators", "executors", "observers", "perturbation",
                         "pipeline", "results", "runner", "sweep", "planning"}
#: known leftovers (issue 30 item 2): none since the navigation pipeline became a package (its map
#: source and benchmark protocol are its modules)
_EXPERIMENT_LEFTOVERS: set[str] = set()


def test_experiments_hold_pipelines_and_their_machinery() -> None:
    """A module in slamkit.experiments is a registered pipeline (module or package) or the
    machinery every pipeline shares; simulation, systems, metrics and loaders live in their layers
    (stereo VO and VIO, used by tests only, and the image-sequence loader left in issue 30)."""
    from slamkit.experiments.pipeline import PIPELINES

    pipelines = {str(entry.target).split(":")[0].split(".")[2] for entry in PIPELINES.values()
                 if isinstance(entry.target, str) and entry.target.startswith("slamkit.experiments.")}
    assert pipelines, "no built-in pipeline found"
    experiments = PACKAGE / "experiments"
    modules = {p.stem for p in experiments.glob("*.py")} | {p.name for p in experiments.iterdir()
                                                             if p.is_dir() and (p / "__init__.py").exists()}
    stray = modules - pipelines - _EXPERIMENT_MACHINERY - _EXPERIMENT_LEFTOVERS
    assert not stray, (f"slamkit.experiments modules that are neither a pipeline nor shared machinery: "
                       f"{sorted(stray)}; move them to sim, systems, metrics or data")


#: function-local slamkit imports left in slamkit.experiments, each for a reason (module stem ->
#: imported modules): the estimator table reads the estimation layer's filter table at every
#: lookup and imports it lazily (importing it pulls every filter: 1 s for any experiments import)
_LAZY_IMPORTS = {"estimators": {"slamkit.estimation", "slamkit.estimation.registry"}}


def _local_slamkit_imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), filename=str(path))
    top_level = {id(node) for node in tree.body}
    out = []
    for node in ast.walk(tree):
        if id(node) in top_level:
            continue
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("slamkit"):
            out.append((node.lineno, node.module))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.startswith("slamkit")]
    return out


@pytest.mark.parametrize("path", sorted((PACKAGE / "experiments").rglob("*.py")),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_experiments_import_slamkit_at_module_level(path: Path) -> None:
    """No import circle is held apart by function-local imports (issue 30): a module of
    slamkit.experiments imports what it needs at its top, except the lazy imports listed."""
    allowed = _LAZY_IMPORTS.get(path.stem, set())
    wrong = [(no, mod) for no, mod in _local_slamkit_imports(path) if mod not in allowed]
    assert not wrong, f"function-local slamkit imports in {path.relative_to(PACKAGE)}: {wrong}"


def test_the_lazy_import_list_is_not_stale() -> None:
    for stem, modules in _LAZY_IMPORTS.items():
        found = {mod for _, mod in _local_slamkit_imports(PACKAGE / "experiments" / f"{stem}.py")}
        assert modules <= found, f"{stem}: {sorted(modules - found)} are module-level now; drop them here"


#: imports of one pipeline's module by another module of slamkit.experiments that are known
#: leftovers (importer stem -> pipeline stems); none left since issue 30
_PIPELINE_IMPORT_LEFTOVERS: dict[str, set[str]] = {}


def test_pipelines_do_not_import_each_other() -> None:
    """What two pipelines share lives in the layer it belongs to (sim, systems, metrics, data);
    a pipeline module or package is imported only by itself and the registry's target string."""
    from slamkit.experiments.pipeline import PIPELINES

    pipelines = {str(entry.target).split(":")[0].split(".")[2] for entry in PIPELINES.values()
                 if isinstance(entry.target, str) and entry.target.startswith("slamkit.experiments.")}
    wrong = []
    for path in sorted((PACKAGE / "experiments").rglob("*.py")):
        parts = path.relative_to(PACKAGE / "experiments").with_suffix("").parts
        own = parts[0]
        for no, mod in _imports(path):
            target = mod.split(".")
            if target[:2] != ["slamkit", "experiments"] or len(target) < 3:
                continue
            if (target[2] in pipelines and target[2] != own
                    and target[2] not in _PIPELINE_IMPORT_LEFTOVERS.get(own, set())):
                wrong.append(f"{path.relative_to(PACKAGE)}:{no} imports {mod}")
    assert not wrong, "imports between pipelines:\n" + "\n".join(wrong)
    for importer, targets in _PIPELINE_IMPORT_LEFTOVERS.items():
        found = {mod.split(".")[2] for _, mod in _imports(PACKAGE / "experiments" / f"{importer}.py")
                 if mod.startswith("slamkit.experiments.")}
        assert targets <= found, f"{importer} no longer imports {sorted(targets - found)}: drop it from the leftovers"
