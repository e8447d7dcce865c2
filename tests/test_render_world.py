"""The sea and the obstacles in the video (issues 7 and 8; usv_mj.outputs.render.world, FrameRenderer.update_sea).

References: the plant's own Environment (``usv_mj.loop.simulate.make_environment`` of the scenario,
built independently of the renderer's copy) evaluated at the hfield node, and MuJoCo's own ray cast
(``mj_ray``) onto the hfield geom, which reads the geometry as MuJoCo holds it; the obstacles'
constant velocity (centre = center + velocity t) for the mocap bodies.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from usv_mj import load_scenario
from usv_mj.record.run_record import RunRecord
from usv_mj.outputs.render import gl_backend
from usv_mj.outputs.render.planner import TopView, plan_frames
from usv_mj.loop.simulate import make_environment

ROOT = Path(__file__).resolve().parents[1]
SEA = {"preset": "moderate", "current": {"speed": 0.3, "direction_deg": 30.0},
       "wind": {"speed": 5.0, "direction_deg": 90.0, "gust_sigma": 1.0}}


def _gl_or_skip():
    try:
        return gl_backend.select_backend()
    except gl_backend.GLUnavailableError as exc:  # pragma: no cover - CI installs Mesa
        pytest.skip(str(exc))


def _in_fresh_process(code: str) -> dict:
    """Run ``code`` (which prints one JSON object last) in a new interpreter whose mujoco is bound to the
    selected GL backend (this process may have imported mujoco with another one)."""
    backend = _gl_or_skip()
    env = {**os.environ, **gl_backend.backend_environment(backend)}
    if backend == "glfw":  # pragma: no cover
        env.pop("PYOPENGL_PLATFORM", None)
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env,
                          cwd=str(ROOT), timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _record(scenario, poses, times):
    poses = np.asarray(poses, float)
    return RunRecord.from_arrays({"t": np.asarray(times, float), "x": poses[:, 0], "y": poses[:, 1],
                                  "psi": poses[:, 2]}, metadata={"scenario": scenario.to_dict()})


def test_hfield_node_under_the_hull_is_the_plants_elevation():
    out = _in_fresh_process("""
        import json
        from usv_mj.outputs.render.gl_backend import select_backend
        select_backend(None)
        import mujoco, numpy as np
        from usv_mj import load_scenario
        from usv_mj.record.run_record import RunRecord
        from usv_mj.outputs.render.planner import plan_frames
        from usv_mj.outputs.render.replay import FrameRenderer
        from usv_mj.outputs.render.world import SEA_NODES
        sea = %r
        sc = load_scenario(preset="paper", overrides={"duration": 20.0, "sea": sea})
        rec = RunRecord.from_arrays({"t": np.array([7.3, 12.05]), "x": np.array([3.13, -7.91]),
                                     "y": np.array([-2.27, 4.06]), "psi": np.array([0.4, -1.0])},
                                    metadata={"scenario": sc.to_dict()})
        plan = plan_frames(rec, rows=[0, 1], width=320, height=240)
        r = FrameRenderer(320, 240)
        rows = []
        for spec in plan.frames:
            frame = r.render(spec)
            nx, ny, nz = r.sea_node_under_hull()
            cell = 2.0 * r.model.hfield_size[r.sea_hfield, 0] / (SEA_NODES - 1)
            geomid = np.array([-1], np.int32)
            dist = mujoco.mj_ray(r.model, r.data, np.array([nx, ny, 5.0]), np.array([0.0, 0.0, -1.0]),
                                 np.array([1, 0, 0, 0, 0, 0], np.uint8), 1, -1, geomid)
            rows.append({"t": spec.t, "pose": list(spec.pose), "node": [nx, ny, nz], "cell": cell,
                         "ray_z": 5.0 - dist, "ray_geom": int(geomid[0]), "sea_geom": r.sea_geom,
                         "std": float(frame.std())})
        r.close()
        print(json.dumps({"rows": rows}))
    """ % (SEA,))
    sc = load_scenario(preset="paper", overrides={"duration": 20.0, "sea": SEA})
    env = make_environment(sc)            # the plant's environment, built here independently
    assert len(out["rows"]) == 2
    for row in out["rows"]:
        nx, ny, nz = row["node"]
        assert row["std"] > 5.0
        assert abs(nx - row["pose"][0]) <= row["cell"] / 2 + 1e-9 and abs(ny - row["pose"][1]) <= row["cell"] / 2 + 1e-9
        want = env.elevation(nx, ny, row["t"])
        assert abs(want) > 1e-3                              # a real wave, not the calm level
        assert nz == pytest.approx(want, abs=1e-5)
        # MuJoCo's own reading of the hfield: a ray straight down onto the node
        assert row["ray_geom"] == row["sea_geom"]
        assert row["ray_z"] == pytest.approx(want, abs=1e-5)


def test_a_sea_frame_shows_moving_waves_and_differs_from_calm_water():
    _gl_or_skip()
    from usv_mj.outputs.render import render_frames

    sea = load_scenario(preset="paper", overrides={"duration": 20.0, "sea": SEA})
    calm = load_scenario(preset="paper", overrides={"duration": 20.0})
    poses, times = [(0.0, 0.0, 0.3)] * 2, [6.0, 6.5]
    view = TopView(0.0, 0.0, 8.0)
    f_sea = render_frames(_record(sea, poses, times), rows=[0, 1], width=320, height=240, layers=(), views=view)
    (f_calm,) = render_frames(_record(calm, poses, times), rows=[0], width=320, height=240, layers=(), views=view)
    diff = np.abs(f_sea[0].astype(int) - f_calm.astype(int)).sum(axis=2) > 20
    assert diff.mean() > 0.3                                    # the water is not the calm plane
    moved = np.abs(f_sea[0].astype(int) - f_sea[1].astype(int)).sum(axis=2) > 10
    assert moved.mean() > 0.1                                   # the waves move between t = 6 and 6.5 s
    # the hull is still drawn on top of the water: its silhouette differs from an empty sea there
    (empty,) = render_frames(_record(sea, [(1e3, 1e3, 0.0)] * 2, times), rows=[0], width=320, height=240,
                             layers=(), views=view)
    hull = np.abs(f_sea[0].astype(int) - empty.astype(int)).sum(axis=2) > 60
    rows, cols = np.nonzero(hull[60:180, 100:220])
    assert len(rows) > 30


def test_moving_obstacles_follow_their_velocity_in_the_video():
    obstacles = [{"kind": "circle", "center": [6.0, 3.0], "radius": 0.8, "name": "buoy"},
                 {"kind": "box", "center": [2.0, -6.0], "size": [3.0, 1.2], "velocity": [0.5, 0.25], "name": "boat"}]
    sc = load_scenario(preset="paper", overrides={"duration": 20.0, "obstacles": obstacles})
    rec = _record(sc, [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)], [0.0, 4.0])
    plan = plan_frames(rec, rows=[0, 1], width=320, height=240)
    for spec in plan.frames:    # the buoy (6, 3), r = 0.8, is within 8 m of the hull: the top view shows it
        v = spec.view
        assert abs(6.0 - v.cx) + 0.8 < v.half_height * 320 / 240 and abs(3.0 - v.cy) + 0.8 < v.half_height
    out = _in_fresh_process("""
        import json
        from usv_mj.outputs.render.gl_backend import select_backend
        select_backend(None)
        import numpy as np
        from usv_mj import load_scenario
        from usv_mj.record.run_record import RunRecord
        from usv_mj.scene.compose import compose_scene, export_scene, obstacle_geom_name
        from usv_mj.outputs.render.planner import plan_frames
        from usv_mj.outputs.render.replay import FrameRenderer
        sc = load_scenario(preset="paper", overrides={"duration": 20.0, "obstacles": %r})
        rec = RunRecord.from_arrays({"t": np.array([0.0, 4.0]), "x": np.array([0.0, 1.0]), "y": np.zeros(2),
                                     "psi": np.zeros(2)}, metadata={"scenario": sc.to_dict()})
        plan = plan_frames(rec, rows=[0, 1], width=320, height=240)
        r = FrameRenderer(320, 240, model_path=export_scene(compose_scene(sc.obstacles)))
        mocap = r.model.body_mocapid[r.model.body(obstacle_geom_name(sc.obstacles[1]) + "_body").id]
        rows = []
        for spec in plan.frames:
            frame = r.render(spec)
            rows.append({"t": spec.t, "mocap": r.data.mocap_pos[mocap, :2].tolist(), "std": float(frame.std())})
        r.close()
        print(json.dumps({"rows": rows}))
    """ % (obstacles,))
    assert [row["t"] for row in out["rows"]] == [0.0, 4.0]
    for row in out["rows"]:
        want = (2.0 + 0.5 * row["t"], -6.0 + 0.25 * row["t"])
        np.testing.assert_allclose(row["mocap"], want, rtol=0, atol=1e-12)
        assert row["std"] > 5.0


def test_figure_and_scene_take_obstacles_without_a_boundary():
    """Moving obstacles have no static-plan inflation (None in the summary): nothing drawn, no error."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from usv_mj.scene.display import draw_obstacles, scene_entities
    from usv_mj.scenario.obstacles import ObstacleSpec

    obstacles = (ObstacleSpec("circle", (6.0, 3.0), 0.8, name="buoy"),
                 ObstacleSpec("box", (2.0, -6.0), 0.0, (3.0, 1.2), 0.0, (0.5, 0.25), name="boat"))
    fig, ax = plt.subplots()
    try:
        draw_obstacles(ax, obstacles, inflation=[1.5, None])
        assert len([ln for ln in ax.lines if ln.get_linestyle() == "--"]) == 1
    finally:
        plt.close(fig)
    entities = scene_entities(obstacles, 2.0, {"sec": 2, "nsec": 0}, [float("nan"), None])
    assert [len(e["lines"]) for e in entities] == [0, 0]
    assert entities[1]["cubes"][0]["pose"]["position"]["x"] == pytest.approx(3.0)   # 2 + 0.5 x 2 s
