"""The ``visual_odometry`` pipeline: a sequence given as a folder spec and as a registry name,
its results folder (metrics with units, trajectories/<name>.tum), its report and its Rerun
recording (checked with the rerun CLI); the shipped config validates and, under ``slow``, runs
on all 51 frames of kitti_vo_a."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slamkit.data.formats.image_sequence import load_image_sequence
from slamkit.data.formats.tum import read_tum
from slamkit.errors import ConfigError
from slamkit.experiments.pipeline import load_config, run_pipeline
from slamkit.viz.pipelines import observer_for

ROOT_PIPELINES = __import__("pathlib").Path(__file__).resolve().parents[2] / "pipelines"
METRICS = ("ate_rmse_m", "ate_se3_rmse_m", "rpe_rmse_m", "rpe_rot_rmse_deg", "inlier_ratio", "time_per_frame_ms")


@pytest.fixture(scope="module")
def kitti_root(shared_datasets):
    return shared_datasets / "vision" / "kitti_vo_a"


def test_folder_spec_run_writes_metrics_trajectory_and_recording(tmp_path, kitti_root, verify_rrd, monkeypatch):
    cfg = {"pipeline": "visual_odometry", "name": "vo_tiny", "max_frames": 6,
           "sequences": [{"name": "kitti_a", "images": str(kitti_root / "image_l"),
                          "calib": str(kitti_root / "calib.txt"), "poses": str(kitti_root / "poses.txt")}],
           "vo": {"window": 5}}
    res = run_pipeline(cfg, tmp_path / "run", progress=False, observer_factory=observer_for)
    out = res.out_dir
    results = json.loads((out / "results.json").read_text())
    runs = {r["estimator"]: r for r in results["runs"]}
    assert set(runs) == {"mono_vo_ba", "mono_vo"}
    for r in runs.values():
        assert set(METRICS) <= set(r["metrics"])
        assert r["metrics"]["num_frames"] == 6
        assert 0.5 < r["metrics"]["inlier_ratio"] <= 1.0
        assert r["metrics"]["keypoints_mean"] > 1000
    # 6 frames, ~6 m: measured 0.012 m with BA
    assert runs["mono_vo_ba"]["metrics"]["ate_rmse_m"] < 0.1
    traj = read_tum(out / "trajectories" / "kitti_a.tum")
    assert len(traj) == 6
    np.testing.assert_allclose(traj.stamps_s, np.arange(6) * 0.1)
    assert (out / "trajectories" / "kitti_a_no_ba.tum").exists()
    assert (out / "plots" / "trajectory_kitti_a.png").exists()
    assert "ate_rmse_m" in (out / "report.md").read_text()
    paths = verify_rrd(out / "recording.rrd")
    base = "/kitti_a/mono_vo_ba/world"
    for entity in ("ground_truth", "estimate", "points", "camera", "camera/image", "camera/image/keypoints",
                   "camera/image/matches"):
        assert f"{base}/{entity}" in paths, entity


def test_registry_name_resolves_to_the_kitti_folder(kitti_root):
    seq = load_image_sequence("kitti-vo-a", max_frames=4)
    assert seq.name == "kitti-vo-a" and len(seq.images) == 4
    assert seq.camera.fx == pytest.approx(707.0912) and (seq.camera.width, seq.camera.height) == (1226, 370)
    assert seq.ground_truth is not None and len(seq.ground_truth) == 4
    full = load_image_sequence({"name": "a", "images": str(kitti_root / "image_l"),
                                "calib": str(kitti_root / "calib.txt"), "poses": str(kitti_root / "poses.txt")})
    assert len(full.images) == 51 and full.ground_truth.path_length_m() == pytest.approx(59.9, abs=0.1)


def test_shipped_config_validates_and_bad_keys_are_named(tmp_path):
    cfg = load_config(ROOT_PIPELINES / "visual_odometry.yaml")
    assert cfg["pipeline"] == "visual_odometry" and cfg["sequences"] == ["kitti-vo-a"]
    bad = tmp_path / "bad.yaml"
    bad.write_text("pipeline: visual_odometry\nsequences: [kitti-vo-a]\nvo: {windw: 3}\n")
    with pytest.raises(ConfigError, match="windw"):
        load_config(bad)
    bad.write_text("pipeline: visual_odometry\nsequences: [kitti-vo-a]\nvo: {orb: {num_features: -1}}\n")
    with pytest.raises(ConfigError):
        load_config(bad)


@pytest.mark.slow
def test_shipped_pipeline_on_all_51_frames(tmp_path):
    """The issue's goal: Sim(3) ATE below 1 % of the 59.9 m driven, and BA lowering it
    (measured: see the report in the final commit message)."""
    res = run_pipeline(load_config(ROOT_PIPELINES / "visual_odometry.yaml"), tmp_path / "run", progress=False)
    runs = {r["estimator"]: r["metrics"] for r in res.results["runs"]}
    assert runs["mono_vo_ba"]["ate_rmse_m"] < 0.6
    assert runs["mono_vo_ba"]["ate_rmse_m"] < runs["mono_vo"]["ate_rmse_m"]


# --- issue 31: frames that cannot be used are refused by index and file -----------------------


def _folder(tmp_path, kitti_root, n: int, replace: dict[int, np.ndarray]) -> dict:
    from PIL import Image

    images = tmp_path / "image_l"
    images.mkdir()
    for k in range(n):
        src = kitti_root / "image_l" / f"{k:06d}.png"
        if k in replace:
            Image.fromarray(replace[k]).save(images / src.name)
        else:
            (images / src.name).write_bytes(src.read_bytes())
    return {"name": "bad", "images": str(images), "calib": str(kitti_root / "calib.txt"),
            "poses": str(kitti_root / "poses.txt")}


def test_a_frame_of_another_size_is_refused_naming_index_and_file(tmp_path, kitti_root):
    """Frame 2 cropped to 1000 x 300 (the camera, from frame 0, is 1226 x 370): before, the run
    went on with the wrong principal point and scored ATE 1.10 m where the run gives ~0.03 m."""
    from slamkit.data.formats.image import read_image
    from slamkit.errors import DataError
    from slamkit.experiments.visual_odometry import run_vo

    crop = read_image(kitti_root / "image_l" / "000002.png")[:300, :1000].astype(np.uint8)
    seq = load_image_sequence(_folder(tmp_path, kitti_root, 4, {2: crop}))
    with pytest.raises(DataError, match=r"image_l/000002\.png: frame 2 \(t=0\.2\d* s\): 1000 x 300 pixels, but the "
                                        r"camera \(and frame 0\) is 1226 x 370"):
        run_vo(seq)


@pytest.mark.parametrize("size", [(1, 1), (62, 400)])
def test_a_frame_too_small_is_refused(tmp_path, kitti_root, size):
    """A 1 x 1 frame 0 (the camera is then 1 x 1) was an OpenCV assertion; 63 px a side is the least
    ORB can describe a keypoint in."""
    from slamkit.errors import DataError
    from slamkit.experiments.visual_odometry import run_vo

    tiny = np.full(size, 128, np.uint8)
    seq = load_image_sequence(_folder(tmp_path, kitti_root, 3, {0: tiny, 1: tiny, 2: tiny}))
    with pytest.raises(DataError, match=rf"image_l/000000\.png: frame 0 \(t=0\.0 s\): {size[1]} x {size[0]} pixels "
                                        r"is too small for visual odometry \(at least 63 x 63\)"):
        run_vo(seq)
