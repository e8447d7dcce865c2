"""Off-screen rendering of runs (issue 4): GL backend choice, the replayed picture, the video file.

The hull's position in the image is checked against a pinhole projection computed here from the
top camera's pose (looking straight down from height D = h / tan(fovy/2) above the look-at point,
image right = world +x, image up = world +y) and MuJoCo's documented default fovy of 45 degrees
(models/scene.xml does not set another), not against anything the renderer reports.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from usv_mj.record.run_record import RunRecord
from usv_mj.outputs.render import gl_backend
from usv_mj.outputs.render.planner import TopView, default_speedup, do_pan_offset, frame_count, plan_frames

ROOT = Path(__file__).resolve().parents[1]


def _gl_or_skip():
    try:
        return gl_backend.select_backend()
    except gl_backend.GLUnavailableError as exc:  # pragma: no cover - CI installs Mesa
        pytest.skip(str(exc))


def straight_run(duration=4.0, dt=0.1, speed=0.5, eps=0.0):
    """A run along +x: hull at (speed t, 0.5, 0.1 rad), reference 1 m ahead on y = 0; Do & Pan errors with eps."""
    t = np.arange(0.0, duration + dt / 2, dt)
    x, y, psi = speed * t, np.full_like(t, 0.5), np.full_like(t, 0.1)
    xd, yd, psid = speed * t + 1.0, np.zeros_like(t), np.zeros_like(t)
    e1 = x + eps * np.cos(psi) - (xd + eps * np.cos(psid))
    e2 = y + eps * np.sin(psi) - (yd + eps * np.sin(psid))
    rho = 16 * np.exp(-0.05 * t) + 2
    cols = {"t": t, "x": x, "y": y, "psi": psi, "x_d": xd, "y_d": yd, "psi_d": psid, "e1": e1, "e2": e2,
            "e3": psi - psid, "rho1": rho, "rho2": rho, "rho3": np.full_like(t, 1.0), "z1": e1 / rho, "z2": e2 / rho,
            "z3": (psi - psid) / 1.0, "tau_u": 10 * np.sin(t), "q_tau_u": 10 * np.sin(t), "tau_r": np.cos(t),
            "q_tau_r": np.cos(t)}
    return RunRecord.from_arrays(cols, metadata={"preset": "test", "controller": "ppc", "plant": "analytic"})


# --- planning: closed forms, no GL ----------------------------------------------------------------


def test_default_speedup_maps_a_300s_run_to_900_frames_of_30s():
    assert default_speedup(300.0) == pytest.approx(10.0)
    assert frame_count(300.0, 30, 10.0) == 900
    assert default_speedup(12.0) == 1.0          # short runs play in real time, not in slow motion


def test_frames_span_the_run_from_first_to_last_row():
    rec = straight_run(duration=4.0, dt=0.1)
    plan = plan_frames(rec, fps=5, speedup=1.0, width=160, height=120)
    assert len(plan.frames) == 20                 # round(4 s * 5 fps / 1)
    assert plan.frames[0].t == 0.0 and plan.frames[-1].t == pytest.approx(4.0)
    ts = np.array([f.t for f in plan.frames])
    assert np.all(np.diff(ts) > 0)
    assert plan.played_speedup == pytest.approx(4.0 * 5 / 19)


def test_do_pan_offset_is_recovered_from_the_errors():
    eps = 5.7 / 191.75                            # SPEC §1: m23 / m22
    assert do_pan_offset(straight_run(eps=eps)) == pytest.approx(eps, rel=1e-9)
    plan = plan_frames(straight_run(eps=eps), fps=5, speedup=1.0, width=160, height=120)
    f = plan.frames[3]
    assert f.funnel_center[0] == pytest.approx(f.ref_pose[0] + eps * math.cos(f.ref_pose[2]))


def test_top_view_keeps_hull_reference_and_funnel_inside_the_image():
    rec = straight_run()
    w, h = 320, 240
    fovy = math.radians(45.0)
    for f in plan_frames(rec, fps=5, speedup=1.0, width=w, height=h).frames:
        v = f.view
        half_w = v.half_height * w / h
        for px, py in [f.pose[:2], f.ref_pose[:2],
                       (f.funnel_center[0] - f.funnel_half[0], f.funnel_center[1] - f.funnel_half[1]),
                       (f.funnel_center[0] + f.funnel_half[0], f.funnel_center[1] + f.funnel_half[1])]:
            assert abs(px - v.cx) < half_w and abs(py - v.cy) < v.half_height
        assert fovy > 0


def test_a_non_finite_tail_is_not_played():
    rec = straight_run()
    rec.data[rec.n_rows - 3:rec.n_rows, 1] = np.nan    # x of the last 3 rows
    plan = plan_frames(rec, fps=5, speedup=1.0, width=160, height=120)
    assert plan.t_end == pytest.approx(rec["t"][-4])


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="fps"):
        plan_frames(straight_run(), fps=0)
    with pytest.raises(ValueError, match="speedup"):
        plan_frames(straight_run(), speedup=float("nan"))
    from usv_mj.outputs.render.video import check_size

    with pytest.raises(ValueError, match="width = 161"):
        check_size(161, 120)


# --- GL backend -----------------------------------------------------------------------------------


def test_missing_gl_stack_gives_one_message_naming_the_packages(monkeypatch):
    monkeypatch.setattr(gl_backend, "_selected", None)
    monkeypatch.setattr(gl_backend, "probe", lambda b, timeout=60.0: (False, f"{b} library not found"))
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    with pytest.raises(RuntimeError) as info:
        gl_backend.select_backend()
    msg = str(info.value)
    for pkg in ("libegl1", "libegl-mesa0", "libgl1-mesa-dri", "libgles2", "libosmesa6"):
        assert pkg in msg
    assert "MUJOCO_GL=egl: egl library not found" in msg and "MUJOCO_GL=osmesa" in msg
    assert "Traceback" not in msg


def test_user_choice_overrides_the_automatic_one(monkeypatch):
    tried = []
    monkeypatch.setattr(gl_backend, "_selected", None)
    monkeypatch.setattr(gl_backend, "probe", lambda b, timeout=60.0: (tried.append(b), (True, "fake"))[1])
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    assert gl_backend.select_backend() == "osmesa" and tried == ["osmesa"]
    assert gl_backend.select_backend("egl") == "egl" and tried[-1] == "egl"
    with pytest.raises(RuntimeError, match="not a rendering backend"):
        gl_backend.select_backend("vulkan")
    monkeypatch.setattr(gl_backend, "_selected", None)


def test_egl_or_osmesa_starts_here():
    backend = _gl_or_skip()
    assert backend in ("egl", "osmesa", "glfw")
    assert gl_backend.probe(backend)[0]


# --- the picture ----------------------------------------------------------------------------------


def _fovy_deg() -> float:
    """The scene's <visual><global fovy>, or MuJoCo's documented default of 45 degrees."""
    root = ET.parse(ROOT / "models" / "scene.xml").getroot()
    g = root.find("visual/global")
    return float(g.get("fovy", 45.0)) if g is not None else 45.0


def project_top(px, py, view: TopView, width, height, fovy_deg, z=0.0):
    """Pixel (column, row) of world point (px, py, z) in the straight-down camera of ``view``."""
    t = math.tan(math.radians(fovy_deg) / 2)
    dist = view.half_height / t                   # camera height above the water (z = 0)
    f = (height / 2) / t                           # focal length in pixels
    depth = dist - z
    return width / 2 + f * (px - view.cx) / depth, height / 2 - f * (py - view.cy) / depth


def pose_record(poses):
    """A record with one row per (x, y, psi) hull pose, reference NaN (nothing else to draw)."""
    poses = np.asarray(poses, float)
    n = len(poses)
    return RunRecord.from_arrays({"t": np.arange(n, dtype=float), "x": poses[:, 0], "y": poses[:, 1],
                                  "psi": poses[:, 2]})


def test_a_rendered_frame_is_not_blank():
    _gl_or_skip()
    from usv_mj.outputs.render import render_frames

    (frame,) = render_frames(straight_run(), rows=[20], width=160, height=120)
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 10.0
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 50


def test_hull_pixel_position_moves_with_the_recorded_state():
    _gl_or_skip()
    from usv_mj.outputs.render import render_frames

    w, h = 320, 240
    view = TopView(0.0, 0.0, 10.0)
    a, b = (3.0, 2.0), (-4.0, -1.5)
    rec = pose_record([(1e4, 1e4, 0.0), (*a, 0.0), (*b, 0.0), (*b, math.pi / 2)])
    empty, fa, fb, fb90 = render_frames(rec, rows=[0, 1, 2, 3], width=w, height=h, layers=(), views=view)
    fovy = _fovy_deg()
    found = []
    for frame in (fa, fb, fb90):
        mask = np.abs(frame.astype(int) - empty.astype(int)).sum(axis=2) > 40
        assert mask.sum() > 30, "the hull is not in the picture"
        rows, cols = np.nonzero(mask)
        found.append((cols.mean(), rows.mean(), cols.max() - cols.min() + 1, rows.max() - rows.min() + 1))
    pa, pb = project_top(*a, view, w, h, fovy), project_top(*b, view, w, h, fovy)
    # the silhouette's centre lies within 0.15 m (2 px here) of the body origin's projection
    for (u, v, _, _), (pu, pv) in zip(found[:2], (pa, pb)):
        assert abs(u - pu) < 3.0 and abs(v - pv) < 3.0, ((u, v), (pu, pv))
    # the displacement between the two poses is the projected displacement (about 84 x 42 px)
    du, dv = found[1][0] - found[0][0], found[1][1] - found[0][1]
    assert du == pytest.approx(pb[0] - pa[0], abs=1.5) and dv == pytest.approx(pb[1] - pa[1], abs=1.5)
    # psi = 0: the 2 m x 0.8 m hull lies along the image's x; psi = 90 deg: along its y
    assert found[1][2] > 1.8 * found[1][3]
    assert found[2][3] > 1.8 * found[2][2]
    px_per_m = (h / 2) / view.half_height
    assert found[1][2] == pytest.approx(2.2 * px_per_m, rel=0.25)   # length incl. the outboard motor


def test_the_funnel_box_and_the_overlay_are_drawn():
    _gl_or_skip()
    from usv_mj.outputs.render import render_frames
    from usv_mj.outputs.render.planner import FUNNEL_OK_RGBA

    rec = straight_run()
    bare, full = render_frames(rec, rows=[10, 10], width=320, height=240, layers=(), views=None)[0], \
        render_frames(rec, rows=[10], width=320, height=240)[0]
    changed = np.abs(full.astype(int) - bare.astype(int)).sum(axis=2) > 40
    assert changed.mean() > 0.05                  # overlay panel, legend, funnel, path, ghost
    green = np.array([int(255 * c) for c in FUNNEL_OK_RGBA[:3]])
    near_green = np.abs(full.astype(int) - green).sum(axis=2) < 90
    assert near_green.sum() > 50                  # the funnel's outline (the run is inside its funnel)


# --- the video ------------------------------------------------------------------------------------


@pytest.mark.parametrize("workers", [1, 2])
def test_mp4_decodes_with_the_expected_frame_count_and_size(tmp_path, workers):
    _gl_or_skip()
    import imageio.v3 as iio
    from PIL import Image

    from usv_mj.outputs.render import render_run

    rec = straight_run(duration=4.0)
    out = tmp_path / "clip.mp4"
    info = render_run(rec, out, width=160, height=120, fps=5, speedup=1.0, workers=workers, progress=False,
                      segment_frames=7)
    expected = 20                                  # round(4 s * 5 fps / 1x)
    assert info["frames"] == expected and Path(info["mp4"]) == out
    frames = list(iio.imiter(out))
    assert len(frames) == expected
    assert frames[0].shape == (120, 160, 3)
    png = Image.open(info["png"])
    assert png.size == (160, 120)
    assert Path(info["png"]) == out.with_suffix(".png")
    # the still is the last frame (up to H.264's loss)
    assert np.abs(np.asarray(png).astype(int) - frames[-1].astype(int)).mean() < 12


def test_render_command_reports_a_missing_run(tmp_path, capsys):
    import argparse

    from usv_mj.cli.render import add_arguments, run as run_command

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args([str(tmp_path / "nope"), "--size", "320x240"])
    assert args.size == (320, 240)
    assert run_command(args) == 2
    assert "does not exist" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        parser.parse_args(["run", "--size", "321x240"])


def test_render_command_replays_an_mcap_run(tmp_path, capsys):
    """usv-mj render RUN: simulate 2 s into run.mcap, render the run directory, decode the video."""
    _gl_or_skip()
    import argparse

    import imageio.v3 as iio

    from usv_mj import load_scenario, simulate
    from usv_mj.cli.render import add_arguments, run as run_command

    runlog = pytest.importorskip("usv_mj.outputs.log")
    scenario = load_scenario(preset="paper", overrides={"duration": 2.0, "plant": {"kind": "analytic"}})
    with runlog.RunLogWriter(tmp_path / "run.mcap", scenario) as writer:
        simulate(scenario, sinks=[writer.sink("main")])
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args([str(tmp_path), "--size", "160x120", "--fps", "10", "--speedup", "0.5",
                              "--no-progress", "--workers", "1"])
    assert run_command(args) == 0, capsys.readouterr().err
    frames = list(iio.imiter(tmp_path / "run.mp4"))
    assert len(frames) == 40                       # round(2 s * 10 fps / 0.5)
    assert frames[0].shape == (120, 160, 3) and (tmp_path / "run.png").is_file()
    assert "frames/s" in capsys.readouterr().out


def test_workers_started_ahead_render_two_videos(tmp_path):
    _gl_or_skip()
    import imageio.v3 as iio

    from usv_mj.outputs.render import RenderWorkers, render_run

    with RenderWorkers(width=160, height=120, workers=2) as pool:
        for duration, expected in ((2.0, 10), (3.0, 15)):
            info = render_run(straight_run(duration=duration), tmp_path / f"v{duration:g}.mp4", width=160,
                              height=120, fps=5, speedup=1.0, pool=pool, progress=False, segment_frames=4)
            assert info["frames"] == expected == len(list(iio.imiter(info["mp4"])))
        with pytest.raises(ValueError, match="workers were started for"):
            render_run(straight_run(), tmp_path / "bad.mp4", width=320, height=240, pool=pool, progress=False)
