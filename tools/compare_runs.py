#!/usr/bin/env python
"""Compare two slamkit run folders: identical run metrics (timing aside) and trajectory files.

A refactor that claims "behaviour identical" proves it with this script (issue 30): run the
pipelines before and after, then compare the folders::

    python tools/compare_runs.py run BEFORE_DIR            # at the old commit
    python tools/compare_runs.py run AFTER_DIR             # at the new one
    python tools/compare_runs.py compare BEFORE_DIR AFTER_DIR

``run`` writes one sub-folder per pipeline (filter_vs_smoother, pose_graph, lidar_slam,
navigation) from small but real configs (``SMALL_CONFIGS`` below; ``--only`` picks some, ``--src``
runs another checkout, e.g. a ``git worktree`` of the old commit, with this checkout's shared
datasets unless ``SLAMKIT_DATA`` says otherwise). ``compare`` accepts either two
run folders (each with a ``results.json``) or two folders of such run folders, and compares

* ``results.json``: every field, recursively, except wall-clock ones (``TIMING``: ``*_ms``,
  ``*_ms_<statistic>`` (visual odometry's ``frontend_ms_median`` of runs before its rename),
  ``time_*`` but simulated ``time_to_*``/``time_over_*``, real-time factors, peak memory,
  ``created``, the version) -- numbers must be
  equal (``--rtol`` loosens that, default 0: identical), lists equally long, keys the same;
  ``summary`` rows of a timing metric are skipped as a whole; rows that name themselves (a run's
  dataset/estimator/seed, a summary row's metric) are matched by that label, so a row added on
  one side is one line, not a shift of every later row;
* ``trajectories/``: the same file names with the same bytes (where they differ the largest
  numeric difference is printed).

Every difference is printed, one a line, with its path; the exit status is 1 if there is any,
0 otherwise (2 for a usage error such as a missing folder). Standard library only, so it runs
under any checkout's interpreter.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

#: result fields that measure wall-clock time or describe the run, not its outcome
TIMING = re.compile(
    r"(_ms$|_ms_|^created$|^slamkit_version$|^machine$|^time_(?!to_|over_)|^total_time_s$|peak_rss|"
    r"real_?time_factor|wall|latency|_build_s$|^scan_matching_s$|^elapsed|runtime|^run_s$)")

#: small but real configs of the four pipelines of the main issue families (about 5 min on 2 cores);
#: YAML is a superset of JSON, so they are written as JSON and the script needs no yaml module
SMALL_CONFIGS: dict[str, dict] = {
    "filter_vs_smoother": {
        "pipeline": "filter_vs_smoother", "name": "filter_vs_smoother", "seeds": 2, "workers": 1,
        "scenarios": [
            {"preset": "mild", "params": {"duration_s": 10.0}},
            {"preset": "strong", "params": {"duration_s": 10.0, "odometry_sigma_v_mps": 0.1,
                                            "odometry_sigma_omega_radps": 0.6,
                                            "sensor": {"rate_hz": 0.5, "sigma_range_m": 0.02,
                                                       "sigma_bearing_rad": 0.01}}}],
        "estimators": {"ekf": {}, "ukf": {}, "pf": {"n_particles": 200}, "ekf_slam": {}, "batch": {},
                       "isam2": {}, "fixed_lag": {"lag_s": 5.0}},
        "record": False},
    "pose_graph": {
        "pipeline": "pose_graph", "name": "pose_graph", "datasets": ["intel", "manhattan-olson", "sphere2500"],
        "solvers": ["lm", "gn"], "inits": ["file", "lago", "chordal"], "robust": "none",
        "options": {"max_iterations": 30}, "record": False},
    "lidar_slam": {
        "pipeline": "lidar_slam", "name": "lidar_slam", "seeds": [0],
        "worlds": [{"name": "office_tour", "world": "office", "world_size_m": [30.0, 30.0], "num_goals": 3,
                    "duration_s": 60.0}],
        "slam": {"robust": "cauchy", "loop_rounds": 2, "submap_keyframes": 3,
                 "keyframes": {"min_translation_m": 0.5, "min_rotation_rad": 0.35},
                 "icp": {"method": "point_to_line", "trim_fraction": 0.9, "max_correspondence_m": 1.0},
                 "loops": {"search_radius_m": 3.0, "min_fitness": 0.6, "max_candidates_per_keyframe": 2,
                           "icp": {"trim_fraction": 0.9}},
                 "map": {"resolution_m": 0.1}},
        "false_loop_closures": 0, "robust_variants": ["cauchy"], "mcl": {"max_updates": 30, "filter_seeds": 2},
        "record": False},
    "navigation": {
        "pipeline": "navigation", "name": "navigation",
        "scenarios": {"worlds": ["office", "warehouse"], "seeds": {"start": 0, "count": 2}, "n_obstacles": 2,
                      "willow_map": "willow"},
        "navigation": {"controller": "dwa", "global_planner": "astar"},
        "episode": {"max_time_s": 90.0, "goal_tolerance_m": 0.03, "heading_tolerance_rad": 0.1},
        "variants": [{"name": "nominal"}], "record_scenarios": 0},
}


# ------------------------------------------------------------------------------------- compare

def _is_timing_row(value: object) -> bool:
    return isinstance(value, dict) and isinstance(value.get("metric"), str) and bool(TIMING.search(value["metric"]))


def _numbers_equal(a: float, b: float, rtol: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if a == b:
        return True
    return rtol > 0 and math.isfinite(a) and math.isfinite(b) and abs(a - b) <= rtol * max(abs(a), abs(b))


def compare_json(a: object, b: object, path: str = "", rtol: float = 0.0) -> list[str]:
    """Differences between two parsed results.json values, timing fields aside, one line each."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b), key=str):
            if TIMING.search(str(key)):
                continue
            where = f"{path}.{key}" if path else str(key)
            if key not in a:
                out.append(f"{where}: only in second ({_short(b[key])})")
            elif key not in b:
                out.append(f"{where}: only in first ({_short(a[key])})")
            else:
                out.extend(compare_json(a[key], b[key], where, rtol))
        return out
    if isinstance(a, list) and isinstance(b, list):
        a = [x for x in a if not _is_timing_row(x)]
        b = [x for x in b if not _is_timing_row(x)]
        la, lb = [_label(x) for x in a], [_label(y) for y in b]
        if all(la) and all(lb) and len(set(la)) == len(la) and len(set(lb)) == len(lb):
            # rows that say who they are (run, summary row): matched by that, so one added or
            # removed row is reported once instead of shifting every row after it
            by_b = dict(zip(lb, b))
            out = [f"{path}{label}: only in first" for label in la if label not in by_b]
            out += [f"{path}{label}: only in second" for label in lb if label not in set(la)]
            for x, label in zip(a, la):
                if label in by_b:
                    out.extend(compare_json(x, by_b[label], f"{path}{label}", rtol))
            return out
        out = [] if len(a) == len(b) else [f"{path}: {len(a)} items against {len(b)}"]
        for i, (x, y) in enumerate(zip(a, b)):
            out.extend(compare_json(x, y, f"{path}[{i}]{_label(x)}", rtol))
        return out
    numeric = (int, float)
    if isinstance(a, numeric) and isinstance(b, numeric) and not isinstance(a, bool) and not isinstance(b, bool):
        return [] if _numbers_equal(float(a), float(b), rtol) else [f"{path}: {a!r} != {b!r}"]
    return [] if a == b else [f"{path}: {_short(a)} != {_short(b)}"]


def _label(item: object) -> str:
    """A run's identity in a difference's path (dataset, estimator, seed ...), to read it quickly."""
    if not isinstance(item, dict):
        return ""
    keys = ("dataset", "world", "scenario", "variant", "estimator", "solver", "init", "seed", "metric")
    parts = [f"{k}={item[k]}" for k in keys if k in item and not isinstance(item[k], (dict, list))]
    return "{" + ",".join(parts) + "}" if parts else ""


def _short(value: object, limit: int = 80) -> str:
    text = json.dumps(value, sort_keys=True, default=str)
    return text if len(text) <= limit else text[:limit] + "..."


def _numbers(text: str) -> list[float]:
    out = []
    for token in text.split():
        try:
            out.append(float(token))
        except ValueError:
            pass
    return out


def compare_trajectories(a_dir: Path, b_dir: Path, label: str) -> list[str]:
    a_files = {p.relative_to(a_dir).as_posix() for p in a_dir.rglob("*") if p.is_file()} if a_dir.is_dir() else set()
    b_files = {p.relative_to(b_dir).as_posix() for p in b_dir.rglob("*") if p.is_file()} if b_dir.is_dir() else set()
    out = [f"{label}/{name}: only in first" for name in sorted(a_files - b_files)]
    out += [f"{label}/{name}: only in second" for name in sorted(b_files - a_files)]
    for name in sorted(a_files & b_files):
        x, y = (a_dir / name).read_bytes(), (b_dir / name).read_bytes()
        if x == y:
            continue
        nx, ny = _numbers(x.decode(errors="replace")), _numbers(y.decode(errors="replace"))
        if len(nx) != len(ny):
            out.append(f"{label}/{name}: differs ({len(nx)} numbers against {len(ny)})")
        else:
            worst = max((abs(p - q) for p, q in zip(nx, ny) if not (math.isnan(p) and math.isnan(q))), default=0.0)
            out.append(f"{label}/{name}: differs (largest numeric difference {worst:.3g})")
    return out


def compare_run(a: Path, b: Path, label: str = "", rtol: float = 0.0) -> list[str]:
    """Differences between two run folders (results.json and trajectories/)."""
    prefix = f"{label}: " if label else ""
    out = []
    for side, folder in (("first", a), ("second", b)):
        if not (folder / "results.json").is_file():
            out.append(f"{prefix}no results.json in the {side} folder ({folder})")
    if out:
        return out
    ra = json.loads((a / "results.json").read_text())
    rb = json.loads((b / "results.json").read_text())
    out = [prefix + d for d in compare_json(ra, rb, "results.json", rtol)]
    out += [prefix + d for d in compare_trajectories(a / "trajectories", b / "trajectories", "trajectories")]
    return out


def compare(a: Path, b: Path, rtol: float = 0.0) -> list[str]:
    """Two run folders, or two folders holding run folders (compared by name)."""
    if (a / "results.json").is_file() or (b / "results.json").is_file():
        return compare_run(a, b, rtol=rtol)
    runs_a = {p.name for p in a.iterdir() if (p / "results.json").is_file()}
    runs_b = {p.name for p in b.iterdir() if (p / "results.json").is_file()}
    if not runs_a and not runs_b:
        return [f"no run folder (with a results.json) in {a} or {b}"]
    out = [f"{name}: run only in first" for name in sorted(runs_a - runs_b)]
    out += [f"{name}: run only in second" for name in sorted(runs_b - runs_a)]
    for name in sorted(runs_a & runs_b):
        out.extend(compare_run(a / name, b / name, name, rtol))
    return out


# ------------------------------------------------------------------------------------- run

def run_pipelines(out: Path, only: list[str] | None = None, src: Path | None = None,
                  python: str = sys.executable) -> int:
    """Run the small configs into ``out/<pipeline>``; ``src``: the checkout to import slamkit from."""
    names = only or list(SMALL_CONFIGS)
    unknown = sorted(set(names) - set(SMALL_CONFIGS))
    if unknown:
        print(f"unknown pipeline(s) {', '.join(unknown)}; known: {', '.join(SMALL_CONFIGS)}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = str(src.resolve()) + os.pathsep + env.get("PYTHONPATH", "")
        # a checkout elsewhere (a git worktree in /tmp) finds no ../shared/datasets of its own
        shared = Path(__file__).resolve().parents[2] / "shared" / "datasets"
        if "SLAMKIT_DATA" not in env and shared.is_dir():
            env["SLAMKIT_DATA"] = str(shared)
    status = 0
    for name in names:
        config = out / f"{name}.config.yaml"
        config.write_text(json.dumps(SMALL_CONFIGS[name], indent=1) + "\n")
        cmd = [python, "-c", "import sys; from slamkit.cli import main; sys.argv[0] = 'slamkit'; main()",
               "run", str(config), "--out", str(out / name), "--quiet", "--overwrite"]
        done = subprocess.run(cmd, env=env, cwd=str(src) if src is not None else None)
        print(f"{name}: exit {done.returncode}")
        status = status or done.returncode
    return status


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("compare", help="compare two run folders (or folders of run folders)")
    c.add_argument("first", type=Path)
    c.add_argument("second", type=Path)
    c.add_argument("--rtol", type=float, default=0.0, help="relative tolerance for numbers (default 0: identical)")
    r = sub.add_parser("run", help="run the four pipelines on small configs into OUT/<pipeline>")
    r.add_argument("out", type=Path)
    r.add_argument("--only", nargs="+", metavar="PIPELINE", help=f"a subset of {', '.join(SMALL_CONFIGS)}")
    r.add_argument("--src", type=Path, help="the checkout to run (default: the installed slamkit)")
    args = parser.parse_args(argv)
    if args.command == "run":
        return run_pipelines(args.out, args.only, args.src)
    for folder in (args.first, args.second):
        if not folder.is_dir():
            print(f"not a folder: {folder}", file=sys.stderr)
            return 2
    diffs = compare(args.first, args.second, args.rtol)
    for line in diffs:
        print(line)
    print(f"{len(diffs)} difference(s)" if diffs else "identical (timing fields aside)")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
