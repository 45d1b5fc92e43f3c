"""The local-planning recording: verified by the rerun CLI, with the entities the viewer needs
to show why each controller acted (rollouts + chosen for DWA, the horizon for MPC)."""

from __future__ import annotations

import numpy as np

from slamkit.control.registry import make_controller
from slamkit.experiments.closed_loop import ClosedLoopConfig, make_scenario, run_episode
from slamkit.viz.control import ClosedLoopRecorder, _score_colors


def test_score_colours_grey_out_inadmissible():
    c = _score_colors(np.array([0.0, 1.0, -np.inf]))
    assert tuple(c[0][:3]) == (255, 0, 40)       # worst: red
    assert tuple(c[1][:3]) == (0, 200, 40)       # best: green
    assert tuple(c[2]) == (150, 150, 150, 90)    # inadmissible: grey


def test_recording_of_dwa_and_mpc_episodes(tmp_path, verify_rrd):
    sc = make_scenario(0, "open")
    loop = ClosedLoopConfig(max_time_s=3.0)
    path = tmp_path / "local.rrd"
    rec = ClosedLoopRecorder(path)
    eps = [run_episode(sc, make_controller(name), loop, [rec]) for name in ("dwa", "mpc_osqp")]
    rec.close()
    assert all(len(e.t_s) == 31 for e in eps)  # 3 s at 10 Hz, plus the start
    entities = verify_rrd(path)
    for ctl in ("dwa", "mpc_osqp"):
        p = f"/{ctl}/{sc.name}"
        for e in ("world/map", "world/global_path", "world/robot", "world/obstacles", "plots/speed_mps",
                  "plots/clearance_m"):
            assert f"{p}/{e}" in entities, (p, e)
    assert f"/dwa/{sc.name}/world/candidates" in entities
    assert f"/dwa/{sc.name}/world/chosen" in entities
    assert f"/mpc_osqp/{sc.name}/world/mpc_horizon" in entities
    assert f"/mpc_osqp/{sc.name}/world/mpc_reference" in entities
