"""``slamkit bench vision``: the monocular VO front-end on real 1226 x 370 KITTI frames
(``kitti-vo-a``), the issue's speed goal (>= 10 frames/s on 2 cores), and its parts.

``mono_vo_frontend_fps``: frames per second of :class:`slamkit.systems.visual_odometry.VisualOdometry`
without bundle adjustment (ORB detection, guided Hamming matching with ratio test and
cross-check, 5-point RANSAC, PnP RANSAC, triangulation), images already decoded. The parts are
timed on the same consecutive frame pairs: ORB detection per image, brute-force and guided
(``match_window_px``) matching per pair (the guided case's reference is the brute force),
essential-matrix RANSAC per pair. The cases carry a goal, not a same-run reference (the OpenCV pipeline that would be the
reference may only be imported by slamkit.vision.orb); ``bundle_adjustment_ms`` is the 10-frame
window's cost per frame. Speed is measured here, never asserted in the tests.
"""

from __future__ import annotations

import time

import numpy as np

from slamkit.bench.cases import BenchCase, best_of
from slamkit.data.formats.image import read_image
from slamkit.data.formats.image_sequence import load_image_sequence
from slamkit.systems.visual_odometry import VisualOdometry, VisualOdometryConfig
from slamkit.vision.orb import detect_orb, match_descriptors, match_descriptors_windowed
from slamkit.vision.two_view import ransac_essential


def run(quick: bool = False) -> list[BenchCase]:
    n = 6 if quick else 30
    seq = load_image_sequence("kitti-vo-a", max_frames=n)
    images = [read_image(p) for p in seq.images]
    cfg = VisualOdometryConfig(window=0)

    def frontend():
        vo = VisualOdometry(seq.camera, cfg)
        for k, img in enumerate(images):
            vo.step(0.1 * k, img)

    frontend_s, _ = best_of(frontend, repeat=1 if quick else 2)
    feats = [detect_orb(img, cfg.orb) for img in images[:4]]
    orb_s, _ = best_of(lambda: [detect_orb(img, cfg.orb) for img in images[:4]], repeat=2)
    match_s, matches = best_of(lambda: [match_descriptors(a.descriptors, b.descriptors, cfg.match_ratio)
                                        for a, b in zip(feats, feats[1:])], repeat=2)
    guided_s, guided = best_of(lambda: [match_descriptors_windowed(a.uv, a.descriptors, b.uv, b.descriptors,
                                                                   cfg.match_window_px, cfg.match_ratio)
                                        for a, b in zip(feats, feats[1:])], repeat=2)
    x = [(seq.camera.unproject(a.uv[m[:, 0]])[:, :2], seq.camera.unproject(b.uv[m[:, 1]])[:, :2])
         for a, b, m in zip(feats, feats[1:], matches)]
    ess_s, _ = best_of(lambda: [ransac_essential(x1, x2, cfg.ransac_threshold_px / seq.camera.fx,
                                                 rng=np.random.default_rng(0)) for x1, x2 in x], repeat=2)
    vo = VisualOdometry(seq.camera, VisualOdometryConfig(window=10))
    t0 = time.perf_counter()
    ba_ms = [vo.step(0.1 * k, img).ba_ms for k, img in enumerate(images)]
    total_s = time.perf_counter() - t0
    pairs = len(x)
    return [
        BenchCase("mono_vo_frontend_fps_1226x370", n / frontend_s, "frames/s", goal=">= 10",
                  extra={"frames": n, "orb_features": cfg.orb.num_features}),
        BenchCase("orb_detect_1226x370", 1e3 * orb_s / 4, "ms", extra={"features": int(np.mean([len(f) for f in feats]))}),
        BenchCase("orb_match_ratio_cross_check", 1e3 * match_s / pairs, "ms",
                  extra={"matches": int(np.mean([len(m) for m in matches]))}),
        BenchCase("orb_match_guided_window", 1e3 * guided_s / len(guided), "ms",
                  reference="orb_match_ratio_cross_check (brute force)", reference_value=1e3 * match_s / pairs,
                  ratio=match_s / guided_s,
                  extra={"matches": int(np.mean([len(m) for m in guided])), "window_px": cfg.match_window_px}),
        BenchCase("essential_5pt_ransac", 1e3 * ess_s / pairs, "ms"),
        BenchCase("bundle_adjustment_window10", float(np.median(ba_ms[2:])), "ms",
                  extra={"vo_with_ba_fps": n / total_s}),
    ]
